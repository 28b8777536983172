"""The gripper in teleoperation: the ``g`` field of stdin/UDP messages (text ``g=V``, JSON ``"g"``) and
``--gripper``; and the replay's ``--gripper`` and hand rule, end to end on the simulated vx300s."""

from __future__ import annotations

import csv
import io
import json

import numpy as np
import pytest

import retarget
from retarget.cli import main
from retarget.control.clock import VirtualClock
from retarget.teleop.gate import Reject, TargetBounds, TargetGate
from retarget.teleop.gripper import split_gripper
from tests.helpers import pinching_hand_bvh


@pytest.mark.parametrize(
    ("message", "closure", "rest"),
    [
        pytest.param("0.3 0 0.2 g=1", 1.0, "0.3 0 0.2", id="text-after"),
        pytest.param("g=0.25, 0.3,0,0.2", 0.25, "0.3,0,0.2", id="text-before-commas"),
        pytest.param("g=open", 0.0, None, id="gripper-only-word"),
        pytest.param("G: close", 1.0, None, id="colon-upper"),
        pytest.param('{"x": 0.3, "y": 0, "z": 0.2, "g": 0.5}', 0.5, '{"x": 0.3, "y": 0, "z": 0.2}', id="json"),
        pytest.param('{"g": "close"}', 1.0, None, id="json-only"),
        pytest.param("0.3 0 0.2", None, "0.3 0 0.2", id="none"),
        pytest.param(b"0.3 0 0.2 g=1", 1.0, "0.3 0 0.2", id="bytes"),
    ],
)
def test_split_gripper(message, closure, rest):
    assert split_gripper(message) == (closure, rest)


def _gate() -> TargetGate:
    return TargetGate(TargetBounds.for_arm(retarget.load_arm("vx300s")), clock=VirtualClock())


def test_the_gate_keeps_the_latest_g_and_a_gripper_only_message_is_no_target():
    gate = _gate()
    assert gate.gripper is None
    target = gate.accept("0.3 0 0.2 g=0.2")
    assert target is not None and np.allclose(target.position, [0.3, 0, 0.2]) and gate.gripper == 0.2
    assert gate.accept("g=1") is None and gate.gripper == 1.0
    assert gate.accepted == 1 and gate.rejects.total == 0


@pytest.mark.parametrize(
    ("message", "reason"),
    [
        pytest.param("0.3 0 0.2 g=2", Reject.MALFORMED, id="above-1"),
        pytest.param("g=shut", Reject.MALFORMED, id="word"),
        pytest.param("g=nan", Reject.NON_FINITE, id="nan"),
        pytest.param('{"x": 0.3, "y": 0, "z": 0.2, "g": true}', Reject.MALFORMED, id="json-bool"),
        pytest.param("5 5 5 g=1", Reject.OUT_OF_BOX, id="bad-target-keeps-the-gripper"),
    ],
)
def test_a_bad_message_changes_neither_the_target_nor_the_gripper(message, reason):
    gate = _gate()
    gate.accept("g=0.5")
    assert gate.accept(message) is None
    assert gate.gripper == 0.5
    assert gate.rejects.total == 1 and gate.rejects.counts()[reason.value] == 1


def test_teleop_stdin_g_closes_the_gripper_on_the_servo(monkeypatch, tmp_path):
    monkeypatch.setattr("sys.stdin", io.TextIOWrapper(io.BytesIO(b"0.3 0 0.2 g=0\ng=1\n0.3 0.05 0.2\n")))
    out = tmp_path / "t.csv"
    argv = ["teleop", "--arm", "vx300s", "--stdin", "--fast", "--telemetry", str(out)]
    assert main(argv) == 0
    rows = list(csv.DictReader(out.open()))
    assert {r["gripper_cmd"] for r in rows[-20:]} == {"1.000000"}
    lower = retarget.load_arm("vx300s").gripper.lower  # type: ignore[union-attr]
    assert float(rows[-1]["gripper_present_rad"]) == pytest.approx(lower, abs=2e-3)


def test_teleop_gripper_option_errors(capsys):
    assert main(["teleop", "--arm", "vx300s", "--to", "0.3,0,0.2", "--gripper", "2", "--fast"]) == 2
    assert "--gripper: Expected open, close or a closure from 0 (open) to 1 (closed)" in capsys.readouterr().err


def test_replay_drives_the_gripper_from_the_hand_and_names_the_rule(tmp_path, capsys):
    t = np.arange(90) / 30
    clip = tmp_path / "pinch.bvh"
    clip.write_text(pinching_hand_bvh(np.clip(np.minimum((t - 0.9) / 0.2, (2.1 - t) / 0.2), 0, 1)))
    out = tmp_path / "t.csv"
    argv = ["replay", str(clip), "--arm", "vx300s", "--side", "left", "--fast", "--json", "--telemetry", str(out)]
    assert main(argv) == 0
    assert json.loads(capsys.readouterr().out)["gripper"] == "pinch"
    rows = [r for r in csv.DictReader(out.open()) if r["lead_in"] == "0"]
    at = {round(float(r["clip_time_s"]), 2): r for r in rows}
    assert float(at[0.5]["gripper_cmd"]) < 0.05 and float(at[1.5]["gripper_cmd"]) > 0.95
    assert float(at[2.9]["gripper_cmd"]) < 0.05
    arm = retarget.load_arm("vx300s")
    assert arm.gripper is not None
    closed = min(float(r["gripper_present_rad"]) for r in rows if r["gripper_present_rad"])
    assert closed < arm.gripper.angle(0.9)  # it did close on the servo
    assert float(rows[-1]["gripper_present_rad"]) > arm.gripper.angle(0.1)  # and opened again


def test_replay_gripper_off_and_fixed(tmp_path, capsys):
    assert main(["replay", "--arm", "vx300s", "--dry-run", "--fast", "--json", "--max-ticks", "5"]) == 0
    assert json.loads(capsys.readouterr().out)["gripper"] is None  # the demo clip has no fingers
    argv = ["replay", "--arm", "vx300s", "--dry-run", "--fast", "--json", "--max-ticks", "5", "--gripper", "close"]
    assert main(argv) == 0
    assert json.loads(capsys.readouterr().out)["gripper"] == "fixed 1"
    assert main(["replay", "--dry-run", "--fast", "--max-ticks", "5", "--gripper", "x"]) == 2
    assert "--gripper" in capsys.readouterr().err
