"""The fault matrix: lost and corrupt replies at 1, 5 and 20 % with fixed seeds, on the simulated wx250s.

Each run connects on the noisy bus (connect retries every write) and plays a short circle of targets through the
pipelined loop.  At 1 % and 5 % every run completes; at 20 % a run completes or stops with a clean BusError at
the stale window, naming the servo.  Either way no goal outside the joint limits reached a servo, and the
telemetry's ``stale`` column adds up to the summary's stale reads.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

import sim
from drivers import DynamixelBus
from drivers.dynamixel_bus import plan_servos
from retarget.control import ControlLoop, LoopConfig, TickRecord
from retarget.control.summary import RunSummary
from retarget.errors import BusError
from tests.helpers import circle_targets, goal_writes, lossy_sdk_timeout

SEEDS = (1, 2)
#: a BusError at 20 % loss may only be the stale window's (or a transaction that ran out of retries), by servo
WINDOW = r"^servo \d+: no status packet "


@pytest.fixture(autouse=True)
def _short_timeouts(monkeypatch: pytest.MonkeyPatch) -> None:
    lossy_sdk_timeout(monkeypatch)


def run_noisy(
    arm, faults: sim.Faults, *, after_connect: bool = False, **options: object
) -> tuple[object, list[TickRecord], sim.SimBus]:
    """Connect and play 1 s of circle targets (after a ~1 s lead-in) on a bus with ``faults`` (the wire model on;
    ``after_connect``: from the first tick on); returns (the summary or the BusError, the tick records, the
    simulated bus)."""
    from retarget.control.clock import VirtualClock

    clock = VirtualClock()
    faults.wire = True
    simbus = sim.SimBus.from_arm(arm, clock=clock, faults=sim.Faults(wire=True) if after_connect else faults)
    url = sim.attach(simbus)
    records: list[TickRecord] = []
    config = LoopConfig(end=1.0, lead_in_speed=2.0)
    loop = ControlLoop(arm, circle_targets(arm), config=config, clock=clock, on_tick=records.append, pipeline=True)
    bus = DynamixelBus(arm, url, clock=clock, shutdown="off", dt=0.01, check_latency=False, **options)  # type: ignore[arg-type]
    try:
        with bus:
            simbus.faults = faults
            outcome: object = loop.run(bus)
    except BusError as exc:
        outcome = exc
    finally:
        sim.unregister(url)
    assert not bus.connected
    return outcome, records, simbus


def assert_within_limits(arm, records: list[TickRecord], simbus: sim.SimBus) -> None:
    """Every commanded pose lies within the joint limits, and every goal a servo got within its own limits."""
    if records:
        q = np.array([r.q_cmd for r in records])
        assert np.all(q >= arm.lower - 1e-9) and np.all(q <= arm.upper + 1e-9)
    limits = {s.id: (s.min_pulse, s.max_pulse) for s in plan_servos(arm)}
    writes = goal_writes(simbus)
    assert writes
    for write in writes:
        for dxl_id, pulse in write.items():
            lo, hi = limits[dxl_id]
            assert lo <= pulse <= hi, (dxl_id, pulse)


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("rate", [0.01, 0.05, 0.20])
@pytest.mark.parametrize("fault", ["drop", "corrupt"])
def test_noisy_bus_completes_or_stops_at_the_window(arm, fault, rate, seed):
    outcome, records, simbus = run_noisy(arm, sim.Faults(bus=sim.ReplyFaults(**{fault: rate}), seed=seed))
    assert_within_limits(arm, records, simbus)
    if isinstance(outcome, BusError):
        assert rate >= 0.2, f"{fault}={rate} seed={seed} must complete, stopped: {outcome}"
        with pytest.raises(BusError, match=WINDOW):
            raise outcome
        return
    summary = outcome
    assert not summary.interrupted and summary.ticks == 101 and summary.bus_errors == 0  # clip times 0..1 s
    assert summary.bus_retries > 0 or rate < 0.05
    assert sum(r.stale for r in records) == summary.stale_reads
    assert summary.worst_stale_ticks <= 10
    stale = [r for r in records if r.stale]
    assert all(r.q_present is not None for r in stale)


def test_a_servo_lost_most_of_the_time_stops_cleanly_at_the_window(arm):
    """Servo 6 (forearm roll) loses 90 % of its replies from the first tick on: stale most ticks, the run stops
    at the window with one BusError naming it and the loss seen; the goals went out every tick until then."""
    faults = sim.Faults(servos={6: sim.ReplyFaults(drop=0.9)}, seed=3)
    outcome, records, simbus = run_noisy(arm, faults, after_connect=True, max_stale_ticks=5)
    assert isinstance(outcome, BusError) and outcome.ids == (6,)
    expected = r"^servo 6: no status packet \(Present Position\).*too long.*6: stale \d+ reads"
    with pytest.raises(BusError, match=expected):
        raise outcome
    assert re.search(r"\d+% of \d+ replies lost", str(outcome))
    assert_within_limits(arm, records, simbus)
    assert records and sum(r.stale for r in records) > 0
    # the failed run's summary goes with the error: the ticks that ran, the failure counted
    summary = outcome.summary
    assert isinstance(summary, RunSummary) and summary.ticks + summary.lead_in_ticks > 0 and summary.bus_errors >= 1
    # every recorded stale read, plus the one of the read that faulted the bus (its tick has no record)
    assert summary.stale_reads == sum(r.stale for r in records) + 1


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("rate", [0.05, 0.20])
def test_a_lossy_gripper_is_watched_without_stopping_the_run(arm, rate, seed):
    """The gripper (9) is outside the position read: the watch PINGs it every 0.2 s; losing its replies costs
    retries, never the run."""
    faults = sim.Faults(servos={9: sim.ReplyFaults(drop=rate)}, seed=seed)
    outcome, records, simbus = run_noisy(arm, faults, after_connect=True)
    assert not isinstance(outcome, BusError), outcome
    assert outcome.ticks == 101 and outcome.bus_errors == 0  # type: ignore[attr-defined]
    assert_within_limits(arm, records, simbus)


@pytest.mark.parametrize(
    ("fault", "expected"),
    [
        pytest.param(sim.Faults(unplug={9: 1.2}), r"^servo 9: no status packet \(PING, the watch\)", id="unplug"),
        pytest.param(
            sim.Faults.from_options(hwerror=["9:overload@1.2"]), r"^servo 9: hardware error: overload; ", id="overload"
        ),
    ],
)
def test_a_gripper_fault_stops_the_run_cleanly(arm, fault, expected):
    """Unplugged or overloaded 1.2 s after the bus started (during the clip): a clean stop naming servo 9, with
    every goal until then within the limits."""
    outcome, records, simbus = run_noisy(arm, fault)
    assert isinstance(outcome, BusError) and outcome.ids == (9,)
    with pytest.raises(BusError, match=expected):
        raise outcome
    assert_within_limits(arm, records, simbus)
