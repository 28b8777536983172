"""``retarget inspect``: text and JSON reports, errors on one line with exit status 2."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from retarget.bvh import DEMO_CLIP
from retarget.cli import main
from tests.helpers import J, arm_skeleton, bvh_text

CMU = {"clavicle": "{side}Shoulder", "upper": "{side}Arm", "fore": "{side}ForeArm", "hand": "{side}Hand"}
CMU |= {"left": "Left", "right": "Right"}


def test_default_is_the_demo_clip(capsys):
    assert main(["inspect"]) == 0
    out, err = capsys.readouterr()
    assert err == ""
    assert out.startswith("demo.bvh\n")
    assert "630 at 60 fps" in out and "10.50 s" in out
    assert "ZYX (21 joints)" in out
    assert "centimetres (169 cm tall, Y up)" in out
    assert "\n  Hips  [pos XYZ, rot ZYX]\n    Spine  [rot ZYX]\n" in out
    assert "right  RightArm > RightForeArm > RightHand  upper arm 29 cm, forearm 25 cm (by names)" in out
    assert "left   LeftArm > LeftForeArm > LeftHand" in out


def test_json_report(capsys):
    assert main(["inspect", str(DEMO_CLIP), "--json"]) == 0
    out, err = capsys.readouterr()
    report = json.loads(out)
    assert err == ""
    assert report["frames"] == 630 and report["fps"] == pytest.approx(60.0, rel=1e-5)
    assert report["duration"] == pytest.approx(10.5, rel=1e-5)
    assert report["rotation_orders"] == {"ZYX": 21}
    assert report["units"]["guess"] == "cm" and report["units"]["up_axis"] == "Y"
    assert report["joints"][0] == {
        "name": "Hips",
        "parent": -1,
        "offset": [0.0, 0.0, 0.0],
        "channels": ["Xposition", "Yposition", "Zposition", "Zrotation", "Yrotation", "Xrotation"],
        "rotation_order": "ZYX",
        "end_sites": [],
    }
    assert report["arms"]["right"]["wrist"] == "RightHand"
    assert report["arms"]["right"]["upper_arm_length"] == pytest.approx(29.0)
    assert len(report["end_sites"]) == 5


def test_side_and_explicit_joints(tmp_path, capsys):
    path = tmp_path / "rig.bvh"
    path.write_text(bvh_text(arm_skeleton(CMU)))
    assert (
        main(["inspect", str(path), "--side", "left", "--arm-joints", "LeftShoulder", "LeftForeArm", "LeftHand"]) == 0
    )
    out, _ = capsys.readouterr()
    assert "left   LeftShoulder > LeftForeArm > LeftHand" in out and "(by explicit)" in out
    assert "right " not in out


def test_missing_arm_is_reported_not_fatal(tmp_path, capsys):
    root = J("Hips", (0, 0, 0), ("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation"))
    root.children = [J("Head", (0, 10, 0), end=(0, 5, 0))]
    path = tmp_path / "snake.bvh"
    path.write_text(bvh_text(root))
    assert main(["inspect", str(path), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["arms"]["left"]["error"].startswith("Expected a left arm chain")
    assert report["units"]["guess"] == "unknown"


def test_unknown_units_say_the_scale(tmp_path, capsys):
    root = J("Hips", (0, 0, 0), ("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation"))
    root.children = [J("Spine", (0, 10, 0), end=(0, 15, 0))]
    path = tmp_path / "tiny.bvh"
    path.write_text(bvh_text(root))
    assert main(["inspect", str(path)]) == 0
    out = capsys.readouterr().out
    assert "units      unknown: 25 units tall (Y up); 0.068 m per unit would make it 1.7 m tall" in out


def test_bad_file_one_line_exit_2(tmp_path, capsys):
    path = tmp_path / "bad.bvh"
    path.write_text("HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0\n")
    assert main(["inspect", str(path)]) == 2
    out, err = capsys.readouterr()
    assert out == ""
    assert err == f"retarget: {path}:4: Expected 3 numbers after OFFSET, got 2\n"


def test_missing_file_exit_2(tmp_path, capsys):
    assert main(["inspect", str(tmp_path / "nope.bvh")]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.startswith("retarget: ") and "nope.bvh" in err and err.count("\n") == 1


def test_explicit_joints_need_a_side(capsys):
    assert main(["inspect", "--arm-joints", "a", "b", "c"]) == 2
    assert "Expected --side left or right with --arm-joints, got --side both" in capsys.readouterr().err


def test_verbose_shows_the_traceback(tmp_path, capsys):
    path = tmp_path / "bad.bvh"
    path.write_text("")
    assert main(["-v", "inspect", str(path)]) == 2
    err = capsys.readouterr().err
    assert "Traceback" in err and err.rstrip().endswith("got an empty file")


def test_help_has_examples(capsys):
    with pytest.raises(SystemExit) as info:
        main(["inspect", "--help"])
    assert info.value.code == 0
    out = capsys.readouterr().out
    assert "examples:" in out and "retarget inspect dance.bvh --json" in out


def test_python_dash_m(tmp_path):
    bad = tmp_path / "bad.bvh"
    bad.write_text("HIERARCHY\nROOT Hips\n")
    ok = subprocess.run([sys.executable, "-m", "retarget", "inspect", "--json"], capture_output=True, text=True)
    assert ok.returncode == 0, ok.stderr
    assert json.loads(ok.stdout)["frames"] == 630
    fail = subprocess.run([sys.executable, "-m", "retarget", "inspect", str(bad)], capture_output=True, text=True)
    assert fail.returncode == 2
    assert fail.stdout == ""
    assert fail.stderr == f"retarget: {bad}:3: Expected '{{' after ROOT 'Hips', got end of file\n"
