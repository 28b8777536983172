"""``retarget inspect``: text and JSON reports, errors on one line with exit status 2."""

from __future__ import annotations

import json
import re
import subprocess
import sys

import numpy as np
import pytest

from retarget.bvh import DEMO_CLIP
from retarget.cli import main
from retarget.cli.inspect import SHOWN_REJECTED
from tests.helpers import (
    ArmNaming,
    J,
    arm_skeleton,
    bvh_text,
    lafan_like,
    left_hand_rig,
    n_channels,
    named_humanoid,
    renamed,
    with_face,
)

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


# ------------------------------------------------------------------ issue 15: how each chain was found, units


def write(tmp_path, name: str, root, frames=None) -> str:
    path = tmp_path / name
    path.write_text(bvh_text(root, frames))
    return str(path)


def test_structure_says_how_and_what_was_not_chosen(tmp_path, capsys):
    path = write(tmp_path, "bones.bvh", renamed(with_face(named_humanoid(ArmNaming(), fingers=True))))
    assert main(["inspect", path]) == 0
    out = capsys.readouterr().out
    arms = out[out.index("arm chains:") :].splitlines()
    assert arms[1].startswith("  left   bone13 > bone14 > bone15  upper arm 28 cm, forearm 25 cm (by structure)")
    assert arms[2] == (
        "         how: no joint is named as a left upper arm, forearm or hand; by structure: the left limb off "
        "bone02, mirrored by bone32 > bone33 > bone34"
    )
    assert "         not chosen: bone32 > bone33 > bone34 (on the right in the rest pose)" in arms
    assert (
        "         not chosen: bone50 > bone51 > bone52 (neither its names nor the rest pose put it on a side)" in arms
    )
    assert sum(line.startswith("         not chosen: ") for line in arms) == 2 * (SHOWN_REJECTED + 1)
    assert re.search(r"\n         not chosen: \d+ more \(see --json\)\n", out)

    assert main(["inspect", path, "--json", "--side", "left"]) == 0
    left = json.loads(capsys.readouterr().out)["arms"]["left"]
    assert (left["method"], left["shoulder"], left["lengths_from"], left["warnings"]) == (
        "structure",
        "bone13",
        "frames",
        [],
    )
    assert left["how"].startswith("no joint is named as a left upper arm")
    assert {"chain": ["bone32", "bone33", "bone34"], "reason": "on the right in the rest pose"} in left["rejected"]
    assert len(left["rejected"]) > SHOWN_REJECTED + 1
    assert any("an arm's are 6-40 %" in r["reason"] for r in left["rejected"])  # fingers and tongue


def test_no_arm_lists_the_candidates_and_why(tmp_path, capsys):
    path = write(tmp_path, "glove.bvh", left_hand_rig())
    assert main(["inspect", path]) == 0
    out = capsys.readouterr().out
    assert (
        "  left   none: named left: hand LeftHand; no upper arm or forearm; no plausible limb by structure\n"
        "         not chosen: LeftHandThumb1 > LeftHandThumb2 > LeftHandThumb3 (its names say finger)\n" in out
    )
    assert "  right  none: no joint is named as a right upper arm, forearm or hand; no plausible" in out
    assert main(["inspect", path, "--json"]) == 0
    right = json.loads(capsys.readouterr().out)["arms"]["right"]
    assert right["error"].startswith("Expected a right arm chain (shoulder, elbow, wrist), found none by joint names")
    assert [r["reason"] for r in right["rejected"]] == ["its names say finger"] * 5


def test_zero_frames_show_the_rest_pose_lengths(tmp_path, capsys):
    root = arm_skeleton(CMU)
    path = tmp_path / "template.bvh"
    path.write_text(bvh_text(root, np.zeros((0, n_channels(root)))))
    assert main(["inspect", str(path), "--side", "right"]) == 0
    out = capsys.readouterr().out
    assert (
        "right  RightArm > RightForeArm > RightHand  upper arm 28 cm, forearm 25 cm (rest pose: no frames) (by names)"
        in out
    )


def test_units_from_the_bones_or_the_motion(tmp_path, capsys):
    root, _ = lafan_like()
    assert main(["inspect", write(tmp_path, "lafan0.bvh", root, np.zeros((0, n_channels(root))))]) == 0
    assert "  units      centimetres (179.2 cm tall from the bone lengths, Y up)\n" in capsys.readouterr().out
    root, frames = lafan_like(3)
    assert main(["inspect", write(tmp_path, "lafan.bvh", root, frames), "--json"]) == 0
    units = json.loads(capsys.readouterr().out)["units"]
    assert (units["guess"], units["height"], units["basis"]) == ("cm", 192.0, "motion")
    assert units["skeleton_height"] == pytest.approx(179.2, abs=0.05)
    assert main(["inspect", write(tmp_path, "lafan.bvh", root, frames)]) == 0
    assert "  units      centimetres (192 cm tall in the motion, Y up)\n" in capsys.readouterr().out


def test_unusual_and_degenerate_arms(tmp_path, capsys, caplog):
    root = arm_skeleton(CMU)
    root.children[0].children[1].children[0].children[0].offset = (6.0, 0.0, 0.0)  # LeftForeArm: upper arm 6 cm
    root.children[0].children[2].children[0].children[0].offset = (-1e-4, 0.0, 0.0)  # RightForeArm: 0.0001 cm
    assert main(["inspect", write(tmp_path, "odd.bvh", root)]) == 0
    out = capsys.readouterr().out
    assert "  left   LeftArm > LeftForeArm > LeftHand  upper arm 6 cm, forearm 25 cm (by names)\n" in out
    assert "         warning: the left upper arm and forearm are usually 6-40 % of the skeleton's height" in out
    assert [r.getMessage().startswith(f"{tmp_path / 'odd.bvh'}: the left upper arm") for r in caplog.records] == [True]
    assert "  right  none: Expected the right upper arm and forearm to be 2-75 % of the skeleton's height" in out
    assert "RightArm > RightForeArm 0.0001 units" in out
