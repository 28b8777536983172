"""Collision safety in the tick loop: a colliding goal is never written, the lead-in and the rest move go through
a safe waypoint (or are refused), and every clip plays on the simulated bus without one blocked goal sent."""

from __future__ import annotations

import csv
import io

import numpy as np
import pytest

import retarget
from retarget.collision import CollisionModel, Sphere, World
from retarget.control import ControlLoop, JointGoal, LoopConfig, TargetSource, TickRecord, run_ticks
from retarget.control.clock import VirtualClock
from retarget.control.park import check_moves, park
from retarget.control.replay import plan_lead_in
from retarget.control.safety import Route
from retarget.control.telemetry import TelemetryWriter
from retarget.errors import ConfigError
from retarget.ik import CCDSolver
from retarget.mapping import retarget_targets
from retarget.mapping.config import MappingConfig, Side
from tests.helpers import brute_force_min_clearances, goal_writes, servo_angles, shared_clip_params

#: a pose reaching low to the left, its mirror to the right; the straight move between them sweeps the tool
#: through the front, where a ball is put; through home (arm up) it is clear
LEFT = np.array([1.2, 0.5, -0.1, 0.0, 0.5, 0.0])
RIGHT = LEFT * np.array([-1, 1, 1, 1, 1, 1])


def tool(arm, q):
    return arm.fk(q)[0][:3, 3]


def ball_on_the_way(arm, q0, q1, f=0.5, radius=0.04):
    """A world with a ball of ``radius`` m around the tool point a fraction ``f`` of the way from q0 to q1."""
    return World(keep_out=(Sphere(tuple(tool(arm, q0 + f * (q1 - q0))), radius),))


def goal_angles(simbus, arm, writes):
    """The joint angles (rad) of each Goal Position write on the wire, from the primary servos' pulses."""
    from drivers.units import pulses_to_rad

    out = []
    for w in writes:
        if all(j.servos[0].id in w for j in arm.joints):
            out.append([pulses_to_rad(w[j.servos[0].id], offset=j.servos[0].offset) for j in arm.joints])
    return np.array(out)


class Toward(TargetSource):
    """A JointGoal at ``q`` every tick, for ``n`` ticks."""

    def __init__(self, q, n):
        self.q, self.n = np.asarray(q, dtype=np.float64), n

    def target_at(self, tick, t):
        return JointGoal(self.q, np.zeros(3))

    def finished(self, tick):
        return tick >= self.n


def test_a_colliding_goal_is_never_written_and_is_counted_blocked(arm, sim_bus):
    from drivers import DynamixelBus

    model = CollisionModel.for_arm(arm, world=ball_on_the_way(arm, arm.home, LEFT, f=0.6, radius=0.04))
    assert model.is_clear(arm.home) and not model.segment_clear(arm.home, LEFT).clear
    simbus, url, clock = sim_bus()
    records: list[TickRecord] = []
    config = LoopConfig(collision=model, velocity_scale=0.2)
    with DynamixelBus(arm, url, clock=clock, shutdown="hold") as bus:
        bus.write_goals(arm.home)  # the servos start at rest: bring them home, no model involved
        clock.advance(3.0)
        stats = run_ticks(arm, Toward(LEFT, 300), CCDSolver(arm), config=config, clock=clock, bus=bus,
                          on_tick=records.append)  # fmt: skip
        held = servo_angles(simbus, arm)
    blocked = [r for r in records if r.blocked]
    assert stats.blocked == len(blocked) > 200  # it got to the ball early and held there ever since
    # a blocked goal brakes at the acceleration limit when that step is clear, else stops at once; from the last
    # clear goal on every goal runs into the ball, and the arm comes to rest within a few ticks and holds there
    last_clear = max(i for i, r in enumerate(records) if not r.blocked)
    assert all(r.blocked for r in records[last_clear + 1 :]) and len(records) - last_clear > 200
    q = np.array([r.q_cmd for r in records])
    np.testing.assert_array_equal(q[last_clear + 10 :], np.broadcast_to(q[-1], q[last_clear + 10 :].shape))
    # the commanded trajectory keeps the acceleration limit except where the check stopped it at once (blocked)
    over = np.abs(np.diff(q, 2, axis=0)) > arm.max_acceleration / 100.0**2 * (1 + 1e-6)
    stops = [i for i in np.flatnonzero(over.any(axis=1)) if records[i + 2].blocked]
    assert len(stops) == np.count_nonzero(over.any(axis=1)) >= 1
    # on the wire: every goal written keeps the clearance (independent check), and none past the held pose
    sent = goal_angles(simbus, arm, goal_writes(simbus))
    assert len(sent) > 300
    assert np.all(brute_force_min_clearances(arm, sent, world=model.world) >= model.clearance - 2e-3)  # 1 pulse
    np.testing.assert_allclose(sent[-1], q[-1], atol=2 * np.pi / 4096)
    np.testing.assert_allclose(held, q[-1], atol=0.01)
    assert all(r.min_clearance >= model.clearance for r in records)
    summary = stats.summary(arm=arm.name, clip="toward", frames=0, duration_s=0.0)
    assert summary.blocked_ticks == stats.blocked and summary.min_clearance_mm >= model.clearance * 1e3
    assert f"collisions: {stats.blocked} blocked goals (not sent)" in summary.format()


def test_telemetry_and_summary_carry_the_blocked_flag_and_the_clearance(arm):
    model = CollisionModel.for_arm(arm, world=ball_on_the_way(arm, arm.home, LEFT, f=0.6))
    out = io.StringIO()
    with TelemetryWriter(out, arm.joint_names) as telemetry:
        config = LoopConfig(collision=model, velocity_scale=0.2)
        stats = run_ticks(arm, Toward(LEFT, 200), CCDSolver(arm), config=config, clock=VirtualClock(), q_start=arm.home,
                          on_tick=telemetry)  # fmt: skip
    rows = list(csv.DictReader(io.StringIO(out.getvalue())))
    assert sum(r["blocked"] == "1" for r in rows) == stats.blocked > 0
    assert min(float(r["min_clearance_mm"]) for r in rows) >= model.clearance * 1e3
    plain = run_ticks(arm, Toward(LEFT, 5), CCDSolver(arm), config=LoopConfig(), clock=VirtualClock())
    summary = plain.summary(arm=arm.name, clip="", frames=0, duration_s=0.0)
    assert summary.blocked_ticks is None and summary.min_clearance_mm is None  # no model: no figures
    assert "collisions" not in summary.format()


# ------------------------------------------------------------------------------------- the lead-in, the rest move


def test_a_blocked_lead_in_goes_through_home(arm):
    model = CollisionModel.for_arm(arm, world=ball_on_the_way(arm, LEFT, RIGHT))
    assert not model.segment_clear(LEFT, RIGHT).clear
    config = LoopConfig(collision=model, rate=50.0)
    plan = plan_lead_in(arm, LEFT, RIGHT, speed=np.full(6, 0.5), rate=config.rate, target=np.zeros(3), collision=model)
    assert isinstance(plan, Route) and len(plan.legs) == 2
    goals = np.array([plan.goal(k).q for k in range(-plan.n_slots, 0)])
    np.testing.assert_allclose(goals[-1], RIGHT)
    assert np.min(np.abs(goals - arm.home).max(axis=1)) < 1e-9  # through home
    assert np.all(brute_force_min_clearances(arm, goals, world=model.world) >= model.clearance)
    # run through the loop (a dry-run preview from LEFT): no tick blocked, every goal clear
    records: list[TickRecord] = []

    class Lead(TargetSource):
        def start(self, q_start):
            return -plan.n_slots

        def target_at(self, tick, t):
            return plan.goal(tick)

        def finished(self, tick):
            return tick >= 0

    stats = run_ticks(arm, Lead(), CCDSolver(arm), config=config, clock=VirtualClock(), q_start=LEFT,
                      on_tick=records.append)  # fmt: skip
    assert stats.lead_in_ticks == plan.n_slots and stats.lead_in_blocked == 0
    np.testing.assert_allclose(records[-1].q_cmd, RIGHT, atol=1e-9)
    straight = plan_lead_in(arm, LEFT, RIGHT, speed=np.full(6, 0.5), rate=100.0, target=np.zeros(3), collision=None)
    assert not isinstance(straight, Route)  # without a model: the straight line


def test_a_lead_in_with_no_safe_route_is_refused(arm):
    model = CollisionModel.for_arm(arm, world=World(keep_out=(Sphere(tuple(tool(arm, RIGHT)), 0.03),)))
    config = LoopConfig(collision=model)
    with pytest.raises(ConfigError, match=r"^collision: Expected a collision-free lead-in .* within the clearance"):
        plan_lead_in(arm, LEFT, RIGHT, speed=np.full(6, 0.5), rate=config.rate, target=np.zeros(3), collision=model)
    with pytest.raises(ConfigError, match=r"collision-free lead-in"):
        check_moves(arm, config, first=RIGHT, rest=False)  # before the bus connects


def start_at(sim_bus, arm, pose):
    """A simulated wx250s whose servos start at ``pose`` (rad)."""
    import sim

    clock = VirtualClock()
    simbus = sim.SimBus.from_arm(arm, clock=clock, pose=pose, faults=sim.Faults(wire=True))
    return simbus, sim.attach(simbus), clock


def test_the_rest_move_goes_through_home_when_straight_collides(arm):
    import sim
    from drivers import DynamixelBus

    model = CollisionModel.for_arm(arm, world=ball_on_the_way(arm, LEFT, arm.rest, radius=0.03))
    assert not model.segment_clear(LEFT, arm.rest).clear and model.segment_clear(arm.home, arm.rest).clear
    config = LoopConfig(collision=model)
    check_moves(arm, config, first=None, rest=True)  # home -> rest is clear: allowed
    simbus, url, clock = start_at(None, arm, LEFT)
    try:
        bus = DynamixelBus(arm, url, clock=clock, shutdown="rest")
        with bus:
            assert park(arm, bus, config=config, clock=clock)
            np.testing.assert_allclose(servo_angles(simbus, arm), arm.home, atol=0.01)  # at home, then to rest
        np.testing.assert_allclose(servo_angles(simbus, arm), arm.rest, atol=0.06)
        sent = goal_angles(simbus, arm, goal_writes(simbus))
        assert np.all(model.distances(sent).min(axis=1) >= model.clearance - 2e-3)
    finally:
        sim.unregister(url)


def test_a_rest_move_with_no_safe_route_is_refused(arm):
    import sim
    from drivers import DynamixelBus

    model = CollisionModel.for_arm(arm, world=ball_on_the_way(arm, LEFT, arm.rest, f=0.7, radius=0.03))
    assert not model.segment_clear(arm.home, arm.rest).clear
    config = LoopConfig(collision=model)
    with pytest.raises(ConfigError, match=r"^collision: Expected a collision-free move to the rest pose"):
        check_moves(arm, config, first=None, rest=True)  # before the bus connects: before torque is on
    simbus, url, clock = start_at(None, arm, LEFT)
    try:
        bus = DynamixelBus(arm, url, clock=clock, shutdown="rest")
        with bus:
            assert not park(arm, bus, config=config, clock=clock)
            assert bus.shutdown_mode.value == "hold"  # the bus's rest move is off: the arm holds where it is
        np.testing.assert_allclose(servo_angles(simbus, arm), LEFT, atol=0.01)
    finally:
        sim.unregister(url)


# ------------------------------------------------------------------------------------------ every shared clip


#: seconds of each clip replayed on the simulated bus (the whole clips, 107 s a side, take ~1 ms a tick there: too
#: slow for the suite); the whole of every clip is replayed offline (the same loop, no bus) below
BUS_SECONDS = 2.0


def clip_targets(arm, model, clip, side):
    motion = retarget.load_bvh(clip)
    config = MappingConfig.from_table(arm.mapping, overrides={"side": side.value})
    return motion, retarget_targets(motion, arm, config, collision=model)


@pytest.mark.parametrize("side", [Side.LEFT, Side.RIGHT], ids=["left", "right"])
@pytest.mark.parametrize("clip", shared_clip_params())
def test_every_whole_clip_plays_offline_without_a_blocked_goal_written(arm, clip, side):
    """The whole clip through the tick loop without a bus (as a dry run): every goal it would write clear, by the
    independent brute-force check, and the loop's own figures agree."""
    model = CollisionModel.for_arm(arm)
    motion, targets = clip_targets(arm, model, clip, side)
    records: list[TickRecord] = []
    summary = ControlLoop(arm, targets, config=LoopConfig(collision=model), clock=VirtualClock(),
                          on_tick=records.append).run(None)  # fmt: skip
    last = (motion.n_frames - 1) / motion.fps  # the whole clip, to its last frame, a tick per slot
    assert records[-1].clip_time == pytest.approx(last, abs=0.01) and len(records) >= last * LoopConfig().rate
    assert summary.min_clearance_mm >= model.clearance * 1e3
    assert all(r.min_clearance >= model.clearance for r in records if not r.blocked)
    written = np.array([r.q_cmd for r in records if not r.blocked])
    assert np.all(brute_force_min_clearances(arm, written) >= model.clearance - 1e-9)


@pytest.mark.parametrize("side", [Side.LEFT, Side.RIGHT], ids=["left", "right"])
@pytest.mark.parametrize("clip", shared_clip_params())
def test_every_clip_plays_on_the_bus_without_a_blocked_goal_sent(arm, sim_bus, clip, side):
    from drivers import DynamixelBus

    model = CollisionModel.for_arm(arm)
    _, targets = clip_targets(arm, model, clip, side)
    simbus, url, clock = sim_bus()
    records: list[TickRecord] = []
    loop = ControlLoop(arm, targets, config=LoopConfig(collision=model, end=BUS_SECONDS), clock=clock,
                       on_tick=records.append)  # fmt: skip
    with DynamixelBus(arm, url, clock=clock, shutdown="hold") as bus:
        summary = loop.run(bus)
    out = io.StringIO()
    with TelemetryWriter(out, arm.joint_names) as telemetry:
        for r in records:
            telemetry(r)
    rows = list(csv.DictReader(io.StringIO(out.getvalue())))
    assert min(float(r["min_clearance_mm"]) for r in rows) >= model.clearance * 1e3
    assert summary.min_clearance_mm >= model.clearance * 1e3 and summary.pushed_targets is not None
    sent = goal_angles(simbus, arm, goal_writes(simbus))
    assert np.all(brute_force_min_clearances(arm, sent) >= model.clearance - 2e-3)  # within a pulse of rounding
    written = np.array([r.q_cmd for r in records if not r.blocked])
    assert np.all(brute_force_min_clearances(arm, written) >= model.clearance)
