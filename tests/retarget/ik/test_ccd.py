"""CCD IK: round trips, limits, early-out, budget, unreachable targets, weights, orientation, errors."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from retarget import ConfigError, load_arm, solve_ik
from retarget.ik import CCDSolver, IKResult, Weighting, joint_weights

ARMS = ["wx250s", "vx300s", "px100", "omx", "koch"]


def tool(arm, q):
    return arm.fk(q)[0][:3, 3]


def random_targets(arm, seed, n):
    rng = np.random.default_rng(seed)
    Q = rng.uniform(arm.lower, arm.upper, (n, arm.n_joints))
    return [tool(arm, q) for q in Q]


@pytest.mark.parametrize("order", ["base-first", "tip-first"])
@pytest.mark.parametrize("name", ARMS)
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_round_trip_from_random_reachable_poses(name, seed, order):
    arm = load_arm(name)
    solver = CCDSolver(arm, order=order)
    failed = 0
    for target in random_targets(arm, seed, 25):
        r = solver.solve(target, arm.home)
        assert np.linalg.norm(tool(arm, r.q) - target) == pytest.approx(r.error, abs=1e-12)
        assert arm.within_limits(r.q)
        assert r.converged == (r.error <= 1e-3)
        failed += not r.converged
        assert r.error < 0.01  # a rare miss still ends close
    assert failed <= 1  # the benchmark measures >= 99.5 % over 2000 targets per arm


@pytest.mark.parametrize("seed", range(6))
def test_limits_never_violated(seed):
    """Property: any target (reachable, unreachable, inside the base), any start inside or outside the limits."""
    arm = load_arm(["wx250s", "px100", "koch"][seed % 3])
    rng = np.random.default_rng(seed)
    solver = CCDSolver(arm, max_iterations=30)
    for _ in range(40):
        target = rng.normal(scale=0.5, size=3)
        q0 = rng.uniform(arm.lower - 1, arm.upper + 1)
        r = solver.solve(target, q0)
        assert np.all(np.isfinite(r.q)) and math.isfinite(r.error)
        assert np.all(r.q >= arm.lower) and np.all(r.q <= arm.upper), r.q


def test_early_out_runs_zero_sweeps():
    """Within a quarter of the tolerance nothing runs; within the tolerance but farther, one DLS step lands the
    tool within that quarter (a warm tick does not stay up to 1 mm off, see test_smooth_ik); pure CCD
    (``dls_steps=0``) stops at the tolerance."""
    arm = load_arm("wx250s")
    q0 = np.array([0.3, -0.2, 0.4, 0.1, 0.5, -0.3])
    close = solve_ik(arm, tool(arm, q0) + [0.0002, 0.0, 0.0], q0)
    assert close.iterations == 0 and close.converged and close.restarts == 0
    np.testing.assert_array_equal(close.q, q0)
    assert close.error == pytest.approx(0.0002)
    target = tool(arm, q0) + [0.0005, 0.0, 0.0]
    r = solve_ik(arm, target, q0)
    assert r.iterations == 1 and r.converged and r.error <= 0.00025
    ccd = CCDSolver(arm, dls_steps=0).solve(target, q0)
    assert ccd.iterations == 0 and ccd.converged
    np.testing.assert_array_equal(ccd.q, q0)


@pytest.mark.parametrize(
    ("order", "joint", "untouched"),
    [("tip-first", 4, slice(0, 4)), ("base-first", 0, slice(1, 6))],
    ids=["tip-first-wrist", "base-first-waist"],
)
def test_sweep_stops_once_within_tolerance(order, joint, untouched):
    """A target one joint alone reaches, visited first: the first sweep stops there and touches nothing else."""
    arm = load_arm("wx250s")
    q0 = np.array([0.3, -0.2, 0.4, 0.1, 0.5, -0.3])
    moved = q0.copy()
    moved[joint] += 0.02 if joint else 0.008  # about 3 mm at the tool
    target = tool(arm, moved)
    assert np.linalg.norm(target - tool(arm, q0)) > 2e-3
    r = CCDSolver(arm, order=order, dls_steps=0).solve(target, q0)  # the CCD sweep itself
    assert r.iterations == 1 and r.converged
    np.testing.assert_array_equal(r.q[untouched], q0[untouched])
    assert r.q[joint] == pytest.approx(moved[joint], abs=1e-6)


def test_budget_exhaustion_returns_the_best_pose_and_residual():
    arm = load_arm("wx250s")
    target = random_targets(arm, 7, 1)[0]
    full = CCDSolver(arm).solve(target, arm.home)
    assert full.iterations > 1
    r = CCDSolver(arm, max_iterations=1).solve(target, arm.home)
    assert r.iterations == 1 and not r.converged
    assert r.error > 1e-3
    assert r.error == pytest.approx(np.linalg.norm(tool(arm, r.q) - target), abs=1e-12)
    assert r.error < np.linalg.norm(tool(arm, arm.home) - target)
    zero = CCDSolver(arm).solve(target, arm.home, max_iterations=0)
    assert zero.iterations == 0 and not zero.converged and np.array_equal(zero.q, arm.home)


@pytest.mark.parametrize("name", ARMS)
def test_unreachable_target_gives_the_closest_pose(name):
    arm = load_arm(name)
    solver = CCDSolver(arm)
    direction = np.array([0.6, -0.3, 0.74])
    direction /= np.linalg.norm(direction)
    target = np.array(arm.joints[0].origin_xyz) + 5.0 * direction
    r = solver.solve(target, arm.home)
    assert not r.converged and np.all(np.isfinite(r.q)) and arm.within_limits(r.q)
    reached = tool(arm, r.q)
    # stretched toward the target: the residual is about the distance left beyond the reach
    assert r.error == pytest.approx(np.linalg.norm(reached - target))
    assert r.error < 5.0 - 0.8 * np.linalg.norm(reached - arm.joints[0].origin_xyz)
    # no random target of the workspace is closer
    samples = [tool(arm, q) for q in np.random.default_rng(0).uniform(arm.lower, arm.upper, (300, arm.n_joints))]
    assert r.error <= min(np.linalg.norm(s - target) for s in samples) + 1e-3


def test_no_full_turn_jump_across_the_seam():
    """The waist sits near +180 deg; a target just across the seam must not make it wrap."""
    arm = load_arm("wx250s")
    q0 = np.array([3.1, 0.2, 0.1, 0.0, 0.3, 0.0])
    T = arm.fk(np.array([-3.1, 0.2, 0.1, 0.0, 0.3, 0.0]))[0]
    r = CCDSolver(arm).solve(T[:3, 3], q0)
    assert r.converged and arm.within_limits(r.q)
    near = CCDSolver(arm).solve(tool(arm, q0) + [0, 0, 0.004], q0)
    assert near.converged and np.abs(near.q - q0).max() < 0.1


@pytest.mark.parametrize(
    "weights", ["uniform", "linear", "sqrt", "power", Weighting.POWER, [0.5, 0.6, 0.7, 0.8, 0.9, 1.0]]
)
def test_weight_variants_solve(weights):
    arm = load_arm("wx250s")
    solver = CCDSolver(arm, weights=weights, weight_exponent=1.5, max_iterations=300)  # damped joints crawl
    for target in random_targets(arm, 3, 10):
        assert solver.solve(target, arm.home).converged


def test_weight_values():
    assert joint_weights(4, "uniform") == (1.0, 1.0, 1.0, 1.0)
    assert joint_weights(4, "linear") == (0.25, 0.5, 0.75, 1.0)
    assert joint_weights(4, "sqrt") == pytest.approx((0.5, math.sqrt(0.5), math.sqrt(0.75), 1.0))
    assert joint_weights(4, "power", exponent=2) == (0.0625, 0.25, 0.5625, 1.0)
    assert joint_weights(2, [0.3, 1]) == (0.3, 1.0)


def test_weights_bias_the_motion():
    """Damping the base joints (linear) leaves more of a small correction to the wrist than uniform."""
    arm = load_arm("wx250s")
    q0 = np.array([0.0, 0.2, 0.3, 0.0, 0.4, 0.0])
    target = tool(arm, q0) + [0.03, 0.02, -0.02]
    uniform = CCDSolver(arm, weights="uniform").solve(target, q0)
    base = np.array([1.0, 1.0, 1.0, 0.05, 0.05, 0.05])
    biased = CCDSolver(arm, weights=base).solve(target, q0)
    assert uniform.converged and biased.converged
    assert np.abs(biased.q - q0)[:3].sum() > np.abs(uniform.q - q0)[:3].sum()


@pytest.mark.parametrize(
    ("weights", "exponent", "message"),
    [
        ("cubic", 2.0, "unknown weighting; expected one of uniform, linear, sqrt, power or 6 numbers"),
        ([1, 1], 2.0, "Expected 6 per-joint weights, got shape (2,)"),
        ([1, 1, 1, 1, 1, -0.1], 2.0, "per-joint weights must lie in [0, 1], one > 0"),
        ([0, 0, 0, 0, 0, 0], 2.0, "per-joint weights must lie in [0, 1], one > 0"),
        ("power", -1.0, "weight exponent must be a finite number > 0"),
    ],
    ids=["unknown-name", "wrong-count", "negative-weight", "all-locked", "bad-exponent"],
)
def test_weight_errors(weights, exponent, message):
    with pytest.raises(ConfigError, match=re.escape(message)):
        CCDSolver(load_arm("wx250s"), weights=weights, weight_exponent=exponent)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"tolerance": 0}, "tolerance: Expected a finite number > 0 (got 0)"),
        ({"max_iterations": 0}, "max_iterations: Expected an integer >= 1 (got 0)"),
        ({"stall_ratio": 1.0}, "stall_ratio must lie in (0, 1)"),
        ({"accel_ratio": 1.0}, "accel_ratio must lie in [0, 1)"),
        ({"max_step": -0.1}, "max_step: Expected a finite number > 0 (got -0.1)"),
        ({"restarts": -1}, "restarts: Expected an integer >= 0 (got -1)"),
        ({"order": "random"}, "unknown sweep order; expected one of base-first, tip-first"),
    ],
    ids=["tolerance", "budget", "stall", "accel", "max-step", "restarts", "order"],
)
def test_solver_knob_errors(kwargs, message):
    with pytest.raises(ConfigError, match=re.escape(message)):
        CCDSolver(load_arm("wx250s"), **kwargs)


@pytest.mark.parametrize(
    ("target", "q0", "rotation", "message"),
    [
        ([0.3, 0.0], None, None, "Expected target of shape (3,), got (2,)"),
        ([0.3, math.nan, 0.2], None, None, "Expected a finite target"),
        ([0.3, 0.0, 0.2], np.zeros(5), None, "Expected q0 of shape (6,), got (5,)"),
        ([0.3, 0.0, 0.2], [0, 0, math.inf, 0, 0, 0], None, "Expected finite joint angles q0"),
        ([0.3, 0.0, 0.2], None, np.eye(2), "Expected rotation of shape (3, 3), got (2, 2)"),
        ([0.3, 0.0, 0.2], None, 2 * np.eye(3), "Expected rotation to be a proper rotation matrix"),
    ],
    ids=["target-shape", "target-nan", "q0-shape", "q0-inf", "rotation-shape", "not-rotation"],
)
def test_bad_inputs(target, q0, rotation, message):
    arm = load_arm("wx250s")
    with pytest.raises(ValueError, match=re.escape(message)):
        solve_ik(arm, target, q0, rotation=rotation)


@pytest.mark.parametrize("name", ["wx250s", "vx300s"])
@pytest.mark.parametrize("seed", [0, 1])
def test_orientation_target(name, seed):
    arm = load_arm(name)
    rng = np.random.default_rng(seed)
    solver = CCDSolver(arm, max_iterations=400)
    solved = 0
    for _ in range(8):
        q = rng.uniform(0.7 * arm.lower, 0.7 * arm.upper)
        T = arm.fk(q)[0]
        r = solver.solve(T[:3, 3], arm.home, rotation=T[:3, :3])
        assert arm.within_limits(r.q)
        R = arm.fk(r.q)[0]
        angle = math.acos(np.clip((np.trace(R[:3, :3].T @ T[:3, :3]) - 1) / 2, -1, 1))
        assert r.orientation_error == pytest.approx(angle, abs=1e-9)
        if r.converged:
            solved += 1
            assert r.error <= 1e-3 and r.orientation_error <= 1e-2
    assert solved >= 7


def test_orientation_early_out_and_position_only_has_nan_orientation():
    arm = load_arm("wx250s")
    q0 = np.array([0.3, -0.2, 0.4, 0.1, 0.5, -0.3])
    T = arm.fk(q0)[0]
    r = solve_ik(arm, T[:3, 3], q0, rotation=T[:3, :3])
    assert r.iterations == 0 and r.converged and r.orientation_error < 1e-6
    assert math.isnan(solve_ik(arm, T[:3, 3], q0).orientation_error)


def test_max_step_is_a_trust_region():
    arm = load_arm("wx250s")
    target = random_targets(arm, 11, 1)[0]
    r = CCDSolver(arm, max_step=0.05).solve(target, arm.home)
    assert np.abs(r.q - arm.home).max() <= 0.05 + 1e-12
    r2 = CCDSolver(arm).solve(target, arm.home, max_step=None)
    assert r2.converged


def test_smooth_path_moves_smoothly():
    """Warm-started along a smooth path of about 4 mm per tick: all converge, no joint jumps."""
    arm = load_arm("wx250s")
    s = np.linspace(0, 1, 700)[:, None]
    Q = np.array([0.2, -0.3, 0.4, 0.3, 0.6, 0.1]) + 0.35 * np.sin(2 * np.pi * s * [1, 2, 1, 3, 2, 1])
    targets = arm.chain.fk_batch(Q)[:, :3, 3]
    assert np.linalg.norm(np.diff(targets, axis=0), axis=1).max() < 0.005
    solver = CCDSolver(arm)
    q = Q[0]
    for t in targets:
        r = solver.solve(t, q)
        assert r.converged
        assert np.abs(r.q - q).max() <= 0.05
        q = r.q


def test_solves_are_deterministic_and_solver_is_cached():
    arm = load_arm("wx250s")
    targets = random_targets(arm, 5, 20)
    a = [solve_ik(arm, t, arm.home) for t in targets]
    b = [CCDSolver(arm).solve(t, arm.home) for t in targets]
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x.q, y.q)
        assert (x.iterations, x.restarts) == (y.iterations, y.restarts)
    assert sum(isinstance(v, CCDSolver) for v in arm._cache.values()) == 1
    assert isinstance(a[0], IKResult)


@pytest.mark.parametrize("order", ["tip-first", "base-first"])
def test_short_lever_damping_keeps_the_forearm_roll_still(order):
    """Wrist nearly straight: the tool sits almost on the forearm-roll axis.  Undamped tip-first CCD swings the
    roll far for a 3 mm sideways step; the damped solver takes it with a small waist turn instead."""
    arm = load_arm("wx250s")
    q0 = np.array([0.0, 0.3, 0.2, 0.0, 0.02, 0.0])
    target = tool(arm, q0) + [0.0, 0.003, 0.0]
    undamped = CCDSolver(arm, short_lever=0, order="tip-first", dls_steps=0).solve(target, q0)
    assert undamped.converged and abs(undamped.q[3] - q0[3]) > 0.3
    for dls in (0, 8):  # CCD alone, and the default DLS first step (its Jacobian column is short too)
        damped = CCDSolver(arm, order=order, dls_steps=dls).solve(target, q0)
        assert damped.converged and np.abs(damped.q - q0).max() < 0.02


def test_restarts_escape_limit_minima():
    arm = load_arm("wx250s")
    targets = random_targets(arm, 5, 100)
    plain, default = CCDSolver(arm, restarts=0), CCDSolver(arm)
    stuck = [t for t in targets if not plain.solve(t, arm.home).converged]
    assert len(stuck) >= 3  # plain CCD (with the line search) still misses some
    results = [default.solve(t, arm.home) for t in stuck]
    assert all(r.converged and r.restarts > 0 for r in results)


def test_line_search_speeds_up_crawling_sweeps():
    arm = load_arm("wx250s")
    targets = random_targets(arm, 6, 40)
    with_search = [CCDSolver(arm, dls_steps=0).solve(t, arm.home) for t in targets]
    without = [CCDSolver(arm, accel_ratio=0, dls_steps=0).solve(t, arm.home) for t in targets]
    assert sum(r.iterations for r in with_search) * 2 < sum(r.iterations for r in without)
    assert all(r.converged for r in with_search)


def test_pose_tracking_stays_on_its_branch():
    """Position + orientation targets along a smooth path, warm-started with a control-loop budget: restarts
    perturb the last pose instead of jumping to another branch."""
    arm = load_arm("wx250s")
    s = np.linspace(0, 1, 300)[:, None]
    Q = np.array([0.2, -0.2, 0.3, 0.4, 0.5, -0.3]) + 0.4 * np.sin(
        2 * np.pi * s * [1, 2, 1, 1, 2, 1] + [0, 1, 2, 3, 4, 5]
    )
    poses = arm.chain.fk_batch(Q)
    solver = CCDSolver(arm, max_iterations=30)
    q, converged = Q[0], 0
    for T in poses:
        r = solver.solve(T[:3, 3], q, rotation=T[:3, :3])
        assert np.abs(r.q - q).max() < 0.2
        converged += r.converged
        q = r.q
    assert converged >= 0.99 * len(poses)


@pytest.mark.parametrize("name", ["wx250s", "koch"])
def test_a_solve_does_not_depend_on_the_solver_history(name):
    """The solver keeps its last forward pass for the next warm start (``_fk_memo``): a walk of warm-started
    solves, with jumps and unreachable targets between (CCD sweeps, restarts), gives bit for bit what a fresh solver
    gives for each solve."""
    arm = load_arm(name)
    used = CCDSolver(arm)
    rng = np.random.default_rng(7)
    q = arm.home.copy()
    point = tool(arm, q)
    for k in range(150):
        if k % 5 == 4:  # a jump anywhere within the reach sphere: often unreachable (limits), with restarts
            target = np.asarray(used.base_pivot) + used.reach * rng.uniform(-1.0, 1.0, 3) / math.sqrt(3.0)
        else:
            target = point + rng.normal(0.0, 0.004, 3)
        result = used.solve(target, q)
        fresh = CCDSolver(arm).solve(target, q)
        assert np.array_equal(result.q, fresh.q), k
        assert (result.error, result.iterations) == (fresh.error, fresh.iterations)
        q, point = result.q, target
