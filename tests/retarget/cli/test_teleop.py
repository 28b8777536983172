"""``retarget teleop`` end to end on the in-process simulator (``--fast``): exit codes, the servos' final
positions through an independent FK, stdin streams, garbage, telemetry, JSON, and every bad input."""

from __future__ import annotations

import csv
import io
import json
import os
import random
import re
import signal

import numpy as np
import pytest

from retarget.cli import main
from tests.helpers import garbage, goal_registers, servo_joint_angles, wx250s_tool


def teleop(capsys, *args: str) -> tuple[int, str, str]:
    code = main(["teleop", *args])
    out, err = capsys.readouterr()
    return code, out, err


def stdin_bytes(monkeypatch, data: bytes) -> None:
    monkeypatch.setattr("sys.stdin", io.TextIOWrapper(io.BytesIO(data)))


def test_one_shot_reached_exit_0(arm, registered, capsys):
    simbus, url = registered
    code, out, err = teleop(capsys, "--to", "0.3,0.05,0.2", "--port", url, "--fast")
    assert code == 0, err
    reached = wx250s_tool(servo_joint_angles(simbus, arm))  # read from the servos' registers after the run
    assert np.linalg.norm(reached - [0.3, 0.05, 0.2]) < 3e-3
    assert out.startswith("target 0.3000 0.0500 0.2000 m  reached ") and "(base frame)" in out
    assert out.rstrip().endswith(" reached (tolerance 5 mm)")
    assert "teleop: --to 0.3,0.05,0.2 on wx250s" in err and "1 received, 1 reached" in err
    assert all(simbus.servo(i).get("Torque Enable") == 1 for i in (1, 2, 4, 6, 7, 8))  # default shutdown: hold


def test_unreachable_exit_3_at_the_nearest_point(arm, registered, capsys):
    from retarget.mapping import arm_geometry

    simbus, url = registered
    code, out, err = teleop(capsys, "--to", "0.8,0.1,0.3", "--port", url, "--fast", "--json")
    assert code == 3, err
    doc = json.loads(out)
    t = doc["teleop"]
    assert t["reached"] is False and t["targets_unreachable"] == 1
    reached = wx250s_tool(servo_joint_angles(simbus, arm))
    np.testing.assert_allclose(t["reached_m"], reached, atol=1e-5)
    g = arm_geometry(arm)
    assert np.linalg.norm(reached - g.pivot) == pytest.approx(g.reach, abs=0.01)  # stretched out
    assert t["residual_mm"] == pytest.approx(1e3 * np.linalg.norm(reached - [0.8, 0.1, 0.3]), abs=0.01)


def test_rpy_and_world_frame(arm, registered, capsys):
    simbus, url = registered
    # the base sits at (1, 2, 0) turned 90 deg: world (1, 2.3, 0.2) is base (0.3, 0, 0.2)
    code, out, err = teleop(
        capsys, "--to", "1,2.3,0.2", "--frame", "world", "--base-pose", "1,2,0,0,0,90", "--port", url, "--fast"
    )
    assert code == 0, err
    np.testing.assert_allclose(wx250s_tool(servo_joint_angles(simbus, arm)), [0.3, 0, 0.2], atol=3e-3)
    assert out.startswith("target 1.0000 2.3000 0.2000 m  reached ") and "(world frame)" in out
    code, out, err = teleop(capsys, "--to", "0.3,0,0.15", "--rpy", "0,90,0", "--port", url, "--fast", "--json")
    assert code == 0, err
    q = servo_joint_angles(simbus, arm)
    T, _ = arm.fk(q)
    assert T[:3, 0] @ [0, 0, -1] > np.cos(np.radians(2.5))  # tool x points down (2 deg + quantisation)
    assert json.loads(out)["teleop"]["orientation_error_deg"] <= 2.0


def test_stdin_stream_followed_in_order(arm, registered, capsys, monkeypatch, tmp_path):
    simbus, url = registered
    points = [(0.3, 0.0, 0.25), (0.3, 0.12, 0.25), (0.22, 0.12, 0.12), (0.35, -0.05, 0.2)]
    lines = [f"{x} {y} {z}" if i % 2 else json.dumps({"x": x, "y": y, "z": z}) for i, (x, y, z) in enumerate(points)]
    stdin_bytes(monkeypatch, ("\n".join(lines) + "\n").encode())
    csv_path = tmp_path / "t.csv"
    # sparse waypoints, each to be visited: unfiltered (the stream filter would round their corners off)
    args = ("--stdin", "--no-filter", "--port", url, "--fast", "--json", "--telemetry", str(csv_path))
    code, out, err = teleop(capsys, *args)
    assert code == 0, err
    doc = json.loads(out)
    assert doc["teleop"]["targets_received"] == 4 and doc["teleop"]["targets_reached"] == 4
    with open(csv_path, newline="") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == doc["ticks"]
    names = arm.joint_names
    present = np.array([[float(r[f"{n}_present_rad"]) for n in names] for r in rows])
    tool = np.array([wx250s_tool(q) for q in present])
    first = [int(np.argmax(np.linalg.norm(tool - p, axis=1) < 0.01)) for p in points]
    assert all(np.linalg.norm(tool[i] - p) < 0.01 for i, p in zip(first, points, strict=True))
    assert first == sorted(first) and len(set(first)) == 4
    np.testing.assert_allclose(wx250s_tool(servo_joint_angles(simbus, arm)), points[-1], atol=3e-3)


def test_garbage_on_stdin_moves_nothing(arm, registered, capsys, monkeypatch):
    simbus, url = registered
    assert teleop(capsys, "--to", "0.3,0,0.2", "--port", url, "--fast")[0] == 0  # the driver has configured them
    goals0 = goal_registers(simbus)
    stdin_bytes(monkeypatch, b"\n".join(garbage(random.Random(9), 1000)) + b"\n")
    code, out, err = teleop(capsys, "--stdin", "--port", url, "--fast", "--json")
    assert code == 0, err
    t = json.loads(out)["teleop"]
    assert t["targets_received"] == 0 and sum(t["rejected"].values()) == 1000
    assert goal_registers(simbus) == goals0
    assert err.count("WARNING") < 40  # counted, rate-limited warnings


def test_sigint_stops_through_the_shutdown_sequence(arm, registered, capsys, monkeypatch):
    from retarget.teleop import Follower
    from tests.helpers import servo_angles, torque

    simbus, url = registered
    observe = Follower.observe

    def observe_then_ctrl_c(self, tick, q_cmd, q_present=None):
        """The real observe; at tick 50, a real SIGINT to this process (delivered in the main thread, as from a
        terminal; a watcher thread can be starved for the whole of a --fast run on a busy machine)."""
        observe(self, tick, q_cmd, q_present)
        if tick == 50:
            os.kill(os.getpid(), signal.SIGINT)

    monkeypatch.setattr(Follower, "observe", observe_then_ctrl_c)
    before = signal.getsignal(signal.SIGINT)  # (the default, unless the suite runs with SIGINT ignored)
    # a slow move (1 cm/s over ~20 cm) that is still under way when Ctrl-C comes
    code, out, err = teleop(
        capsys, "--to", "0.3,0,0.2", "--max-speed", "0.01", "--port", url, "--fast", "--shutdown", "rest", "--json"
    )
    assert code == 130, err
    doc = json.loads(out)
    assert doc["interrupted"] is True and doc["ticks"] == 51
    assert "stopping" in err and "teleop (interrupted)" in err
    assert torque(simbus, arm) == [0] * 8  # moved to rest, then torque off
    np.testing.assert_allclose(servo_angles(simbus, arm), arm.rest, atol=0.06)
    assert signal.getsignal(signal.SIGINT) is before  # the handler was put back


def test_help_has_examples(capsys):
    with pytest.raises(SystemExit) as info:
        main(["teleop", "--help"])
    assert info.value.code == 0
    out = capsys.readouterr().out
    assert "retarget teleop --to 0.3,0,0.2" in out and "--udp" in out and "--interactive" in out


@pytest.mark.parametrize(
    ("args", "match"),
    [
        (["--to", "0.3,0"], "--to: Expected 'x y z'"),
        (["--to", "nan,0,0.2"], "--to: Expected finite"),
        (["--to", "3,0,0.2"], "--to: Expected a point inside the box"),
        (["--to", "0.3,0,0.2", "--rpy", "1,2"], "--rpy"),
        (["--stdin", "--rpy", "0,0,0"], "--rpy goes with --to"),
        (["--to", "0.3,0,0.2", "--port", "/dev/ttyUSB9", "--fast"], "--port: --fast needs the simulated bus"),
        (["--udp", "nope"], "--udp: Expected"),
        (["--to", "0.3,0,0.2", "--timeout", "0"], "--timeout: Expected a number > 0"),
        (["--stdin", "--max-lag", "-1"], "--max-lag: Expected a number > 0"),
        (["--to", "0.3,0,0.2", "--max-speed", "-1"], "--max-speed"),
        (["--to", "0.3,0,0.2", "--max-speed", "fast"], "--max-speed: Expected a number"),
        (["--to", "0.3,0,0.2", "--box", "1,2"], "--box: Expected 6"),
        (["--to", "0.3,0,0.2", "--box", "0,0,0,1,1,-1"], "--box: Expected each minimum"),
        (["--to", "0.3,0,0.2", "--margin", "-1"], "--margin"),
        (["--to", "0.3,0,0.2", "--base-pose", "1,2,3"], "--base-pose goes with --frame world"),
        (["--to", "0.3,0,0.2", "--frame", "world", "--base-pose", "1,2"], "--base-pose: Expected 3 or 6"),
        (["--to", "0.3,0,0.2", "--frame", "world", "--base-pose", "0,nan,0"], "--base-pose: Expected finite"),
        (["--to", "0.3,0,0.2", "--frame", "world", "--base-pose", "0,0,0,0,inf,0"], "--base-pose: Expected finite"),
        (["--interactive", "--fast"], "--fast: --interactive runs in real time"),
        (["--interactive"], "--interactive needs a terminal"),
        (["--to", "0.3,0,0.2", "--rate", "0"], "--rate"),
        (["--to", "0.3,0,0.2", "--arm", "nosuch"], "nosuch"),
        (["--to", "0.3,0,0.2", "--telemetry", "-", "--json"], "--telemetry"),
    ],
    ids=lambda v: "_".join(v)[:40] if isinstance(v, list) else None,
)
def test_bad_input_exits_2_with_one_line(capsys, args, match):
    code, out, err = teleop(capsys, *args)
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("retarget: "), err
    assert re.search(match, lines[0]), lines[0]


def test_telemetry_on_stdout_is_the_csv_alone_and_the_result_line_goes_to_stderr(registered, capsys, monkeypatch):
    stdin_bytes(monkeypatch, b"0.3 0.0 0.2\n")
    code, out, err = teleop(capsys, "--stdin", "--port", registered[1], "--fast", "--telemetry", "-")
    assert code == 0, err
    rows = list(csv.reader(io.StringIO(out)))
    assert rows[0][:3] == ["time_s", "clip_time_s", "tick"] and len(rows) > 10
    assert all(len(row) == len(rows[0]) for row in rows)  # every line of stdout is a telemetry row
    assert "target 0.3000 0.0000 0.2000 m  reached " in err
