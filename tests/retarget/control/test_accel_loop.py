"""The acceleration limit through the real tick loop (run_ticks, ControlLoop): seeded random goal sequences (jumps,
reversals, goals at and beyond the joint limits, HOLD ticks, points for IK), overruns that skip slots, the lead-in
and the move to a waypoint; the commanded trajectory never exceeds the velocity or acceleration limit and never
leaves the joint limits."""

from __future__ import annotations

import numpy as np
import pytest

from retarget.control import ControlLoop, JointGoal, LoopConfig, TargetSource, TickRecord, run_ticks
from retarget.control.clock import VirtualClock
from retarget.control.replay import LeadIn
from retarget.control.source import TickTarget
from retarget.ik import CCDSolver
from tests.helpers import circle_targets

RATE = 100.0
EPS = 1e-9


class JitterClock(VirtualClock):
    """A virtual clock whose reading jumps ahead now and then (a slow tick, a stalled bus call): the loop overruns
    and skips slots.  Seeded."""

    def __init__(self, rng: np.random.Generator, p: float = 0.03, most: float = 0.08):
        super().__init__()
        self.rng, self.p, self.most = rng, p, most

    def now(self) -> float:
        if self.rng.random() < self.p:
            self._t += float(self.rng.uniform(0.0, self.most))
        return self._t


class RandomGoals(TargetSource):
    """``n`` ticks of one kind of goal sequence, seeded; now and then a HOLD tick, a point for IK, or a tighter
    ``max_step``."""

    def __init__(self, arm, kind: str, n: int, rng: np.random.Generator):
        self.arm, self.kind, self.n, self.rng = arm, kind, n, rng
        lo, hi = arm.lower, arm.upper
        span = hi - lo
        if kind == "jumps":  # a new pose anywhere (beyond the limits too) every 15 ticks
            poses = lo - 0.2 * span + rng.random((n // 15 + 1, arm.n_joints)) * 1.4 * span
            self.goals = poses[np.arange(n) // 15]
        elif kind == "reversals":  # full-range sweeps that flip every 9 ticks
            self.goals = np.where((np.arange(n) // 9 % 2 == 0)[:, None], hi + 0.5, lo - 0.5)
        else:  # "limits": at a limit, a little past it, or jumping to the other
            self.goals = np.where(rng.random((n, arm.n_joints)) < 0.5, hi, lo) + rng.normal(0, 0.02, (n, arm.n_joints))

    def target_at(self, tick, t):
        roll = self.rng.random()
        if roll < 0.05:
            return None  # HOLD: brake
        if roll < 0.15:  # a point for IK: the tool point of a random pose
            q = self.arm.lower + self.rng.random(self.arm.n_joints) * (self.arm.upper - self.arm.lower)
            return TickTarget(np.asarray(self.arm.fk(q)[0][:3, 3], dtype=np.float64))
        max_step = None
        if roll < 0.25:
            max_step = tuple((self.arm.max_velocity / RATE * self.rng.uniform(0.1, 1.0)).tolist())
        return JointGoal(self.goals[min(tick, self.n - 1)], np.zeros(3), max_step)

    def finished(self, tick):
        return tick >= self.n


def check_limits(arm, q_start: np.ndarray, records: list[TickRecord], *, max_step: np.ndarray) -> None:
    """Every commanded pose inside the limits; every step within ``max_step`` (rad per tick); every change of step
    within one slot's acceleration per slot passed; starting at rest at ``q_start``."""
    q = np.array([q_start, *(r.q_cmd for r in records)])
    ticks = np.array([records[0].tick - 1, *(r.tick for r in records)])
    assert np.all(q >= arm.lower - EPS) and np.all(q <= arm.upper + EPS), "left the joint limits"
    steps = np.diff(q, axis=0)
    assert np.all(np.abs(steps) <= max_step * (1 + 1e-9) + EPS), "over the velocity limit"
    accel = arm.max_acceleration / RATE**2  # rad per slot^2
    changes = np.diff(np.vstack([np.zeros(arm.n_joints), steps]), axis=0)  # from rest
    gaps = np.diff(ticks)[:, None]
    assert np.all(np.abs(changes) <= accel * gaps * (1 + 1e-9) + EPS), "over the acceleration limit"


@pytest.mark.parametrize("kind", ["jumps", "reversals", "limits"])
@pytest.mark.parametrize("seed", [1, 2])
def test_random_goals_through_the_loop_keep_every_limit(arm, kind, seed):
    rng = np.random.default_rng(seed)
    q_start = arm.lower + rng.random(arm.n_joints) * (arm.upper - arm.lower)
    records: list[TickRecord] = []
    stats = run_ticks(arm, RandomGoals(arm, kind, 250, rng), CCDSolver(arm), config=LoopConfig(rate=RATE),
                      clock=JitterClock(rng), q_start=q_start, on_tick=records.append)  # fmt: skip
    assert stats.overruns > 0 and stats.holds > 0  # slots were skipped, and HOLD ticks braked
    assert np.any(np.diff([r.tick for r in records]) > 1)
    check_limits(arm, q_start, records, max_step=arm.max_velocity / RATE)
    # it moved, and hard: some joint reached full speed and some tick used the whole acceleration limit
    steps = np.diff([r.q_cmd for r in records], axis=0)
    assert np.any(np.isclose(np.abs(steps), arm.max_velocity / RATE, rtol=1e-9))
    assert np.any(np.isclose(np.abs(np.diff(steps, axis=0)), arm.max_acceleration / RATE**2, rtol=1e-9))


def test_a_hold_brakes_at_the_acceleration_limit_to_rest(arm):
    """Full speed on the waist, then HOLD ticks: the step shrinks by one slot's acceleration per tick, to rest."""

    class RunThenHold(TargetSource):
        def target_at(self, tick, t):
            return JointGoal(np.r_[3.0, arm.rest[1:]], np.zeros(3)) if tick < 100 else None

        def finished(self, tick):
            return tick >= 140

    q0 = np.r_[-3.0, arm.rest[1:]]
    records: list[TickRecord] = []
    run_ticks(arm, RunThenHold(), CCDSolver(arm), config=LoopConfig(rate=RATE), clock=VirtualClock(), q_start=q0,
              on_tick=records.append)  # fmt: skip
    waist = np.diff([q0[0], *(r.q_cmd[0] for r in records)])
    full, accel = arm.max_velocity[0] / RATE, arm.max_acceleration[0] / RATE**2
    assert waist[99] == pytest.approx(full)  # at full speed when the HOLDs begin
    expected = np.maximum(full - accel * np.arange(1, 41), 0.0)  # braking by one slot's acceleration per tick
    np.testing.assert_allclose(waist[100:], expected, atol=1e-12)
    assert waist[-1] == 0.0


@pytest.mark.parametrize("seed", range(4))
def test_the_lead_in_keeps_the_limits_and_arrives_after_overruns(arm, seed):
    """A dry-run preview of the lead-in from a random pose, with overruns: within its own speed and the
    acceleration limit, and on the clip's first pose when it ends."""
    rng = np.random.default_rng(seed)
    q_start = arm.lower + rng.random(arm.n_joints) * (arm.upper - arm.lower)
    records: list[TickRecord] = []
    config = LoopConfig(rate=RATE, end=0.2, lead_in_speed=float(rng.uniform(0.3, 2.0)))
    loop = ControlLoop(arm, circle_targets(arm), config=config, clock=JitterClock(rng, p=0.05),
                       on_tick=records.append)  # fmt: skip
    summary = loop.run(None, q_start=q_start, lead_in=True)
    lead = [r for r in records if r.lead_in]
    assert len(lead) > 0 and summary.lead_in_ticks == len(lead)
    speed = np.minimum(config.lead_in_speed, arm.max_velocity)
    check_limits(arm, np.clip(q_start, arm.lower, arm.upper), lead, max_step=speed / RATE)
    check_limits(arm, np.clip(q_start, arm.lower, arm.upper), records, max_step=arm.max_velocity / RATE)
    np.testing.assert_allclose(lead[-1].q_cmd, loop.initial_pose(), atol=1e-9)


@pytest.mark.parametrize("seed", range(6))
def test_a_lead_in_plan_within_the_acceleration_limit_is_followed_exactly(arm, seed):
    """LeadIn.plan with ``accel``: its own steps and changes of step keep the speed and the acceleration limit, so
    the loop (the move to a waypoint on the way to rest runs the same way, retarget.control.park) follows it
    tick for tick without cutting a step."""
    rng = np.random.default_rng(seed)
    lo, hi = arm.lower + 0.2, arm.upper - 0.2
    q_from, q_to = lo + rng.random(arm.n_joints) * (hi - lo), lo + rng.random(arm.n_joints) * (hi - lo)
    speed = arm.max_velocity * rng.uniform(0.1, 1.0)
    plan = LeadIn.plan(q_from, q_to, speed=speed, rate=RATE, target=np.zeros(3), accel=arm.max_acceleration)
    goals = np.array([q_from, *(plan.goal(k).q for k in range(-plan.n_slots, 0))])
    steps = np.diff(goals, axis=0)
    assert np.all(np.abs(steps) <= speed / RATE * (1 + 1e-9))
    changes = np.diff(np.vstack([np.zeros(arm.n_joints), steps, np.zeros(arm.n_joints)]), axis=0)  # rest to rest
    assert np.all(np.abs(changes) <= arm.max_acceleration / RATE**2 * (1 + 1e-9))
    slower = LeadIn.plan(q_from, q_to, speed=speed, rate=RATE, target=np.zeros(3))
    assert plan.n_slots >= slower.n_slots  # the acceleration bound only ever lengthens it

    class Plan(TargetSource):
        def start(self, q):
            return -plan.n_slots

        def target_at(self, tick, t):
            return plan.goal(tick)

        def finished(self, tick):
            return tick >= 0

    records: list[TickRecord] = []
    run_ticks(arm, Plan(), CCDSolver(arm), config=LoopConfig(rate=RATE), clock=VirtualClock(), q_start=q_from,
              on_tick=records.append)  # fmt: skip
    np.testing.assert_allclose(np.array([r.q_cmd for r in records]), goals[1:], atol=1e-9)
    assert not any(r.velocity_limited for r in records)
