"""Collision-aware IK (``CCDSolver(collision=...)``): no result within the clearance, blocked targets reported."""

from __future__ import annotations

import math

import numpy as np
import pytest

from retarget import load_arm
from retarget.collision import CollisionModel, Sphere, World
from retarget.ik import CCDSolver
from tests.helpers import brute_force_min_clearances

ARMS = ["wx250s", "vx300s", "px100", "omx", "koch"]
N_TARGETS = 10_000  #: random targets per arm in the property test


def tool(arm, q):
    return arm.fk(q)[0][:3, 3]


def target_walk(solver, n, seed):
    """``(n, 3)`` random targets, metres, base frame: a walk drawn back toward a point in front of the arm (a
    discrete Ornstein-Uhlenbeck process: most steps stay in free space, as teleop does), folded at 3 cm below the
    table, that now and then jumps to anywhere in the box around the reach (out of reach too), dips below the
    table or into the base, and walks back from there."""
    arm = solver.arm
    rng = np.random.default_rng(seed)
    reach, pivot = solver.reach, np.array(solver.base_pivot)
    home = tool(arm, arm.home)
    front = (home - pivot) * [1.0, 1.0, 0.0]
    centre = pivot + reach * (0.45 * front / np.linalg.norm(front) + [0.0, 0.0, 0.3])
    noise = rng.normal(0.0, 0.03 * reach, (n, 3))
    kind = rng.choice(4, n, p=[0.995, 0.002, 0.002, 0.001])  # walk on, jump, below the table, into the base
    anywhere = pivot + rng.uniform(-1.0, 1.0, (n, 3)) * reach
    table = np.c_[pivot[:2] + rng.uniform(-0.8, 0.8, (n, 2)) * reach, rng.uniform(-0.03, 0.0, n)]
    base = np.c_[pivot[:2] + rng.uniform(-0.03, 0.03, (n, 2)), rng.uniform(0.0, pivot[2] + 0.01, n)]
    points, point = np.empty((n, 3)), home
    for k in range(n):
        point = (point + 0.05 * (centre - point) + noise[k], anywhere[k], table[k], base[k])[kind[k]]
        point[2] = abs(point[2] + 0.03) - 0.03
        points[k] = point
    return points


@pytest.mark.parametrize("name", ARMS)
def test_no_solution_comes_within_the_clearance(name):
    """Random targets (a walk through the arm's reach, below the table and into the base too), each solved warm
    from the last solution as the control loop does: every pose clear, by an independent brute-force check."""
    arm = load_arm(name)
    model = CollisionModel.for_arm(arm)
    solver = CCDSolver(arm, collision=model, max_iterations=30)
    q = arm.home.copy()
    poses, blocked = np.empty((N_TARGETS, arm.n_joints)), 0
    for k, point in enumerate(target_walk(solver, N_TARGETS, seed=7)):
        result = solver.solve(point, q)
        q = poses[k] = result.q
        blocked += result.blocked
        assert not result.blocked or not result.converged
    worst = brute_force_min_clearances(arm, np.unique(poses, axis=0))  # every distinct pose solved
    assert np.all(worst >= model.clearance - 1e-9), f"{int(np.sum(worst < model.clearance))} poses too close"
    assert 0.01 * N_TARGETS < blocked < 0.5 * N_TARGETS  # the walk went into blocked zones, and not only


@pytest.fixture(scope="module")
def wx():
    return load_arm("wx250s")


def test_a_target_inside_a_keep_out_ends_at_the_nearest_safe_pose_reported_blocked(wx):
    ball = Sphere((0.3, 0.0, 0.2), 0.05)
    model = CollisionModel.for_arm(wx, world=World(keep_out=(ball,)))
    result = CCDSolver(wx, collision=model).solve([0.3, 0.0, 0.2], wx.home)
    assert (result.converged, result.blocked) == (False, True)
    assert result.clearance >= model.clearance and model.is_clear(result.q)
    assert result.error == pytest.approx(np.linalg.norm(tool(wx, result.q) - [0.3, 0.0, 0.2]), abs=1e-12)
    assert 0.05 < result.error < 0.2  # held outside the ball: its radius, the clearance, the gripper's size
    free = CCDSolver(wx).solve([0.3, 0.0, 0.2], wx.home)  # without the model: into the ball
    assert free.converged and not model.is_clear(free.q)


def test_a_clear_target_costs_one_check_and_reports_its_clearance(wx):
    model = CollisionModel.for_arm(wx)
    result = CCDSolver(wx, collision=model).solve([0.3, 0.0, 0.2], wx.home)
    assert result.converged and not result.blocked
    assert result.clearance == pytest.approx(model.min_clearance(result.q))
    plain = CCDSolver(wx).solve([0.3, 0.0, 0.2], wx.home)
    np.testing.assert_array_equal(plain.q, result.q)  # the same solve: the check changed nothing
    assert not plain.blocked and math.isnan(plain.clearance)


@pytest.mark.parametrize("target", [[0.3, 0.0, -0.05], [0.0, 0.0, 0.02]], ids=["below-table", "inside-base"])
def test_targets_in_blocked_zones_stop_clear_of_them(wx, target):
    model = CollisionModel.for_arm(wx)
    result = CCDSolver(wx, collision=model).solve(target, wx.home)
    assert result.blocked and not result.converged
    assert brute_force_min_clearances(wx, result.q[None])[0] >= model.clearance


@pytest.mark.parametrize(
    "target", [[0.3, 0.0, -0.05], [0.0, 0.0, 0.02], [0.25, 0.1, 0.0]], ids=["below-table", "inside-base", "table-edge"]
)
def test_a_held_blocked_target_settles_on_one_pose(wx, target):
    """Solved again and again from its own answer (a held teleop target), a blocked target stops creeping along
    the obstacle: within a few ticks the answer is the seed itself, blocked, and clear."""
    model = CollisionModel.for_arm(wx)
    solver = CCDSolver(wx, collision=model)
    q, poses = wx.home, []
    for _ in range(4):
        result = solver.solve(target, q)
        assert result.blocked and not result.converged
        q = result.q
        poses.append(q)
    np.testing.assert_array_equal(poses[-1], poses[-2])
    assert np.all(brute_force_min_clearances(wx, poses) >= model.clearance)


@pytest.mark.parametrize(
    ("nudge", "seed_nudge", "held"),
    [(0.0, 0.0, True), (0.2e-3, 0.0, True), (0.2e-3, 0.5e-3, True), (2.5e-3, 0.0, False), (0.0, 5e-3, False)],
    ids=["same", "target-within-tolerance", "seed-within-step", "target-beyond", "seed-beyond"],
)
def test_a_stuck_blocked_target_is_held_for_targets_within_its_tolerance(wx, monkeypatch, nudge, seed_nudge, held):
    """Once a blocked re-solve gets no closer, a call from (within HELD_STEP of) the pose it returned, for a target
    within HELD tolerances of the one it got stuck on, gets that pose back without a query (blocked, clear, its
    error to the new target); a target or a seed farther off is solved again."""
    from retarget.ik import collide

    model = CollisionModel.for_arm(wx)
    solver = CCDSolver(wx, collision=model)
    target, q = np.array([0.3, 0.0, -0.05]), wx.home
    for _ in range(4):  # settles on one pose (see the test above)
        q = solver.solve(target, q).q
    assert solver._guard._fixed is not None
    assert nudge <= collide.HELD * solver.tolerance or not held
    queries = []
    real = model.min_clearance
    monkeypatch.setattr(model, "min_clearance", lambda p: queries.append(1) or real(p))
    moved = target + [nudge, 0.0, 0.0]
    seed = q + seed_nudge
    result = solver.solve(moved, seed)
    assert result.blocked and not result.converged
    if held:
        assert not queries
        np.testing.assert_array_equal(result.q, q)
        assert result.error == pytest.approx(float(np.linalg.norm(tool(wx, q) - moved)), abs=1e-12)
    else:
        assert queries
    assert brute_force_min_clearances(wx, result.q[None])[0] >= model.clearance


def test_a_seed_trapped_against_an_obstacle_gives_way_to_the_free_solution_from_home(wx):
    """A pose a random walk left the arm in (turned to the back and folded down, after targets below the table):
    the warm solve toward a reachable target collides and shortened steps cannot get out, so the free solution
    from home is taken: converged, clear."""
    model = CollisionModel.for_arm(wx)
    seed, target = np.array([-3.142, -1.791, 1.416, -0.476, 0.824, 0.0]), [0.098, 0.06, 0.136]
    assert model.is_clear(seed)
    free = CCDSolver(wx, max_iterations=30).solve(target, seed)
    assert free.converged and not model.is_clear(free.q)  # the warm free solution: into the base
    solver = CCDSolver(wx, collision=model, max_iterations=30)
    result = solver.solve(target, seed)
    assert result.converged and not result.blocked and result.error <= solver.tolerance
    assert brute_force_min_clearances(wx, result.q[None])[0] >= model.clearance


def test_a_path_around_an_obstacle_is_found_by_shortened_steps(wx):
    """A target reachable clear of a keep-out box, whose free solution from the seed collides with it."""
    model = CollisionModel.for_arm(wx, world=World(keep_out=(Sphere((0.25, 0.0, 0.35), 0.04),)))
    solver = CCDSolver(wx, collision=model)
    for target in ([0.25, 0.15, 0.3], [0.35, -0.1, 0.25], [0.2, 0.2, 0.1]):
        result = solver.solve(target, wx.home)
        assert model.is_clear(result.q)
        if not result.blocked:
            assert result.converged and result.error <= solver.tolerance


def test_an_orientation_target_is_checked_too(wx):
    model = CollisionModel.for_arm(wx, world=World(keep_out=(Sphere((0.3, 0.0, 0.2), 0.05),)))
    T, _ = wx.fk([0.0, 0.3, 0.2, 0.0, 0.4, 0.0])
    solver = CCDSolver(wx, collision=model, max_iterations=200)
    result = solver.solve([0.3, 0.0, 0.2], wx.home, T[:3, :3])
    assert result.blocked and not result.converged and model.is_clear(result.q)


@pytest.mark.parametrize("arm_name", ["wx250s", "vx300s", "koch"])
def test_the_bounds_never_exceed_the_true_clearance_near_a_noted_pose(arm_name):
    """Seeded property: from one noted pose, quick(q) <= lower_bound(q) <= the model's min clearance of q, for
    poses near it and far from it; pair_bounds never exceeds distances and is exact below its reach."""
    from retarget.ik.bound import ClearanceBound

    arm = load_arm(arm_name)
    model = CollisionModel.for_arm(arm, world=World(keep_out=(Sphere((0.3, 0.0, 0.2), 0.05),)))
    bound = ClearanceBound(model)
    rng = np.random.default_rng(7)
    for _ in range(40):
        ref = rng.uniform(arm.lower, arm.upper) * 0.6
        bound.note(ref, model.distances(ref))
        for scale in (0.002, 0.02, 0.2):
            q = np.clip(ref + rng.normal(0.0, scale, arm.n_joints), arm.lower, arm.upper)
            exact = model.distances(q)
            assert bound.quick(q) <= bound.lower_bound(q) + 1e-12 <= float(exact.min()) + 2e-12
            reach = model.clearance + 0.01
            pairs = model.pair_bounds(q, reach)
            assert np.all(pairs <= exact + 1e-12)
            near = exact < reach
            np.testing.assert_allclose(pairs[near], exact[near], atol=1e-12)
