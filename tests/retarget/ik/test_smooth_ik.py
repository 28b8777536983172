"""Smooth IK (issue 14): locked roll joints in position-only mode, the base-axis damping (no waist flip near the
base's vertical axis, a turn when the target really goes to the other side), the per-joint trust region, the
orientation mode's convergence on the demo clip, and teleop's Cartesian speed limit from rest."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

import retarget
from retarget import ConfigError, load_arm
from retarget.control import LoopConfig
from retarget.control.clock import VirtualClock
from retarget.ik import CCDSolver
from retarget.mapping import retarget_targets
from retarget.mapping.config import MappingConfig
from retarget.mapping.workspace import ik_weights
from retarget.teleop import Follower, run_teleop, tool_point
from retarget.teleop.gate import TargetBounds, TargetGate
from retarget.teleop.sources import OneShotSource
from tests.helpers import SHARED_BVH

RATE = 100.0  #: ticks per second, the loop's default


def tool(arm, q):
    return arm.fk(q)[0][:3, 3]


def follow(arm, solver, positions, rotations=None, *, budget=30):
    """Warm solves along ``positions`` ``(n, 3)`` at :data:`RATE` as the control loop makes them: seeded from the
    commanded pose, the IK's answer then cut to each joint's max velocity per tick.  Returns the commanded poses
    ``(n, n_joints)`` and the IK results."""
    step = np.asarray(arm.max_velocity) / RATE
    q = solver.solve(positions[0], arm.home, None if rotations is None else rotations[0], max_iterations=200).q
    poses, results = [], []
    for i, p in enumerate(positions):
        r = solver.solve(p, q, None if rotations is None else rotations[i], max_iterations=budget)
        q = q + np.clip(r.q - q, -step, step)
        poses.append(q)
        results.append(r)
    return np.array(poses), results


# ------------------------------------------------------------------------------------------- redundant joints
@pytest.mark.parametrize(
    ("name", "locked"),
    [("wx250s", ["forearm_roll", "wrist_rotate"]), ("vx300s", ["forearm_roll", "wrist_rotate"]),
     ("koch", ["wrist_roll"]), ("px100", [])],
    ids=["wx250s", "vx300s", "koch", "px100"],
)  # fmt: skip
def test_position_only_weights_lock_the_roll_joints(name, locked):
    arm = load_arm(name)
    w = ik_weights(arm, MappingConfig())
    assert [n for n, x in zip(arm.joint_names, w, strict=True) if x == 0.0] == locked
    assert all(x == 1.0 for x in w if x != 0.0)
    np.testing.assert_array_equal(ik_weights(arm, MappingConfig(orientation_weight=0.5)), np.ones(arm.n_joints))


@pytest.mark.parametrize("name", ["wx250s", "vx300s"])
@pytest.mark.parametrize("seed", [0, 1])
def test_locked_joints_keep_their_value_through_restarts(name, seed):
    """Random reachable targets from random starts (cold: restarts and uniform seeds happen): the locked roll
    joints come back bit for bit, and the four free joints still reach nearly every target."""
    arm = load_arm(name)
    solver = CCDSolver(arm, weights=ik_weights(arm, MappingConfig()))
    locked = [3, 5]
    rng = np.random.default_rng(seed)
    converged = restarts = 0
    for _ in range(30):
        q0 = rng.uniform(arm.lower, arm.upper)
        r = solver.solve(tool(arm, rng.uniform(arm.lower, arm.upper)), q0)
        np.testing.assert_array_equal(r.q[locked], q0[locked])
        converged += r.converged
        restarts += r.restarts
    assert converged >= 28 and restarts > 0


def test_the_redundant_joints_stay_still_on_a_clip():
    """motion_dance, position only, through the loop's per-tick velocity limit: forearm_roll and wrist_rotate do
    not move at all (the issue's target: at most 1 rad of travel; CCD with damped weights moved them 0.25 rad)."""
    clip = SHARED_BVH / "motion_dance.bvh"
    if not clip.exists():
        pytest.skip(f"{clip} not found (set RETARGET_SHARED_BVH)")
    arm = load_arm("wx250s")
    config = MappingConfig.from_table(arm.mapping)
    targets = retarget_targets(retarget.load_bvh(clip), arm, config)
    positions, _, _ = targets.sample(np.arange(0.0, 8.0, 1.0 / RATE))
    poses, results = follow(arm, CCDSolver(arm, weights=ik_weights(arm, config)), positions)
    travel = np.abs(np.diff(poses, axis=0)).sum(axis=0)
    assert travel[[3, 5]].tolist() == [0.0, 0.0] and travel[[0, 1, 2, 4]].min() > 1.0
    assert np.mean([r.converged for r in results]) >= 0.99


# ------------------------------------------------------------------------------------------- the base axis
def through_the_axis(x: float = 0.01, z: float = 0.35) -> np.ndarray:
    """A straight line 1 cm in front of the base's vertical axis, from its right to its left, 5 mm a tick
    (0.5 m/s at 100 Hz), above the shoulder: ``(81, 3)`` metres."""
    return np.array([[x, y, z] for y in np.arange(-0.2, 0.2001, 0.005)])


def test_a_path_through_the_base_axis_does_not_flip_the_waist():
    """Undamped, the waist turns by half a turn as the target passes the axis (a 0.45 rad jump in one solve);
    damped, it turns less than 0.2 rad a solve and 1 rad in all, the arm reaching over instead, and the position
    error stays below the target's distance ``r`` from the axis (the stated bound)."""
    arm = load_arm("wx250s")
    w = ik_weights(arm, MappingConfig())
    path = through_the_axis()
    base = np.array(arm.joints[0].origin_xyz)
    r_axis = np.hypot(path[:, 0] - base[0], path[:, 1] - base[1])
    for solver, flips in ((CCDSolver(arm, weights=w), False), (CCDSolver(arm, weights=w, base_radius=0), True)):
        q = solver.solve(path[0], arm.home, max_iterations=200).q
        waist, errors = [q[0]], []
        for p in path[1:]:
            r = solver.solve(p, q, max_iterations=30)
            q = r.q
            waist.append(q[0])
            errors.append(r.error)
        turn = np.abs(np.diff(waist))
        if flips:
            assert turn.sum() > 2.5
            continue
        assert turn.max() < 0.2 and turn.sum() < 1.0
        assert np.all(np.array(errors) <= np.maximum(r_axis[1:], solver.tolerance) + 1e-9)
        assert errors[-1] <= solver.tolerance


def test_the_waist_speed_stays_within_its_limit_through_the_axis():
    """The same path through the loop's per-tick velocity limit.  Undamped, the waist chases the flipping IK
    answer at its full speed on 29 ticks, turns 1.18 rad and trails by up to 25 mm; damped it turns 0.8 rad, runs
    at its limit on 13 ticks (catching up as the target leaves the damped zone) and trails by 18 mm at most."""
    arm = load_arm("wx250s")
    w = ik_weights(arm, MappingConfig())
    path = through_the_axis()
    limit = arm.max_velocity[0] / RATE
    for solver, damped in ((CCDSolver(arm, weights=w), True), (CCDSolver(arm, weights=w, base_radius=0), False)):
        poses, results = follow(arm, solver, path)
        turn = np.abs(np.diff(poses[:, 0]))
        at_limit = int(np.sum(turn >= limit * (1 - 1e-9)))
        trail = max(np.linalg.norm(tool(arm, q) - p) for q, p in zip(poses, path, strict=True))
        assert turn.max() <= limit * (1 + 1e-9) and results[-1].converged
        if damped:
            assert turn.sum() < 1.0 and at_limit <= 15 and trail < 0.02
        else:
            assert turn.sum() > 1.0 and at_limit > 20 and trail > 0.02


def test_a_move_to_the_other_side_turns_the_waist():
    """An arc 0.3 m from the axis round to 150 degrees, and a jump to the back: the waist follows (the damping
    only acts within ``base_radius`` of the axis, and on small moves)."""
    arm = load_arm("wx250s")
    solver = CCDSolver(arm, weights=ik_weights(arm, MappingConfig()))
    assert solver.base_radius == pytest.approx(0.1 * solver.reach)
    q = solver.solve([0.3, 0.0, 0.2], arm.home).q
    for a in np.radians(np.arange(1.0, 150.1, 1.0)):
        r = solver.solve([0.3 * math.cos(a), 0.3 * math.sin(a), 0.2], q, max_iterations=30)
        assert r.converged
        q = r.q
    assert q[0] == pytest.approx(math.radians(150), abs=0.01)
    front = solver.solve([0.3, 0.0, 0.2], arm.home).q
    back = solver.solve([-0.3, 0.05, 0.2], front)
    assert back.converged and abs(back.q[0]) > 2.5


# ------------------------------------------------------------------------------------------- trust region
def test_a_per_joint_max_step_is_a_box():
    arm = load_arm("wx250s")
    steps = np.array([0.01, 0.02, 0.03, 0.04, 0.05, 0.06])
    target = tool(arm, [0.4, -0.3, 0.5, 0.2, 0.4, 0.1])
    r = CCDSolver(arm).solve(target, arm.home, max_step=steps)
    assert np.all(np.abs(r.q - arm.home) <= steps + 1e-12) and not r.converged
    assert np.any(np.abs(np.abs(r.q - arm.home) - steps) < 1e-12)  # it leans on the box
    with pytest.raises(ConfigError, match=re.escape("max_step: Expected one max_step or 6, got shape (2,)")):
        CCDSolver(arm).solve(target, arm.home, max_step=[0.1, 0.1])
    with pytest.raises(ConfigError, match=re.escape("max_step: Expected a finite number > 0 (got -0.1)")):
        CCDSolver(arm).solve(target, arm.home, max_step=[0.1, 0.1, -0.1, 0.1, 0.1, 0.1])


@pytest.mark.parametrize(("knob", "value"), [("dls_steps", -1), ("damping", 0.0), ("base_radius", -0.1)])
def test_smoothing_knob_errors(knob, value):
    with pytest.raises(ConfigError, match=f"^{knob}: "):
        CCDSolver(load_arm("wx250s"), **{knob: value})


# ------------------------------------------------------------------------------------------- orientation mode
def test_orientation_mode_converges_on_the_demo_clip():
    """``--orientation-weight 0.5`` on the bundled demo clip, the loop's budget of 30 sweeps a tick: CCD alone
    converged on 98.7 % of ticks (it crawls near the wrist singularity, wrist_angle ~ 0); the DLS polish of the
    best pose gets >= 99 %."""
    arm = load_arm("wx250s")
    config = MappingConfig.from_table(arm.mapping, overrides={"orientation_weight": 0.5})
    targets = retarget_targets(retarget.load_bvh(retarget.DEMO_CLIP), arm, config)
    positions, rotations, _ = targets.sample(np.arange(0.0, 6.0, 1.0 / RATE))
    assert rotations is not None
    solver = CCDSolver(arm, orientation_weight=0.5)
    _, results = follow(arm, solver, positions, rotations)
    assert np.mean([r.converged for r in results]) >= 0.99


# ------------------------------------------------------------------------------------------- teleop
@pytest.mark.parametrize("target", ["0.35,0.1,0.3", "0.25,0.15,0.28", "0.2,-0.2,0.1"])
def test_teleop_from_rest_holds_the_cartesian_speed_limit(target):
    """From the folded rest pose at 5 cm/s (dry run): the commanded tool point moves at most ``max_speed`` over
    any window of 1, 10 or 50 ticks, plus twice the distance a solve may leave between the tool and its setpoint
    (a quarter of the 1 mm tolerance: 0.5 mm).  The IK once stopped anywhere within 1 mm of the setpoint from a
    seed that the loop moves on by half the last step, and the tool ran at 0.08 m/s over 10 ticks."""
    arm, max_speed = load_arm("wx250s"), 0.05
    clock = VirtualClock()
    source = OneShotSource(TargetGate(TargetBounds.for_arm(arm), clock=clock), target)
    follower = Follower(arm, source, clock=clock, rate=RATE, max_speed=max_speed)
    records = []
    result = run_teleop(arm, follower, config=LoopConfig(), clock=clock, on_tick=records.append, q_start=arm.rest)
    assert result.reached_target
    points = np.array([tool_point(arm, r.q_cmd) for r in records])
    slack = 2 * 0.25 * LoopConfig().ik_tolerance
    for window in (1, 10, 50):
        moved = np.linalg.norm(points[window:] - points[:-window], axis=1)
        assert moved.max() <= max_speed * window / RATE + slack, (window, moved.max())
