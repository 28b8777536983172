"""Human -> arm targets: invariances (units, rigid motion of the whole body), the T-pose and reaching, the
workspace clamp and hand orientations of whole clips, sampling, clips that cannot drive an arm."""

from __future__ import annotations

import numpy as np
import pytest

import retarget
from retarget.bvh import parse_bvh
from retarget.bvh.motion import ArmChain
from retarget.errors import BvhError
from retarget.mapping.config import Axis, MappingConfig
from retarget.mapping.targets import Targets, retarget_targets
from retarget.mapping.workspace import Workspace, arm_geometry, default_origin
from tests.helpers import CMU_JOINTS, J, cmu_random_frames, joints_in_order, pose, rig, t_pose, targets_of
from tests.helpers import bvh_text as rig_text


@pytest.mark.parametrize("seed", [0, 1, 2], ids=lambda s: f"seed{s}")
@pytest.mark.parametrize("scale", [100.0, 0.01, 1 / 2.54], ids=["x100", "metres", "inches"])
def test_units_do_not_matter(arm, seed, scale):
    frames = cmu_random_frames(seed)
    base = targets_of(frames, arm)
    other = targets_of(frames, arm, scale=scale)
    np.testing.assert_allclose(other.raw, base.raw, atol=1e-9)
    np.testing.assert_array_equal(other.clamped, base.clamped)
    assert other.scale == pytest.approx(base.scale / scale)


@pytest.mark.parametrize("seed", [0, 3], ids=lambda s: f"seed{s}")
@pytest.mark.parametrize("yaw", [37.0, 180.0, -120.0], ids=lambda y: f"yaw{y:g}")
def test_turning_and_walking_the_whole_body_does_not_move_the_arm(arm, seed, yaw):
    frames = cmu_random_frames(seed)
    moved = frames.copy()
    moved[:, 3] += yaw  # the root's first rotation channel: a turn about the vertical
    moved[:, 0] += 250.0 * np.linspace(0, 1, len(frames))  # and a walk
    moved[:, 2] -= 80.0
    np.testing.assert_allclose(targets_of(moved, arm).raw, targets_of(frames, arm).raw, atol=1e-9)


def test_a_fixed_forward_axis_follows_the_world_instead(arm):
    frames = cmu_random_frames(4)
    moved = frames.copy()
    moved[:, 3] += 90.0
    fixed = MappingConfig(forward=Axis.PZ)
    assert not np.allclose(targets_of(moved, arm, fixed).raw, targets_of(frames, arm, fixed).raw, atol=1e-3)
    # translation alone still does not matter: only the wrist relative to the shoulder is used
    walked = frames.copy()
    walked[:, 0] += 100.0
    np.testing.assert_allclose(targets_of(walked, arm, fixed).raw, targets_of(frames, arm, fixed).raw, atol=1e-9)


@pytest.mark.parametrize(
    ("side", "forward", "sign"),
    [("right", "auto", -1.0), ("left", "auto", 1.0), ("right", "+z", -1.0), ("right", "-z", 1.0)],
    ids=["right-auto", "left-auto", "right-fixed+z", "right-fixed-z"],
)
def test_t_pose_arm_points_sideways_on_the_robot(arm, side, forward, sign):
    """In the T-pose the right arm points to the body's right: the robot's -y (its right), scaled to arm_scale."""
    config = MappingConfig.from_table({"side": side, "forward": forward, "arm_scale": 0.3})
    targets = targets_of(t_pose(), arm, config)
    g = arm_geometry(arm)
    origin = default_origin(config, g)
    expected = origin + np.array([0.0, sign * 0.3 * g.reach, 0.0])
    np.testing.assert_allclose(targets.raw, np.broadcast_to(expected, (3, 3)), atol=1e-9)


def test_arm_reaching_forward_maps_in_front(arm):
    frames = t_pose()
    right_arm = 6 + 3 * (next(i for i, j in enumerate(CMU_JOINTS) if j[0] == "RightArm") - 1)
    frames[:, right_arm + 2] = 90.0  # Yrotation +90 turns the arm from -X to +Z: forward
    targets = targets_of(frames, arm, MappingConfig(origin=(0.3, 0.0, 0.3), arm_scale=0.2))
    reach = arm_geometry(arm).reach
    np.testing.assert_allclose(targets.raw[0], [0.3 + 0.2 * reach, 0.0, 0.3], atol=1e-9)


def test_targets_outside_the_workspace_are_pulled_in_and_counted(arm):
    frames = cmu_random_frames(5)
    targets = targets_of(frames, arm, MappingConfig(arm_scale=0.8))
    ws = targets.workspace
    assert 0 < targets.n_clamped < targets.n_frames
    r = np.linalg.norm(targets.positions - ws.center, axis=1)
    assert np.all(r <= ws.r_max + 1e-9) and np.all(r >= ws.r_min - 1e-9)
    assert np.all(targets.positions[:, 2] >= ws.floor - 1e-12)
    untouched = ~targets.clamped
    np.testing.assert_array_equal(targets.positions[untouched], targets.raw[untouched])
    assert np.all(np.linalg.norm(targets.positions[targets.clamped] - targets.raw[targets.clamped], axis=1) > 0)


def test_hand_orientation_gives_rotation_targets(arm):
    frames = cmu_random_frames(6)
    targets = targets_of(frames, arm, MappingConfig(orientation_weight=0.5))
    R = targets.rotations
    assert R is not None and R.shape == (targets.n_frames, 3, 3)
    np.testing.assert_allclose(R @ np.swapaxes(R, -1, -2), np.broadcast_to(np.eye(3), R.shape), atol=1e-9)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-9)
    # T-pose: tool x along the right hand (robot -y), tool z up
    Rt = targets_of(t_pose(), arm, MappingConfig(orientation_weight=1.0)).rotations[0]
    np.testing.assert_allclose(Rt[:, 0], [0, -1, 0], atol=1e-9)
    np.testing.assert_allclose(Rt[:, 2], [0, 0, 1], atol=1e-9)
    assert targets_of(frames, arm).rotations is None


def test_sampling_hits_frames_and_interpolates_between(arm):
    raw = np.array([[0.3, 0.0, 0.2], [0.3, 0.1, 0.2], [0.4, 0.1, 0.3]])
    targets = Targets.from_raw(raw, frame_time=0.5, workspace=Workspace.for_arm(arm))
    pos, rot, clamped = targets.sample(np.array([0.0, 0.25, 0.5, 1.0, 5.0]))
    expected = [[0.3, 0, 0.2], [0.3, 0.05, 0.2], [0.3, 0.1, 0.2], [0.4, 0.1, 0.3], [0.4, 0.1, 0.3]]
    np.testing.assert_allclose(pos, expected)
    assert rot is None and not clamped.any()
    with pytest.raises(ValueError, match=r"Expected raw targets of shape \(n_frames, 3\), got \(3,\)"):
        Targets.from_raw(raw[0], frame_time=0.5, workspace=targets.workspace)
    with pytest.raises(ValueError, match="Expected a frame time > 0 s, got 0"):
        Targets.from_raw(raw, frame_time=0, workspace=targets.workspace)


def test_a_clip_without_frames_is_a_bvh_error(arm):
    motion = parse_bvh(rig_text(rig(), np.zeros((0, 0)), n_frames=0), path="template.bvh")
    assert motion.n_frames == 0
    with pytest.raises(BvhError, match=r"^template\.bvh: Expected at least one frame of motion, got Frames: 0") as info:
        retarget_targets(motion, arm)
    assert info.value.path == "template.bvh" and isinstance(info.value, ValueError)


def test_a_zero_length_arm_is_a_bvh_error(arm, monkeypatch):
    kinect = rig(positions=("LeftForeArm", "LeftHand"))
    values = {(name, f"{axis}position"): 0.0 for name in ("LeftForeArm", "LeftHand") for axis in "XYZ"}
    motion = parse_bvh(rig_text(kinect, pose(kinect, 4, values)), path="folded.bvh")
    # the skeleton detection may refuse the folded arm first, in its own words; either way one BvhError naming it
    with pytest.raises(BvhError, match=r"^folded\.bvh: Expected .*LeftArm > LeftForeArm"):
        retarget_targets(motion, arm, MappingConfig(side=retarget.mapping.Side.LEFT))
    assert retarget_targets(motion, arm).n_frames == 4  # the right arm is fine
    # the mapping's own check, whatever the detection lets through
    right = motion.arm_points("right")
    folded = ArmChain("right", right.names, right.indices, False, np.zeros((4, 3, 3)))
    monkeypatch.setattr(motion, "arm_points", lambda side, **_: folded if side == "right" else right)
    match = r"^folded\.bvh: Expected a right arm of positive length, got 0 .* for RightArm > RightForeArm > RightHand$"
    with pytest.raises(BvhError, match=match) as info:
        retarget_targets(motion, arm)
    assert info.value.path == "folded.bvh" and isinstance(info.value, ValueError)


def test_hand_orientation_with_a_zero_length_hand_bone(arm):
    """CMU hands: the finger joints sit on the wrist (zero OFFSET); the tool x follows the forearm instead."""
    root = rig()
    for j in joints_in_order(root):
        if j.name.endswith("Hand"):
            j.children = [J(j.name + "Finger", (0.0, 0.0, 0.0), end=(4.0, 0.0, 0.0))]
            j.end = None
    motion = parse_bvh(rig_text(root, pose(root, 3)))
    rotations = retarget_targets(motion, arm, MappingConfig(orientation_weight=1.0)).rotations
    assert rotations is not None and np.isfinite(rotations).all()
    np.testing.assert_allclose(rotations[0][:, 0], [0, -1, 0], atol=1e-9)  # T-pose: along the right arm
