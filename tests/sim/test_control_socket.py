"""The control socket of ``retarget sim``: hand, release and status commands over loopback TCP and a unix socket,
checked against what the plain dynamixel-sdk reads over the pty; and ``retarget sim --control`` as a process."""

from __future__ import annotations

import json
import re
import select
import signal
import socket
import subprocess
import sys
import time

import pytest
from dynamixel_sdk import COMM_SUCCESS, PacketHandler, PortHandler

import sim
from retarget.control.clock import MonotonicClock, VirtualClock
from retarget.errors import ConfigError
from sim.control import MAX_LINE, ControlServer, parse_address
from sim.hand_commands import HandSchedule
from sim.server import PtyServer
from tests.helpers import address, needs_pty


class Client:
    """A line client of the control socket."""

    def __init__(self, where: str):
        if where.startswith("unix:"):
            self.sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
            self.sock.connect(where.removeprefix("unix:"))
        else:
            host, _, port = where.rpartition(":")
            self.sock = socket.create_connection((host, int(port)), timeout=10)
        self.sock.settimeout(10)
        self.file = self.sock.makefile("rw", encoding="utf-8")

    def ask(self, line: str) -> dict:
        self.file.write(line + "\n")
        self.file.flush()
        return json.loads(self.file.readline())

    def close(self) -> None:
        self.file.close()
        self.sock.close()


@pytest.fixture
def control():
    """A ControlServer on a two-servo bus (virtual clock), not served: commands run through ``execute``."""
    bus = sim.SimBus.from_ids([1, 2], clock=VirtualClock())
    server = ControlServer("127.0.0.1:0", HandSchedule(bus, []))
    yield server
    server.close()


@pytest.mark.parametrize(
    ("line", "match"),
    [
        pytest.param("wave 2", r"Expected a command: hand, release, status, help \(got 'wave 2'\)", id="verb"),
        pytest.param("hand 2 sweep 1000 1000 1", r"^hand: Expected LO and HI to differ", id="sweep-empty"),
        pytest.param("hand 2 to 3000 -1", r"^hand: Expected seconds > 0", id="seconds"),
        pytest.param("hand 2 to 3000", r"^hand: Expected hand ID sweep LO HI SECONDS", id="short"),
        pytest.param("hand 7 to 3000 1", r"^no servo with ID 7 on the bus \(IDs: \[1, 2\]\)", id="id"),
        pytest.param("release 7", r"^no servo with ID 7", id="release-id"),
        pytest.param("status x", r"Expected status \[ID \.\.\.\] with servo IDs", id="status-id"),
        pytest.param("status 9", r"^no servo with ID 9", id="status-missing"),
    ],
)
def test_bad_commands_answer_one_line_errors(control, line, match):
    reply = json.loads(control.execute(line))
    assert reply["ok"] is False
    assert "\n" not in reply["error"]
    assert re.search(match, reply["error"]), reply["error"]


def test_commands_move_the_servo_and_status_reports_it(control):
    bus, clock = control.bus, control.bus.clock
    assert control.execute("") == ""
    assert json.loads(control.execute("help"))["commands"][0] == "hand ID sweep LO HI SECONDS"
    assert json.loads(control.execute("hand 2 to 3000 1.0")) == {
        "ok": True, "id": 2, "hand": "to 3000 in 1 s", "torque": False
    }  # fmt: skip
    clock.advance(0.5)
    status = json.loads(control.execute("status 2"))
    servo = status["servos"][0]
    assert status["t"] == pytest.approx(0.5)
    assert servo["position"] == 2524 and servo["moving"] == 1 and servo["velocity"] > 0
    clock.advance(0.5)
    assert json.loads(control.execute("release 2"))["hand"] is None
    clock.advance(1.0)
    servos = json.loads(control.execute("status"))["servos"]
    assert [(s["id"], s["position"], s["moving"], s["hand"]) for s in servos] == [
        (1, 2048, 0, None),
        (2, 3000, 0, None),
    ]
    assert bus.servo(2).get("Present Position") == 3000


def test_a_hand_on_a_servo_under_torque_says_so_and_waits(control):
    control.bus.servo(1).set("Torque Enable", 1)
    assert json.loads(control.execute("hand 1 sweep 0 4000 1"))["torque"] is True
    control.bus.clock.advance(1.0)
    assert json.loads(control.execute("status 1"))["servos"][0]["position"] == 2048


@pytest.mark.parametrize(
    ("text", "match"),
    [
        pytest.param("host:x", r"^--control: Expected \[HOST:\]PORT or unix:PATH", id="port"),
        pytest.param("70000", r"^--control: Expected a port 0\.\.65535", id="range"),
        pytest.param("unix:", r"^--control: Expected unix:PATH", id="unix"),
    ],
)
def test_bad_addresses_are_config_errors(text, match):
    with pytest.raises(ConfigError, match=match):
        parse_address(text)


def test_a_busy_address_is_a_config_error(control):
    with pytest.raises(ConfigError, match=r"^--control: Expected an address to listen on"):
        ControlServer(control.address, control.hands)


@pytest.mark.pty
@needs_pty
@pytest.mark.parametrize("kind", ["tcp", "unix"])
def test_over_the_socket_a_hand_turns_a_limp_servo_the_sdk_reads_over_the_pty(patient_sdk, tmp_path, kind):
    bus = sim.SimBus.from_ids([1, 2], "XM430-W350", clock=MonotonicClock())
    server = PtyServer(bus)
    control = ControlServer("127.0.0.1:0" if kind == "tcp" else f"unix:{tmp_path / 'sim.sock'}", HandSchedule(bus, []))
    server.add_hook(control)
    server.start()
    port, ph = PortHandler(server.path), PacketHandler(2.0)
    client = Client(control.address)
    try:
        assert port.setBaudRate(1_000_000)
        assert client.ask("hand 2 to 3000 0.3")["ok"]
        time.sleep(0.35)
        deadline = time.monotonic() + 10
        while client.ask("status 2")["servos"][0]["moving"] == 1:  # the turn has ended by now, unless the box is slow
            assert time.monotonic() < deadline
        value, result, _ = ph.read4ByteTxRx(port, 2, address("Present Position"))
        assert (result, value) == (COMM_SUCCESS, 3000)
        assert client.ask("release 2")["hand"] is None
        assert client.ask("x" * (MAX_LINE + 10))["ok"] is False  # a long line is an error, the connection stays
        assert client.ask("status 1")["servos"][0]["position"] == 2048
    finally:
        client.close()
        port.closePort()
        server.close()
        control.close()
    assert kind == "tcp" or not (tmp_path / "sim.sock").exists()


@pytest.mark.pty
@needs_pty
def test_retarget_sim_control_and_hand_options_as_a_process(patient_sdk):
    """``retarget sim --hand ... --control 127.0.0.1:0``: the second stdout line is the control address; the scripted
    hand sweeps servo 2 and the socket's hand turns servo 1, both seen by the plain SDK over the pty."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "retarget", "sim", "--ids", "1-2", "--hand", "2:sweep:1500-2500:0.2",
         "--control", "127.0.0.1:0"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        ready, _, _ = select.select([proc.stdout], [], [], 30.0)
        assert ready, "retarget sim printed nothing in 30 s"
        path, where = proc.stdout.readline().strip(), proc.stdout.readline().strip()
        client = Client(where)
        port, ph = PortHandler(path), PacketHandler(2.0)
        try:
            assert port.setBaudRate(1_000_000)
            assert client.ask("hand 1 to 1000 0.2")["ok"]
            seen = set()
            for _ in range(30):
                value, result, _ = ph.read4ByteTxRx(port, 2, address("Present Position"))
                assert result == COMM_SUCCESS
                seen.add(value)
                time.sleep(0.01)
            time.sleep(0.25)
            one, result, _ = ph.read4ByteTxRx(port, 1, address("Present Position"))
            status = client.ask("status")
        finally:
            port.closePort()
            client.close()
    finally:
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(timeout=10) == 0
    assert (result, one) == (COMM_SUCCESS, 1000)
    assert len(seen) > 5 and all(1500 <= v <= 2500 for v in seen)
    assert status["servos"][1]["hand"] == "sweep 1500..2500, 0.2 s per pass"
