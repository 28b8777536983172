"""URDF import: chain extraction, fixed-joint folding, the servo file and every error path."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from retarget import ConfigError, load_arm
from retarget.arm.kinematics import rpy_matrix
from retarget.arm.urdf import find_chain, parse_urdf
from tests.helpers import urdf_text

# The WidowX-250 6DOF chain as in Interbotix' wx250s.urdf.xacro, with the gripper's fixed and prismatic joints.
_WX = [
    ("waist", "revolute", "base_link", "shoulder_link", "0 0 0.072", "0 0 1", (-3.14158, 3.14158)),
    ("shoulder", "revolute", "shoulder_link", "upper_arm_link", "0 0 0.03865", "0 1 0", (-1.8850, 1.9897)),
    ("elbow", "revolute", "upper_arm_link", "upper_forearm_link", "0.04975 0 0.25", "0 1 0", (-2.1468, 1.6057)),
    ("forearm_roll", "revolute", "upper_forearm_link", "lower_forearm_link", "0.175 0 0", "1 0 0", (-3.14158, 3.14158)),
    ("wrist_angle", "revolute", "lower_forearm_link", "wrist_link", "0.075 0 0", "0 1 0", (-1.7453, 2.1468)),
    ("wrist_rotate", "revolute", "wrist_link", "gripper_link", "0.065 0 0", "1 0 0", (-3.14158, 3.14158)),
    ("ee_arm", "fixed", "gripper_link", "ee_arm_link", "0.043 0 0", None, None),
    ("gripper", "continuous", "ee_arm_link", "gripper_prop_link", "0.0055 0 0", "1 0 0", None),
    ("gripper_bar", "fixed", "ee_arm_link", "gripper_bar_link", "0 0 0", None, None),
    ("ee_bar", "fixed", "gripper_bar_link", "fingers_link", "0.023 0 0", None, None),
    ("left_finger", "prismatic", "fingers_link", "left_finger_link", "0 0 0", "0 1 0", (0.015, 0.037)),
    ("right_finger", "prismatic", "fingers_link", "right_finger_link", "0 0 0", "0 1 0", (-0.037, -0.015)),
    ("ee_gripper", "fixed", "fingers_link", "ee_gripper_link", "0.027575 0 0", None, None),
]

WX_SERVOS = """\
name = "wx250s_urdf"
[joints.waist]
servos = [{ id = 1, model = "XM430-W350" }]
[joints.shoulder]
servos = [{ id = 2, model = "XM430-W350" }, { id = 3, model = "XM430-W350", direction = -1 }]
[joints.elbow]
servos = [{ id = 4, model = "XM430-W350" }, { id = 5, model = "XM430-W350", direction = -1 }]
[joints.forearm_roll]
servos = [{ id = 6, model = "XM430-W350" }]
[joints.wrist_angle]
servos = [{ id = 7, model = "XM430-W350", direction = -1 }]
[joints.wrist_rotate]
servos = [{ id = 8, model = "XL430-W250" }]
[gripper]
servo = { id = 9, model = "XL430-W250" }
limits = [-21.7, 72.7]
[poses]
home = [0, 0, 0, 0, 0, 0]
rest = [0, -103.1324, 88.8085, 0, 45.8366, 0]
"""


def write_arm(tmp_path: Path, joints=_WX, servos: str | None = WX_SERVOS, name: str = "arm", **kw) -> Path:
    path = tmp_path / f"{name}.urdf"
    path.write_text(urdf_text(joints, **kw))
    if servos is not None:
        (tmp_path / f"{name}.servos.toml").write_text(servos)
    return path


def test_wx250s_urdf_matches_the_bundled_description(tmp_path):
    arm = load_arm(write_arm(tmp_path), tip="ee_gripper_link")
    ref = load_arm("wx250s")
    assert arm.name == "wx250s_urdf" and arm.joint_names == ref.joint_names
    assert arm.servo_ids == ref.servo_ids
    np.testing.assert_allclose(arm.tool_xyz, ref.tool_xyz, atol=1e-12)  # fixed joints folded into the tool
    np.testing.assert_allclose(arm.rest, ref.rest, atol=1e-9)
    np.testing.assert_allclose(arm.max_velocity, 3.14159)  # URDF <limit velocity>
    rng = np.random.default_rng(0)
    for q in rng.uniform(ref.lower, ref.upper, (20, 6)):
        np.testing.assert_allclose(arm.fk(q)[0], ref.fk(q)[0], atol=1e-12)


def test_tip_from_the_servo_file(tmp_path):
    arm = load_arm(write_arm(tmp_path, servos='tip = "ee_gripper_link"\n' + WX_SERVOS))
    assert arm.tool_xyz == pytest.approx((0.093575, 0, 0))


def test_ambiguous_tip_lists_the_leaves(tmp_path):
    leaves = "ee_gripper_link, gripper_prop_link, left_finger_link, right_finger_link"
    with pytest.raises(ConfigError, match=re.escape(f"cannot tell the tip link: leaves {leaves}; name one")):
        load_arm(write_arm(tmp_path))


def test_prismatic_joint_on_the_chain(tmp_path):
    with pytest.raises(ConfigError, match="unsupported joint type on the chain") as info:
        load_arm(write_arm(tmp_path), tip="left_finger_link")
    assert info.value.key == "joint[left_finger].type" and info.value.value == "prismatic"


def test_fixed_joints_with_rotations_fold_into_the_next_origin_and_the_tool(tmp_path):
    joints = [
        ("mount", "fixed", "world", "base", "0.1 0.2 0.3", None, None, "0 0 1.5707963267948966"),
        ("j1", "revolute", "base", "l1", "0 0 0.1", "0 0 1", (-2, 2)),
        ("bend", "fixed", "l1", "l1b", "0.05 0 0", None, None, "0.3 0.2 0.1"),
        ("j2", "continuous", "l1b", "l2", "0.2 0 0", "0 1 0", None),
        ("tool", "fixed", "l2", "tip", "0.1 0 0", None, None, "0 0.5 0"),
    ]
    servos = "[joints.j1]\nservos = [{ id = 1, model = 'XL430-W250' }]\n"
    servos += "[joints.j2]\nservos = [{ id = 2, model = 'XL430-W250' }]\nmax_velocity = 90\n"
    arm = load_arm(write_arm(tmp_path, joints, servos))
    assert arm.joint_names == ("j1", "j2")
    assert (arm.joints[1].lower, arm.joints[1].upper) == (-math.pi, math.pi)  # continuous
    assert arm.joints[1].max_velocity == pytest.approx(math.pi / 2)

    def tf(xyz, rpy=(0, 0, 0), axis=None, angle=0.0):
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = rpy_matrix(rpy), xyz
        if axis is not None:
            k = np.array(axis, dtype=float)
            K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
            R = np.eye(4)
            R[:3, :3] = np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K
            T = T @ R
        return T

    q = [0.7, -1.1]
    expected = (
        tf((0.1, 0.2, 0.3), (0, 0, math.pi / 2))
        @ tf((0, 0, 0.1), axis=(0, 0, 1), angle=q[0])
        @ tf((0.05, 0, 0), (0.3, 0.2, 0.1))
        @ tf((0.2, 0, 0), axis=(0, 1, 0), angle=q[1])
        @ tf((0.1, 0, 0), (0, 0.5, 0))
    )
    np.testing.assert_allclose(arm.fk(q)[0], expected, atol=1e-12)
    assert arm.home.tolist() == [0.0, 0.0]


def test_cycle_is_named(tmp_path):
    joints = [
        ("ab", "revolute", "a", "b", "0 0 1", "0 0 1", (-1, 1)),
        ("bc", "revolute", "b", "c", "0 0 1", "0 0 1", (-1, 1)),
        ("ca", "revolute", "c", "a", "0 0 1", "0 0 1", (-1, 1)),
    ]
    with pytest.raises(ConfigError, match=re.escape("the joints form a cycle: a -> c -> b -> a")):
        load_arm(write_arm(tmp_path, joints))


def test_missing_link_is_named(tmp_path):
    joints = [*_WX[:2], ("elbow", "revolute", "upper_arm_link", "ghost_link", "0 0 1", "0 1 0", (-1, 1))]
    links = ["base_link", "shoulder_link", "upper_arm_link"]
    with pytest.raises(ConfigError, match="child link 'ghost_link' is not defined") as info:
        load_arm(write_arm(tmp_path, joints, links=links))
    assert info.value.key == "joint[elbow].child"


def test_two_roots_ask_for_a_base(tmp_path):
    joints = [_WX[0], ("other", "revolute", "floor", "shelf", "0 0 1", "0 0 1", (-1, 1))]
    with pytest.raises(ConfigError, match="cannot tell the base link: roots base_link, floor"):
        find_chain(parse_urdf(write_arm(tmp_path, joints, links=["base_link", "shoulder_link", "floor", "shelf"])))


def test_base_and_tip_must_be_links_on_one_branch(tmp_path):
    model = parse_urdf(write_arm(tmp_path))
    with pytest.raises(ConfigError, match="no link named 'hand'"):
        find_chain(model, tip="hand")
    with pytest.raises(ConfigError, match="tip link 'wrist_link' is not below base link 'gripper_link'"):
        find_chain(model, base="gripper_link", tip="wrist_link")
    with pytest.raises(ConfigError, match="no revolute or continuous joint"):
        find_chain(model, base="fingers_link", tip="ee_gripper_link")
    assert [j.name for j in find_chain(model, base="upper_arm_link", tip="wrist_link")] == [
        "elbow",
        "forearm_roll",
        "wrist_angle",
    ]


def test_link_with_two_parents(tmp_path):
    joints = [_WX[0], ("again", "revolute", "base_link", "shoulder_link", "0 0 1", "0 0 1", (-1, 1))]
    with pytest.raises(ConfigError, match=re.escape("link 'shoulder_link' is the child of two joints (waist, again)")):
        parse_urdf(write_arm(tmp_path, joints))


SERVO_ERRORS = [
    ("missing-table", WX_SERVOS.replace("[joints.waist]\nservos = [{ id = 1, model = \"XM430-W350\" }]\n", ""),
     "joints.waist", "missing the servo table"),
    ("unknown-joint", WX_SERVOS + "[joints.nope]\nservos = []\n", "joints.nope", "unknown key 'nope'"),
    ("unknown-key", "colour = 1\n" + WX_SERVOS, "colour", "unknown key 'colour'"),
    ("bad-model", WX_SERVOS.replace("XL430-W250\" }]", "XL9\" }]"), "joints.wrist_rotate.servos[0].model",
     "unknown servo model"),
    ("duplicate-id", WX_SERVOS.replace("id = 8", "id = 1"), "joints.wrist_rotate.servos[0].id", "duplicate servo ID"),
    ("bad-limits", WX_SERVOS.replace("[joints.elbow]\n", "[joints.elbow]\nlimits = [10, -10]\n"),
     "joints.elbow.limits", "lower limit must be below"),
]  # fmt: skip


@pytest.mark.parametrize(("servos", "key", "message"), [e[1:] for e in SERVO_ERRORS], ids=[e[0] for e in SERVO_ERRORS])
def test_servo_file_errors(tmp_path, servos, key, message):
    with pytest.raises(ConfigError, match=re.escape(message)) as info:
        load_arm(write_arm(tmp_path, servos=servos), tip="ee_gripper_link")
    assert info.value.key == key and info.value.path.endswith("arm.servos.toml")


def test_missing_servo_file(tmp_path):
    with pytest.raises(ConfigError, match="servo file not found: .*arm.servos.toml"):
        load_arm(write_arm(tmp_path, servos=None), tip="ee_gripper_link")


def test_continuous_joint_needs_a_velocity(tmp_path):
    joints = [("j", "continuous", "a", "b", "0 0 1", "0 0 1", None)]
    with pytest.raises(ConfigError, match="no velocity for this joint: set max_velocity"):
        load_arm(write_arm(tmp_path, joints, "[joints.j]\nservos = [{ id = 1, model = 'XL430-W250' }]\n"))


@pytest.mark.parametrize(
    ("text", "message", "key"),
    [
        ('<robot name="r">\n<link name="a">\n</robot>', "invalid URDF XML", "line 3"),
        ('<model name="r"/>', "not a URDF: the root element must be <robot>", None),
        (
            '<robot name="r"><link name="a"/><link name="b"/><joint name="j" type="revolute"><parent link="a"/>'
            '<child link="b"/><origin xyz="0 0 x"/></joint></robot>',
            "expected 3 numbers",
            "joint[j].origin.xyz",
        ),
        (
            '<robot name="r"><link name="a"/><link name="b"/><joint name="j" type="revolute"><parent link="a"/>'
            "</joint></robot>",
            "missing <child link=...>",
            "joint[j].child",
        ),
    ],
    ids=["xml-syntax", "not-robot", "bad-number", "no-child"],
)
def test_malformed_urdf(tmp_path, text, message, key):
    path = tmp_path / "bad.urdf"
    path.write_text(text)
    with pytest.raises(ConfigError, match=re.escape(message)) as info:
        parse_urdf(path)
    assert info.value.key == key


def test_revolute_without_limits_and_zero_axis(tmp_path):
    servos = "[joints.j]\nservos = [{ id = 1, model = 'XL430-W250' }]\nmax_velocity = 90\n"
    with pytest.raises(ConfigError, match="revolute joint without <limit"):
        load_arm(write_arm(tmp_path, [("j", "revolute", "a", "b", "0 0 1", "0 0 1", None)], servos))
    with pytest.raises(ConfigError, match="joint axis has zero length"):
        load_arm(write_arm(tmp_path, [("j", "revolute", "a", "b", "0 0 1", "0 0 0", (-1, 1))], servos))
