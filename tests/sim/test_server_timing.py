"""Timing of the served simulator: the wire-time model is ``retarget sim``'s default, REBOOT is silent for a while,
and a client that flushes its output after a write is seen (pty) or harmless (TCP).  Plain dynamixel-sdk and
pyserial clients; lower bounds on time only (a slow box only makes answers later)."""

from __future__ import annotations

import argparse
import logging
import os
import select
import termios
import time
import tty

import pytest
import serial
from dynamixel_sdk import COMM_RX_TIMEOUT, COMM_SUCCESS, PacketHandler, PortHandler

from retarget.cli import sim as sim_cli
from sim.faults import wire_time
from sim.protocol import PacketParser, build_instruction
from sim.server import PtyServer, TcpServer
from tests.helpers import needs_pty

PING = build_instruction(1, 0x01)  # 10 bytes; the status is 14


def parse(*argv: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="retarget")
    sim_cli.add_parser(parser.add_subparsers(dest="command"))
    return parser.parse_args(["sim", *argv])


@pytest.mark.parametrize(
    ("argv", "wire"),
    [
        pytest.param([], True, id="default"),
        pytest.param(["--wire"], True, id="wire"),
        pytest.param(["--no-wire"], False, id="no-wire"),
        pytest.param(["--tcp", "0", "--no-wire"], False, id="tcp-no-wire"),
    ],
)
def test_the_wire_model_is_on_unless_no_wire(argv, wire):
    assert sim_cli.build_bus(parse("--ids", "1", *argv)).faults.wire is wire


def test_reboot_is_silent_for_400_ms_by_default():
    bus = sim_cli.build_bus(parse("--ids", "1-2"))
    assert [s.boot_time for s in bus.servos] == [0.4, 0.4]
    assert sim_cli.build_bus(parse("--ids", "1", "--boot-ms", "0")).servo(1).boot_time == 0.0


@pytest.mark.pty
@needs_pty
def test_over_a_pty_a_ping_takes_at_least_its_wire_time_by_default(patient_sdk):
    bus = sim_cli.build_bus(parse("--ids", "1", "--baud", "57600"))
    with PtyServer(bus) as server:
        port, ph = PortHandler(server.path), PacketHandler(2.0)
        assert port.setBaudRate(57600)
        try:
            times = []
            for _ in range(5):
                t0 = time.perf_counter()
                assert ph.ping(port, 1)[1] == COMM_SUCCESS
                times.append(time.perf_counter() - t0)
        finally:
            port.closePort()
    on_the_wire = wire_time(len(PING) + 14, 57600) + bus.servo(1).return_delay  # 4.17 ms + 0.5 ms
    assert min(times) >= on_the_wire


@pytest.mark.pty
@needs_pty
def test_over_a_pty_a_rebooted_servo_is_silent_then_answers(patient_sdk):
    bus = sim_cli.build_bus(parse("--ids", "1"))
    with PtyServer(bus) as server:
        port, ph = PortHandler(server.path), PacketHandler(2.0)
        assert port.setBaudRate(1_000_000)
        try:
            assert ph.reboot(port, 1) == (COMM_SUCCESS, 0)  # the servo answers, then boots
            assert ph.ping(port, 1)[1] == COMM_RX_TIMEOUT  # sent within 400 ms: nobody listens
            time.sleep(0.45)
            assert ph.ping(port, 1)[1] == COMM_SUCCESS
        finally:
            port.closePort()


def _raw_client(path: str) -> int:
    """The pty opened as a raw serial port at 1 Mbps (the servos' rate)."""
    fd = os.open(path, os.O_RDWR | os.O_NOCTTY)
    tty.setraw(fd)
    attrs = termios.tcgetattr(fd)
    attrs[4] = attrs[5] = termios.B1000000
    termios.tcsetattr(fd, termios.TCSANOW, attrs)
    return fd


def _reply(fd: int, timeout: float) -> bytes:
    got = b""
    end = time.monotonic() + timeout
    while len(got) < 14 and time.monotonic() < end:
        if select.select([fd], [], [], 0.01)[0]:
            got += os.read(fd, 64)
    return got


@pytest.mark.pty
@needs_pty
def test_over_a_pty_the_server_sees_each_output_flush_and_warns_once(caplog):
    """pypot's pattern: a write then tcflush(TCOFLUSH).  On a pty Linux may drop the write (see sim.server); the
    server counts every flush and warns once, so a lost packet is explained."""
    bus = sim_cli.build_bus(parse("--ids", "1", "--no-wire"))
    n = 10
    with caplog.at_level(logging.WARNING, logger="sim.server"), PtyServer(bus) as server:
        fd = _raw_client(server.path)
        try:
            answered = 0
            for _ in range(n):
                os.write(fd, PING)
                termios.tcflush(fd, termios.TCOFLUSH)
                answered += len(_reply(fd, 0.1)) == 14
        finally:
            os.close(fd)
        flushes = server.output_flushes
    assert flushes == n
    assert answered + (n - len(bus.log)) == n  # every write either reached the bus and was answered, or was lost
    warnings = [r.message for r in caplog.records if "TCOFLUSH" in r.message]
    assert len(warnings) == 1 and "retarget sim --tcp" in warnings[0]


def test_over_tcp_a_write_then_output_flush_always_gets_its_reply():
    """The workaround for flushing clients: pyserial's socket:// port has no output buffer to lose."""
    bus = sim_cli.build_bus(parse("--ids", "1", "--no-wire", "--tcp", "0"))
    n = 50
    with TcpServer(bus) as server:
        port = serial.serial_for_url(server.url, timeout=5)
        try:
            replies = []
            for _ in range(n):
                port.write(PING)
                port.reset_output_buffer()
                replies += PacketParser().feed(port.read(14))
        finally:
            port.close()
    assert [p.id for p in replies] == [1] * n and len(bus.log) == n
