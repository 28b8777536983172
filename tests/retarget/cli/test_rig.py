"""``retarget rig``: text and JSON output, --list, --port overrides, bad input exits 2 with one line."""

from __future__ import annotations

import json
import re

import pytest

from retarget.cli import main


def run(capsys, *argv):
    code = main(["rig", *argv])
    out, err = capsys.readouterr()
    return code, out, err


def test_default_rig_text(capsys):
    code, out, err = run(capsys)
    assert code == 0 and err == ""
    assert out.startswith("rig aloha  (")
    assert "  left     vx300s     +0.000, +0.300, +0.000      0.0°  left   sim://vx300s" in out
    assert "  at home  nearest left:base/right:base: 307.7 mm" in out


def test_json_with_a_port_override(capsys):
    code, out, _ = run(capsys, "wx250s-pair", "--port", "right=/dev/ttyUSB1", "--json")
    report = json.loads(out)
    assert code == 0 and report["rig"] == "wx250s-pair"
    assert [(a["name"], a["port"], a["side"]) for a in report["arms"]] == [
        ("left", "sim://wx250s", "left"),
        ("right", "/dev/ttyUSB1", "right"),
    ]
    assert report["nearest"]["home"]["clearance_mm"] > 300 and report["clearance_mm"] == 10.0


def test_list(capsys):
    code, out, _ = run(capsys, "--list")
    assert code == 0 and out.split() == ["aloha", "wx250s-pair"]


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--port", "left"], "retarget: --port: Expected NAME=PORT, e.g. left=/dev/ttyUSB0 (got 'left')\n"),
        (["--port", "middle=/dev/x"], "retarget: --port: Expected one of the rig's arms left, right (got 'middle')\n"),
        (
            ["--port", "left=/a", "--port", "left=/b"],
            "retarget: --port: Expected one port for arm 'left' (got 'left=/b')\n",
        ),
        (["nope"], "retarget: rig: unknown rig 'nope'; known rigs: aloha, wx250s-pair (or give a .toml path)\n"),
    ],
    ids=["no-equals", "unknown-arm", "twice", "unknown-rig"],
)
def test_bad_input_is_one_line_and_exit_2(capsys, argv, message):
    code, out, err = run(capsys, *argv)
    assert (code, out, err) == (2, "", message)


def test_export_rig_writes_every_arm_and_reports_each(capsys, tmp_path):
    out = tmp_path / "both.csv"
    code = main(["export", "--rig", "wx250s-pair", "--end", "1", "-o", str(out)])
    err = capsys.readouterr().err
    assert code == 0
    lines = out.read_text().splitlines()
    header = lines[0].split(",")
    assert header[0] == "time_s" and header[1] == "left/waist_rad" and header[7] == "right/waist_rad"
    assert len(header) == 13 and len(lines) == 1 + 101  # 1 s at 100 Hz, both ends
    assert "rig wx250s-pair" in err and "  left: IK" in err and "  right: IK" in err


@pytest.mark.parametrize(
    ("flags", "match"),
    [
        (["--side", "left"], r"--side: Expected no arm or side with --rig .*\(got 'left'\)"),
        (["--arm", "px100"], r"--arm: Expected no arm or side with --rig"),
    ],
    ids=["side", "arm"],
)
def test_export_rig_refuses_one_arm_options(capsys, flags, match):
    code = main(["export", "--rig", "wx250s-pair", "-o", "-", *flags])
    assert code == 2
    assert re.search(match, capsys.readouterr().err)
