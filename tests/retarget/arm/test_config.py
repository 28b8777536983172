"""Arm descriptions: bundled files, name resolution and every validation error."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from retarget import ConfigError, load_arm
from retarget.arm import config as arm_config
from retarget.arm.config import list_arms

BUNDLED = ["koch", "omx", "px100", "vx300s", "wx250s"]

VALID = """\
name = "toy"
title = "Toy arm"
baud = 1_000_000

[tool]
link = "tip"
xyz = [0.1, 0.0, 0.0]

[poses]
home = [0, 0]
rest = [0, 10]

[[joints]]
name = "a"
xyz = [0, 0, 0.1]
axis = [0, 0, 2]
limits = [-90, 90]
max_velocity = 180
servos = [{ id = 1, model = "XM430-W350" }]

[[joints]]
name = "b"
xyz = [0, 0, 0.2]
axis = [0, 1, 0]
limits = [-45, 45]
max_velocity = 90
servos = [{ id = 2, model = "XM430-W350" }, { id = 3, model = "XM430-W350", direction = -1, offset = 12 }]

[gripper]
servo = { id = 4, model = "XL430-W250" }
limits = [-10, 60]

[mapping]
anything = "goes"
"""


def write(tmp_path: Path, text: str, name: str = "toy.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def edited(old: str, new: str) -> str:
    assert old in VALID, old
    return VALID.replace(old, new, 1)


def test_valid_file_loads_in_radians(tmp_path):
    arm = load_arm(write(tmp_path, VALID))
    assert arm.name == "toy" and arm.title == "Toy arm" and arm.baud == 1_000_000
    assert arm.joint_names == ("a", "b")
    np.testing.assert_allclose(arm.lower, np.radians([-90, -45]))
    np.testing.assert_allclose(arm.upper, np.radians([90, 45]))
    np.testing.assert_allclose(arm.max_velocity, np.radians([180, 90]))
    np.testing.assert_allclose(arm.rest, np.radians([0, 10]))
    assert arm.joints[0].axis == (0.0, 0.0, 1.0)  # normalised
    assert arm.joints[1].servos[1].direction == -1 and arm.joints[1].servos[1].offset == 12
    assert arm.servo_ids == (1, 2, 3, 4)
    assert arm.gripper.servo.model == "XL430-W250"
    assert arm.gripper.lower == pytest.approx(math.radians(-10))
    assert arm.mapping == {"anything": "goes"}
    assert arm.source == tmp_path / "toy.toml"


def test_rest_defaults_to_home_and_gripper_is_optional(tmp_path):
    text = edited("rest = [0, 10]\n", "").split("[gripper]")[0]
    arm = load_arm(write(tmp_path, text))
    assert np.array_equal(arm.rest, arm.home) and arm.gripper is None and arm.mapping == {}


BAD = [
    ("unknown-top-key", ('name = "toy"', 'name = "toy"\ncolour = "red"'), "colour", "unknown key 'colour'"),
    ("unknown-joint-key", ('name = "b"', 'name = "b"\nmass = 1.0'), "joints[1].mass", "unknown key 'mass'"),
    (
        "unknown-servo-key",
        ("direction = -1,", "direction = -1, torque = 1,"),
        "joints[1].servos[1].torque",
        "unknown key",
    ),
    ("unknown-tool-key", ('link = "tip"', 'frame = "tip"'), "tool.frame", "unknown key"),
    ("unknown-model", ('model = "XL430-W250"', 'model = "XL999"'), "gripper.servo.model", "unknown servo model"),
    ("missing-velocity", ("max_velocity = 90\n", ""), "joints[1].max_velocity", "missing required key"),
    ("missing-servo-id", ("{ id = 1, model", "{ model"), "joints[0].servos[0].id", "missing required key"),
    ("missing-home", ("home = [0, 0]\n", ""), "poses.home", "missing required key"),
    ("missing-name", ('name = "toy"\n', ""), "name", "missing required key"),
    ("lower-ge-upper", ("limits = [-45, 45]", "limits = [45, 45]"), "joints[1].limits", "lower limit must be below"),
    ("gripper-lower-ge-upper", ("limits = [-10, 60]", "limits = [60, -10]"), "gripper.limits", "lower limit"),
    ("duplicate-id", ("{ id = 3,", "{ id = 1,"), "joints[1].servos[1].id", "duplicate servo ID"),
    ("duplicate-gripper-id", ("{ id = 4,", "{ id = 2,"), "gripper.servo.id", "duplicate servo ID"),
    ("zero-axis", ("axis = [0, 1, 0]", "axis = [0, 0, 0]"), "joints[1].axis", "zero length"),
    ("axis-length", ("axis = [0, 1, 0]", "axis = [0, 1]"), "joints[1].axis", "expected a list of 3 numbers"),
    ("xyz-type", ("xyz = [0, 0, 0.2]", 'xyz = "up"'), "joints[1].xyz", "expected a list of 3 numbers"),
    ("direction", ("direction = -1", "direction = 2"), "joints[1].servos[1].direction", "direction must be"),
    ("offset-range", ("offset = 12", "offset = 5000"), "joints[1].servos[1].offset", "-2048..2048"),
    ("id-range", ("{ id = 1,", "{ id = 300,"), "joints[0].servos[0].id", "0..252"),
    ("id-type", ("{ id = 1,", '{ id = "1",'), "joints[0].servos[0].id", "expected an integer"),
    ("velocity-negative", ("max_velocity = 90", "max_velocity = -1"), "joints[1].max_velocity", "> 0"),
    ("baud-bool", ("baud = 1_000_000", "baud = true"), "baud", "expected an integer"),
    ("empty-servos", ('servos = [{ id = 1, model = "XM430-W350" }]', "servos = []"), "joints[0].servos", "non-empty"),
    ("duplicate-joint", ('name = "b"', 'name = "a"'), "joints[1].name", "duplicate joint name"),
    ("joint-type", ('name = "b"', 'name = "b"\ntype = "prismatic"'), "joints[1].type", "only 'revolute'"),
    ("pose-outside", ("rest = [0, 10]", "rest = [0, 50]"), "poses.rest[1]", "outside the limits of joint 'b'"),
    ("pose-length", ("home = [0, 0]", "home = [0, 0, 0]"), "poses.home", "expected a list of 2 numbers"),
]


@pytest.mark.parametrize(("change", "key", "message"), [b[1:] for b in BAD], ids=[b[0] for b in BAD])
def test_config_errors_name_file_key_and_value(tmp_path, change, key, message):
    path = write(tmp_path, edited(*change))
    with pytest.raises(ConfigError, match=re.escape(message)) as info:
        load_arm(path)
    assert info.value.key == key
    assert info.value.path == str(path)
    assert str(info.value).startswith(f"{path}: {key}: ")


def test_mapping_must_be_a_table(tmp_path):
    text = edited("baud = 1_000_000", "baud = 1_000_000\nmapping = 3").replace('[mapping]\nanything = "goes"\n', "")
    with pytest.raises(ConfigError, match="expected a table") as info:
        load_arm(write(tmp_path, text))
    assert info.value.key == "mapping"


def test_error_carries_the_bad_value(tmp_path):
    with pytest.raises(ConfigError, match=re.escape("(got [45, -45])")) as info:
        load_arm(write(tmp_path, edited("limits = [-45, 45]", "limits = [45, -45]")))
    assert info.value.value == [45, -45]


def test_toml_syntax_error_names_the_line(tmp_path):
    path = write(tmp_path, edited('title = "Toy arm"', 'title = "Toy arm'))
    with pytest.raises(ConfigError, match=r"invalid TOML: .*line 2") as info:
        load_arm(path)
    assert info.value.key == "line 2"


def test_unknown_arm_name_lists_the_known_ones():
    with pytest.raises(ConfigError, match=re.escape("unknown arm 'nope'; known arms: " + ", ".join(BUNDLED))):
        load_arm("nope")


def test_missing_file(tmp_path):
    with pytest.raises(ConfigError, match="arm description not found"):
        load_arm(tmp_path / "absent.toml")


def test_base_tip_only_for_urdf():
    with pytest.raises(ConfigError, match="base/tip only apply to a URDF"):
        load_arm("wx250s", tip="ee_gripper_link")


def test_list_arms_has_every_bundled_arm():
    assert list_arms() == BUNDLED


def test_bare_name_resolves_from_any_working_directory(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    arm = load_arm("wx250s")
    assert arm.source.name == "wx250s.toml" and arm.source.is_absolute()


def test_installed_copy_wins_over_the_checkout(tmp_path, monkeypatch):
    installed, checkout = tmp_path / "installed", tmp_path / "checkout"
    installed.mkdir()
    checkout.mkdir()
    write(installed, VALID, "toy.toml")
    write(checkout, edited('title = "Toy arm"', 'title = "Other"'), "toy.toml")
    write(checkout, VALID.replace('name = "toy"', 'name = "other"'), "other.toml")
    monkeypatch.setattr(arm_config, "arm_dirs", lambda: [installed, checkout])
    assert load_arm("toy").title == "Toy arm"
    assert arm_config.list_arms() == ["other", "toy"]


@pytest.mark.parametrize("name", BUNDLED)
def test_bundled_arm_is_consistent(name):
    arm = load_arm(name)
    assert arm.name == name and arm.baud == 1_000_000 and arm.gripper is not None
    ids = arm.servo_ids
    assert len(set(ids)) == len(ids)
    assert np.all(arm.lower < arm.upper)
    assert arm.within_limits(arm.home) and arm.within_limits(arm.rest)
    assert np.all(arm.max_velocity > 0)
    for joint in arm.joints:
        assert math.isclose(math.hypot(*joint.axis), 1.0)
        primary, *shadows = joint.servos
        for shadow in shadows:  # mirrored shadows
            assert shadow.direction == -primary.direction and shadow.model == primary.model


EXPECTED = {
    "wx250s": (6, (1, 2, 3, 4, 5, 6, 7, 8, 9), {"shoulder": (2, 3), "elbow": (4, 5)}),
    "vx300s": (6, (1, 2, 3, 4, 5, 6, 7, 8, 9), {"shoulder": (2, 3), "elbow": (4, 5)}),
    "px100": (4, (1, 2, 3, 4, 5), {}),
    "omx": (4, (11, 12, 13, 14, 15), {}),
    "koch": (5, (1, 2, 3, 4, 5, 6), {}),
}


@pytest.mark.parametrize("name", BUNDLED)
def test_bundled_arm_ids_and_shadows(name):
    n, ids, shadowed = EXPECTED[name]
    arm = load_arm(name)
    assert arm.n_joints == n and arm.servo_ids == ids
    for joint in arm.joints:
        assert tuple(s.id for s in joint.servos) == shadowed.get(joint.name, (joint.servos[0].id,))


def test_wx250s_numbers_from_the_urdf():
    arm = load_arm("wx250s")
    np.testing.assert_allclose(np.degrees(arm.lower[1:3]), [-108, -123])
    np.testing.assert_allclose(np.degrees(arm.upper[1:3]), [114, 92])
    np.testing.assert_allclose(arm.rest, [0, -1.80, 1.55, 0, 0.8, 0], atol=1e-6)
    assert [s.model for j in arm.joints for s in j.servos][-1] == "XL430-W250"
    assert arm.joints[4].servos[0].direction == -1  # wrist_angle Drive_Mode 1
