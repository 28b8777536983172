"""``retarget teleop --rig``: a two-arm stream on stdin, one shot, bad input, a fault on one arm, the rig's move to
rest at the end and its telemetry."""

from __future__ import annotations

import csv
import io
import json
import random
import re
import signal

import numpy as np
import pytest

import sim
from retarget.cli import main
from retarget.control.clock import VirtualClock
from retarget.rig import load_rig
from tests.helpers import (
    SignalAfterSyncWrites,
    garbage,
    goal_registers,
    goal_writes,
    servo_joint_angles,
    torques,
    wx250s_tool,
)

LINE = re.compile(
    r"^(left|right): target (\S+) (\S+) (\S+) m  reached (\S+) (\S+) (\S+) m \(world frame\)  residual (\S+) mm  "
    r"(reached|NOT reached \(nearest point\)) \(tolerance 5 mm\)$"
)


def teleop(capsys, *args: str) -> tuple[int, str, str]:
    code = main(["teleop", "--rig", "wx250s-pair", *args])
    out, err = capsys.readouterr()
    return code, out, err


def stdin_lines(monkeypatch, lines: list[bytes]) -> None:
    monkeypatch.setattr("sys.stdin", io.TextIOWrapper(io.BytesIO(b"\n".join(lines) + b"\n")))


def world_tool(rig_arm, q):
    """Independent FK of a wx250s (tests.helpers) plus the base's offset: the rig's bases are not turned."""
    return wx250s_tool(q) + np.asarray(rig_arm.placement.xyz)


@pytest.fixture
def rig_sims():
    """Each arm of wx250s-pair simulated on ONE virtual clock, registered: ``(rig, {arm: simbus}, --port args)``;
    ``faults``: the right arm's sim.Faults options."""
    rig = load_rig("wx250s-pair")
    made: list[str] = []

    def make(**faults):
        clock = VirtualClock()
        sims, ports = {}, []
        for a in rig.arms:
            options = {"wire": True, **(faults if a.name == "right" else {})}
            sims[a.name] = sim.SimBus.from_arm(a.arm, clock=clock, faults=sim.Faults.from_options(**options))
            made.append(f"test-rig-teleop-{a.name}-{id(sims[a.name])}")
            ports += ["--port", f"{a.name}={sim.register(made[-1], sims[a.name])}"]
        return rig, sims, ports

    yield make
    for name in made:
        sim.unregister(name)


def test_dry_run_stdin_stream_with_garbage_exit_0_one_line_per_arm(capsys, monkeypatch):
    junk = garbage(random.Random(7), 30)
    stdin_lines(monkeypatch, [b"left 0.3 0.35 0.2 right 0.3 -0.35 0.2", *junk[:15], b"right 0.25 -0.3 0.25",
                              *junk[15:], b'{"left": {"x": 0.32, "y": 0.28, "z": 0.18}}'])  # fmt: skip
    code, out, err = teleop(capsys, "--stdin", "--dry-run")
    assert code == 0, err
    lines = out.splitlines()
    assert [LINE.match(line).group(1) for line in lines] == ["left", "right"]
    expected = {"left": (0.32, 0.28, 0.18), "right": (0.25, -0.3, 0.25)}
    for line in lines:
        m = LINE.match(line)
        target, reached = np.array(m.groups()[1:4], float), np.array(m.groups()[4:7], float)
        np.testing.assert_allclose(target, expected[m.group(1)], atol=1e-4)
        assert np.linalg.norm(reached - target) < 5e-3 and m.group(9) == "reached"
    assert "teleop (dry run): --stdin on rig wx250s-pair" in err and "messages: 30 rejected" in err


def test_stream_on_simulated_buses_each_arm_ends_at_its_own_target(capsys, monkeypatch, rig_sims):
    rig, sims, ports = rig_sims()
    junk = garbage(random.Random(3), 40)
    stream = [b"left 0.3 0.35 0.2 right 0.3 -0.35 0.2", *junk[:20], b"left 0 0.3 0.02",  # left: at its base
              b'{"right": {"x": 0.28, "y": -0.25, "z": 0.27}}', *junk[20:], b"left 0.33,0.32,0.16"]  # fmt: skip
    stdin_lines(monkeypatch, stream)
    code, out, err = teleop(capsys, "--stdin", "--no-filter", "--fast", "--json", *ports)
    assert code == 0, err
    doc = json.loads(out)
    t = doc["teleop"]
    assert t["reached"] is True and sum(t["rejected"].values()) == 40
    last = {"left": (0.33, 0.32, 0.16), "right": (0.28, -0.25, 0.27)}
    for a in rig.arms:
        arm_doc = t["arms"][a.name]
        reached = world_tool(a, servo_joint_angles(sims[a.name], a.arm))  # from the servos' registers
        np.testing.assert_allclose(reached, last[a.name], atol=3e-3)
        np.testing.assert_allclose(arm_doc["reached_world_m"], reached, atol=2e-3)
        np.testing.assert_allclose(arm_doc["target_world_m"], last[a.name], atol=1e-6)
        assert arm_doc["targets_received"] == arm_doc["targets_reached"] == 2
    assert t["arms"]["left"]["rejected"]["blocked"] == 1 and sum(t["arms"]["right"]["rejected"].values()) == 0
    assert all(v == 1 for s in sims.values() for v in torques(s).values())  # default shutdown: hold


def test_garbage_only_moves_neither_arm(capsys, monkeypatch, rig_sims):
    rig, sims, ports = rig_sims()
    assert teleop(capsys, "--to", "left 0.3 0.35 0.2 right 0.3 -0.35 0.2", "--fast", *ports)[0] == 0
    goals = {name: goal_registers(s) for name, s in sims.items()}
    stdin_lines(monkeypatch, [*garbage(random.Random(5), 200), b"left 0.3 0.35", b"middle 0.3 0 0.2",
                              b"left 0.3 0.3 0.2 right 9 9 9", b"right nan 0 0"])  # fmt: skip
    code, out, err = teleop(capsys, "--stdin", "--fast", "--json", *ports)
    assert code == 0, err
    t = json.loads(out)["teleop"]
    assert sum(t["rejected"].values()) == 203 and t["arms"]["right"]["rejected"]["out_of_box"] == 1
    assert all(t["arms"][n]["targets_received"] == 0 for n in ("left", "right"))
    assert {name: goal_registers(s) for name, s in sims.items()} == goals


def test_one_shot_out_of_reach_exits_3_at_the_nearest_point(capsys):
    code, out, err = teleop(capsys, "--to", "left 0.3 0.35 0.2 right 0.78 -0.3 0.2", "--dry-run")
    assert code == 3, err
    left, right = (LINE.match(line) for line in out.splitlines())
    assert left.group(9) == "reached" and right.group(9).startswith("NOT reached")
    assert float(right.group(8)) > 50  # mm: stretched out toward it


def test_a_fault_on_one_arm_stops_both_through_the_shutdown_sequence(capsys, monkeypatch, rig_sims):
    rig, sims, ports = rig_sims(hwerror=["4:overload@1.5"])  # the right elbow overloads mid-run
    stdin_lines(monkeypatch, [b"left 0.3 0.35 0.2 right 0.3 -0.35 0.2", b"left 0.25 0.2 0.3 right 0.25 -0.2 0.3"])
    code, out, err = teleop(capsys, "--stdin", "--fast", "--shutdown", "off", "--timeout", "60", *ports)
    assert code == 4, err
    assert re.search(r"right: servo 4: hardware error: overload", err)
    assert all(v == 0 for s in sims.values() for v in torques(s).values())  # both arms: torque off


@pytest.mark.parametrize(
    "args, match",
    [
        pytest.param(["--to", "middle 0.3 0 0.2", "--dry-run"], r"to: Expected an arm of the rig", id="unknown-arm"),
        pytest.param(["--to", "0.3,0,0.2", "--dry-run"], r"to: Expected 'NAME x y z", id="one-arm-form"),
        pytest.param(["--to", "left 5 0 0.2", "--dry-run"], r"to\.left: Expected a point inside the box",
                     id="out-of-box"),
        pytest.param(["--stdin", "--arm", "koch"], r"--arm: Expected no such option with --rig", id="arm"),
        pytest.param(["--stdin", "--rpy", "0,90,0"], r"--rpy", id="rpy"),
        pytest.param(["--stdin", "--frame", "world"], r"--frame: Expected no --frame with --rig", id="frame"),
        pytest.param(["--to", "left 0.3 0.35 0.2", "--fast", "--shutdown", "rest", "--keep-out",
                      "sphere:0.15,0,0.15,0.08"],
                     r"collision: Expected a collision-free move of the rig's arms to rest", id="rest-blocked"),
        pytest.param(["--interactive", "--dry-run"], r"--interactive: --interactive needs a terminal",
                     id="interactive-no-terminal"),
        pytest.param(["--interactive", "--fast"], r"--fast: --interactive runs in real time", id="interactive-fast"),
        pytest.param(["--stdin", "--json", "--telemetry", "-"], r"--telemetry: --telemetry - and --json",
                     id="telemetry-json"),
        pytest.param(["--stdin", "--dry-run", "--fast"], r"--fast: --dry-run uses no bus", id="dry-fast"),
        pytest.param(["--stdin", "--port", "middle=sim://wx250s"], r"--port: Expected one of the rig's arms left",
                     id="port-arm"),
        pytest.param(["--stdin", "--port", "/dev/null"], r"--port: Expected NAME=PORT with --rig", id="bare-port"),
        pytest.param(["--stdin", "--port", "left=/dev/null", "--fast"], r"--port: --fast needs every arm on a sim",
                     id="fast-real"),
    ],
)  # fmt: skip
def test_bad_input_exits_2_with_one_line(capsys, args, match):
    code, out, err = teleop(capsys, *args)
    assert code == 2
    assert re.search(match, err), err
    assert err.count("\n") == 1 and "Traceback" not in err


def test_dry_run_needs_the_rig(capsys):
    assert main(["teleop", "--stdin", "--dry-run"]) == 2
    assert re.search(r"--dry-run: --dry-run goes with --rig", capsys.readouterr().err)


# ------------------------------------------------------------------ the end: the move to rest, the telemetry


def read_csv(path) -> list[dict[str, str]]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def assert_tracking_is_fk(rig, rows, targets):
    """Each arm's ``tracking_mm`` (where it has a target): an independent FK of its ``_cmd_rad`` columns to its
    target as sent (world frame)."""
    for a in rig.arms:
        p = f"{a.name}/"
        tracked = [r for r in rows if r[f"{p}tracking_mm"] != ""]
        assert len(tracked) >= len(rows) - 2, a.name  # from the first tick that had the target
        for r in tracked:
            q = np.array([float(r[f"{p}{j}_cmd_rad"]) for j in a.arm.joint_names])
            expected = np.linalg.norm(world_tool(a, q) - targets[a.name]) * 1e3
            assert float(r[f"{p}tracking_mm"]) == pytest.approx(expected, abs=2e-3), (a.name, r["tick"])


def test_dry_run_telemetry_one_row_per_tick_each_arm_prefixed(capsys):
    targets = {"left": (0.3, 0.35, 0.2), "right": (0.25, -0.3, 0.25)}
    code, out, err = teleop(capsys, "--to", "left 0.3 0.35 0.2 right 0.25 -0.3 0.25", "--dry-run", "--telemetry", "-")
    assert code == 0, err
    table = out.splitlines()  # the CSV alone: each arm's result line goes to stderr (as one arm's teleop)
    assert [m.group(1) for m in map(LINE.match, err.splitlines()) if m] == ["left", "right"]
    assert all(len(line.split(",")) == len(table[0].split(",")) for line in table)
    rows = list(csv.DictReader(table))
    ticks = int(re.search(r"on rig wx250s-pair: (\d+) ticks", err).group(1))
    assert len(rows) == ticks > 50 and list(rows[0])[10:13] == ["left/target_x_m", "left/target_y_m", "left/target_z_m"]
    assert all(r["left/waist_present_rad"] == "" and r["right/wrist_rotate_present_rad"] == "" for r in rows)
    assert_tracking_is_fk(load_rig("wx250s-pair"), rows, targets)
    assert all(float(rows[-1][f"{n}/tracking_mm"]) < 5 for n in targets)  # both reached their own


def test_a_fault_mid_run_keeps_the_telemetry_up_to_it(capsys, monkeypatch, rig_sims, tmp_path):
    rig, sims, ports = rig_sims(hwerror=["4:overload@0.6"])  # the right elbow overloads 0.6 s in
    path = tmp_path / "rig.csv"
    stdin_lines(monkeypatch, [b"left 0.3 0.35 0.2 right 0.3 -0.35 0.2"])
    code, out, err = teleop(capsys, "--stdin", "--fast", "--max-speed", "0.05", "--shutdown", "off", "--telemetry",
                            str(path), *ports)  # fmt: skip
    assert code == 4 and re.search(r"right: servo 4: hardware error: overload", err), err
    rows = read_csv(path)
    assert 40 < len(rows) and 0.4 < float(rows[-1]["time_s"]) <= 0.6  # 0.05 m/s: still moving at the fault
    assert [int(r["tick"]) for r in rows] == list(range(len(rows)))
    assert all(r["right/waist_present_rad"] != "" for r in rows)
    assert_tracking_is_fk(rig, rows, {"left": (0.3, 0.35, 0.2), "right": (0.3, -0.35, 0.2)})
    assert 50 < float(rows[-1]["left/tracking_mm"]) < float(rows[0]["left/tracking_mm"])  # on its way


def test_sigterm_mid_run_then_both_arms_go_to_rest_together(capsys, rig_sims, tmp_path):
    rig, sims, ports = rig_sims()
    right = sims["right"]
    right.log = SignalAfterSyncWrites(40, signal.SIGTERM, maxlen=right.log.maxlen)
    path = tmp_path / "rig.csv"
    code, out, err = teleop(capsys, "--to", "left 0.3 0.35 0.2 right 0.3 -0.35 0.2", "--fast", "--max-speed", "0.05",
                            "--shutdown", "rest", "--json", "--telemetry", str(path), *ports)  # fmt: skip
    assert code == 143, err
    assert "stopping on SIGTERM" in err
    summary = json.loads(out)
    assert summary["interrupted"] is True
    rows = read_csv(path)
    assert len(rows) == summary["ticks"] and 20 < len(rows) < 80  # every tick that ran, flushed
    assert_tracking_is_fk(rig, rows, {"left": (0.3, 0.35, 0.2), "right": (0.3, -0.35, 0.2)})
    for a in rig.arms:  # the rig's move to rest played through the tick loop (many goals, not the driver's one)
        assert len(goal_writes(sims[a.name])) - len(rows) > 20, a.name
        np.testing.assert_allclose(servo_joint_angles(sims[a.name], a.arm), a.arm.rest, atol=0.06)
        assert set(torques(sims[a.name]).values()) == {0}
    assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL
