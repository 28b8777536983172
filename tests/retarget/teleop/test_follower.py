"""Teleop sessions on the simulated bus (through the real driver), checked from the simulated servos' registers
with an independent FK: one-shot reached, unreachable -> nearest point, a stream followed in order, garbage
causes no motion, a stale stream holds, holding runs no IK, the Cartesian speed limit."""

from __future__ import annotations

import io
import random

import numpy as np
import pytest

from retarget.control import LoopConfig, TickRecord
from retarget.control.clock import VirtualClock
from retarget.errors import ConfigError
from retarget.teleop import Follower, Phase, run_teleop, tool_point
from retarget.teleop.gate import TargetBounds, TargetGate
from retarget.teleop.sources import OneShotSource, Source, StdinSource, UdpSource
from tests.helpers import garbage, goal_registers, servo_joint_angles, wx250s_tool

# ------------------------------------------------------------------------------------------------ independent FK


#: WidowX-250 6DOF from the Interbotix URDF (wx250s.urdf.xacro): joint origin (all rpy 0) and axis, tool offset


def test_independent_fk_matches_arm_fk(arm):
    rng = np.random.default_rng(0)
    for _ in range(20):
        q = rng.uniform(arm.lower, arm.upper)
        np.testing.assert_allclose(wx250s_tool(q), tool_point(arm, q), atol=1e-12)


# ------------------------------------------------------------------------------------------------ harness


@pytest.fixture
def session(arm):
    """``session(source_factory, **follower_kwargs)`` -> (result, records, simbus, goals after connect)."""
    import sim
    from drivers import DynamixelBus

    def go(make_source, *, max_ticks=None, on_tick=None, settle_time=2.0, ref=None, **kwargs):
        clock = VirtualClock()
        simbus = sim.SimBus.from_arm(arm, clock=clock, faults=sim.Faults(wire=True))
        url = sim.attach(simbus)
        gate = TargetGate(TargetBounds.for_arm(arm), clock=clock)
        source = make_source(gate)
        follower = Follower(arm, source, clock=clock, rate=100.0, **kwargs)
        if ref is not None:
            ref.append(follower)
        records: list[TickRecord] = []

        def tick(r):
            records.append(r)
            if on_tick is not None:
                on_tick(r, source)

        bus = DynamixelBus(arm, url, clock=clock, shutdown="hold")
        bus.connect()
        goals0 = goal_registers(simbus)
        try:
            result = run_teleop(
                arm,
                follower,
                config=LoopConfig(max_ticks=max_ticks),
                clock=clock,
                bus=bus,
                on_tick=tick,
                settle_time=settle_time,
            )
        finally:
            bus.close()
            source.close()
            sim.unregister(url)
        return result, records, simbus, goals0, follower

    return go


# ------------------------------------------------------------------------------------------------ one shot


@pytest.mark.parametrize("to", ["0.3,0,0.2", "0.2,0.2,0.35", "0.35,-0.15,0.1"], ids=["front", "left-high", "right-low"])
def test_one_shot_is_reached_on_the_servos(arm, session, to):
    result, records, simbus, _, _ = session(lambda g: OneShotSource(g, to))
    target = np.array([float(v) for v in to.split(",")])
    reached = wx250s_tool(servo_joint_angles(simbus, arm))
    assert np.linalg.norm(reached - target) < 3e-3  # IK tolerance + a tick of quantisation per joint
    np.testing.assert_allclose(result.reached, reached, atol=1e-9)  # the result reports the servos' point
    assert result.reached_target and result.residual == pytest.approx(np.linalg.norm(reached - target))
    assert [v.reached for v in result.visits] == [True]
    assert not result.summary.interrupted and result.summary.bus_errors == 0
    q = np.array([r.q_cmd for r in records])
    assert np.all(q >= arm.lower) and np.all(q <= arm.upper)
    assert np.all(np.abs(np.diff(q, axis=0)) <= arm.max_velocity / 100 + 1e-12)


def test_unreachable_goes_to_the_nearest_point(arm, session):
    from retarget.mapping import arm_geometry

    result, _, simbus, _, follower = session(lambda g: OneShotSource(g, "0.75,0,0.3"))
    target = np.array([0.75, 0, 0.3])
    reached = wx250s_tool(servo_joint_angles(simbus, arm))
    g = arm_geometry(arm)
    # stretched toward the target: on the line from the shoulder pivot, at the full reach
    direction = (target - g.pivot) / np.linalg.norm(target - g.pivot)
    along = reached - g.pivot
    assert np.linalg.norm(along) == pytest.approx(g.reach, abs=0.01)
    assert np.linalg.norm(along - direction * (along @ direction)) < 0.01
    assert not result.reached_target and result.residual > 0.05
    assert [v.reached for v in result.visits] == [False] and follower.phase is Phase.HOLDING


def test_holding_runs_no_ik(arm, session):
    result, records, _, _, _ = session(lambda g: OneShotSource(g, "0.3,0,0.2"), settle_time=0.5)
    held = [r for r in records if r.tick > result.visits[-1].tick]
    assert result.stats.holds == len(held) >= 1
    assert all(r.ik_sweeps == 0 for r in held)
    assert len({tuple(r.q_cmd) for r in held}) == 1


@pytest.mark.parametrize("max_speed", [0.05, 0.2], ids=["5cm/s", "20cm/s"])
def test_cartesian_speed_limit(arm, session, max_speed):
    result, records, _, _, _ = session(lambda g: OneShotSource(g, "0.35,0.1,0.3"), max_speed=max_speed)
    moving = [r for r in records if r.tick <= result.visits[0].tick]
    steps = np.linalg.norm(np.diff([r.target for r in moving], axis=0), axis=1) / np.diff([r.tick for r in moving])
    assert steps.max() <= max_speed / 100 + 1e-12
    assert steps.max() > 0.9 * max_speed / 100  # and it does move at the limit


@pytest.mark.parametrize(
    ("first", "at", "kwargs"),
    [("0.30 0 0.20", 900, {}), ("0.45 0.1 0.25", 500, {"timeout": 4.0})],
    ids=["after-a-hold", "after-a-stale-stream"],
)
def test_cartesian_speed_limit_holds_after_standing_still(arm, session, first, at, kwargs):
    """A first target reached (or given up when the stream went stale), the arm standing still, then a
    target about 0.17 m away: the first moving tick gets one tick's step, not the whole pause's (the setpoint
    once jumped 0.17 m in one tick and the tool ran at 2.4 m/s with a 5 cm/s limit).

    Tolerances: the commanded tool point is the FK of an IK solution within ``ik_tolerance`` (1 mm) of the
    setpoint, so it may lead or trail the setpoint by that at each end of a window: ``2 x 1 mm``; the servos'
    read-back adds position quantisation and the servos' lag behind their goals: 1 mm more."""
    max_speed, rate, ik_tolerance = 0.05, 100.0, LoopConfig().ik_tolerance
    b = np.array([0.25, 0.15, 0.28])

    def feed(r: TickRecord, source):
        if r.tick == 0:
            source.feed(first)
        if r.tick == at - 1:  # taken at tick `at`
            source.feed(" ".join(map(str, b)))

    result, records, _, _, _ = session(Source, max_ticks=at + 500, on_tick=feed, max_speed=max_speed, **kwargs)
    assert [r.tick for r in records] == list(range(len(records)))  # one slot apart: no overruns here
    left = result.visits[0].tick
    assert left < at - 90 and all(np.array_equal(r.q_cmd, records[left].q_cmd) for r in records[left:at])  # still
    assert np.linalg.norm(b - wx250s_tool(records[at - 1].q_cmd)) > 0.15
    assert len(result.visits) == 2 and result.visits[1].reached
    step = max_speed / rate
    # the setpoint (the target of each moving tick) walks one step per tick at most, from where the arm stood
    setpoints = [wx250s_tool(records[at - 1].q_cmd)] + [r.target for r in records[at : result.visits[1].tick + 1]]
    walk = np.linalg.norm(np.diff(setpoints, axis=0), axis=1)
    assert walk.max() <= step + 1e-12 and walk.max() > 0.9 * step
    for name, slack in (("q_cmd", 2 * ik_tolerance), ("q_present", 2 * ik_tolerance + 1e-3)):
        tool = np.array([wx250s_tool(getattr(r, name)) for r in records[at - 1 :]])
        for window in (1, 10, 50):  # ticks
            moved = np.linalg.norm(tool[window:] - tool[:-window], axis=1)
            assert moved.max() <= max_speed * window / rate + slack, (name, window, moved.max())


def test_a_moving_tick_after_skipped_slots_steps_one_tick(arm):
    """Slots skipped by an overrun (or spent holding) give the setpoint no extra step: the loop's joint limit
    is one slot per tick too, so a longer step would only run the IK ahead of the speed limit."""
    clock = VirtualClock()
    source = Source(TargetGate(TargetBounds.for_arm(arm), clock=clock))
    follower = Follower(arm, source, clock=clock, rate=100.0, max_speed=0.1)
    follower.start(arm.rest)
    source.feed("0.3 0 0.2")
    p0 = follower.setpoint.copy()
    p1, _, _ = follower.target_at(0, 0.0)
    p2, _, _ = follower.target_at(40, 0.4)  # 39 slots skipped
    assert np.linalg.norm(p1 - p0) == pytest.approx(0.001) and np.linalg.norm(p2 - p1) == pytest.approx(0.001)


def test_skipped_slots_do_not_count_toward_giving_a_target_up(arm):
    """``stall_time`` counts ticks that ran: 30 slots skipped by a bus stall while the arm closes in on a
    target do not make it unreachable at the next tick (they once did, 0.25 s = 25 slots)."""
    clock = VirtualClock()
    source = Source(TargetGate(TargetBounds.for_arm(arm), clock=clock))
    follower = Follower(arm, source, clock=clock, rate=100.0, max_speed=1.0, stall_time=0.25)
    follower.start(arm.rest)
    goal = follower.tool + np.array([0.005, 0.0, 0.0])  # 5 mm: one tick's step, beyond the 1.5 mm tolerance
    source.feed(" ".join(f"{x:.6f}" for x in goal))
    for tick in [0, 31, *range(32, 55)]:  # the best at 0, 29 slots skipped, then 24 ticks without progress
        follower.target_at(tick, tick / 100)
        follower.observe(tick, arm.rest)  # the arm makes no progress
        assert follower.goal is not None and not follower.visits, tick
    follower.target_at(55, 0.55)
    follower.observe(55, arm.rest)  # the 25th tick without progress
    assert [(v.reached, v.tick) for v in follower.visits] == [(False, 55)]


# ------------------------------------------------------------------------------------------------ streams


def test_stdin_stream_is_followed_in_order(arm, session):
    points = [(0.30, 0.0, 0.25), (0.30, 0.10, 0.25), (0.25, 0.10, 0.15), (0.35, -0.05, 0.20), (0.30, 0.0, 0.30)]
    text = "".join(f"{x} {y} {z}\n" for x, y, z in points).encode()
    result, records, simbus, _, _ = session(lambda g: StdinSource(g, io.BytesIO(text)).start(), lockstep=True)
    assert [v.seq for v in result.visits] == [0, 1, 2, 3, 4] and all(v.reached for v in result.visits)
    # the servos' positions, read back each tick, pass near every point, in order
    tool = np.array([wx250s_tool(r.q_present) for r in records])
    first_near = []
    for p in points:
        d = np.linalg.norm(tool - np.array(p), axis=1)
        assert d.min() < 0.01, p
        first_near.append(int(np.argmax(d < 0.01)))
    assert first_near == sorted(first_near)
    np.testing.assert_allclose(wx250s_tool(servo_joint_angles(simbus, arm)), points[-1], atol=3e-3)


def test_garbage_lines_cause_no_motion(arm, session):
    lines = b"\n".join(garbage(random.Random(2), 1000)) + b"\n"
    result, records, simbus, goals0, _ = session(lambda g: StdinSource(g, io.BytesIO(lines)).start(), lockstep=True)
    assert goal_registers(simbus) == goals0  # not one goal moved
    assert result.received == 0 and sum(result.rejects.values()) == 1000
    assert all(r.ik_sweeps == 0 for r in records)


def test_garbage_datagrams_cause_no_motion(arm, session):
    import socket
    import time

    def make(gate):
        def gated() -> int:  # datagrams the gate has finished with; ``src.datagrams`` counts before the gate runs
            return gate.accepted + gate.rejects.total

        src = UdpSource(gate).start()
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            for i, m in enumerate(garbage(random.Random(4), 1000)):
                s.sendto(m, src.address)
                if i % 50 == 49:  # let the reader keep up: loopback drops datagrams on a full buffer
                    deadline = time.monotonic() + 5  # only a bound on a hang: the condition is the count
                    while gated() <= i and time.monotonic() < deadline:
                        time.sleep(0.001)
        deadline = time.monotonic() + 30
        while gated() < 1000 and time.monotonic() < deadline:
            time.sleep(0.001)
        assert (src.datagrams, gated()) == (1000, 1000)
        return src

    result, records, simbus, goals0, _ = session(make, max_ticks=50)
    assert goal_registers(simbus) == goals0
    assert result.received == 0 and sum(result.rejects.values()) == 1000
    assert all(r.ik_sweeps == 0 for r in records) and result.stats.holds == 50


def test_stale_stream_holds_position(arm, session):
    gate_holder = {}

    def make(gate):
        gate_holder["gate"] = gate
        return Source(gate)  # fed by the test, never closed

    def feed(r: TickRecord, source):
        if r.tick == 0:
            source.feed("0.45 0.1 0.25")  # far: still on the way when the stream goes quiet
        if r.tick == 150:
            source.feed("0.3 0 0.2")

    result, records, _, _, follower = session(make, max_ticks=400, on_tick=feed, timeout=0.5)
    by_tick = {r.tick: r for r in records}
    assert result.stale_events >= 1 and result.visits[0].reached is False  # given up when it went stale
    # between going stale (0.5 s after the first target) and the second target: no motion, no IK
    stale = [by_tick[k] for k in range(52, 151)]
    assert len({tuple(r.q_cmd) for r in stale}) == 1 and all(r.ik_sweeps == 0 for r in stale)
    assert not np.allclose(by_tick[51].q_cmd, records[0].q_cmd)  # it had been moving
    # the stream resumed: it moved again, and went stale again 0.5 s after the second target
    assert not np.allclose(by_tick[200].q_cmd, by_tick[150].q_cmd)
    assert follower.phase is Phase.STALE and result.stale_events == 2


def test_a_fast_live_stream_lags_at_most_max_lag(arm, session):
    """A target every tick moving at 1 m/s, five times the speed limit: old targets are skipped, so the one
    steered toward is never more than max_lag behind the newest, and the arm ends at the last one."""
    followers: list[Follower] = []
    lags: list[float] = []

    def stream(r: TickRecord, source):
        if r.tick < 200:
            source.feed(f"0.25 {-0.1 + 0.001 * r.tick:.4f} 0.2")  # 1 mm per tick for 2 s
        elif r.tick == 200:
            source.close()
        goal = followers[0].goal
        if goal is not None:
            lags.append(source.latest().received - goal.received)

    result, _, simbus, _, follower = session(Source, max_ticks=2000, on_tick=stream, max_lag=0.25, ref=followers)
    # a quarter of the 200 targets at least are skipped (76 measured: the arm passes targets as it catches up)
    assert follower.skipped > 50 and result.skipped == follower.skipped
    # one tick of slack (targets are taken at the next tick), plus that tick's wire time beyond its slot on the
    # virtual clock (the driver's watch ping of the gripper, every 0.2 s: about 0.25 ms)
    assert max(lags) <= 0.25 + 0.01 + 0.001
    assert result.reached_target
    np.testing.assert_allclose(wx250s_tool(servo_joint_angles(simbus, arm)), [0.25, 0.099, 0.2], atol=3e-3)


@pytest.mark.parametrize(
    ("times", "goal_index", "skipped"),
    [
        ([0.00, 0.01, 0.02, 0.03, 0.04, 0.05, 0.06, 0.07, 0.08, 0.50], 9, 9),  # all but the newest too old
        ([0.0, 0.1, 0.2, 0.3, 0.4, 0.5], 3, 3),  # 0.3 and 0.4 are within 0.25 s of the newest: kept, in order
    ],
    ids=["straight-to-the-newest", "keeps-the-recent-ones"],
)
def test_a_burst_before_one_tick_is_trimmed_to_max_lag(arm, times, goal_index, skipped):
    """Targets received over more than ``max_lag`` before one tick: those more than ``max_lag`` older than the
    newest are skipped (counted) at that tick, the follower steers to the oldest one left, and nothing older
    than ``max_lag`` stays queued."""
    clock = VirtualClock()
    source = Source(TargetGate(TargetBounds.for_arm(arm), clock=clock))
    follower = Follower(arm, source, clock=clock, rate=100.0, max_speed=0.1, max_lag=0.25)
    follower.start(arm.rest)
    p0 = follower.setpoint.copy()
    for k, t in enumerate(times):
        clock.advance(t - clock.now())
        source.feed(f"0.3 {-0.1 + 0.02 * k:.2f} 0.2")
    p1, _, _ = follower.target_at(0, clock.now())
    assert follower.skipped == skipped and follower.received == len(times)
    assert follower.goal.seq == goal_index and follower.goal.received == pytest.approx(times[goal_index])
    assert follower.pending == len(times) - 1 - goal_index  # the ones after the goal, all within max_lag
    assert [t.seq for t in follower._queue] == list(range(goal_index + 1, len(times)))
    assert all(times[-1] - t.received <= 0.25 + 1e-9 for t in follower._queue)
    goal = np.array([0.3, -0.1 + 0.02 * goal_index, 0.2])
    np.testing.assert_allclose(follower.goal.position, goal)
    step = p1 - p0  # one tick's step, straight toward the goal
    assert np.linalg.norm(step) == pytest.approx(0.001)
    np.testing.assert_allclose(step / np.linalg.norm(step), (goal - p0) / np.linalg.norm(goal - p0), atol=1e-12)


# ------------------------------------------------------------------------------------------------ errors


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"rate": 0}, "rate: "),
        ({"max_speed": -1}, "max_speed: "),
        ({"max_speed": float("nan")}, "max_speed: "),
        ({"tolerance": 0}, "tolerance: "),
        ({"timeout": 0}, "timeout: "),
    ],
    ids=["rate", "speed", "speed-nan", "tolerance", "timeout"],
)
def test_follower_option_errors(arm, kwargs, match):
    clock = VirtualClock()
    source = Source(TargetGate(TargetBounds.for_arm(arm), clock=clock))
    args = {"rate": 100.0, **kwargs}
    with pytest.raises(ConfigError, match=match):
        Follower(arm, source, clock=clock, **args)


def test_follower_needs_start(arm):
    clock = VirtualClock()
    f = Follower(arm, Source(TargetGate(TargetBounds.for_arm(arm), clock=clock)), clock=clock, rate=100)
    with pytest.raises(RuntimeError, match="start"):
        f.target_at(0, 0.0)


def test_dry_run_without_bus(arm):
    clock = VirtualClock()
    gate = TargetGate(TargetBounds.for_arm(arm), clock=clock)
    f = Follower(arm, OneShotSource(gate, "0.3,0,0.2"), clock=clock, rate=100)
    result = run_teleop(arm, f, config=LoopConfig(), clock=clock)
    assert result.summary.dry_run and result.reached_target
    np.testing.assert_allclose(result.reached, wx250s_tool(result.q_final), atol=1e-12)
