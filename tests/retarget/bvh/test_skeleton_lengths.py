"""Arm bone lengths against the skeleton's height (issue 15): degenerate chains are errors, unusual ones warnings,
clips without frames measure the rest pose; and the units guess when the rest pose is not upright."""

from __future__ import annotations

import logging

import numpy as np
import pytest

from retarget.bvh import DEMO_CLIP, load_bvh, parse_bvh
from retarget.bvh.chains import ArmJoints
from retarget.bvh.proportions import ARM_BONE_LIMITS, ARM_BONE_RANGE, check_arm_lengths, height_from_bones
from retarget.bvh.units import guess_units
from retarget.errors import BvhError
from tests.helpers import POS_XYZ, ROT_ZXY, J, arm_skeleton, bvh_text, joints_in_order, lafan_like, n_channels

CMU = {"clavicle": "{side}Shoulder", "upper": "{side}Arm", "fore": "{side}ForeArm", "hand": "{side}Hand"}
CMU |= {"left": "Left", "right": "Right"}


def cmu_rig() -> J:
    return arm_skeleton(CMU)


def joint(root: J, name: str) -> J:
    return next(j for j in joints_in_order(root) if j.name == name)


def column(root: J, name: str, channel: str) -> int:
    """The frame column of ``channel`` of joint ``name``."""
    col = 0
    for j in joints_in_order(root):
        if j.name == name:
            return col + list(j.channels).index(channel)
        col += len(j.channels)
    raise KeyError(name)


def test_collapsed_position_channels_are_an_error_naming_the_joints():
    """An upper arm of 1e-4 units on a 156-unit body: LeftForeArm's position channels say (1e-4, 0, 0)."""
    root = cmu_rig()
    joint(root, "LeftForeArm").channels = (*POS_XYZ, *ROT_ZXY)
    frames = np.zeros((4, n_channels(root)))
    frames[:, column(root, "LeftForeArm", "Xposition")] = 1e-4
    motion = parse_bvh(bvh_text(root, frames), path="collapsed.bvh")
    with pytest.raises(BvhError) as info:
        motion.arm_points("left")
    message = str(info.value)
    assert message.startswith(
        "collapsed.bvh: Expected the left upper arm and forearm to be 2-75 % of the skeleton's height (156.5 units "
        "from its bone lengths), got LeftArm > LeftForeArm 0.0001 units (6.4e-05 %) and LeftForeArm > LeftHand "
        "25 units (16 %), measured median over 4 frames;"
    )
    assert "\n" not in message
    assert motion.rest_positions()[motion.joint_index("LeftForeArm"), 0] == 45.0  # the OFFSET says 28
    assert motion.arm_points("right").bone_lengths == pytest.approx((28.0, 25.0))


def test_an_absurdly_long_forearm_is_an_error():
    root = cmu_rig()
    joint(root, "LeftHand").offset = (2500.0, 0.0, 0.0)
    motion = parse_bvh(bvh_text(root), path="long.bvh")
    with pytest.raises(BvhError, match=r"LeftForeArm > LeftHand 2\.5e\+03 units \(1\.3e\+02 %\), measured median"):
        motion.arm_points("left")


def test_a_short_but_possible_upper_arm_is_a_warning(caplog):
    root = cmu_rig()
    joint(root, "LeftForeArm").offset = (6.0, 0.0, 0.0)
    motion = parse_bvh(bvh_text(root), path="short.bvh")
    with caplog.at_level(logging.WARNING, logger="retarget.bvh.motion"):
        chain = motion.arm_points("left")
    assert chain.names == ("LeftArm", "LeftForeArm", "LeftHand")
    want = (
        "the left upper arm and forearm are usually 6-40 % of the skeleton's height (156.5 units from its bone "
        "lengths), got LeftArm > LeftForeArm 6 units (3.8 %) and LeftForeArm > LeftHand 25 units (16 %), measured "
        "median over 1 frame"
    )
    assert chain.warnings == (want,)
    assert [r.getMessage() for r in caplog.records] == [f"short.bvh: {want}"]
    assert motion.arm_points("right").warnings == ()


def test_zero_frames_measure_the_rest_pose():
    """Perception Neuron templates: ``Frames: 0``.  The arm is 28 and 25 cm, not 0."""
    root = cmu_rig()
    motion = parse_bvh(bvh_text(root, np.zeros((0, n_channels(root)))))
    chain = motion.arm_points("left")
    assert chain.points.shape == (0, 3, 3) and chain.lengths_from == "rest pose"
    assert chain.bone_lengths == pytest.approx((28.0, 25.0))
    np.testing.assert_allclose(chain.rest_points[:, 0], [17, 45, 70])
    joint(root, "LeftForeArm").offset = (1e-4, 0.0, 0.0)
    motion = parse_bvh(bvh_text(root, np.zeros((0, n_channels(root)))), path="template.bvh")
    with pytest.raises(
        BvhError, match=r"LeftArm > LeftForeArm 0\.0001 units .* measured in the rest pose \(no frames\)"
    ):
        motion.arm_points("left")


def test_an_end_site_wrist_has_rest_points_too():
    motion = parse_bvh(bvh_text(cmu_rig(), np.zeros((0, n_channels(cmu_rig())))))
    chain = motion.arm_points("left", names=("LeftArm", "LeftForeArm", "LeftHand/End Site"))
    assert chain.bone_lengths == pytest.approx((28.0, 33.0))


def test_bone_lengths_measure_position_channels_over_the_frames():
    root = cmu_rig()
    joint(root, "LeftForeArm").channels = ("Xposition", *ROT_ZXY)  # Y and Z stay the OFFSET's (0, 0)
    frames = np.zeros((3, n_channels(root)))
    frames[:, column(root, "LeftForeArm", "Xposition")] = [10.0, 20.0, 90.0]
    motion = parse_bvh(bvh_text(root, frames))
    lengths = motion.bone_lengths()
    assert lengths[motion.joint_index("LeftForeArm")] == 20.0  # the median
    assert lengths[0] == 0.0 and lengths[motion.joint_index("LeftHand")] == 25.0
    assert not lengths.flags.writeable
    assert motion.arm_points("left").bone_lengths == pytest.approx((20.0, 25.0))


def test_height_from_bones():
    motion = parse_bvh(bvh_text(cmu_rig()))
    # the longest path: a toe (45 + 43 + 9.85 up to the hips), the spine (30), the other arm to its fingertip
    path = 45 + 43 + np.hypot(9, 4) + 30 + 2 * np.hypot(2, 15) - np.hypot(2, 15) + np.hypot(15, 2) + 28 + 25 + 8
    assert motion.skeleton_height() == pytest.approx(path / 1.4)
    assert height_from_bones(np.array([-1]), [0.0]) == 0.0
    chain = ArmJoints("left", ("a", "b", "c"), (0, 1, 2), False)
    assert check_arm_lengths(chain, 1.0, 1.0, 0.0) is None  # nothing to compare with
    assert ARM_BONE_LIMITS[0] < ARM_BONE_RANGE[0] < ARM_BONE_RANGE[1] < ARM_BONE_LIMITS[1]


def test_units_when_the_rest_pose_lies_along_x():
    """LAFAN's zero-rotation pose lays every bone along +X: 18 units "tall" along Z; the bones say 179 cm."""
    root, _ = lafan_like()
    motion = parse_bvh(bvh_text(root, np.zeros((0, n_channels(root)))))
    rest = np.vstack([motion.rest_positions(), motion.rest_end_site_positions()])
    before = guess_units(rest)  # the rest pose alone, as before
    assert (before.unit, round(before.height), before.up_axis) == ("unknown", 18, "Z")
    after = motion.guess_units()
    assert (after.unit, round(after.height), after.up_axis, after.basis) == ("cm", 179, "Y", "bone lengths")
    root, frames = lafan_like(5)  # frames that stand it upright: the motion's extent is the height
    guess = parse_bvh(bvh_text(root, frames)).guess_units()
    assert (guess.unit, guess.height, guess.up_axis, guess.basis) == ("cm", 192.0, "Y", "motion")


def test_units_of_an_upright_rest_pose_are_unchanged():
    guess = load_bvh(DEMO_CLIP).guess_units()
    assert (guess.unit, guess.height, guess.up_axis, guess.basis) == ("cm", 169.0, "Y", "rest pose")
    tiny = parse_bvh(bvh_text(J("Hips", (0, 0, 0), POS_XYZ, children=[J("Spine", (0, 10, 0), end=(0, 15, 0))])))
    assert tiny.guess_units().height == 25.0  # within a factor 1.6 of 25 / 1.4


REAL_UNITS = {  # name: (unit, height, basis); the same as before issue 15
    "motion_basket.bvh": ("unknown", 23.88, "rest pose"),  # CMU: ASF units of 1/0.45 inch
    "motion_dance.bvh": ("unknown", 23.88, "rest pose"),
    "motion_walk.bvh": ("unknown", 23.88, "rest pose"),
    "push.bvh": ("m", 1.57, "rest pose"),
    "unity_walk_random.bvh": ("cm", 183.24, "rest pose"),
}


@pytest.mark.shared
@pytest.mark.parametrize("name", sorted(REAL_UNITS), ids=sorted(REAL_UNITS))
def test_real_clip_units(shared_bvh, name):
    path = shared_bvh / name
    if not path.exists():
        pytest.skip(f"{name} not in {shared_bvh}")
    guess = load_bvh(path).guess_units()
    unit, height, basis = REAL_UNITS[name]
    assert (guess.unit, round(guess.height, 2), guess.up_axis, guess.basis) == (unit, height, "Y", basis)
