"""The look-ahead planner (retarget.control.plan) and the clip loop that plays its plan."""

from __future__ import annotations

import numpy as np
import pytest

import retarget
from retarget.control.clock import VirtualClock
from retarget.control.limits import StepLimiter
from retarget.control.loop import LoopConfig, TickRecord
from retarget.control.plan import JERK_COST, _follow, _steady, plan_path
from retarget.control.replay import ControlLoop
from retarget.mapping import Targets, Workspace

LO, HI = np.array([-1.0, -2.0, -0.5]), np.array([1.0, 2.0, 0.5])
VMAX, AMAX = np.array([0.05, 0.1, 0.02]), np.array([0.01, 0.005, 0.002])  # rad per slot, rad per slot^2


def _random_goals(rng: np.random.Generator, n: int) -> np.ndarray:
    """Goal paths ``(n, 3)`` that jump, reverse, ramp and sit at or beyond the joint limits."""
    kinds = []
    for j in range(3):
        t = np.arange(n)
        jumps = np.repeat(rng.uniform(-1.5, 1.5, size=n // 10 + 1) * HI[j], 10)[:n]
        wave = 1.3 * HI[j] * np.sin(2 * np.pi * t / rng.uniform(5, 60))
        noise = rng.normal(0.0, 0.3 * HI[j], size=n)
        kinds.append([jumps, wave, noise, np.full(n, 2 * HI[j]), np.full(n, 2 * LO[j])][rng.integers(5)])
    return np.stack(kinds, axis=1)


@pytest.mark.parametrize("seed", range(12), ids=lambda s: f"seed{s}")
def test_plan_never_exceeds_the_limits(seed: int) -> None:
    rng = np.random.default_rng(seed)
    goals = _random_goals(rng, int(rng.integers(2, 300)))
    q0 = rng.uniform(LO, HI)
    plan = plan_path(goals, q0, lower=LO, upper=HI, max_step=VMAX, max_accel=AMAX, iterations=int(rng.integers(4)))
    assert plan.shape == goals.shape
    assert np.all(plan >= LO) and np.all(plan <= HI)
    v = np.diff(np.vstack([q0, plan]), axis=0)  # from q0 at rest
    a = np.diff(np.vstack([np.zeros(3), v]), axis=0)
    assert np.all(np.abs(v) <= VMAX * (1 + 1e-9))
    assert np.all(np.abs(a) <= AMAX * (1 + 1e-9) + 1e-15)


def test_the_limiter_passes_a_plan_unchanged() -> None:
    """The loop's own limiter, fed the plan tick by tick, reproduces it (so its counts keep their meaning)."""
    goals = _random_goals(np.random.default_rng(7), 200)
    plan = plan_path(goals, np.zeros(3), lower=LO, upper=HI, max_step=VMAX, max_accel=AMAX)
    limiter = StepLimiter(LO, HI, VMAX, np.zeros(3), max_accel=AMAX)
    followed = []
    for q in plan:
        limiter.step(q.tolist(), 1)
        followed.append(limiter.q)
    np.testing.assert_allclose(followed, plan, atol=1e-9)


def test_a_feasible_path_is_returned_as_it_is() -> None:
    t = np.arange(100)
    goals = np.stack([0.1 * np.sin(t / 30.0), 0.2 * np.sin(t / 50.0), 0.05 * np.cos(t / 40.0) - 0.05], axis=1)
    plan = plan_path(goals, goals[0], lower=LO, upper=HI, max_step=VMAX, max_accel=AMAX)
    np.testing.assert_array_equal(plan, goals)


def _causal(goals: np.ndarray, q0: np.ndarray) -> np.ndarray:
    limiter = StepLimiter(LO, HI, VMAX, q0, max_accel=AMAX)
    out = []
    for g in goals:
        limiter.step(g.tolist(), 1)
        out.append(limiter.q)
    return np.array(out)


def test_look_ahead_removes_the_causal_lag() -> None:
    """A triangle too sharp for the acceleration limit: the causal limiter reaches its peak late and overshoots
    on the way down; the plan turns early, centred on the peak, and its worst error is about half the causal one
    (it spreads the error before and after the peak, so its mean error is not lower)."""
    up = np.linspace(0.0, 0.4, 20)
    column = np.r_[np.zeros(20), up, up[::-1], np.zeros(40)]
    goals = np.stack([column, np.zeros_like(column), np.zeros_like(column)], axis=1)
    plan = plan_path(goals, np.zeros(3), lower=LO, upper=HI, max_step=VMAX, max_accel=AMAX)
    causal = _causal(goals, np.zeros(3))
    peak = 39  # the goal's peak: slots 39 and 40 are both at 0.4
    assert int(np.argmax(causal[:, 0])) == peak + 2  # late
    assert int(np.argmax(plan[:, 0])) in (peak, peak + 1)  # on time (the goal is at its peak on both)
    plan_error, causal_error = np.abs(plan[:, 0] - column), np.abs(causal[:, 0] - column)
    assert plan_error.max() < 0.6 * causal_error.max()


def test_a_too_sharp_oscillation_is_followed_in_phase_as_far_as_the_limits_allow() -> None:
    """A sine that needs twice the acceleration limit (ramped in from rest over two periods): the plan swings in
    phase with it, over nearly the most any path within the limit can (``a T^2 / 16`` peak to peak: full
    acceleration one way for a quarter period, then the other), so its error is the least the limit leaves.
    Measured: 97 % of that swing, RMS error 0.27 of the amplitude; the profile's forward and backward passes
    averaged (the earlier method) swung 48 % and erred 0.80, as much as a path a quarter period late."""
    period, amax = 40, 0.002
    t = np.arange(400)
    amplitude = 2 * amax / (2 * np.pi / period) ** 2
    goal = np.clip(t / 80, 0, 1) * amplitude * np.sin(2 * np.pi * t / period)
    plan = plan_path(goal[:, None], [0.0], lower=[-5.0], upper=[5.0], max_step=[1.0], max_accel=[amax])[:, 0]
    steady = slice(150, 350)
    swing = plan[steady].max() - plan[steady].min()
    assert 0.9 * amax * period**2 / 16 < swing <= amax * period**2 / 16 * (1 + 1e-9)
    assert np.sqrt(np.mean((plan[steady] - goal[steady]) ** 2)) < 0.35 * amplitude


@pytest.mark.parametrize("seed", range(8), ids=lambda s: f"seed{s}")
def test_a_task_plan_never_exceeds_the_limits_either(seed: int) -> None:
    """With ``jacobians`` (random, some columns zero) the fit is to the task, and the limits hold all the same."""
    rng = np.random.default_rng(seed)
    goals = _random_goals(rng, int(rng.integers(2, 300)))
    q0 = rng.uniform(LO, HI)
    jacobians = rng.normal(0.0, 0.3, (len(goals), 3, 3)) * (rng.random(3) > 0.2)
    residuals = rng.normal(0.0, 0.001, (len(goals), 3))
    plan = plan_path(goals, q0, lower=LO, upper=HI, max_step=VMAX, max_accel=AMAX, jacobians=jacobians,
                     residuals=residuals, iterations=int(rng.integers(0, 80)))  # fmt: skip
    assert np.all(plan >= LO) and np.all(plan <= HI)
    v = np.diff(np.vstack([q0, plan]), axis=0)
    a = np.diff(np.vstack([np.zeros(3), v]), axis=0)
    assert np.all(np.abs(v) <= VMAX * (1 + 1e-9))
    assert np.all(np.abs(a) <= AMAX * (1 + 1e-9) + 1e-15)


def _two_joints_one_point() -> tuple[np.ndarray, dict[str, object]]:
    """A point at ``x = q0 + q1`` (1 m per rad each): joint 0's goal a triangle too sharp for its acceleration
    limit, joint 1's a slow drift (it moves, so it may help) with room to spare."""
    up = np.linspace(0.0, 0.4, 20)
    sharp = np.r_[np.zeros(20), up, up[::-1], np.zeros(40)]
    goals = np.stack([sharp, np.linspace(0.0, 0.01, len(sharp))], axis=1)
    limits = {"lower": [-1.0, -1.0], "upper": [1.0, 1.0], "max_step": [0.05, 0.05], "max_accel": [0.01, 0.05]}
    return goals, limits


@pytest.mark.parametrize(
    ("jerk_cost", "share"), [(JERK_COST, 0.35), (0.0, 0.05)], ids=["default-jerk-cost", "no-jerk-cost"]
)
def test_the_task_fit_makes_up_for_a_joint_that_falls_behind_with_one_that_can(jerk_cost: float, share: float) -> None:
    """Measured, worst and RMS task error against the joints' fit (12.3 and 2.5 mm): 3.5 and 0.7 mm with the default
    jerk cost, 0.35 and 0.08 without it (it keeps the helping joint's acceleration from flipping tick to tick)."""
    goals, limits = _two_joints_one_point()
    target = goals.sum(axis=1)
    joints = plan_path(goals, np.zeros(2), **limits)  # type: ignore[arg-type]
    task = plan_path(goals, np.zeros(2), jacobians=np.ones((len(goals), 1, 2)), jerk_cost=jerk_cost,
                     **limits)  # type: ignore[arg-type]  # fmt: skip
    joint_error, task_error = np.abs(joints.sum(axis=1) - target), np.abs(task.sum(axis=1) - target)
    assert np.array_equal(joints[:, 1], goals[:, 1])  # alone, joint 1 is within its limits: passed through
    assert np.abs(task[:, 1] - goals[:, 1]).max() > 0.005  # in the task's fit it moves to help (measured 13-15 mm)
    assert task_error.max() < share * joint_error.max()
    assert np.sqrt(np.mean(task_error**2)) < share * np.sqrt(np.mean(joint_error**2))


def test_a_task_plan_corrects_the_goals_own_residual() -> None:
    """Goals whose task point misses its target by a constant 5 mm (``residuals``), within every limit: the plan
    moves by that much (the linearised task), where the joints' fit would pass them through."""
    t = np.arange(200)
    goals = np.stack([0.1 * np.sin(t / 30.0), np.zeros(200), 0.05 * np.cos(t / 40.0) - 0.05], axis=1)
    goals[:, 1] = np.linspace(0.0, 0.01, 200)
    jacobians = np.broadcast_to(np.eye(3), (200, 3, 3))
    hard = np.r_[[[0.0, 0.0, 0.0]] * 100, [[0.5, 0.0, 0.0]] * 100]  # a jump in joint 0: something to plan
    plan = plan_path(goals + hard, goals[0], lower=LO, upper=HI, max_step=VMAX, max_accel=AMAX, jacobians=jacobians,
                     residuals=np.broadcast_to([0.0, 0.005, 0.0], (200, 3)))  # fmt: skip
    np.testing.assert_allclose(plan[150:, 1], goals[150:, 1] - 0.005, atol=2e-4)


@pytest.mark.parametrize(
    ("goals", "kwargs", "match"),
    [
        (np.zeros(5), {}, r"Expected goals of shape \(n, n_joints\), got \(5,\)"),
        (np.zeros((5, 3)), {"iterations": -1}, r"Expected iterations >= 0, got -1"),
        (np.zeros((5, 3)), {"max_step": np.zeros(3)}, r"Expected max_step and max_accel > 0"),
        (np.zeros((5, 3)), {"speed_cost": -1.0}, r"Expected speed_cost >= 0 and 0 < easy_speed <= 1, got -1\.0 and"),
        (np.zeros((5, 3)), {"easy_speed": 0.0}, r"Expected speed_cost >= 0 and 0 < easy_speed <= 1, got .* and 0\.0"),
        (np.zeros((5, 3)), {"jacobians": np.zeros((5, 3))}, r"Expected jacobians of shape \(5, d, 3\), got \(5, 3\)"),
        (np.zeros((5, 3)), {"jacobians": np.zeros((4, 3, 3))}, r"Expected jacobians of shape \(5, d, 3\), got \(4, 3"),
        (
            np.zeros((5, 3)),
            {"jacobians": np.zeros((5, 2, 3)), "residuals": np.zeros((5, 3))},
            r"Expected residuals of shape \(5, 2\), got \(5, 3\)",
        ),
        (np.zeros((5, 3)), {"residuals": np.zeros((5, 3))}, r"Expected jacobians with residuals, got residuals alone"),
        (np.zeros((5, 3)), {"jerk_cost": -1.0}, r"Expected jerk_cost >= 0, got -1\.0"),
        (np.zeros((5, 3)), {"jerk_cost": float("nan")}, r"Expected jerk_cost >= 0, got nan"),
    ],
    ids=[
        "1-d goals",
        "negative iterations",
        "zero speed",
        "negative speed cost",
        "zero easy speed",
        "2-d jacobians",
        "jacobians too short",
        "residuals of the wrong shape",
        "residuals alone",
        "negative jerk cost",
        "nan jerk cost",
    ],
)
def test_bad_arguments(goals: np.ndarray, kwargs: dict[str, object], match: str) -> None:
    args: dict[str, object] = {"lower": LO, "upper": HI, "max_step": VMAX, "max_accel": AMAX, **kwargs}
    with pytest.raises(ValueError, match=match):
        plan_path(goals, np.zeros(3), **args)  # type: ignore[arg-type]


# --------------------------------------------------------------------------------------------- the clip loop


def _fast_circle(arm: retarget.Arm) -> Targets:
    """2 s of a 0.1 m circle at 1.5 turns per second: faster than the joints' acceleration limit allows."""
    t = np.linspace(0.0, 2.0, 201)
    w = 2 * np.pi * 1.5 * t
    points = np.stack([0.35 + 0 * t, 0.1 * np.sin(w), 0.25 + 0.1 * np.cos(w)], axis=-1)
    return Targets.from_raw(points, frame_time=0.01, workspace=Workspace.for_arm(arm))


def _swing(arm: retarget.Arm) -> Targets:
    """2 s, a 0.3 m sideways swing in 0.15 s at 0.8 s (smoothstep), still before and after."""
    t = np.linspace(0.0, 2.0, 201)
    s = np.clip((t - 0.8) / 0.15, 0.0, 1.0)
    points = np.stack([0.35 + 0 * t, -0.15 + 0.3 * s * s * (3 - 2 * s), 0.25 + 0 * t], axis=-1)
    return Targets.from_raw(points, frame_time=0.01, workspace=Workspace.for_arm(arm))


def _run(loop: ControlLoop) -> tuple[list[TickRecord], float]:
    records: list[TickRecord] = []
    loop.on_tick = records.append
    summary = loop.run(None, q_start=loop.initial_pose())
    assert summary.tracking_p95_mm is not None
    return records, summary.tracking_p95_mm


def test_the_loop_plays_the_plan_and_reports_its_ik() -> None:
    arm = retarget.load_arm("wx250s")
    loop = ControlLoop(arm, _fast_circle(arm), clock=VirtualClock())
    records, planned_p95 = _run(loop)
    plan = loop.plan(loop.initial_pose())
    assert plan is not None and len(plan) == len(records) == 201
    np.testing.assert_allclose([r.q_cmd for r in records], plan.q, atol=1e-9)  # the limiter passed it unchanged
    assert [r.ik_sweeps for r in records] == [r.iterations for r in plan.ik]  # the IK's figures, not 0
    assert sum(r.ik_sweeps for r in records) > 0
    assert [r.ik_error for r in records] == [r.error for r in plan.ik]


def test_look_ahead_follows_a_fast_swing_closer() -> None:
    """The arm starts the swing early instead of lagging it: tracking p95 78 mm instead of 120 (no velocity-limited
    tick instead of 18).  (Not on every motion: on a steady fast circle the causal loop's IK, which re-solves from
    where the lagging joints are, tracks closer than a plan made in joint space.)"""
    arm = retarget.load_arm("wx250s")
    causal, causal_p95 = _run(ControlLoop(arm, _swing(arm), clock=VirtualClock(), look_ahead=False))
    planned, planned_p95 = _run(ControlLoop(arm, _swing(arm), clock=VirtualClock()))
    assert sum(r.velocity_limited for r in causal) > 10  # the case does hit the limits
    assert sum(r.velocity_limited for r in planned) < sum(r.velocity_limited for r in causal)
    assert planned_p95 < 0.8 * causal_p95


@pytest.mark.parametrize(
    ("config", "ticks"),
    [(LoopConfig(speed=0.5), 401), (LoopConfig(max_ticks=50), 50), (LoopConfig(speed=2.0, end=1.5), 76)],
    ids=["half speed", "max ticks", "double speed window"],
)
def test_the_plan_covers_the_ticks_played(config: LoopConfig, ticks: int) -> None:
    arm = retarget.load_arm("wx250s")
    loop = ControlLoop(arm, _fast_circle(arm), config=config, clock=VirtualClock())
    records, _ = _run(loop)
    plan = loop.plan(loop.initial_pose())
    assert plan is not None and len(plan) == len(records) == ticks
    np.testing.assert_allclose([r.q_cmd for r in records], plan.q, atol=1e-9)


def test_a_looping_run_plays_causally() -> None:
    arm = retarget.load_arm("wx250s")
    loop = ControlLoop(arm, _fast_circle(arm), config=LoopConfig(loop=True, max_ticks=300), clock=VirtualClock())
    assert loop.plan() is None
    records, _ = _run(loop)
    assert len(records) == 300 and sum(r.ik_sweeps for r in records) > 0


def test_a_plan_with_collisions_proves_its_moves_and_no_proof_claims_too_much() -> None:
    """solve_and_plan with a collision-aware solver bounds each planned move from the IK pass's notes (each
    segment from the last command, the first from q_start): every bound is at most the clearance of 21 samples of
    its move, most keep the clearance (the loop's goal check then takes them without a query), and the goal check
    walking the plan takes every move."""
    from retarget.collision import CollisionModel
    from retarget.control.plan import solve_and_plan
    from retarget.control.safety import GoalCheck
    from retarget.ik import CCDSolver
    from retarget.ik.bound import shared_bound

    arm = retarget.load_arm("wx250s")
    model = CollisionModel.for_arm(arm)
    solver = CCDSolver(arm, collision=model)
    t = np.linspace(0.0, 2.0 * np.pi, 120)
    positions = np.stack([0.3 + 0.08 * np.cos(t), 0.15 * np.sin(2 * t), 0.25 + 0.08 * np.sin(t)], axis=1)
    q_start = solver.solve(positions[0], arm.home).q
    limits = {"lower": arm.lower, "upper": arm.upper}
    limits |= {"max_step": arm.max_velocity / 100, "max_accel": arm.max_acceleration / 1e4}  # at 100 Hz
    plan = solve_and_plan(solver, positions, None, np.zeros(len(t), dtype=bool), q_start, **limits)
    proven = shared_bound(model).proven
    assert proven is not None and len(proven) == len(t)
    lows = np.array(proven._low)
    starts = np.vstack([q_start[None], plan.q[:-1]])
    s = np.linspace(0.0, 1.0, 21)[:, None]
    for i in range(0, len(t), 3):
        true = float(model.distances(starts[i] + s * (plan.q[i] - starts[i])).min())
        assert lows[i] <= max(true, 0.0) + 1e-12
    assert np.mean(lows >= model.clearance) > 0.9
    check = GoalCheck(model, q_start)
    assert all(check.allows(a.tolist(), b.tolist()) for a, b in zip(starts, plan.q, strict=True))
    assert proven._next == len(t)  # every move was found proven: walked to its end


def _smooth_with_jumps(rng: np.random.Generator, n: int) -> list[float]:
    """A slow wave (the joint can stay on it) with a few steps in it that it cannot follow."""
    t = np.arange(n)
    path = 0.3 * np.sin(t / rng.uniform(20, 80)) + np.repeat(rng.uniform(-0.2, 0.2, n // 50 + 1), 50)[:n]
    return path.tolist()


@pytest.mark.parametrize("seed", range(6), ids=lambda s: f"seed{s}")
def test_the_profile_copies_the_slots_it_stays_on_the_goal_exactly_as_it_would_step_them(seed: int) -> None:
    """``_follow`` copies the goal where the joint stays on it (``_steady``); stepping every slot instead gives
    the same floats, bit for bit, on waves with steps in them, near the joint limits and from an offset start."""
    rng = np.random.default_rng(seed)
    goal = _smooth_with_jumps(rng, int(rng.integers(100, 400)))
    limits = (0.01, 0.002, -rng.uniform(0.3, 0.6), rng.uniform(0.3, 0.6))
    for q0 in (goal[0], goal[0] + 0.05, limits[2]):
        q0 = min(max(q0, limits[2]), limits[3])
        assert _follow(goal, q0, limits) == _follow(goal, q0, limits, jump=False)


def test_steady_marks_where_a_joint_on_the_goal_falls_off() -> None:
    """On a wave within the limits every slot keeps a joint on it to the end; a step beyond the velocity limit at
    slot 30 is where it falls off, from every slot before it, and slot 31 (back to the wave's step, beyond the
    acceleration limit of the step before); a goal near a joint limit is never copied."""
    wave = (0.2 * np.sin(np.arange(60) / 20.0)).tolist()
    limits = (0.05, 0.01, -1.0, 1.0)
    assert _steady(wave, limits) == [60] * 60
    stepped = wave[:30] + [x + 0.1 for x in wave[30:]]
    assert _steady(stepped, limits) == [30] * 30 + [31] + [60] * 29
    near = [0.99] * 10  # within the braking run of the upper limit (0.05^2 / 0.02 + 0.05 + 0.01 = 0.185)
    assert _steady(near, limits) == list(range(1, 11))


@pytest.mark.parametrize("look_ahead", [True, False], ids=["planned", "causal"])
def test_orientation_mode_on_the_demo_clip_converges(look_ahead: bool) -> None:
    """The demo clip at orientation weight 0.5 (issue 14: IK converges on >= 99 % of ticks).  Planned, each tick's IK
    is seeded where a joint at full speed toward the last solution would be: seeded from the last solution itself,
    the roll joints wound up to their limits near the wrist singularity and stalled there (44 % converged, tracking
    p95 291 mm).  Measured: planned 99.7 % and p95 18 mm, causal 99.6 % and 48 mm."""
    arm = retarget.load_arm("wx250s")
    config = retarget.MappingConfig.from_table(arm.mapping, overrides={"orientation_weight": 0.5})  # as export's flag
    targets = retarget.retarget_targets(retarget.load_bvh(retarget.DEMO_CLIP), arm, config)
    loop = ControlLoop(arm, targets, clock=VirtualClock(), look_ahead=look_ahead)
    records, p95 = _run(loop)
    assert sum(r.ik_converged for r in records) >= 0.99 * len(records)
    assert p95 < (25.0 if look_ahead else 60.0)


@pytest.mark.parametrize("side, most", [("left", 100.0), ("right", 300.0)], ids=["still-hand", "moving-hand"])
def test_the_planned_ik_is_tight_enough_that_the_joints_do_not_saw(side: str, most: float) -> None:
    """The look-ahead IK pass solves to the solver's 1 mm, then one batched DLS step polishes every tick
    (retarget.control.polish): unpolished, the error saws between ~0 and 0.25 mm from tick to tick and the plan
    follows it.  The demo clip's commanded jerk RMS, measured: left (a hand that hardly moves) 1297 rad/s^3
    unpolished, 24 now; right 438, 222 now; the planned tool point within 2 um of its target."""
    arm = retarget.load_arm("wx250s")
    config = retarget.MappingConfig.from_table(arm.mapping, overrides={"side": side})
    targets = retarget.retarget_targets(retarget.load_bvh(retarget.DEMO_CLIP), arm, config)
    loop = ControlLoop(arm, targets, clock=VirtualClock())
    records, _ = _run(loop)
    plan = loop.plan(loop.initial_pose())
    assert plan is not None and max(r.error for r in plan.ik) <= 1e-3  # the solver's own tolerance
    error = np.linalg.norm(arm.chain.tool_points(plan.q) - plan.positions, axis=1)
    assert float(error.max()) < 0.01e-3  # polished: nothing to plan on this clip, so the goals are the plan
    q = np.array([r.q_cmd for r in records])
    jerk = np.diff(q, 3, axis=0) * loop.config.rate**3
    assert float(np.sqrt(np.mean(jerk**2))) < most
