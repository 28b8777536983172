"""ROBOTIS-style example programs (ping, read/write, sync read/write; see tests.helpers.ROBOTIS_EXAMPLES) run as
their own processes against the simulator on a pty, unchanged but for the port name, driven through their
"Press any key" prompts on a terminal: two factory-fresh XL430-W250 (IDs 1 and 2, 57600 baud, the wire model on,
as ``retarget sim`` serves by default)."""

from __future__ import annotations

import re

import pytest

import sim
from retarget.control.clock import MonotonicClock
from sim.server import PtyServer
from tests.helpers import needs_pty, robotis_example, run_with_keys

pytestmark = [pytest.mark.pty, needs_pty]

PROMPT = b"Press any key to continue! (or press ESC to quit!)"
ESC = b"\x1b"
FAILURES = ("There is no status packet", "Failed", "failed", "Traceback", "[RxPacketError]", "[TxRxResult]")


@pytest.fixture
def served():
    bus = sim.SimBus.from_ids([1, 2], "XL430-W250", clock=MonotonicClock(), baud=57600, faults=sim.Faults(wire=True))
    with PtyServer(bus) as server:
        yield bus, server.path


def run(name: str, device: str, tmp_path, keys: list[bytes]) -> str:
    script = tmp_path / f"{name}.py"
    script.write_text(robotis_example(name, device))
    out = run_with_keys(script, keys, prompt=PROMPT)
    assert not [line for line in out.splitlines() if line.startswith(FAILURES)], out
    assert "Succeeded to open the port" in out and "Succeeded to change the baudrate" in out, out
    return out


def test_ping(served, tmp_path):
    _, device = served
    out = run("ping", device, tmp_path, [])
    assert "[ID:001] ping Succeeded. Dynamixel model number : 1060" in out, out


def test_read_write_moves_to_the_goal_and_leaves_torque_off(served, tmp_path):
    bus, device = served
    out = run("read_write", device, tmp_path, [b" ", ESC])
    assert "Dynamixel has been successfully connected" in out
    readings = [int(m) for m in re.findall(r"\[ID:001\] GoalPos:000  PresPos:(\d+)", out)]
    assert len(readings) > 3 and readings[0] > readings[-1] and readings[-1] <= 20, out  # from 2048 down to goal 0
    assert out.count(PROMPT.decode()) == 2
    assert not bus.servo(1).torque and bus.servo(1).get("Present Position") <= 20


def test_sync_read_write_moves_both_servos(served, tmp_path):
    bus, device = served
    out = run("sync_read_write", device, tmp_path, [b" ", ESC])
    assert "Dynamixel#1 has been successfully connected" in out and "Dynamixel#2 has been successfully connected" in out
    last = re.findall(r"\[ID:001\] GoalPos:000  PresPos:(\d+)\t\[ID:002\] GoalPos:000  PresPos:(\d+)", out)[-1]
    assert min(map(int, last)) <= 20, out
    assert [s.torque for s in bus.servos] == [False, False]
    assert all(s.get("Present Position") <= 40 for s in bus.servos)
