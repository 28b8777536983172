"""retarget.arm.calibration: the calibration file (round trip, atomic write, every error naming the file and key),
applying it to an arm, the default place per platform, and the arm-file keys the calibration reads."""

from __future__ import annotations

import math
import os
import random
from pathlib import Path

import numpy as np
import pytest

from retarget.arm import calibration as calmod
from retarget.arm.calibration import (
    Calibration,
    JointCalibration,
    ServoCalibration,
    apply_calibration,
    default_calibration_path,
    load_calibration,
    save_calibration,
)
from retarget.arm.load import load_arm
from retarget.errors import ConfigError


def random_calibration(arm_name: str, seed: int) -> Calibration:
    arm = load_arm(arm_name)
    rng = random.Random(seed)
    servos = tuple(
        ServoCalibration(s.id, j.name, rng.randint(-2048, 2048), rng.choice((1, -1)), rng.choice((None, 45, 46)))
        for j in arm.joints
        for s in j.servos
    )
    joints = []
    for j in arm.joints:
        lo = j.lower + rng.uniform(0, 0.2)
        hi = j.upper - rng.uniform(0, 0.2)
        joints.append(JointCalibration(j.name, (lo, hi), (lo, hi) if rng.random() < 0.5 else None))
    return Calibration(arm_name, f"unit-{seed}", "2026-11-24T17:00:00+00:00", servos, tuple(joints))


@pytest.mark.parametrize("arm_name,seed", [("koch", 1), ("wx250s", 2), ("omx", 3)], ids=["koch", "wx250s", "omx"])
def test_a_saved_calibration_reloads_equal(tmp_path, arm_name, seed):
    cal = random_calibration(arm_name, seed)
    path = save_calibration(cal, tmp_path / "sub" / "unit.toml")
    back = load_calibration(path)
    assert back.source == path and (back.arm, back.name, back.date, back.servos) == (
        cal.arm,
        cal.name,
        cal.date,
        cal.servos,
    )
    for a, b in zip(back.joints, cal.joints, strict=True):
        assert a.name == b.name
        assert np.allclose(a.measured, b.measured, atol=1e-6)  # 4 decimals of a degree in the file
        assert (a.limits is None) == (b.limits is None)
    assert [p.name for p in path.parent.iterdir()] == ["unit.toml"]  # no temporary file left


@pytest.mark.parametrize("exc", [KeyboardInterrupt, OSError], ids=["ctrl-c", "disk"])
def test_an_interrupted_save_leaves_the_old_file_and_no_temporary(tmp_path, monkeypatch, exc):
    path = tmp_path / "koch.toml"
    path.write_text("old")

    def fail(src, dst):
        raise exc()

    monkeypatch.setattr(calmod.os, "replace", fail)
    with pytest.raises(exc):
        save_calibration(random_calibration("koch", 1), path)
    assert path.read_text() == "old" and [p.name for p in tmp_path.iterdir()] == ["koch.toml"]


def test_apply_sets_offsets_and_directions_narrows_limits_and_clips_poses():
    arm = load_arm("wx250s")
    cal = random_calibration("wx250s", 7)
    shoulder = arm.joints[1]
    narrow = (shoulder.lower + 0.5, shoulder.lower + 0.9)  # excludes home (0) and rest
    wide = (-10.0, 10.0)  # wider than the file's: never widened
    joints = [JointCalibration(j.name, None, narrow if j.name == "shoulder" else wide) for j in arm.joints]
    cal = Calibration(cal.arm, cal.name, cal.date, cal.servos, tuple(joints))
    out = apply_calibration(arm, cal)
    for joint in out.joints:
        for s in joint.servos:
            c = cal.servo(s.id)
            assert (s.offset, s.direction) == (c.offset, c.direction)
    assert (out.joints[1].lower, out.joints[1].upper) == narrow
    assert np.array_equal(out.lower[[0, 2]], arm.lower[[0, 2]]) and np.array_equal(out.upper[[0, 2]], arm.upper[[0, 2]])
    assert out.home[1] == pytest.approx(narrow[1]) and out.within_limits(out.rest)
    assert out.gripper == arm.gripper and arm.joints[1].servos[1].direction == -1  # the input is unchanged


def _edit(cal: Calibration, **changes) -> Calibration:
    return Calibration(**{**cal.__dict__, **changes})


@pytest.mark.parametrize(
    "change,match",
    [
        pytest.param(
            {"arm": "wx250s"}, r"arm: Expected a calibration of arm 'koch', got one of 'wx250s'", id="other-arm"
        ),
        pytest.param({"servos_drop": 2}, r"servos: no entry for servo 3 of joint 'elbow_flex'", id="missing-servo"),
        pytest.param({"servo_id": 42}, r"servos\[0\]\.id: servo 42 is not a servo of arm 'koch'", id="unknown-servo"),
        pytest.param(
            {"servo_joint": "elbow"}, r"servos\[0\]\.joint: Expected servo 1 on joint 'shoulder_pan'", id="joint"
        ),
        pytest.param({"joint_name": "knee"}, r"joints\.knee: no joint 'knee' in arm 'koch'", id="unknown-joint"),
    ],
)
def test_apply_errors_name_the_file_and_key(tmp_path, change, match):
    cal = random_calibration("koch", 3)
    path = save_calibration(cal, tmp_path / "lab.toml")
    cal = load_calibration(path)
    servos = list(cal.servos)
    if "servos_drop" in change:
        del servos[change["servos_drop"]]
    if "servo_id" in change:
        servos[0] = ServoCalibration(change["servo_id"], servos[0].joint, 0)
    if "servo_joint" in change:
        servos[0] = ServoCalibration(servos[0].id, change["servo_joint"], 0)
    joints = cal.joints + ((JointCalibration(change["joint_name"]),) if "joint_name" in change else ())
    cal = _edit(cal, arm=change.get("arm", "koch"), servos=tuple(servos), joints=joints)
    with pytest.raises(ConfigError, match=f"^{path}: {match}"):
        apply_calibration(load_arm("koch"), cal)


GOOD = """arm = "koch"
name = "lab"
date = "2026-11-24"
[[servos]]
id = 1
joint = "shoulder_pan"
offset = 10
"""


@pytest.mark.parametrize(
    "text,match",
    [
        pytest.param('arm = "koch"\nname = =\n', r"line 2: invalid TOML", id="syntax"),
        pytest.param(
            GOOD.replace("offset = 10", 'offset = "x"'), r"servos\[0\]\.offset: expected an integer", id="type"
        ),
        pytest.param(
            GOOD.replace("offset = 10", "offset = 5000"),
            r"servos\[0\]\.offset: expected an integer in -2048\.\.2048",
            id="range",
        ),
        pytest.param(GOOD + "direction = 0\n", r"servos\[0\]\.direction: direction must be 1", id="direction"),
        pytest.param(GOOD + "colour = 1\n", r"servos\[0\]\.colour: unknown key", id="unknown-key"),
        pytest.param(GOOD.replace('name = "lab"\n', ""), r"name: missing required key", id="missing"),
        pytest.param(GOOD.replace('"lab"', '"../x"'), r"name: Expected a name of letters", id="name"),
        pytest.param(
            GOOD + "[[servos]]\nid = 1\njoint = 'a'\noffset = 0\n", r"servos\[1\]\.id: duplicate servo ID", id="dup"
        ),
        pytest.param(
            GOOD + "[joints.shoulder_pan]\nlimits = [10, -10]\n",
            r"joints\.shoulder_pan\.limits: lower limit",
            id="limits",
        ),
        pytest.param(GOOD.split("[[servos]]")[0] + "servos = 3\n", r"servos: expected a non-empty list", id="servos"),
    ],
)
def test_a_malformed_file_names_the_file_and_the_key(tmp_path, text, match):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=f"^{path}: {match}"):
        load_calibration(path)


def test_a_missing_file_is_named(tmp_path):
    with pytest.raises(ConfigError, match=f"^{tmp_path / 'none.toml'}: calibration file not found"):
        load_calibration(tmp_path / "none.toml")


@pytest.mark.skipif(os.name != "posix" or os.uname().sysname != "Linux", reason="the Linux (XDG) rule")
def test_the_default_place_follows_xdg_config_home(monkeypatch, tmp_path):
    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path))
    assert default_calibration_path("koch") == tmp_path / "retarget" / "calibration" / "koch.toml"
    monkeypatch.delenv("XDG_CONFIG_HOME")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert (
        default_calibration_path("lab-1") == tmp_path / "home" / ".config" / "retarget" / "calibration" / "lab-1.toml"
    )


@pytest.mark.parametrize("platform,env,expected", [
    ("darwin", {}, "Library/Application Support/retarget/calibration/koch.toml"),
    ("win32", {"APPDATA": "APPDATA_DIR"}, "APPDATA_DIR/retarget/calibration/koch.toml"),
], ids=["macos", "windows"])  # fmt: skip
def test_the_default_place_on_other_platforms(monkeypatch, tmp_path, platform, env, expected):
    monkeypatch.setattr(calmod.sys, "platform", platform)
    monkeypatch.setenv("HOME", str(tmp_path))
    for k, v in env.items():
        monkeypatch.setenv(k, str(tmp_path / v))
    assert default_calibration_path("koch") == tmp_path / expected


@pytest.mark.parametrize(
    "name", ["", "../koch", "a/b", "x" * 65, ".hidden"], ids=["empty", "dots", "slash", "long", "dot"]
)
def test_a_name_that_cannot_be_a_file_stem_is_refused(name):
    with pytest.raises(ConfigError, match="name: Expected a name of letters"):
        default_calibration_path(name)


# ------------------------------------------------------------------------------------------ the arm-file keys


def test_bundled_arms_carry_a_calibration_pose_and_hints():
    for name in ("wx250s", "vx300s", "px100", "omx", "koch"):
        arm = load_arm(name)
        assert arm.within_limits(arm.calibration_pose) and all(j.calibration_hint for j in arm.joints), name
    assert load_arm("koch").requires_calibration and load_arm("koch").calibrate_directions
    assert not load_arm("wx250s").requires_calibration and not load_arm("wx250s").calibrate_directions
    assert np.allclose(load_arm("omx").calibration_pose, 0.0)  # the zero pose, not home


def _arm_file(tmp_path: Path, extra_top: str = "", pose: str = "", hint: str = "") -> Path:
    text = Path(load_arm("koch").source).read_text()
    text = text.replace("baud = 1_000_000\n", f"baud = 1_000_000\n{extra_top}", 1)
    if pose:
        text = text.replace("calibration = [0.0, 0.0, 0.0, 0.0, 0.0]", pose)
    if hint:
        text = text.replace('calibration_hint = "upper arm vertical"', hint)
    path = tmp_path / "arm.toml"
    path.write_text(
        text.replace("requires_calibration = true\n", "", 1) if "requires_calibration" in extra_top else text
    )
    return path


@pytest.mark.parametrize(
    "kwargs,match",
    [
        pytest.param(
            {"extra_top": 'requires_calibration = "yes"\n'}, r"requires_calibration: expected true or false", id="flag"
        ),
        pytest.param(
            {"pose": "calibration = [0.0, 90.0, 0.0, 0.0, 0.0]"},
            r"poses\.calibration\[1\]: outside the limits",
            id="pose",
        ),
        pytest.param({"pose": "calibration = [0.0]"}, r"poses\.calibration: expected a list of 5 numbers", id="length"),
        pytest.param(
            {"hint": "calibration_hint = 3"}, r"joints\[1\]\.calibration_hint: expected a non-empty string", id="hint"
        ),
    ],
)
def test_bad_calibration_keys_in_an_arm_file(tmp_path, kwargs, match):
    path = _arm_file(tmp_path, **kwargs)
    with pytest.raises(ConfigError, match=f"^{path}: {match}"):
        load_arm(path)


def test_apply_keeps_the_radians(tmp_path):
    arm = load_arm("koch")
    cal = random_calibration("koch", 5)
    out = apply_calibration(arm, cal)
    assert all(math.isfinite(j.lower) for j in out.joints) and out.calibration_pose.flags.writeable is False
