"""``retarget teleop --rig``: a two-arm stream on stdin, one shot, bad input, and a fault on one arm."""

from __future__ import annotations

import io
import json
import random
import re

import numpy as np
import pytest

import sim
from retarget.cli import main
from retarget.control.clock import VirtualClock
from retarget.rig import load_rig
from tests.helpers import garbage, goal_registers, servo_joint_angles, torques, wx250s_tool

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
        pytest.param(["--stdin", "--shutdown", "rest"], r"--shutdown: Expected hold or off with --rig", id="rest"),
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
