"""Arm-chain detection: every naming convention, prefixes, structure fallback, ambiguity, overrides, real clips."""

from __future__ import annotations

import re

import numpy as np
import pytest

from retarget.bvh import load_bvh, parse_bvh
from retarget.bvh.names import name_side
from retarget.bvh.units import guess_units
from retarget.errors import BvhError
from tests.helpers import J, arm_skeleton, bvh_text

CMU = {"clavicle": "{side}Shoulder", "upper": "{side}Arm", "fore": "{side}ForeArm", "hand": "{side}Hand"}
LR_WORDS = {"left": "Left", "right": "Right"}

CONVENTIONS = {
    "cmu": (dict(CMU, **LR_WORDS), "", False, ("LeftArm", "LeftForeArm", "LeftHand")),
    "mixamo": (dict(CMU, **LR_WORDS), "mixamorig:", False, ("mixamorig:LeftArm", "mixamorig:LeftForeArm", None)),
    "any-prefix": (dict(CMU, **LR_WORDS), "ns:", False, ("ns:LeftArm", "ns:LeftForeArm", "ns:LeftHand")),
    "collar": (
        {
            "clavicle": "{side}Collar",
            "upper": "{side}Shoulder",
            "fore": "{side}Elbow",
            "hand": "{side}Wrist",
            **LR_WORDS,
        },
        "",
        False,
        ("LeftShoulder", "LeftElbow", "LeftWrist"),
    ),
    "short": (
        {"clavicle": "{side}Torso_Clavicle", "upper": "{side}Shoulder", "fore": "{side}Elbow", "hand": "{side}Wrist"}
        | {"left": "l", "right": "r"},
        "",
        False,
        ("lShoulder", "lElbow", "lWrist"),
    ),
    "rigify-end-site": (
        {"clavicle": "shoulder.{side}", "upper": "upper_arm.{side}", "fore": "forearm.{side}", "hand": "hand.{side}"}
        | {"left": "L", "right": "R"},
        "",
        True,
        ("upper_arm.L", "forearm.L", "forearm.L/End Site"),
    ),
    "rigify-hand": (
        {"clavicle": "shoulder.{side}", "upper": "upper_arm.{side}", "fore": "forearm.{side}", "hand": "hand.{side}"}
        | {"left": "L", "right": "R"},
        "DEF-",
        False,
        ("DEF-upper_arm.L", "DEF-forearm.L", "DEF-hand.L"),
    ),
    "biped": (
        {"clavicle": "Bip01 {side} Clavicle", "upper": "Bip01 {side} UpperArm", "fore": "Bip01 {side} Forearm"}
        | {"hand": "Bip01 {side} Hand", "left": "L", "right": "R"},
        "",
        False,
        ("Bip01 L UpperArm", "Bip01 L Forearm", "Bip01 L Hand"),
    ),
    "asf": (
        {"clavicle": "{side}clavicle", "upper": "{side}humerus", "fore": "{side}radius", "hand": "{side}wrist"}
        | {"left": "l", "right": "r"},
        "",
        False,
        ("lhumerus", "lradius", "lwrist"),
    ),
    "no-clavicle": (
        {"upper": "{side}_upperarm", "fore": "{side}_lowerarm", "hand": "{side}_hand", "left": "L", "right": "R"},
        "",
        False,
        ("L_upperarm", "L_lowerarm", "L_hand"),
    ),
}


@pytest.mark.parametrize(("names", "prefix", "end_site", "want"), CONVENTIONS.values(), ids=CONVENTIONS.keys())
def test_naming_conventions(names, prefix, end_site, want):
    motion = parse_bvh(bvh_text(arm_skeleton(names, prefix=prefix, wrist_end_site=end_site)))
    left = motion.arm_points("left")
    want = tuple(w if w is not None else "mixamorig:LeftHand" for w in want)
    assert left.names == want
    assert left.method == "names"
    assert left.wrist_is_end_site == end_site
    right = motion.arm_points("right")
    assert right.names != left.names
    # rest pose T: shoulder at x=+17 (left) / -17 (right) (15 without clavicle), elbow 28 further out, wrist 25 more
    x = np.array([17.0, 45.0, 70.0]) - (0 if "clavicle" in names else 2)
    np.testing.assert_allclose(left.points[0, :, 0], x)
    np.testing.assert_allclose(right.points[0, :, 0], -x)
    assert left.bone_lengths == pytest.approx((28.0, 25.0))


def makehuman() -> J:
    def arm(s: str, x: float) -> J:
        wrist = J(f"wrist.{s}", (x * 12, 0, 0), end=(x * 8, 0, 0))
        lower2 = J(f"lowerarm02.{s}", (x * 13, 0, 0), children=[wrist])
        lower1 = J(f"lowerarm01.{s}", (x * 14, 0, 0), children=[lower2])
        upper2 = J(f"upperarm02.{s}", (x * 14, 0, 0), children=[lower1])
        upper1 = J(f"upperarm01.{s}", (x * 12, 0, 0), children=[upper2])
        shoulder = J(f"shoulder01.{s}", (x * 3, 0, 0), children=[upper1])
        return J(f"clavicle.{s}", (x * 2, 15, 0), children=[shoulder])

    chest = J("spine01", (0, 30, 0), children=[J("neck01", (0, 20, 0), end=(0, 20, 0)), arm("L", 1), arm("R", -1)])
    return J("root", (0, 0, 0), ("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation"), [chest])


def test_makehuman_skips_twist_segments():
    motion = parse_bvh(bvh_text(makehuman()))
    assert motion.arm_points("left").names == ("upperarm01.L", "lowerarm01.L", "wrist.L")
    assert motion.arm_points("right").names == ("upperarm01.R", "lowerarm01.R", "wrist.R")


def test_structure_fallback_without_meaningful_names():
    root = arm_skeleton(dict(CMU, **LR_WORDS))
    counter = iter(range(100))

    def rename(j: J) -> None:
        j.name = f"bone{next(counter):02d}"
        for c in j.children:
            rename(c)

    rename(root)
    motion = parse_bvh(bvh_text(root))
    left = motion.arm_points("left")
    assert left.method == "structure"
    np.testing.assert_allclose(left.points[0, :, 0], [17, 45, 70])  # +X is the character's left
    right = motion.arm_points("right")
    np.testing.assert_allclose(right.points[0, :, 0], [-17, -45, -70])


def test_structure_fallback_on_an_upper_body_rooted_at_the_chest():
    full = arm_skeleton({"upper": "{side}a", "fore": "{side}b", "hand": "{side}c", "left": "x", "right": "y"})
    chest = full.children[0]
    chest.channels = ("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation")
    motion = parse_bvh(bvh_text(chest))
    assert motion.arm_points("left").method == "structure"
    np.testing.assert_allclose(motion.arm_points("left").points[0, :, 0], [15, 43, 68])
    np.testing.assert_allclose(motion.arm_points("right").points[0, :, 0], [-15, -43, -68])


def test_structure_fallback_with_forearm_end_site():
    root = arm_skeleton({"upper": "{side}a", "fore": "{side}b", "hand": "{side}c", "left": "x", "right": "y"})
    for j in (root.children[0].children[1], root.children[0].children[2]):
        j.children[0].children = []  # drop the hands
        j.children[0].end = (25.0 if j.name.startswith("x") else -25.0, 0, 0)
    motion = parse_bvh(bvh_text(root))
    left = motion.arm_points("left")
    assert left.wrist_is_end_site and left.names[2].endswith("/End Site")
    np.testing.assert_allclose(left.points[0, :, 0], [15, 43, 68])


def test_ambiguous_skeleton_lists_the_candidates():
    second = arm_skeleton(dict(CMU, **LR_WORDS), prefix="B:").children[0].children[1]  # B:LeftShoulder subtree
    root = arm_skeleton(dict(CMU, **LR_WORDS), prefix="A:", extra=[second])
    motion = parse_bvh(bvh_text(root), path="two.bvh")
    with pytest.raises(BvhError, match="Expected one left arm chain, found 2 equally good") as info:
        motion.arm_points("left")
    assert "A:LeftArm > A:LeftForeArm > A:LeftHand" in str(info.value)
    assert "B:LeftArm > B:LeftForeArm > B:LeftHand" in str(info.value)
    assert str(info.value).startswith("two.bvh: ")
    assert motion.arm_points("right").names[0] == "A:RightArm"  # the other side is fine


def test_override_by_names_resolves_ambiguity():
    second = arm_skeleton(dict(CMU, **LR_WORDS), prefix="B:").children[0].children[1]
    root = arm_skeleton(dict(CMU, **LR_WORDS), prefix="A:", extra=[second])
    motion = parse_bvh(bvh_text(root))
    chain = motion.arm_points("left", names=("B:LeftArm", "B:LeftForeArm", "B:LeftHand"))
    assert chain.names == ("B:LeftArm", "B:LeftForeArm", "B:LeftHand") and chain.method == "explicit"


def test_override_with_clavicle_and_end_site():
    motion = parse_bvh(bvh_text(arm_skeleton(dict(CMU, **LR_WORDS))))
    chain = motion.arm_points("left", names=("LeftShoulder", "LeftForeArm", "LeftHand/End Site"))
    assert chain.wrist_is_end_site
    np.testing.assert_allclose(chain.points[0, :, 0], [2, 45, 78])


@pytest.mark.parametrize(
    ("names", "message"),
    [
        (
            ("LeftArm", "LeftElbow", "LeftHand"),
            "Expected a joint named 'LeftElbow' for the left elbow, got no such joint",
        ),
        (("LeftArm", "LeftForeArm", "Nope/End Site"), "Expected a joint named 'Nope/End Site' for the left wrist"),
        (("LeftArm", "LeftForeArm", "LeftArm/End Site"), "Expected an End Site below joint"),
        (("LeftArm", "RightForeArm", "RightHand"), "to run down the hierarchy, got joints on other branches"),
    ],
    ids=["missing", "missing-end-site-owner", "no-end-site", "other-branch"],
)
def test_bad_override(names, message):
    motion = parse_bvh(bvh_text(arm_skeleton(dict(CMU, **LR_WORDS))), path="x.bvh")
    with pytest.raises(BvhError, match=re.escape(message)):
        motion.arm_points("left", names=names)


def test_override_needs_three_names():
    motion = parse_bvh(bvh_text(arm_skeleton(dict(CMU, **LR_WORDS))))
    with pytest.raises(ValueError, match="Expected 3 joint names"):
        motion.arm_points("left", names=("LeftArm", "LeftForeArm"))


@pytest.mark.parametrize("side", ["x", "Left", "", "both"])
def test_bad_side(side):
    motion = parse_bvh(bvh_text(arm_skeleton(dict(CMU, **LR_WORDS))))
    with pytest.raises(ValueError, match=f"Expected side 'left' or 'right', got {side!r}"):
        motion.arm_points(side)


def test_no_arm_at_all():
    root = J("Hips", (0, 0, 0), ("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation"))
    root.children = [J("Spine", (0, 10, 0), children=[J("Head", (0, 10, 0), end=(0, 5, 0))])]
    motion = parse_bvh(bvh_text(root), path="snake.bvh")
    with pytest.raises(BvhError, match=r"snake\.bvh: Expected a left arm chain \(shoulder, elbow, wrist\), found none"):
        motion.arm_points("left")


@pytest.mark.parametrize(
    ("name", "side"),
    [
        ("LeftArm", "left"),
        ("mixamorig:RightHand", "right"),
        ("upper_arm.L", "left"),
        ("forearm_r", "right"),
        ("Bip01 R Forearm", "right"),
        ("lShoulder", "left"),
        ("rTorso_Clavicle", "right"),
        ("LThumb", "left"),
        ("LowerBack", None),
        ("Spine1", None),
        ("lhumerus", "left"),
        ("rwrist", "right"),
        ("lowerback", None),
        ("HandL", "left"),
    ],
)
def test_name_side(name, side):
    assert name_side(name)[0] == side


REAL_CHAINS = {
    "motion_dance.bvh": (("LeftArm", "LeftForeArm", "LeftHand"), ("RightArm", "RightForeArm", "RightHand")),
    "motion_walk.bvh": (("LeftArm", "LeftForeArm", "LeftHand"), ("RightArm", "RightForeArm", "RightHand")),
    "motion_basket.bvh": (("LeftArm", "LeftForeArm", "LeftHand"), ("RightArm", "RightForeArm", "RightHand")),
    "push.bvh": (("lShoulder", "lElbow", "lWrist"), ("rShoulder", "rElbow", "rWrist")),
    "unity_walk_random.bvh": (
        ("LeftShoulder", "LeftElbow", "LeftWrist"),
        ("RightShoulder", "RightElbow", "RightWrist"),
    ),
}


@pytest.mark.shared
@pytest.mark.parametrize("name", sorted(REAL_CHAINS), ids=sorted(REAL_CHAINS))
def test_real_clip_chains(shared_bvh, name):
    path = shared_bvh / name
    if not path.exists():
        pytest.skip(f"{name} not in {shared_bvh}")
    motion = load_bvh(path)
    left, right = REAL_CHAINS[name]
    assert motion.arm_points("left").names == left
    assert motion.arm_points("right").names == right
    chain = motion.arm_points("right")
    assert chain.points.shape == (motion.n_frames, 3, 3)
    upper, fore = chain.bone_lengths
    assert 0.6 < upper / fore < 1.7


@pytest.mark.parametrize(
    ("height", "unit"),
    [(1.7, "m"), (170.0, "cm"), (1700.0, "mm"), (67.0, "in"), (24.0, "unknown"), (0.0, "unknown")],
)
def test_guess_units(height, unit):
    pts = np.array([[0.0, 0.0, 0.0], [0.3 * height, height, 0.1 * height]])
    guess = guess_units(pts)
    assert guess.unit == unit and guess.up_axis == "Y"
    assert guess.height == pytest.approx(height)
    if unit == "unknown" and height > 0:
        assert guess.metres_per_unit * height == pytest.approx(1.7)


def test_guess_units_z_up():
    guess = guess_units(np.array([[0.0, 0.0, 0.0], [20.0, 30.0, 175.0]]))
    assert guess.up_axis == "Z" and guess.unit == "cm"
