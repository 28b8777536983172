"""The tick path of DynamixelBus (write_goals, read_positions) works on plain floats for speed: check it against
the vectorized reference (``drivers.units`` and numpy clipping) on the simulated servos, seeded, for arms with
shadows, offsets and step limits.
"""

from __future__ import annotations

import numpy as np
import pytest

import retarget
import sim
from drivers import units
from drivers.dynamixel_bus import DynamixelBus, plan_servos
from retarget.control.bus import ShutdownMode
from retarget.control.clock import VirtualClock
from retarget.errors import BusError
from tests.helpers import GOAL, goal_writes


@pytest.fixture(params=["wx250s", "koch"], ids=["wx250s", "koch"])
def rig(request: pytest.FixtureRequest):
    """(arm, simulated bus, its URL, the shared clock) for one bundled arm."""
    arm = retarget.load_arm(request.param)
    clock = VirtualClock()
    simbus = sim.SimBus.from_arm(arm, clock=clock, return_delay_time=0)
    url = sim.attach(simbus)
    yield arm, simbus, url, clock
    sim.unregister(url)


def reference_pulses(bus: DynamixelBus, goal: np.ndarray) -> dict[int, int]:
    """Goal Position per joint servo, the vectorized way: encode the joint goal, clip to the servo's limits."""
    out = {}
    for s in plan_servos(bus.arm):
        if s.role == "gripper":
            continue
        pulses = int(units.rad_to_pulses(goal[s.joint], offset=s.offset))
        out[s.id] = int(np.clip(pulses, s.min_pulse, s.max_pulse))
    return out


@pytest.mark.parametrize("dt", [None, 0.01], ids=["no-step-limit", "step-limit"])
def test_goals_on_the_wire_match_the_vectorized_encoding_seeded(rig, dt):
    arm, simbus, url, clock = rig
    bus = DynamixelBus(arm, url, clock=clock, shutdown=ShutdownMode.OFF, check_latency=False, dt=dt)
    rng = np.random.default_rng(7)
    with bus:
        last = bus.read_positions()
        for k in range(200):
            span = bus.upper - bus.lower
            q = rng.uniform(bus.lower - 0.2 * span, bus.upper + 0.2 * span)  # some beyond the limits
            if k % 4 == 0:  # exactly between two pulses: rounds half to even, as np.rint does
                q = np.round(q / units.RAD_PER_PULSE) * units.RAD_PER_PULSE + units.RAD_PER_PULSE / 2
            bus.write_goals(q)
            goal = np.clip(q, bus.lower, bus.upper)
            if bus.max_step is not None:
                goal = last + np.clip(goal - last, -bus.max_step, bus.max_step)
            assert goal_writes(simbus)[-1] == reference_pulses(bus, goal), k
            last = goal


def test_positions_decode_as_pulses_to_rad_seeded(rig):
    arm, simbus, url, clock = rig
    bus = DynamixelBus(arm, url, clock=clock, shutdown=ShutdownMode.OFF, check_latency=False)
    primaries = sorted((s for s in plan_servos(arm) if s.role == "primary"), key=lambda s: s.joint)
    rng = np.random.default_rng(11)
    with bus:
        for _ in range(10):
            bus.write_goals(rng.uniform(bus.lower, bus.upper))
            clock.advance(0.05)  # part of the way: positions between goals
            q = bus.read_positions()
            present = [simbus.servo(s.id).get("Present Position") for s in primaries]
            expected = units.pulses_to_rad(np.array(present), offset=[s.offset for s in primaries])
            assert q.dtype == np.float64 and q.shape == (arm.n_joints,)
            np.testing.assert_array_equal(q, expected)


def test_a_failed_goal_write_names_every_servo_of_the_packet(rig):
    arm, simbus, url, clock = rig
    bus = DynamixelBus(arm, url, clock=clock, shutdown=ShutdownMode.OFF, check_latency=False)
    ids = tuple(s.id for s in plan_servos(arm) if s.role != "gripper")
    with bus:
        q = bus.read_positions()
        bus.link.port.is_using = True  # another transaction holds the port: the SDK refuses to send
        with pytest.raises(BusError, match=rf"port busy \(sync write at address {GOAL}\)") as info:
            bus.write_goals(q)
        assert info.value.ids == tuple(sorted(ids))
        bus.link.release()
