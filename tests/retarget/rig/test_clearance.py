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
