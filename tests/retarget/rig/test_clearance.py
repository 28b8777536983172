"""Arm-against-arm clearance on a rig, against an independent sampled check."""

from __future__ import annotations

import numpy as np
import pytest

from retarget.rig import load_rig
from retarget.rig.clearance import RigClearance
from tests.helpers import sampled_min_clearance


@pytest.fixture(scope="module")
def pair():
    rig = load_rig("wx250s-pair")
    return rig, RigClearance(rig)


def test_the_clearance_matches_a_sampled_check_on_random_poses(pair):
    rig, check = pair
    rng = np.random.default_rng(19)
    N = 40
    poses = {a.name: rng.uniform(a.arm.lower, a.arm.upper, (N, a.arm.n_joints)) for a in rig.arms}
    fast = check.min_clearance(poses)
    assert fast.shape == (N,)
    for k in range(N):
        one = {name: q[k] for name, q in poses.items()}
        slow = sampled_min_clearance(rig, one)
        # the sampled minimum is never below the exact one, and within the sampling error (half a spacing)
        assert fast[k] - 1e-9 <= slow <= fast[k] + 0.002, k
        assert float(check.min_clearance(one)) == pytest.approx(fast[k], abs=1e-12)


def test_arms_reaching_for_each_other_collide_and_apart_they_do_not(pair):
    rig, check = pair
    left, right = rig["left"].arm, rig["right"].arm
    toward = {"left": left.home.copy(), "right": right.home.copy()}
    toward["left"][0], toward["right"][0] = -np.pi / 2, np.pi / 2  # waists turned to face each other
    name, value = check.worst_pair(toward)
    assert value < 0 and not check.is_clear(toward), (name, value)
    apart = {"left": left.home.copy(), "right": right.home.copy()}
    apart["left"][0], apart["right"][0] = np.pi / 2, -np.pi / 2  # turned away from each other
    assert check.is_clear(apart) and float(check.min_clearance(apart)) > 0.3


def test_pair_names_name_both_arms_and_links(pair):
    rig, check = pair
    n = len(check.shapes["left"].names) * len(check.shapes["right"].names)
    assert len(check.pair_names) == n and check.distances({a.name: a.arm.home for a in rig.arms}).shape == (n,)
    assert "left:upper_arm/right:gripper" in check.pair_names


def finite_speeds(check, rig_arm, Q, joint, h=1e-6):
    """Each shape's fastest end ``(n_poses, m)`` m/rad when ``joint`` of ``rig_arm`` turns, by finite differences of
    the shapes' world ends."""
    shapes = check.shapes[rig_arm.name]
    moved = Q.copy()
    moved[:, joint] += h
    return np.linalg.norm(shapes.world(rig_arm, moved) - shapes.world(rig_arm, Q), axis=-1).max(axis=-1) / h


@pytest.mark.parametrize("name", ["wx250s-pair", "aloha"])
def test_shape_motion_bounds_every_ends_speed_and_is_nearly_reached(name):
    """Seeded property: no shape's end moves faster per radian of any joint than ``ArmShapes.motion`` says, and for
    the shoulder and elbow some pose comes within 3 % of it (a bound weakened by more fails)."""
    rig = load_rig(name)
    check = RigClearance(rig)
    rig_arm = rig.arms[0]
    motion = check.shapes[rig_arm.name].motion
    Q = np.random.default_rng(23).uniform(rig_arm.arm.lower, rig_arm.arm.upper, (1500, rig_arm.arm.n_joints))
    reached = np.zeros_like(motion)
    for joint in range(rig_arm.arm.n_joints):
        speeds = finite_speeds(check, rig_arm, Q, joint).max(axis=0)
        assert np.all(speeds <= motion[:, joint] * (1 + 1e-5) + 1e-9), joint
        reached[:, joint] = np.divide(speeds, motion[:, joint], out=np.zeros_like(speeds), where=motion[:, joint] > 0)
    assert reached[:, 1:3].max() > 0.97


def test_measured_levers_are_the_ends_distances_from_the_joint_axes(pair):
    """``measure``'s levers against each end's distance from each joint's axis, by the chain's own batch FK and the
    rig placement; its clearances are ``distances``'."""
    rig, check = pair
    rng = np.random.default_rng(29)
    for _ in range(5):
        poses = {a.name: rng.uniform(a.arm.lower, a.arm.upper) for a in rig.arms}
        gaps, levers = check.measure(poses)
        assert gaps == pytest.approx(check.distances(poses), abs=1e-12)
        row = 0
        for rig_arm, joints in zip(rig.arms, check.joint_slices, strict=True):
            shapes, chain = check.shapes[rig_arm.name], rig_arm.arm.chain
            frames = rig_arm.placement.matrix @ chain.frames_batch(poses[rig_arm.name][None])[0]
            ends = shapes.world(rig_arm, poses[rig_arm.name][None])[0]  # (m, 2, 3)
            for i, frame in enumerate(shapes.frames):
                for j in range(chain.n):
                    origin, axis = frames[j + 1, :3, 3], frames[j + 1, :3, :3] @ chain.axes[j]
                    want = max(np.linalg.norm(np.cross(e - origin, axis)) for e in ends[i]) if j < frame else 0.0
                    assert levers[row + i, joints.start + j] == pytest.approx(want, abs=1e-12), (i, j)
                assert not levers[row + i, joints.stop :].any() and not levers[row + i, : joints.start].any()
            row += len(shapes.names)


@pytest.mark.parametrize("name", ["wx250s-pair", "aloha"])
def test_some_pairs_and_the_least_are_every_pairs_figures(name):
    """Seeded property: ``distances`` of some pairs, ``pair_gaps`` of scattered (pose, pair) entries and ``measure``'s
    least (from only the pairs that may be the nearest) are exactly the figures among all pairs, on poses far apart
    and with the arms reaching into each other (where many pairs are near: the least's screen must keep the right
    one)."""
    rig = load_rig(name)
    check = RigClearance(rig)
    rng = np.random.default_rng(31)
    for spread in (1.0, 0.3):
        poses = {a.name: rng.uniform(a.arm.lower, a.arm.upper, (60, a.arm.n_joints)) * spread for a in rig.arms}
        poses["left"][:, 0], poses["right"][:, 0] = -np.pi / 2, np.pi / 2  # waists turned toward each other
        every, levers = check.measure(poses)
        least, same_levers = check.measure(poses, every_pair=False)
        np.testing.assert_array_equal(least, every.min(axis=1))
        np.testing.assert_array_equal(same_levers, levers)
        some = rng.choice(len(check.pair_names), 17, replace=False)
        np.testing.assert_array_equal(check.distances(poses, pairs=some), every[:, some])
        rows, pairs = rng.integers(0, 60, 200), rng.integers(0, len(check.pair_names), 200)
        ends = check.ends([poses[n] for n in rig.names])
        np.testing.assert_array_equal(check.pair_gaps(ends, rows, pairs), every[rows, pairs])
    assert (every < 0).any()  # (the arms went into each other)
