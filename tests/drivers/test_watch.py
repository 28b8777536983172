"""The watch: every servo on the bus, those outside the position read included (the gripper, ID 9 on the wx250s),
is checked during the run, so an overload or an unplug there ends it within a second, by the same rules as a
position read (a BusError naming the servo and the alert; a silent servo by the stale window), and costs the
loop one PING every ``watch_period``.
"""

from __future__ import annotations

import pytest

import sim
from drivers import DynamixelBus
from drivers.control_table import Instruction
from retarget.control import ControlLoop, LoopConfig
from retarget.control.bus import close_after_failure
from retarget.control.clock import VirtualClock
from retarget.errors import BusError
from tests.helpers import circle_targets, torque

GRIPPER = 9
FAULT_AT = 1.0  #: s after the simulated bus was built


def run_until_fault(
    arm, faults: sim.Faults, *, after_connect: bool = False, **options: object
) -> tuple[BusError | None, float, sim.SimBus]:
    """A replay-like run (circle targets, looped, 100 Hz, pipelined read-back, lead-in off) of at most 4 s on the
    simulated wx250s with ``faults`` (``after_connect``: from the first tick on); (the run's BusError or None, the
    time it was raised on the virtual clock, from the bus's start, the simulated bus).  Connect must succeed."""
    clock = VirtualClock()
    simbus = sim.SimBus.from_arm(arm, clock=clock, faults=sim.Faults() if after_connect else faults)
    url = sim.attach(simbus)
    config = LoopConfig(loop=True, max_ticks=400, lead_in_speed=0.0)
    loop = ControlLoop(arm, circle_targets(arm), config=config, clock=clock, pipeline=True)
    bus = DynamixelBus(arm, url, clock=clock, shutdown="off", dt=0.01, check_latency=False, **options)  # type: ignore[arg-type]
    error: BusError | None = None
    raised_at = clock.now()
    try:
        bus.connect()
        if after_connect:
            simbus.faults = faults
        try:
            loop.run(bus)
        except BusError as exc:
            error, raised_at = exc, clock.now()
            close_after_failure(bus)  # an unplugged servo also fails its torque off: logged
        bus.close()
    finally:
        sim.unregister(url)
    assert not bus.connected
    return error, raised_at - simbus.t_start, simbus


def test_no_fault_the_gripper_is_pinged_every_watch_period(arm):
    error, _, simbus = run_until_fault(arm, sim.Faults())
    assert error is None
    pings = [e for e in simbus.log if e.instruction == Instruction.PING and e.id == GRIPPER]
    # connect pings every servo once; then one per 0.2 s = 20 ticks of the 400
    assert len(pings) == 1 + 400 // 20


@pytest.mark.parametrize("fault", ["overload", "overheating"])
def test_a_gripper_hardware_error_ends_the_run_within_a_second(arm, fault):
    error, at, simbus = run_until_fault(arm, sim.Faults.from_options(hwerror=[f"{GRIPPER}:{fault}@{FAULT_AT}"]))
    assert error is not None, "the gripper's hardware error went unnoticed"
    assert error.ids == (GRIPPER,)
    with pytest.raises(BusError, match=rf"^servo 9: hardware error: {fault}; "):
        raise error
    assert FAULT_AT <= at <= FAULT_AT + 1.0
    assert torque(simbus, arm) == [0] * 8  # the shutdown ran (OFF)


def test_an_unplugged_gripper_ends_the_run_within_a_second(arm):
    error, at, _ = run_until_fault(arm, sim.Faults(unplug={GRIPPER: FAULT_AT}))
    assert error is not None, "the unplugged gripper went unnoticed"
    assert error.ids == (GRIPPER,)
    with pytest.raises(BusError, match=r"^servo 9: no status packet \(PING, the watch\).*too long.*9: missed 11 "):
        raise error
    assert FAULT_AT <= at <= FAULT_AT + 1.0


def test_a_shadow_hardware_error_ends_the_run_within_a_second(arm):
    """Servo 3 is the shoulder's shadow: it is in the position read, whose status packets carry its Alert bit."""
    error, at, _ = run_until_fault(arm, sim.Faults.from_options(hwerror=[f"3:overload@{FAULT_AT}"]))
    assert error is not None and error.ids == (3,)
    with pytest.raises(BusError, match=r"^servo 3: hardware error: overload; "):
        raise error
    assert FAULT_AT <= at <= FAULT_AT + 1.0


def test_recover_reboots_the_gripper_and_the_run_goes_on(arm):
    error, _, simbus = run_until_fault(
        arm, sim.Faults.from_options(hwerror=[f"{GRIPPER}:overload@{FAULT_AT}"]), recover=True
    )
    assert error is None
    assert any(e.instruction == Instruction.REBOOT and e.id == GRIPPER for e in simbus.log)


def test_a_gripper_that_misses_a_few_pings_is_watched_every_tick_until_it_answers(arm):
    """Silent for a moment (fewer reads than ``max_stale_ticks``): watched every tick meanwhile, then every
    ``watch_period`` again; the run completes."""
    faults = sim.Faults(servos={GRIPPER: sim.ReplyFaults(drop=0.6)}, seed=5)
    error, _, simbus = run_until_fault(
        arm, faults, after_connect=True, retries=0, max_stale_ticks=50, max_stale_fraction=1.0
    )
    assert error is None
    pings = [e for e in simbus.log if e.instruction == Instruction.PING and e.id == GRIPPER]
    assert len(pings) > 1 + 400 // 20


def test_watch_period_option(arm):
    assert DynamixelBus(arm, "sim://wx250s", dt=0.01).watch_ticks == 20
    assert DynamixelBus(arm, "sim://wx250s", dt=0.001, watch_period=0.5).watch_ticks == 500
    assert DynamixelBus(arm, "sim://wx250s", dt=0.1, watch_period=0.01).watch_ticks == 1
    assert DynamixelBus(arm, "sim://wx250s").watch_ticks == 20
    for bad in (0.0, -1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="watch_period"):
            DynamixelBus(arm, "sim://wx250s", watch_period=bad)
