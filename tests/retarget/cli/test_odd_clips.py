"""Odd but real-world clips end to end (issue 15): ``export`` and ``replay`` either retarget them to finite
joint angles (exit 0) or refuse them on one stderr line naming the file (exit 2), never with a traceback.

Perception Neuron templates (``Frames: 0``), exporters that write all-zero channels (Kinect v2: every joint
on its parent, shoulders that coincide), shoulders that coincide in some frames only, one-armed rigs and
zero-length arms.  The outcome is asserted where the mapping decides it; where the parser or the skeleton
detection decides, only the contract (exit 0 with finite output, or exit 2 with one line) is.
"""

from __future__ import annotations

import csv
import io
from pathlib import Path

import numpy as np
import pytest

from retarget.cli import main
from tests.helpers import POS_XYZ, ROT_ZXY, J, arm_skeleton, bvh_text, joints_in_order

CMU = {"clavicle": "{side}Shoulder", "upper": "{side}Arm", "fore": "{side}ForeArm", "hand": "{side}Hand"}
CMU |= {"left": "Left", "right": "Right"}
SHOULDERS = ("LeftShoulder", "RightShoulder", "LeftArm", "RightArm")  # the clavicles and the upper arms


def rig(*, arms: tuple[str, ...] = ("left", "right"), positions: tuple[str, ...] = ()) -> J:
    """A CMU-named humanoid with legs, the arms of ``arms`` only, position channels on the joints ``positions``."""
    root = arm_skeleton(CMU)
    chest = root.children[0]
    gone = {f"{CMU[s]}Shoulder" for s in ("left", "right") if s not in arms}
    chest.children = [c for c in chest.children if c.name not in gone]
    for j in joints_in_order(root):
        if j.name in positions:
            j.channels = (*POS_XYZ, *ROT_ZXY)
    return root


def frames(root: J, n: int, *, zero: tuple[str, ...] = (), bad: list[int] | None = None) -> np.ndarray:
    """``(n, n_channels)``: the body turns and walks, the arms swing; position channels hold the joint's OFFSET,
    except those of the joints ``zero``, which are 0 in the frames ``bad`` (default: every frame)."""
    t = np.linspace(0.0, 1.0, n)
    motion = {
        ("Hips", "Xposition"): 50 * t,
        ("Hips", "Yrotation"): 90 * t,
        ("Chest", "Xrotation"): 20 * np.sin(3 * t),
        ("LeftArm", "Zrotation"): 60 * np.sin(5 * t),
        ("RightArm", "Xrotation"): 40 * np.cos(4 * t),
        ("RightForeArm", "Yrotation"): 50 * t,
    }
    rows = np.arange(n) if bad is None else np.asarray(bad)
    cols = []
    for j in joints_in_order(root):
        for ch in j.channels:
            col = np.array(motion.get((j.name, ch), np.zeros(n)), dtype=np.float64)
            if ch.endswith("position"):
                col = col + j.offset["XYZ".index(ch[0])]
                if j.name in zero:
                    col[rows] = 0.0
            cols.append(col)
    return np.stack(cols, axis=-1)


def write(tmp_path: Path, name: str, root: J, data: np.ndarray) -> str:
    path = tmp_path / name
    path.write_text(bvh_text(root, data))
    return str(path)


def run(capsys, command: str, path: str, *args: str) -> tuple[int, str, str]:
    argv = ["export", path, "-o", "-"] if command == "export" else ["replay", path, "--dry-run", "--fast"]
    code = main([*argv, *args])
    out, err = capsys.readouterr()
    return code, out, err


def check_contract(code: int, out: str, err: str, path: str, command: str = "export") -> None:
    """Exit 0 with finite joint angles, or exit 2 with exactly one stderr line naming the file; no traceback."""
    assert "Traceback" not in err
    if code == 0:
        if command == "export":
            rows = list(csv.reader(io.StringIO(out)))
            assert rows[0][0] == "time_s" and len(rows) > 1
            assert np.isfinite(np.array(rows[1:], dtype=np.float64)).all()
        return
    assert code == 2, err
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith(f"retarget: {path}"), lines[0]


def make(tmp_path: Path, case: str) -> str:
    """The clip of ``case``, written into ``tmp_path``."""
    if case == "frames0":  # a Perception Neuron template: the skeleton, no motion
        root = rig()
        return write(tmp_path, "template.bvh", root, np.zeros((0, sum(len(j.channels) for j in joints_in_order(root)))))
    if case == "all-zero":  # Kinect v2 style: every joint positioned by its channels, all of them 0
        root = rig(positions=tuple(j.name for j in joints_in_order(rig())))
        return write(tmp_path, "all_zero.bvh", root, np.zeros_like(frames(root, 6)))
    if case == "shoulders-zero":  # the shoulders on the chest in every frame, the rest of the arm intact
        root = rig(positions=SHOULDERS)
        return write(tmp_path, "shoulders_zero.bvh", root, frames(root, 12, zero=SHOULDERS))
    if case == "shoulders-zero-some":  # the shoulders on the chest in some frames (drop-outs), first and last too
        root = rig(positions=SHOULDERS)
        return write(tmp_path, "dropouts.bvh", root, frames(root, 30, zero=SHOULDERS, bad=[0, 1, 12, 13, 29]))
    if case.startswith("one-arm-"):
        root = rig(arms=(case.removeprefix("one-arm-"),))
        return write(tmp_path, f"{case}.bvh", root, frames(root, 12))
    if case == "zero-arm":  # the left forearm and hand folded onto the shoulder in every frame
        folded = ("LeftForeArm", "LeftHand")
        root = rig(positions=folded)
        return write(tmp_path, "zero_arm.bvh", root, frames(root, 8, zero=folded))
    raise AssertionError(case)


@pytest.mark.parametrize(
    ("case", "args", "expected"),
    [
        ("frames0", (), 2),
        ("frames0", ("--side", "left"), 2),
        ("all-zero", (), 2),  # nothing of the arm is left
        ("shoulders-zero", (), 0),  # the chest carries the shoulders as in the rest pose
        ("shoulders-zero", ("--side", "left"), 0),
        ("shoulders-zero-some", (), 0),  # the chest carries them as in the other frames
        ("shoulders-zero-some", ("--side", "left"), 0),
        ("one-arm-left", ("--side", "left"), 0),
        ("one-arm-right", ("--side", "right"), 0),
        ("one-arm-left", ("--side", "right"), None),  # no right arm: the skeleton detection decides
        ("one-arm-left", ("--side", "left", "--forward", "+z"), 0),
        ("zero-arm", ("--side", "left"), 2),
        ("zero-arm", ("--side", "right"), 0),
    ],
    ids=lambda v: "-".join(v) if isinstance(v, tuple) else str(v),
)
def test_export(capsys, tmp_path, case, args, expected):
    path = make(tmp_path, case)
    code, out, err = run(capsys, "export", path, *args)
    check_contract(code, out, err, path)
    if expected is not None:
        assert code == expected, err


@pytest.mark.parametrize("case", ["frames0", "all-zero", "shoulders-zero-some", "one-arm-left", "zero-arm"])
def test_replay(capsys, tmp_path, case):
    path = make(tmp_path, case)
    side = ("--side", "left") if case in ("one-arm-left", "zero-arm") else ()
    code, out, err = run(capsys, "replay", path, *side, "--max-ticks", "20")
    check_contract(code, out, err, path, "replay")
    assert code == (0 if case in ("shoulders-zero-some", "one-arm-left") else 2), err


def test_the_error_line_names_the_file_and_what_is_wrong(capsys, tmp_path):
    """The line names the file, then what is wrong with it (the parser and the detection word their own)."""
    template = make(tmp_path, "frames0")
    assert run(capsys, "export", template)[2].startswith(f"retarget: {template}: ")
    zero_arm = make(tmp_path, "zero-arm")
    _, _, err = run(capsys, "export", zero_arm, "--side", "left")
    assert err.startswith(f"retarget: {zero_arm}: ") and "LeftArm > LeftForeArm" in err  # the mapping or detection
