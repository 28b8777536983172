"""Arm-chain detection by structure (issue 15): the fallback takes a limb only when it is plausible (near the top
of the spine, human proportions, on the requested side, mirrored), and otherwise says why for every candidate."""

from __future__ import annotations

import numpy as np
import pytest

from retarget.bvh import load_bvh, parse_bvh
from retarget.bvh.skeleton import search_arm
from retarget.errors import BvhError
from tests.helpers import (
    ROT_ZXY,
    ArmNaming,
    J,
    arm_skeleton,
    bvh_text,
    joints_in_order,
    left_hand_rig,
    named_humanoid,
    renamed,
    staggered_arm_rig,
    with_face,
)

POS_ROT = ("Xposition", "Yposition", "Zposition", *ROT_ZXY)


def stripped(root: J) -> tuple[J, dict[str, str]]:
    """``root`` renamed bone00, bone01, ... and the map from the new names back to the old ones."""
    old = [j.name for j in joints_in_order(root)]
    renamed(root)
    return root, {j.name: name for j, name in zip(joints_in_order(root), old, strict=True)}


def found(motion, side: str, back: dict[str, str]) -> tuple[str, ...]:
    chain = motion.arm_points(side)
    assert chain.method == "structure"
    return tuple(back.get(n, n) for n in chain.names)


@pytest.mark.parametrize(
    "build",
    [
        lambda: named_humanoid(ArmNaming()),
        lambda: with_face(named_humanoid(ArmNaming())),  # the head branches deeper than the chest
        lambda: named_humanoid(ArmNaming(), fingers=True),  # so do the hands
        lambda: with_face(named_humanoid(ArmNaming(), fingers=True, upper_twists=0)),
    ],
    ids=["plain", "face", "fingers", "face-and-fingers"],
)
def test_the_arms_of_a_rig_whose_names_say_nothing(build):
    root, back = stripped(build())
    motion = parse_bvh(bvh_text(root))
    assert found(motion, "left", back) == ("LeftArm", "LeftForeArm", "LeftHand")
    assert found(motion, "right", back) == ("RightArm", "RightForeArm", "RightHand")
    chain = motion.arm_points("left")
    assert "no joint is named as a left upper arm, forearm or hand" in chain.detail
    assert "by structure: the left limb off bone02" in chain.detail  # the chest
    reasons = {tuple(back[n.split("/")[0]] for n in r.names): r.reason for r in chain.rejected}
    assert reasons[("RightArm", "RightForeArm", "RightHand")] == "on the right in the rest pose"
    assert reasons[("LeftUpLeg", "LeftLeg", "LeftFoot")].startswith("neither its names nor the rest pose")


def test_face_and_finger_bones_are_out_of_proportion():
    root, back = stripped(with_face(named_humanoid(ArmNaming(), fingers=True)))
    chain = parse_bvh(bvh_text(root)).arm_points("left")
    small = [r for r in chain.rejected if "an arm's are 6-40 %" in r.reason]
    assert {back[r.names[0]] for r in small} >= {"Tongue1", "LeftHandIndex1", "RightHandPinky1"}


def test_a_clavicle_as_long_as_the_forearm_is_not_the_upper_arm():
    """CMU's LeftShoulder > LeftArm bone is about as long as the forearm: the upper arm is the longest bone."""
    root = named_humanoid(ArmNaming())
    for joint in joints_in_order(root):
        if joint.name in ("LeftArm", "RightArm"):
            joint.offset = (24.5 if joint.name == "LeftArm" else -24.5, 0.0, 0.0)
        if joint.name in ("LeftHand", "RightHand"):
            joint.end = (1.0 if joint.name == "LeftHand" else -1.0, 0.0, 0.0)
    root, back = stripped(root)
    motion = parse_bvh(bvh_text(root))
    assert found(motion, "left", back) == ("LeftArm", "LeftForeArm", "LeftHand")


def test_a_leg_is_not_an_arm_when_the_arm_is_named_like_one():
    """Arms ``Arm_L_01 > _02 > _03`` off two spine joints, the hips the only three-way branch: not the legs."""
    for legs in ("bone", "LeftUpLeg"):
        motion = parse_bvh(bvh_text(staggered_arm_rig(legs)))
        left, right = motion.arm_points("left"), motion.arm_points("right")
        assert left.names == ("Arm_L_01", "Arm_L_02", "Arm_L_03") and left.method == "structure"
        assert right.names == ("Arm_R_01", "Arm_R_02", "Arm_R_03")
        assert "named left: upper arm Arm_L_01; no forearm or hand" in left.detail
        assert left.detail.endswith("named like an arm")
    leg = next(r for r in left.rejected if r.names[0] == "LeftUpLeg1a")
    assert leg.reason == "its names say leg"


def test_a_named_arm_needs_no_mirror_image():
    root = staggered_arm_rig()
    spine2 = root.children[0].children[0]
    spine2.children = spine2.children[:1]  # no right arm
    motion = parse_bvh(bvh_text(root))
    assert motion.arm_points("left").names == ("Arm_L_01", "Arm_L_02", "Arm_L_03")
    with pytest.raises(BvhError, match="found none by joint names .* or skeleton structure"):
        motion.arm_points("right")


def test_a_left_hand_alone_has_no_arm_on_either_side():
    motion = parse_bvh(bvh_text(left_hand_rig()), path="glove.bvh")
    with pytest.raises(BvhError, match=r"^glove\.bvh: Expected a right arm chain .*its names say finger") as info:
        motion.arm_points("right")
    assert info.value.message.count("(its names say finger)") == 5
    assert str(info.value).count("\n") == 0
    with pytest.raises(BvhError, match=r"named left: hand LeftHand; no upper arm or forearm"):
        motion.arm_points("left")
    root, _ = stripped(left_hand_rig())
    motion = parse_bvh(bvh_text(root), path="glove.bvh")
    with pytest.raises(BvhError, match=r"bone01 > bone02 > bone03 \(no limb mirrors it on the right\)"):
        motion.arm_points("left")
    with pytest.raises(BvhError, match=r"bone01 > bone02 > bone03 \(on the left in the rest pose\)"):
        motion.arm_points("right")


def test_legs_alone_are_not_arms():
    legs = [
        J(f"leg{k}", (x, -4, 0), children=[J(f"knee{k}", (0, -43, 0), children=[J(f"ankle{k}", (0, -43, 0))])])
        for k, x in ((1, 9), (2, -9))
    ]
    for leg in legs:
        leg.children[0].children[0].end = (0, -4, 12)
    root, _ = stripped(J("Hips", (0, 98, 0), POS_ROT, children=[J("Spine", (0, 30, 0), end=(0, 40, 0)), *legs]))
    motion = parse_bvh(bvh_text(root), path="legs.bvh")
    with pytest.raises(BvhError, match=r"bone02 > bone03 > bone04 \(neither its names nor the rest pose put it on a"):
        motion.arm_points("left")


def test_names_and_rest_pose_must_agree():
    """Limbs named _R on the +X side (the character's left when facing +Z): neither side takes them."""
    names = {"clavicle": "Clav_{side}", "upper": "Limb_{side}_1", "fore": "Limb_{side}_2", "hand": "Limb_{side}_3"}
    motion = parse_bvh(bvh_text(arm_skeleton(names | {"left": "R", "right": "L"})))
    with pytest.raises(BvhError, match=r"Limb_R_1 > Limb_R_2 > Limb_R_3 \(its names say right but the rest pose"):
        motion.arm_points("right")


def test_two_skeletons_side_by_side_tie():
    chests = []
    for k, x in ((1, 80.0), (2, -80.0)):
        names = {"upper": f"{{side}}a{k}", "fore": f"{{side}}b{k}", "hand": f"{{side}}c{k}", "left": "x", "right": "y"}
        chest = arm_skeleton(names).children[0]
        chest.name, chest.offset = f"chest{k}", (x, 100.0, 0.0)
        chest.children[0].name = f"neck{k}"
        chests.append(chest)
    motion = parse_bvh(bvh_text(J("world", (0, 0, 0), POS_ROT, children=chests)), path="two.bvh")
    with pytest.raises(BvhError, match=r"Expected one left arm chain, found 2 equally plausible by skeleton structure"):
        motion.arm_points("left")
    search = motion.arm_search("left")
    assert search.found is None and [r.reason for r in search.rejected].count("tied") == 2


def test_search_without_raising_and_the_default_height():
    motion = parse_bvh(bvh_text(left_hand_rig()))
    search = search_arm(
        "left", joint_names=motion.joint_names, parents=motion.parents, offsets=motion.offsets
    )  # no End Sites, height from the OFFSETs
    assert search.found is None and len(search.rejected) == 5
    assert search.error.startswith("Expected a left arm chain (shoulder, elbow, wrist), found none")


def test_names_still_win_over_structure():
    motion = parse_bvh(bvh_text(with_face(named_humanoid(ArmNaming()))))
    chain = motion.arm_points("left")
    assert chain.method == "names" and chain.names == ("LeftArm", "LeftForeArm", "LeftHand")
    assert chain.detail == "joint names: LeftArm is an upper arm, LeftForeArm a forearm, LeftHand the wrist"
    assert [str(r) for r in chain.rejected] == [
        "LeftShoulder > LeftForeArm (LeftShoulder is the clavicle here: LeftArm lies between it and the elbow)"
    ]


REAL = {  # name: (left, right)
    "motion_dance.bvh": (("LeftArm", "LeftForeArm", "LeftHand"), ("RightArm", "RightForeArm", "RightHand")),
    "push.bvh": (("lShoulder", "lElbow", "lWrist"), ("rShoulder", "rElbow", "rWrist")),
    "unity_walk_random.bvh": (
        ("LeftShoulder", "LeftElbow", "LeftWrist"),
        ("RightShoulder", "RightElbow", "RightWrist"),
    ),
}


@pytest.mark.shared
@pytest.mark.parametrize("name", sorted(REAL), ids=sorted(REAL))
def test_real_skeletons_with_their_names_removed(shared_bvh, name):
    path = shared_bvh / name
    if not path.exists():
        pytest.skip(f"{name} not in {shared_bvh}")
    motion = load_bvh(path)
    names = [f"bone{k:02d}" for k in range(motion.n_joints)]
    for side, want in zip(("left", "right"), REAL[name], strict=True):
        search = search_arm(
            side,
            joint_names=names,
            parents=motion.parents,
            offsets=motion.offsets,
            end_site_parents=[e.parent for e in motion.end_sites],
            end_site_offsets=[e.offset for e in motion.end_sites],
        )
        assert search.found is not None and search.found.method == "structure"
        assert search.found.indices == motion.arm_points(side).indices
        assert tuple(motion.joint_names[i] for i in search.found.indices) == want
        assert np.all((1 if side == "left" else -1) * motion.arm_points(side).rest_points[:, 0] > 0)
