"""Arm-chain detection by names: the conventions of issue 15 (MakeHuman MHX, Poser/DAZ/Second Life, DAZ Genesis
with twist bones, OptiTrack Motive), side markers, and a seeded property test over generated skeletons."""

from __future__ import annotations

import logging
import random

import numpy as np
import pytest

from retarget.bvh import parse_bvh
from retarget.bvh.names import joint_roles, name_side
from tests.helpers import ArmNaming, arm_skeleton, bvh_text, expected_arm, named_humanoid, random_arm_naming

CONVENTIONS = {
    "mhx": (
        {"clavicle": "Clavicle_{side}", "upper": "UpArm_{side}", "fore": "LoArm_{side}", "hand": "Hand_{side}"}
        | {"left": "L", "right": "R"},
        ("UpArm_L", "LoArm_L", "Hand_L"),
    ),
    "poser": (
        {"clavicle": "{side}Collar", "upper": "{side}Shldr", "fore": "{side}ForeArm", "hand": "{side}Hand"}
        | {"left": "l", "right": "r"},
        ("lShldr", "lForeArm", "lHand"),
    ),
    "poser-lowercase": (
        {"clavicle": "{side}collar", "upper": "{side}shldr", "fore": "{side}forearm", "hand": "{side}hand"}
        | {"left": "l", "right": "r"},
        ("lshldr", "lforearm", "lhand"),
    ),
    "genesis-no-twist": (
        {"clavicle": "{side}Collar", "upper": "{side}ShldrBend", "fore": "{side}ForearmBend", "hand": "{side}Hand"}
        | {"left": "l", "right": "r"},
        ("lShldrBend", "lForearmBend", "lHand"),
    ),
    "optitrack": (
        {"clavicle": "Skeleton1_{side}Shoulder", "upper": "Skeleton1_{side}UArm", "fore": "Skeleton1_{side}FArm"}
        | {"hand": "Skeleton1_{side}Hand", "left": "L", "right": "R"},
        ("Skeleton1_LUArm", "Skeleton1_LFArm", "Skeleton1_LHand"),
    ),
    "second-life": (
        {"clavicle": "mCollar{side}", "upper": "mShoulder{side}", "fore": "mElbow{side}", "hand": "mWrist{side}"}
        | {"left": "Left", "right": "Right"},
        ("mShoulderLeft", "mElbowLeft", "mWristLeft"),
    ),
}


@pytest.mark.parametrize(("names", "want"), CONVENTIONS.values(), ids=CONVENTIONS.keys())
def test_more_naming_conventions(names, want):
    motion = parse_bvh(bvh_text(arm_skeleton(names)))
    left, right = motion.arm_points("left"), motion.arm_points("right")
    assert left.names == want and left.method == "names"
    assert want == tuple(names[role].format(side=names["left"]) for role in ("upper", "fore", "hand"))
    assert right.names == tuple(names[role].format(side=names["right"]) for role in ("upper", "fore", "hand"))
    assert right.method == "names"
    np.testing.assert_allclose(left.points[0, :, 0], [17, 45, 70])  # +X is the character's left
    np.testing.assert_allclose(right.points[0, :, 0], [-17, -45, -70])


def test_daz_genesis_twist_bones_sit_inside_the_chain():
    naming = ArmNaming(convention="genesis", side_style="l")
    motion = parse_bvh(bvh_text(named_humanoid(naming, upper_twists=1, fore_twists=1)))
    assert motion.joint_names[5:11] == (
        "lCollar",
        "lShldrBend",
        "lShldrTwist",
        "lForearmBend",
        "lForearmTwist",
        "lHand",
    )
    left = motion.arm_points("left")
    assert left.names == ("lShldrBend", "lForearmBend", "lHand") and left.method == "names"
    assert left.bone_lengths == pytest.approx((28.0, 25.0))
    assert motion.arm_points("right").names == ("rShldrBend", "rForearmBend", "rHand")


def test_mhx_lower_arm_is_a_forearm_not_an_upper_arm():
    (side, role, _), (_, fore, _) = joint_roles(["UpArm_L", "LoArm_L"])
    assert (side, role, fore) == ("left", "upper", "fore")


@pytest.mark.parametrize(
    ("name", "side", "role"),
    [
        ("Skeleton1_LUArm", "left", "upper"),
        ("Skeleton1_RFArm", "right", "fore"),
        ("skeleton1_lfarm", "left", "fore"),
        ("SKELETON1_LFARM", "left", "fore"),
        ("DEF-Arm.L", "left", "upper"),  # "defarm" ends in "farm", but FArm is only a word of its own
        ("lShldrBend", "left", "upper"),
        ("rForearmBend", "right", "fore"),
        ("lShldrTwist", "left", None),
        ("LeftForeArmRoll", "left", None),
        ("upperarm_twist_01_l", "left", None),
        ("lupper_arm", "left", "upper"),
        ("Bip01 lShldr", "left", "upper"),
        ("bip01 rshldr", "right", "upper"),
        ("mShoulderRight", "right", "shoulder"),
        ("Hips", None, None),
        ("lowerback", None, None),
    ],
)
def test_sides_and_roles(name, side, role):
    assert joint_roles([name])[0][:2] == (side, role)
    assert name_side(name)[0] == side


N_CASES = 300


def test_generated_skeletons_are_found_by_names_on_the_right_side(caplog):
    """Seeded: prefixes, conventions, side styles, separators, case, twist and roll bones, fingers, End Sites."""
    rng = random.Random(15)
    seen = set()
    for case in range(N_CASES):
        naming = random_arm_naming(rng)
        end_site = rng.random() < 0.2
        options = {
            "upper_twists": rng.randrange(3),
            "fore_twists": 0 if end_site else rng.randrange(3),
            "fingers": not end_site and rng.random() < 0.5,
            "wrist_end_site": end_site,
            "clavicle": rng.random() < 0.85,
        }
        motion = parse_bvh(bvh_text(named_humanoid(naming, **options)))
        for side, sign in (("left", 1.0), ("right", -1.0)):
            with caplog.at_level(logging.WARNING):
                chain = motion.arm_points(side)
            context = f"case {case}: {naming} {options} {side}"
            assert chain.names == expected_arm(naming, side, wrist_end_site=end_site), context
            assert chain.method == "names" and not chain.warnings, context
            assert np.all(sign * chain.rest_points[:, 0] > 0), context  # on its side of the body
            assert chain.bone_lengths == pytest.approx((28.0, 25.0)), context
        seen.add((naming.convention, naming.side_style, naming.case))
    assert not caplog.records
    assert len(seen) > 150  # the cases cover most combinations
