"""``retarget arm``: text and JSON output, --list, --ik, URDF --tip, bad input exits 2 with one line."""

from __future__ import annotations

import json

import numpy as np
import pytest

from retarget import load_arm
from retarget.cli import main
from tests.helpers import REPO


def run(capsys, *argv):
    code = main(["arm", *argv])
    out, err = capsys.readouterr()
    return code, out, err


def test_default_arm_text(capsys):
    code, out, err = run(capsys)
    assert code == 0 and err == ""
    assert out.startswith("wx250s: WidowX-250 6DOF\n")
    assert "shoulder         y        -108.00 ..  114.00        180.0  2 XM430-W350, 3 XM430-W350 reverse" in out
    assert "tool point at home (0.4583, 0.0000, 0.3607) m" in out


def test_json(capsys):
    code, out, _ = run(capsys, "omx", "--json")
    report = json.loads(out)
    assert code == 0 and report["name"] == "omx" and report["servo_ids"] == [11, 12, 13, 14, 15]
    assert report["joints"][2]["limits_deg"] == [-85.9437, 80.2141]
    assert report["home_deg"] == [0.0, -57.2958, 57.2958, 0.0]


def test_list(capsys):
    code, out, _ = run(capsys, "--list")
    assert code == 0 and [line.split()[0] for line in out.splitlines()] == ["koch", "omx", "px100", "vx300s", "wx250s"]


def test_ik(capsys):
    code, out, _ = run(capsys, "wx250s", "--ik", "0.35,0.05,0.25", "--json")
    ik = json.loads(out)["ik"]
    assert code == 0 and ik["converged"] and ik["error_mm"] <= 1.0
    arm = load_arm("wx250s")
    reached = arm.fk(np.radians(ik["q_deg"]))[0][:3, 3]
    np.testing.assert_allclose(reached, [0.35, 0.05, 0.25], atol=1.01e-3)


def test_ik_text_unreachable(capsys):
    code, out, _ = run(capsys, "px100", "--ik", "2,0,0", "--from", "rest")
    assert code == 0 and "NOT converged (closest pose)" in out


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (
            ["wx250s", "--ik", "0.3,0,x"],
            "retarget: --ik: expected three finite numbers X,Y,Z in metres (got '0.3,0,x')",
        ),
        (["wx250s", "--ik", "0.3,0"], "retarget: --ik: expected three finite numbers"),
        (["wx250s", "--ik", "nan,0,0"], "retarget: --ik: expected three finite numbers"),
        (["nope"], "retarget: arm: unknown arm 'nope'; known arms: koch, omx, px100, vx300s, wx250s"),
        (
            ["wx250s", "--tip", "x"],
            "retarget: " + str(load_arm("wx250s").source) + ": tip: base/tip only apply to a URDF file",
        ),
    ],
    ids=["bad-number", "two-numbers", "nan", "unknown-arm", "tip-on-toml"],
)
def test_bad_input_exits_2_with_one_line(capsys, argv, message):
    code, out, err = run(capsys, *argv)
    assert code == 2 and out == ""
    assert err.startswith(message) and err.count("\n") == 1


def test_bad_file_names_the_key(capsys, tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text('name = "x"\njoints = []\n[poses]\nhome = []\n')
    code, _, err = run(capsys, str(path))
    assert code == 2 and err == f"retarget: {path}: joints: expected at least one [[joints]] table (got [])\n"


def test_urdf_with_tip(capsys, tmp_path):
    (tmp_path / "two.urdf").write_text(
        '<robot name="two"><link name="a"/><link name="b"/><link name="c"/><link name="d"/>'
        '<joint name="j1" type="revolute"><parent link="a"/><child link="b"/><axis xyz="0 0 1"/>'
        '<limit lower="-1" upper="1" velocity="2"/></joint>'
        '<joint name="t1" type="fixed"><parent link="b"/><child link="c"/><origin xyz="0.2 0 0"/></joint>'
        '<joint name="t2" type="fixed"><parent link="b"/><child link="d"/><origin xyz="0 0.3 0"/></joint></robot>'
    )
    (tmp_path / "two.servos.toml").write_text("[joints.j1]\nservos = [{ id = 7, model = 'XL330-M288' }]\n")
    code, _, err = run(capsys, str(tmp_path / "two.urdf"))
    assert code == 2 and "cannot tell the tip link: leaves c, d; name one" in err
    code, out, _ = run(capsys, str(tmp_path / "two.urdf"), "--tip", "d", "--json")
    report = json.loads(out)
    assert code == 0 and report["tool_xyz"] == [0.0, 0.3, 0.0] and report["servo_ids"] == [7]


def test_a_bad_mapping_table_is_caught_by_retarget_arm(tmp_path, capsys):
    text = (REPO / "config" / "arms" / "px100.toml").read_text() + '\n[mapping]\narm_scale = "big"\n'  # no [mapping]
    path = tmp_path / "px100_bad.toml"
    path.write_text(text)
    assert main(["arm", str(path)]) == 2
    err = capsys.readouterr().err
    assert err == f"retarget: {path}: mapping.arm_scale: Expected a number > 0 (got 'big')\n"
