"""Body frames from torso points: right-handed, degenerate frames flagged, the torso joint, spine frames
that match the shoulder frames."""

from __future__ import annotations

import numpy as np
import pytest

from retarget.bvh import parse_bvh
from retarget.mapping.torso import body_frames, body_frames_masked, shoulder_offsets, spine_frames, torso_joint
from tests.helpers import CMU_JOINTS, angles, cmu_bvh_text, cmu_random_frames, pose, rig
from tests.helpers import bvh_text as rig_text


def test_body_frames_are_right_handed_rotations():
    rng = np.random.default_rng(7)
    hips = rng.normal(size=(50, 3))
    left = hips + [0.2, 0.5, 0] + rng.normal(scale=0.05, size=(50, 3))
    right = hips + [-0.2, 0.5, 0] + rng.normal(scale=0.05, size=(50, 3))
    F = body_frames(hips, left, right)
    np.testing.assert_allclose(F @ np.swapaxes(F, -1, -2), np.broadcast_to(np.eye(3), F.shape), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(F), 1.0, atol=1e-12)
    assert np.all(F[:, 2, 0] > 0.5)  # facing +z when left is +x and up is +y
    with pytest.raises(ValueError, match="Expected a non-degenerate shoulder line"):
        body_frames(hips, left, left)


def test_body_frames_masked_flags_the_degenerate_frames():
    hips = np.zeros((4, 3))
    left = np.array([[1.0, 5, 0], [0, 5, 0], [0, 10, 0], [np.nan, 5, 0]])
    right = np.array([[-1.0, 5, 0], [0, 5, 0], [0, 2, 0], [-1, 5, 0]])  # fine, coincide, along the spine, NaN
    frames, ok = body_frames_masked(hips, left, right)
    assert ok.tolist() == [True, False, False, False]
    np.testing.assert_array_equal(frames[0], body_frames(hips[:1], left[:1], right[:1])[0])
    assert np.isnan(frames[1:]).all()
    with pytest.raises(ValueError, match="Expected a non-degenerate torso"):
        body_frames(hips[2:3], left[2:3], right[2:3])


def test_the_torso_joint_carries_the_shoulders():
    motion = parse_bvh(rig_text(rig(), pose(rig(), 1)))
    both = [motion.joint_index("LeftArm"), motion.joint_index("RightArm")]
    assert motion.joint_names[torso_joint(motion.parents, both)] == "Chest"
    assert motion.joint_names[torso_joint(motion.parents, both[:1])] == "Chest"  # it branches to the neck too


@pytest.mark.parametrize("seed", [0, 1, 2], ids=lambda s: f"seed{s}")
def test_spine_frames_match_the_shoulder_frames(seed):
    """The torso joint carries the shoulders: exact while the clavicles are still, a few degrees when they move."""
    for clavicles, tolerance in ((0.0, 1e-4), (1 / 3, 7.0)):  # still, then +-5 degrees
        frames = cmu_random_frames(seed)
        for i, (name, _, _) in enumerate(CMU_JOINTS):
            if name.endswith("Shoulder"):
                frames[:, 6 + 3 * (i - 1) : 9 + 3 * (i - 1)] *= clavicles
        motion = parse_bvh(cmu_bvh_text(frames))
        positions = motion.positions()
        rotations, _ = motion.global_transforms()
        left, right = motion.arm_points("left").points[:, 0], motion.arm_points("right").points[:, 0]
        hips = positions[:, 0]
        truth = body_frames(hips, left, right)
        t = torso_joint(motion.parents, [motion.joint_index("LeftArm"), motion.joint_index("RightArm")])
        assert motion.joint_names[t] == "Spine"
        good = np.ones(len(hips), dtype=bool)
        rest = motion.rest_positions()
        for offsets in (
            shoulder_offsets(positions[:, t], rotations[:, t], left, side="left", other_shoulder=right, good=good),
            shoulder_offsets(positions[:, t], rotations[:, t], left, side="left", spine_axis=rest[t] - rest[0]),
            shoulder_offsets(positions[:, t], rotations[:, t], right, side="right", spine_axis=rest[t] - rest[0]),
        ):
            spine, ok = spine_frames(hips, positions[:, t], rotations[:, t], offsets)
            assert ok.all()
            assert angles(truth, spine).max() < tolerance
