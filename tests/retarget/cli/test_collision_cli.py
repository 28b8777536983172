"""The collision options of ``replay``, ``export`` and ``teleop`` end to end: ``--clearance``, ``--keep-out``,
``--no-table``; blocked targets exit 3 at the nearest safe point; moves with no safe route are refused."""

from __future__ import annotations

import csv
import io
import json

import numpy as np
import pytest

from retarget.cli import main
from retarget.collision import CollisionModel, Sphere, World
from tests.helpers import servo_joint_angles, wx250s_tool


def cli(capsys, *args: str) -> tuple[int, str, str]:
    code = main(list(args))
    out, err = capsys.readouterr()
    return code, out, err


def test_teleop_to_the_base_exits_3_at_the_nearest_safe_point(arm, registered, capsys):
    simbus, url = registered
    code, out, err = cli(capsys, "teleop", "--to", "0,0,0", "--port", url, "--fast", "--json")
    assert code == 3, err
    t = json.loads(out)["teleop"]
    assert t["reached"] is False and t["rejected"]["blocked"] == 1 and t["targets_unreachable"] == 1
    q = servo_joint_angles(simbus, arm)
    model = CollisionModel.for_arm(arm)
    assert model.min_clearance(q) >= model.clearance - 2e-3  # the servos hold the last clear goal to a pulse
    np.testing.assert_allclose(t["reached_m"], wx250s_tool(q), atol=1e-5)


def test_teleop_into_a_keep_out_from_the_command_line(arm, registered, capsys):
    simbus, url = registered
    code, out, err = cli(capsys, "teleop", "--to", "0.3,0,0.2", "--keep-out", "sphere:0.3,0,0.2,0.04", "--port",
                         url, "--fast")  # fmt: skip
    assert code == 3, err
    assert "NOT reached (nearest point)" in out and "1 rejected (blocked 1)" in err
    model = CollisionModel.for_arm(arm, world=World(keep_out=(Sphere((0.3, 0, 0.2), 0.04),)))
    assert model.min_clearance(servo_joint_angles(simbus, arm)) >= model.clearance - 2e-3


def test_a_stream_of_blocked_targets_never_moves_the_arm(arm, registered, capsys, monkeypatch):
    simbus, url = registered
    monkeypatch.setattr("sys.stdin", io.TextIOWrapper(io.BytesIO(b"0 0 0.02\n0.3 0 0.2\n")))
    code, out, err = cli(capsys, "teleop", "--stdin", "--keep-out", "box:0.25,-0.05,0.15,0.35,0.05,0.25", "--port",
                         url, "--fast", "--json")  # fmt: skip
    assert code == 0, err
    t = json.loads(out)["teleop"]
    assert t["rejected"]["blocked"] == 2 and t["targets_received"] == 0
    np.testing.assert_allclose(servo_joint_angles(simbus, arm), arm.rest, atol=2e-3)  # where it started


def test_replay_reports_the_collision_figures(capsys, tmp_path):
    telemetry = tmp_path / "run.csv"
    code, out, err = cli(capsys, "replay", "--fast", "--json", "--max-ticks", "200", "--clearance", "10.5",
                         "--telemetry", str(telemetry))  # fmt: skip
    assert code == 0, err
    doc = json.loads(out)
    assert doc["blocked_ticks"] == 0 and doc["min_clearance_mm"] >= 10.5 and doc["pushed_targets"] == 0
    rows = list(csv.DictReader(telemetry.open()))
    assert min(float(r["min_clearance_mm"]) for r in rows) >= 10.5 and {r["blocked"] for r in rows} == {"0"}
    assert "collisions: 0 blocked goals (not sent)" in err


def test_export_with_a_keep_out_on_the_clip_pushes_its_targets_out(capsys, tmp_path, arm):
    out_path = tmp_path / "traj.csv"
    code, _, err = cli(capsys, "export", "--keep-out", "sphere:0.32,0,0.22,0.06", "-o", str(out_path))
    assert code == 0, err
    q = np.loadtxt(out_path, delimiter=",", skiprows=1)[:, 1:]
    model = CollisionModel.for_arm(arm, world=World(keep_out=(Sphere((0.32, 0, 0.22), 0.06),)))
    assert np.all(model.distances(q).min(axis=1) >= model.clearance)
    assert "pushed out of blocked zones" in err


def test_a_rest_move_with_no_safe_route_is_refused_before_the_bus_connects(arm, registered, capsys):
    simbus, url = registered
    rest_tool = arm.fk(arm.rest)[0][:3, 3]
    ball = f"sphere:{rest_tool[0]:.4f},{rest_tool[1]:.4f},{rest_tool[2]:.4f},0.03"
    code, out, err = cli(capsys, "replay", "--fast", "--max-ticks", "5", "--keep-out", ball, "--port", url)
    assert code == 2
    assert err.strip().count("\n") == 0 and "collision: Expected a collision-free" in err
    assert all(simbus.servo(j.servos[0].id).get("Torque Enable") == 0 for j in arm.joints)  # torque never on


@pytest.mark.parametrize(
    ("args", "match"),
    [
        (["--clearance", "abc"], r"--clearance: Expected a number of millimetres \(got 'abc'\)"),
        (["--clearance", "500"], r"--clearance: Expected a clearance from 0 to 100 mm \(got '500'\)"),
        (["--clearance", "-1"], r"--clearance: Expected a clearance from 0 to 100 mm \(got '-1'\)"),
        (["--keep-out", "cube:1,2,3"], r"--keep-out: Expected box:X0,Y0,Z0,X1,Y1,Z1 or sphere:X,Y,Z,R .*'cube:1,2,3'"),
        (["--keep-out", "box:0,0,0,1,1"], r"--keep-out: Expected box:.*'box:0,0,0,1,1'"),
        (["--keep-out", "box:0,0,0,1,-1,1"], r"--keep-out: Expected each box minimum below its maximum"),
        (["--keep-out", "sphere:0,0,0,-1"], r"--keep-out: Expected a sphere radius > 0 m \(got 'sphere:0,0,0,-1'\)"),
        (["--keep-out", "sphere:nan,0,0,1"], r"--keep-out: Expected box:.*'sphere:nan,0,0,1'"),
    ],
    ids=["clearance-text", "clearance-big", "clearance-negative", "kind", "box-count", "box-order", "radius", "nan"],
)
@pytest.mark.parametrize("command", ["replay", "export", "teleop"])
def test_bad_collision_options_exit_2_with_one_line(capsys, command, args, match):
    import re

    extra = {"replay": ["--fast"], "export": ["-o", "-"], "teleop": ["--to", "0.3,0,0.2", "--fast"]}[command]
    code, out, err = cli(capsys, command, *extra, *args)
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and re.search(match, err), err


def test_no_table_lets_the_arm_reach_below_z_0(arm, capsys):
    code, out, err = cli(capsys, "teleop", "--to", "0.35,0,0.02", "--fast", "--json", "--no-table", "--clearance",
                         "5")  # fmt: skip
    assert code == 0, err
    assert json.loads(out)["teleop"]["rejected"]["blocked"] == 0
