"""The servos' own Profile Acceleration, the second line of defence behind the loop's acceleration limit: the
registers the driver writes, and what the simulated servos (velocity-based profile, sim/profile.py) then do with a
goal that jumps and with the loop's acceleration-limited stream of goals."""

from __future__ import annotations

import numpy as np
import pytest

import sim
from drivers import units
from drivers.control_table import Instruction
from drivers.servo_plan import servo_acceleration
from retarget.control.bus import ShutdownMode
from retarget.control.limits import StepLimiter
from tests.helpers import PROFILE_ACCELERATION

WAIST = 1  #: the waist's servo ID on the wx250s (joint 0, no shadow)
GRIPPER = 9


def profile_accelerations(sim_bus: sim.SimBus) -> dict[int, int]:
    return {s.id: s.get("Profile Acceleration") for s in sim_bus.servos}


def waist_angle(sim_bus: sim.SimBus) -> float:
    return float(units.pulses_to_rad(sim_bus.servo(WAIST).get("Present Position")))


@pytest.mark.parametrize(
    ("dt", "expected"),
    # max_velocity / (2 dt) at 180 deg/s, over 0.374508 rad/s^2 per unit (214.577 rev/min^2), rounded down
    [(None, 419), (0.01, 419), (0.02, 209), (0.002, 2097)],
    ids=["dt-unset", "100Hz", "50Hz", "500Hz"],
)
def test_each_joint_servo_gets_one_ticks_lag_worth_of_profile_acceleration(make_bus, url, sim_bus, arm, dt, expected):
    make_bus(url, shutdown=ShutdownMode.HOLD, dt=dt).connect()
    registers = profile_accelerations(sim_bus)
    assert registers.pop(GRIPPER) == 0  # the gripper's profile stays unlimited (its current limit bounds it)
    assert set(registers.values()) == {expected}
    # never below the loop's own limit: at a low rate the joint's max_acceleration is the larger
    slow = servo_acceleration(arm.joints[0], dt=10.0)
    assert slow == arm.joints[0].max_acceleration > arm.joints[0].max_velocity / 20.0


@pytest.mark.parametrize(("value", "expected"), [(0.0, 0), (50.0, 133)], ids=["unlimited", "explicit"])
def test_an_explicit_profile_acceleration_is_written_as_asked(make_bus, url, sim_bus, value, expected):
    make_bus(url, shutdown=ShutdownMode.HOLD, dt=0.01, profile_acceleration=value).connect()
    assert set(profile_accelerations(sim_bus).values()) == {expected}


def test_a_goal_that_jumps_is_ramped_by_the_servo(make_bus, url, sim_bus, arm, clock):
    """One goal 0.5 rad away: the servo speeds up at its Profile Acceleration (157 rad/s^2 at 100 Hz), not at once:
    after t seconds it has gone a t^2 / 2, within a pulse; with Profile Acceleration 0 it jumps to speed."""
    moved = {}
    for name, value in [("default", None), ("unlimited", 0.0)]:
        bus = make_bus(url, shutdown=ShutdownMode.HOLD, dt=0.01, profile_acceleration=value, step_limit=False)
        bus.connect()
        goal = bus.read_positions()
        goal[0] += 0.5
        bus.write_goals(goal)
        start = waist_angle(sim_bus)
        clock.advance(0.01)
        moved[name] = waist_angle(sim_bus) - start
        bus.close()
        clock.advance(3.0)  # settle before the next run
    a = float(units.accel_units_to_rad_s2(419))
    assert moved["default"] == pytest.approx(a * 0.01**2 / 2, abs=units.RAD_PER_PULSE)
    assert moved["unlimited"] > 3 * moved["default"]


@pytest.mark.parametrize(("value", "lag_ticks"), [(None, 1.0), ("ours", None)], ids=["default", "at-our-limit"])
def test_the_servo_follows_the_loops_stream_within_one_ticks_travel(make_bus, url, sim_bus, arm, clock, value,
                                                                    lag_ticks):  # fmt: skip
    """The waist streamed at 100 Hz through the loop's own step limiter (full speed, our acceleration limit, a
    reversal): with the default Profile Acceleration the servo trails the last goal by at most one tick's travel at
    full speed (plus 2 pulses); at our own limit it would trail by several ticks' worth (why it is set higher)."""
    dt = 0.01
    joint = arm.joints[0]
    accel = joint.max_acceleration if value == "ours" else None
    bus = make_bus(url, shutdown=ShutdownMode.HOLD, dt=dt, profile_acceleration=accel)
    bus.connect()
    q = bus.read_positions()
    limiter = StepLimiter(arm.lower, arm.upper, arm.max_velocity * dt, q, max_accel=arm.max_acceleration * dt**2)
    lags = []
    for k in range(300):  # out to +1.2 rad, back to -1.2 rad
        goal = q.copy()
        goal[0] = 1.2 if k < 120 else -1.2
        limiter.step(goal.tolist(), elapsed=1)
        bus.write_goals(np.array(limiter.q))
        clock.advance(dt)
        lags.append(abs(limiter.q[0] - waist_angle(sim_bus)))
    one_tick = joint.max_velocity * dt
    assert min(limiter.q[0], waist_angle(sim_bus)) < -1.0  # it went out and came back
    if lag_ticks is not None:
        assert max(lags) <= lag_ticks * one_tick + 2 * units.RAD_PER_PULSE
    else:
        assert max(lags) > 3 * one_tick


def test_the_rest_move_accelerates_at_each_joints_max_acceleration(make_bus, url, sim_bus, arm, clock):
    bus = make_bus(url, shutdown=ShutdownMode.REST, dt=0.01)
    bus.connect()
    mark = len(sim_bus.log)
    bus.close()
    writes = [
        e.params
        for e in list(sim_bus.log)[mark:]
        if e.instruction == Instruction.SYNC_WRITE and int.from_bytes(e.params[0:2], "little") == PROFILE_ACCELERATION
    ]
    assert len(writes) == 1
    body = writes[0][4:]
    values = {body[k]: int.from_bytes(body[k + 1 : k + 5], "little") for k in range(0, len(body), 5)}
    expected = int(units.rad_s2_to_accel_units(arm.joints[0].max_acceleration))
    assert values == dict.fromkeys(range(1, 9), expected)
