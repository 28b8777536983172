"""``retarget replay --rig`` end to end: both arms of wx250s-pair on simulated buses sharing one virtual clock
(``--fast``), a fault on one arm's bus, a stop signal, and bad input exits 2 with one line."""

from __future__ import annotations

import csv
import json
import re
import signal

import numpy as np
import pytest

import retarget
import sim
from retarget.cli import main
from retarget.control.clock import VirtualClock
from sim.faults import Faults
from tests.helpers import SignalAfterSyncWrites, servo_angles, torque, wx250s_tool

RIG = "wx250s-pair"
BASE_Y = {"left": 0.3, "right": -0.3}  #: config/rigs/wx250s-pair.toml: each base's y in the world, no rotation
NAMES = ("left", "right")


def replay(capsys, *args: str) -> tuple[int, str, str]:
    code = main(["replay", "--rig", RIG, *args])
    out, err = capsys.readouterr()
    return code, out, err


def read_csv(path) -> list[dict[str, str]]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


@pytest.fixture
def arm() -> retarget.Arm:
    return retarget.load_arm("wx250s")


@pytest.fixture
def pair(arm):
    """``pair(right=Faults options)``: both arms' simulated wx250s (wire model on) on ONE virtual clock, registered
    as ``sim://@NAME``; returns ``(sims by arm, --port arguments)``.  Unregistered after the test."""
    urls: list[str] = []

    def make(**right: list[str]) -> tuple[dict[str, sim.SimBus], list[str]]:
        clock = VirtualClock()
        sims = {
            name: sim.SimBus.from_arm(
                arm, clock=clock, faults=Faults.from_options(wire=True, **(right if name == "right" else {}))
            )  # fmt: skip
            for name in NAMES
        }
        ports: list[str] = []
        for name, simbus in sims.items():
            urls.append(sim.register(f"test-rig-{name}-{id(simbus)}", simbus))
            ports += ["--port", f"{name}={urls[-1]}"]
        return sims, ports

    yield make
    for url in urls:
        sim.unregister(url)


def assert_rested(simbus: sim.SimBus, arm: retarget.Arm) -> None:
    assert torque(simbus, arm) == [0] * 8
    np.testing.assert_allclose(servo_angles(simbus, arm), arm.rest, atol=0.06)


def world(rows: list[dict[str, str]], name: str, what: str, columns: list[str]) -> np.ndarray:
    """``(n_rows, len(columns))`` floats of arm ``name``'s columns ``<name>/<column>``."""
    return np.array([[float(r[f"{name}/{c}"]) for c in columns] for r in rows])


@pytest.mark.shared
def test_a_shared_clip_on_both_arms_each_following_its_own_hand(arm, pair, capsys, tmp_path, shared_bvh):
    sims, ports = pair()
    csv_path = tmp_path / "rig.csv"
    clip = shared_bvh / "motion_dance.bvh"
    code, out, err = replay(capsys, str(clip), *ports, "--fast", "--json", "--start", "120f", "--end", "2",
                            "--lead-in", "2", "--telemetry", str(csv_path))  # fmt: skip
    assert code == 0, err
    summary = json.loads(out)
    assert summary["rig"]["ticks"] == 101 and summary["rig"]["clip"] == "motion_dance.bvh"
    assert summary["rig"]["bus_errors"] == 0 and not summary["rig"]["interrupted"]
    assert sorted(summary["arms"]) == ["left", "right"]
    assert all(s["ik_converged_pct"] > 95 for s in summary["arms"].values())
    for name in NAMES:  # the human lines: as export --rig prints them
        assert re.search(rf"^  {name}: IK [0-9.]+% converged, velocity-limited \d+, tracking error p95", err, re.M)
    # --shutdown rest (default): the rig's move to rest, then every servo's torque off, on both arms
    for name in NAMES:
        assert_rested(sims[name], arm)
    rows = read_csv(csv_path)
    assert {f"{n}/{j}_{k}_rad" for n in NAMES for j in arm.joint_names for k in ("cmd", "present")} <= set(rows[0])
    clip_rows = [r for r in rows if r["lead_in"] == "0"]
    assert len(clip_rows) == 101 and len(rows) - 101 == summary["rig"]["lead_in_ticks"] > 0
    # each arm's tool point (an FK of its own, in the world) follows its own side's targets, not the other's
    xyz = ["target_x_m", "target_y_m", "target_z_m"]
    targets = {n: world(clip_rows, n, "target", xyz) + [0, BASE_Y[n], 0] for n in NAMES}
    for name, other in (("left", "right"), ("right", "left")):
        q = world(clip_rows, name, "cmd", [f"{j}_cmd_rad" for j in arm.joint_names])
        tool = np.array([wx250s_tool(qi) for qi in q]) + [0, BASE_Y[name], 0]
        own = np.linalg.norm(tool - targets[name], axis=1)
        across = np.linalg.norm(tool - targets[other], axis=1)
        assert np.median(own) < 0.03, (name, np.median(own))
        assert np.all(own < across), name
        present = world(clip_rows, name, "present", [f"{j}_present_rad" for j in arm.joint_names])
        assert np.max(np.abs(present[-1] - q[-1])) < 0.1  # the servos were there


def test_a_fault_on_the_right_arm_stops_both_through_their_shutdown(arm, pair, capsys, caplog, tmp_path):
    """Servo 4 of the right arm overloads 1.5 s (bus time) in: exit 4, one line naming the right arm, the summary
    so far and the error as JSON; both arms end torque off (the left at rest); the telemetry is on disk up to the
    failure."""
    sims, ports = pair(hwerror=["4:overload@1.5"])
    csv_path = tmp_path / "rig.csv"
    code, out, err = replay(capsys, *ports, "--fast", "--json", "--end", "1", "--lead-in", "2", "--telemetry",
                            str(csv_path))  # fmt: skip
    assert code == 4
    last = err.strip().splitlines()[-1]
    assert re.fullmatch(r"retarget: right: servo 4: hardware error: overload; .*", last), last
    assert "Traceback" not in err
    summary = json.loads(out)
    assert summary["error"]["message"].startswith("right: servo 4: ") and summary["error"]["ids"] == [4]
    assert 0 < summary["rig"]["ticks"] < 101 and summary["rig"]["lead_in_ticks"] > 0
    assert_rested(sims["left"], arm)
    assert torque(sims["right"], arm) == [0] * 8
    rows = read_csv(csv_path)
    assert all(None not in r.values() and None not in r for r in rows)  # every row written whole
    clip_rows = [r for r in rows if r["lead_in"] == "0"]
    assert len(rows) - len(clip_rows) == summary["rig"]["lead_in_ticks"]
    assert summary["rig"]["ticks"] - 1 <= len(clip_rows) <= summary["rig"]["ticks"]
    assert all(r["right/waist_present_rad"] != "" for r in rows)


def test_the_rig_files_ports_share_one_clock_and_a_port_override_carries_a_fault(capsys):
    """No --port: each arm on its rig file's ``sim://wx250s``, built on the loop's one virtual clock; a sim:// URL
    for one arm replaces its port, and that bus's fault (timed on the shared clock) ends the run naming it."""
    code, out, err = replay(capsys, "--fast", "--json", "--end", "0.3", "--lead-in", "0", "--shutdown", "off")
    assert code == 0, err
    assert json.loads(out)["rig"]["ticks"] == 31
    code, out, err = replay(capsys, "--fast", "--end", "1", "--lead-in", "0", "--shutdown", "off", "--port",
                            "right=sim://wx250s?hwerror=2:overheating@0.3")  # fmt: skip
    assert code == 4
    assert re.fullmatch(r"retarget: right: servo 2: hardware error: overheating; .*", err.strip().splitlines()[-1]), err


def test_a_dry_run_writes_both_arms_telemetry_with_nothing_read_back(capsys):
    code, out, err = replay(capsys, "--dry-run", "--fast", "--end", "0.2", "--telemetry", "-")
    assert code == 0, err
    rows = list(csv.DictReader(out.splitlines()))
    assert len(rows) == 21 and all(r["lead_in"] == "0" for r in rows)
    assert all(r["left/waist_present_rad"] == "" and r["right/waist_cmd_rad"] != "" for r in rows)
    assert "dry run: demo.bvh on wx250s-pair" in err


def test_sigterm_in_the_lead_in_stops_at_a_tick_and_both_arms_go_to_rest(arm, pair, capsys):
    sims, ports = pair()
    right = sims["right"]
    right.log = SignalAfterSyncWrites(40, signal.SIGTERM, maxlen=right.log.maxlen)
    # --max-ticks bounds the --loop run: without the signal it would end with exit 0 and fail below
    code, out, err = replay(capsys, *ports, "--fast", "--loop", "--end", "0.5", "--max-ticks", "2000", "--json",
                            "--lead-in", "2")  # fmt: skip
    assert right.log.sync_writes >= 40
    assert code == 143, err
    summary = json.loads(out)
    # at 2 rad/s the lead-in to the clip's first poses is over 100 ticks: the signal lands in it, before any clip tick
    assert summary["rig"]["interrupted"] is True and summary["rig"]["ticks"] == 0
    assert summary["rig"]["lead_in_ticks"] >= 30
    assert "stopping on SIGTERM" in err
    for name in NAMES:
        assert_rested(sims[name], arm)
    assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL  # the handler was put back


@pytest.mark.parametrize(
    ("args", "match"),
    [
        (["--port", "middle=sim://wx250s"], r"--port: Expected one of the rig's arms left, right \(got 'middle'\)"),
        (["--port", "sim://wx250s"], r"--port: Expected NAME=PORT with --rig, NAME one of left, right"),
        (["--port", "left=sim://wx250s", "--port", "left=sim://vx300s"], r"--port: Expected one port for arm 'left'"),
        (
            ["--fast", "--port", "right=/dev/ttyUSB1"],
            r"--port: --fast needs every arm on a simulated bus \(sim://\), not a real port "
            r"\(got 'right=/dev/ttyUSB1'\)",
        ),
        (["--arm", "vx300s"], r"--arm: Expected no arm or side with --rig"),
        (["--side", "left"], r"--side: Expected no arm or side with --rig"),
        (["--gripper", "close"], r"--gripper: Expected no --gripper with --rig"),
        (["--dry-run", "--port", "left=sim://wx250s"], r"--port: --dry-run uses no bus"),
        (["--fast", "--port", "right=sim://wx250s?bogus=1"], r"unknown option\(s\) bogus"),
        (["--fast", "--port", "right=sim://@no-such-bus"], r"--port: no SimBus registered as 'no-such-bus'"),
        (["--json", "--telemetry", "-"], r"--telemetry: --telemetry - and --json both write to stdout"),
        (
            ["--keep-out", "sphere:0.15,0,0.15,0.08", "--fast", "--end", "0.1"],
            r"collision: Expected a collision-free move of the rig's arms to rest",
        ),
    ],
    ids=lambda v: " ".join(v) if isinstance(v, list) else None,
)
def test_bad_input_exits_2_with_one_line(capsys, args, match):
    code, out, err = replay(capsys, *args)
    assert code == 2
    assert out == ""
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert re.search(match, lines[0]), lines[0]


@pytest.mark.parametrize(
    ("args", "match"),
    [
        (["--port", "left=sim://wx250s"], r"--port: Expected a port; NAME=PORT gives a rig arm's port and needs --rig"),
        (["--port", "sim://wx250s", "--port", "sim://vx300s"], r"--port: Expected one --port"),
    ],
    ids=["named-port", "two-ports"],
)
def test_without_rig_port_keeps_its_one_arm_meaning(capsys, args, match):
    code = main(["replay", "--fast", *args])
    _, err = capsys.readouterr()
    assert code == 2 and re.fullmatch(rf"retarget: {match}.*", err.strip()), err


def test_help_has_a_rig_example(capsys):
    with pytest.raises(SystemExit):
        main(["replay", "--help"])
    out, _ = capsys.readouterr()
    assert "--rig aloha" in out and "--port left=" in out
