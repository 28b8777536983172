"""drivers.port, drivers.comm and drivers.scan (and ``retarget scan``) against the simulator."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys

import numpy as np
import pytest

import sim
from drivers.comm import Link, comm_result_name, status_error_name
from drivers.control_table import ALERT_BIT, HardwareError
from drivers.dynamixel_bus import DynamixelBus
from drivers.port import UrlPortHandler, open_port
from drivers.scan import ALL_BAUDS, scan
from retarget.cli import main
from retarget.control.bus import ShutdownMode
from retarget.errors import BusError
from sim.server import TcpServer
from tests.helpers import GOAL, PRESENT, address

TEMPERATURE = address("Present Temperature")  #: 1 byte

# ---------------------------------------------------------------------------------------------- port


def test_open_port_opens_a_sim_url(url):
    port = open_port(url, 1_000_000)
    try:
        assert isinstance(port, UrlPortHandler) and port.is_open and port.getBaudRate() == 1_000_000
    finally:
        port.closePort()
    assert not port.is_open


def test_socket_port_has_nagle_off(sim_bus):
    """A SYNC_WRITE then a READ must not wait for a delayed ACK (~40 ms, past the SDK's 34 ms timeout)."""
    with TcpServer(sim_bus) as server:
        port = open_port(server.url, 1_000_000)
        try:
            assert port.ser._socket.getsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY) == 1
            link = Link(port, retries=0)
            for _ in range(3):
                link.sync_write(GOAL, 4, {1: (2048).to_bytes(4, "little")})
                link.read(1, PRESENT, 4)  # raises when the READ sat behind Nagle's algorithm
        finally:
            port.closePort()


@pytest.mark.parametrize(
    ("port", "baud", "message"),
    [
        ("/dev/does-not-exist", 1_000_000, r"cannot open port '/dev/does-not-exist' at 1000000 baud"),
        ("socket://127.0.0.1:1", 1_000_000, r"cannot open port 'socket://127.0.0.1:1'"),
        ("sim://@nobody-registered-this", 1_000_000, r"cannot open port 'sim://@nobody-registered-this'"),
        ("sim://wx250s", 4_500_000, r"baud rate 4500000 is not supported by dynamixel-sdk"),
    ],
    ids=["no-device", "tcp-refused", "sim-unknown", "baud"],
)
def test_open_failures_are_bus_errors(port, baud, message):
    with pytest.raises(BusError, match=message):
        open_port(port, baud)


# ---------------------------------------------------------------------------------------------- comm


@pytest.fixture
def link(url):
    port = open_port(url, 1_000_000)
    yield Link(port, retries=1)
    port.closePort()


def test_status_error_names():
    assert status_error_name(0) is None
    assert status_error_name(ALERT_BIT) is None  # the Alert bit alone is not an error number
    assert status_error_name(7) == "access error"
    assert status_error_name(ALERT_BIT | 6) == "data limit error"
    assert comm_result_name(-3001) == "no status packet"


def test_ping_reports_model_and_firmware(link):
    reply = link.ping(2)
    assert (reply.id, reply.model_number, reply.firmware) == (2, 1020, 46)
    assert link.ping(42) is None
    assert link.retry_count == 1  # one retry for the absent ID


def test_eeprom_write_with_torque_on_names_the_access_error(link, sim_bus):
    sim_bus.servo(1).set("Torque Enable", 1)
    reg = sim_bus.servo(1).model.register("Drive Mode")
    with pytest.raises(BusError, match=r"^servo 1: access error writing Drive Mode = 1$"):
        link.write_register(1, reg, 1)
    assert link.retry_count == 0  # a refused value is not repeated


def test_data_limit_error_is_named(link, sim_bus):
    model = sim_bus.servo(1).model
    link.write_register(1, model.register("Max Position Limit"), 3000)
    with pytest.raises(BusError, match=r"servo 1: data limit error writing Goal Position = 3500"):
        link.write_register(1, model.register("Goal Position"), 3500)


def test_alert_bit_is_collected(link, sim_bus):
    sim_bus.servo(3).trigger_hardware_error(HardwareError.INPUT_VOLTAGE)
    link.read(3, PRESENT, 4)
    assert link.alerts == {3}


def test_bulk_read_when_addresses_differ(link, sim_bus):
    sim_bus.servo(1).set_position(1234)
    replies = link.group_read({1: (PRESENT, 4), 2: (TEMPERATURE, 1)}, what="mixed")
    assert int.from_bytes(replies[1].data, "little") == 1234
    assert replies[2].data[0] == sim_bus.servo(2).get("Present Temperature")


@pytest.mark.parametrize("fast", [True, False], ids=["fast", "plain"])
def test_group_read_names_the_silent_servo(link, sim_bus, fast):
    sim_bus.servo(2).unplug()
    with pytest.raises(BusError, match=r"^servo 2: no status packet \(Present Position\)") as info:
        link.group_read({i: (PRESENT, 4) for i in (1, 2, 4)}, fast=fast, what="Present Position")
    assert info.value.ids == (2,)
    assert link.error_count == 1


def test_retries_must_be_non_negative(link):
    with pytest.raises(ValueError, match="Expected retries >= 0, got -1"):
        Link(link.port, retries=-1)


# ---------------------------------------------------------------------------------------------- scan


def test_all_bauds_start_with_the_common_ones():
    assert ALL_BAUDS[:2] == (1_000_000, 57_600) and 4_500_000 not in ALL_BAUDS


def test_scan_broadcast_finds_the_arm(url):
    found = scan(url, (1_000_000,))
    assert [s.id for s in found] == list(range(1, 10))
    assert {s.model for s in found} == {"XM430-W350", "XL430-W250"}
    assert {(s.firmware, s.baud) for s in found} == {(46, 1_000_000)}


def test_scan_per_id_across_bauds(clock):
    mixed = sim.SimBus([sim.SimServo("XL330-M288", 7, clock=clock, baud=57_600)], clock=clock)
    url = sim.register("drivers-scan-57600", mixed)
    try:
        found = scan(url, (1_000_000, 57_600), (6, 7), broadcast=False)
    finally:
        sim.unregister(url)
    assert [(s.id, s.model, s.model_number, s.baud) for s in found] == [(7, "XL330-M288", 1200, 57_600)]


def test_cli_scan_json(url, capsys):
    assert main(["scan", "--port", url, "--ids", "1-3", "--no-broadcast", "--json"]) == 0
    out = capsys.readouterr()
    rows = json.loads(out.out)
    assert [(r["id"], r["model"]) for r in rows] == [(1, "XM430-W350"), (2, "XM430-W350"), (3, "XM430-W350")]
    assert "scanning" in out.err


def test_cli_scan_table(url, capsys):
    assert main(["scan", "--port", url, "--ids", "8-9", "--no-broadcast"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].split() == ["ID", "MODEL", "NUMBER", "FIRMWARE", "BAUD"]
    assert lines[1].split() == ["8", "XL430-W250", "1060", "46", "1000000"]


@pytest.mark.parametrize(
    ("argv", "status", "message"),
    [
        (["--ids", "20-21", "--no-broadcast"], 4, "no servo answered on"),
        (["--ids", "x"], 2, "--ids: Expected IDs like 1-6 or 1,3,5 (got 'x')"),  # ids -> --ids: retarget.cli.options
    ],
    ids=["nothing-found", "bad-ids"],
)
def test_cli_scan_errors(url, capsys, argv, status, message):
    assert main(["scan", "--port", url, *argv]) == status
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) <= 2  # progress line(s) + one error line


@pytest.mark.pty
@pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs a POSIX pseudo-terminal")
def test_out_of_process_sim_over_a_pty(arm):
    """``retarget sim --pty`` in another process: scan it, then connect, move and close the arm through it."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "retarget", "sim", "--arm", "wx250s", "--pty", "--rdt", "0"],
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
    )
    try:
        path = proc.stdout.readline().strip()
        assert path.startswith("/dev/"), path
        found = scan(path, (1_000_000,), (1, 2, 9), broadcast=False)
        assert [(s.id, s.model) for s in found] == [(1, "XM430-W350"), (2, "XM430-W350"), (9, "XL430-W250")]
        with DynamixelBus(arm, path, shutdown=ShutdownMode.OFF, check_latency=False) as bus:
            bus.write_goals(np.zeros(6))
            assert bus.read_positions().shape == (6,)
            assert bus.status().errors == 0
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
