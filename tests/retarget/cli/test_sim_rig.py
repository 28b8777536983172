"""``retarget sim --rig``: one simulated bus per rig arm, each on its own TCP port (or pty), NAME=WHERE lines."""

from __future__ import annotations

import os
import re
import select
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import serial

from retarget.cli import main
from sim.protocol import PacketParser, build_instruction

WRITE, READ = 0x03, 0x02
TORQUE_ENABLE = 64


def start(*argv: str) -> tuple[subprocess.Popen, dict[str, str]]:
    proc = subprocess.Popen(
        [sys.executable, "-m", "retarget", "sim", *argv], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    ready, _, _ = select.select([proc.stdout], [], [], 30.0)
    if not ready:
        proc.kill()
        pytest.fail(f"retarget sim printed nothing in 30 s: {proc.communicate()[1]}")
    lines = {}
    for _ in range(2):  # both lines are printed (and flushed) together, once every server is up
        name, _, where = proc.stdout.readline().strip().partition("=")
        lines[name] = where
    return proc, lines


def arm_processes(pid: int, n: int) -> dict[str, int]:
    """The ``n`` serving processes of the ``retarget sim --rig`` process ``pid``: ``sim-NAME`` (their name) -> pid."""
    children = Path(f"/proc/{pid}/task/{pid}/children")
    if not children.exists():
        pytest.skip("needs Linux's /proc/PID/task/PID/children")
    for _ in range(200):  # they are started right after the NAME=WHERE lines
        pids = [int(p) for p in children.read_text().split()]
        names = {Path(f"/proc/{p}/comm").read_text().strip(): p for p in pids}
        if len(names) == n and all(name.startswith("sim-") for name in names):
            return names
        time.sleep(0.05)
    pytest.fail(f"expected {n} processes named sim-NAME under {pid}, got {names}")


def request(port: serial.Serial, packet: bytes, reply_length: int) -> list:
    port.write(packet)
    return PacketParser().feed(port.read(reply_length))


def test_each_arm_of_a_rig_has_its_own_bus_on_its_own_port():
    proc, where = start("--rig", "wx250s-pair", "--tcp", "127.0.0.1:0", "--no-wire")
    try:
        assert list(where) == ["left", "right"] and where["left"] != where["right"]
        assert all(url.startswith("socket://127.0.0.1:") for url in where.values())
        left, right = (serial.serial_for_url(where[name], timeout=5) for name in ("left", "right"))
        assert [p.id for p in request(left, build_instruction(1, 0x01), 14)] == [1]  # ping servo 1 on each bus
        assert [p.id for p in request(right, build_instruction(1, 0x01), 14)] == [1]
        # torque on for servo 1 on the left bus only: the right bus's servo 1 is another servo
        request(left, build_instruction(1, WRITE, bytes([TORQUE_ENABLE, 0, 1])), 11)
        read = build_instruction(1, READ, bytes([TORQUE_ENABLE, 0, 1, 0]))
        assert request(left, read, 12)[0].params == b"\x00\x01"  # no error, torque on
        assert request(right, read, 12)[0].params == b"\x00\x00"  # no error, torque off
        left.close()
        right.close()
        arms = arm_processes(proc.pid, 2)
    finally:
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(timeout=10) == 0
        assert "stopped" in proc.stderr.read()
    assert set(arms) == {"sim-left", "sim-right"}  # each arm served by its own process, gone with the command
    assert not any(
        Path(f"/proc/{pid}").exists() and "sim-" in Path(f"/proc/{pid}/comm").read_text() for pid in arms.values()
    )


def test_when_one_arms_server_dies_the_rig_stops_with_status_1_and_one_line_naming_it():
    proc, _ = start("--rig", "wx250s-pair", "--tcp", "127.0.0.1:0", "--no-wire")
    try:
        arms = arm_processes(proc.pid, 2)
        os.kill(arms["sim-right"], signal.SIGKILL)
        assert proc.wait(timeout=10) == 1
        err = proc.stderr.read().splitlines()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert err[-1] == "retarget sim: arm right: its server process ended (killed by signal 9); stopped the other arms"
    assert (
        not Path(f"/proc/{arms['sim-left']}").exists()
        or "sim-" not in Path(f"/proc/{arms['sim-left']}/comm").read_text()
    )


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--arm", "koch"], r"--arm: Expected no such option with --rig \(each arm's servos come from the rig file\)"),
        (
            ["--hand", "2:release"],
            r"--hand: Expected no such option with --rig \(it is one arm's\) \(got \['2:release'\]\)",
        ),
        (["--control", "127.0.0.1:0"], r"--control: Expected no such option with --rig"),
        (["--drop", "x"], r"--drop: Expected a number \(got 'x'\)"),
    ],
    ids=["arm", "hand", "control", "bad-fault"],
)
def test_one_arm_options_and_bad_values_are_refused_with_one_line(capsys, argv, message):
    assert main(["sim", "--rig", "aloha", *argv]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.count("\n") == 1
    assert re.search(message, err), err
