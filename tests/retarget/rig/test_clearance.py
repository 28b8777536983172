"""Arm-against-arm clearance on a rig, against an independent sampled check."""

from __future__ import annotations

import numpy as np
import pytest

from retarget.rig import load_rig
from retarget.rig.clearance import RigClearance


def sampled_min_clearance(rig, poses, spacing=0.004):
    """The arm-arm clearance by brute force: points every ``spacing`` m along each capsule's segment (a box's
    bounding sphere is one point), each arm's shapes placed by its own FK chain product written here."""
    clouds = []
    for rig_arm in rig.arms:
        arm, q = rig_arm.arm, np.asarray(poses[rig_arm.name], dtype=np.float64)
        frames = [np.eye(4)]
        for joint, angle in zip(arm.joints, q, strict=True):
            x, y, z = joint.origin_xyz
            r, p, w = joint.origin_rpy
            cr, sr, cp, sp, cw, sw = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(w), np.sin(w)
            origin = np.eye(4)
            origin[:3, :3] = [[cw * cp, cw * sp * sr - sw * cr, cw * sp * cr + sw * sr],
                              [sw * cp, sw * sp * sr + cw * cr, sw * sp * cr - cw * sr],
                              [-sp, cp * sr, cp * cr]]  # fmt: skip
            origin[:3, 3] = (x, y, z)
            k = np.asarray(joint.axis, dtype=np.float64) / np.linalg.norm(joint.axis)
            K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
            spin = np.eye(4)
            spin[:3, :3] = np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K
            frames.append(frames[-1] @ origin @ spin)
        place = rig_arm.placement.matrix
        points, radii = [], []
        for link in arm.geometry.links:
            shape, T = link.shape, place @ frames[link.frame]
            if hasattr(shape, "radius"):
                a, b = np.asarray(shape.a), np.asarray(shape.b)
                n = max(2, int(np.ceil(np.linalg.norm(b - a) / spacing)) + 1)
                local = a + np.linspace(0, 1, n)[:, None] * (b - a)
                radius = shape.radius
            else:
                local, radius = np.asarray(shape.center)[None], float(np.linalg.norm(shape.half_size))
            points.append(local @ T[:3, :3].T + T[:3, 3])
            radii.append(np.full(len(local), radius))
        clouds.append((np.concatenate(points), np.concatenate(radii)))
    (pa, ra), (pb, rb) = clouds
    gaps = np.linalg.norm(pa[:, None] - pb[None], axis=-1) - ra[:, None] - rb[None]
    return float(gaps.min())


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
