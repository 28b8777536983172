"""``retarget sim``: option handling, and the server run as a real process on loopback TCP and on a pty."""

from __future__ import annotations

import argparse
import os
import select
import signal
import subprocess
import sys

import pytest
import serial
from dynamixel_sdk import COMM_SUCCESS, PacketHandler, PortHandler

from retarget.cli import sim as sim_cli
from retarget.errors import ConfigError
from sim.protocol import PacketParser, build_instruction


def parse(*argv: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="retarget")
    sim_cli.add_parser(parser.add_subparsers(dest="command"))
    return parser.parse_args(["sim", *argv])


def test_builds_the_arm_by_default():
    bus = sim_cli.build_bus(parse())
    assert bus.ids == tuple(range(1, 10)) and bus.baud == 1_000_000


def test_builds_ids_of_one_model_with_faults():
    bus = sim_cli.build_bus(parse("--ids", "1-3", "--model", "XM540-W270", "--baud", "57600", "--drop", "2:0.5"))
    assert bus.ids == (1, 2, 3) and bus.servo(1).model.name == "XM540-W270" and bus.servo(3).baud == 57600
    assert bus.faults.for_servo(2).drop == 0.5 and bus.faults.for_servo(1).drop == 0.0


@pytest.mark.parametrize(
    ("argv", "match"),
    [
        pytest.param(["--drop", "2"], r"drop: Expected a fraction", id="drop"),
        pytest.param(["--ids", "1-3", "--arm", "wx250s"], "either --arm or --ids", id="arm-and-ids"),
        pytest.param(["--model", "XL430-W250"], "--model goes with --ids", id="model-alone"),
        pytest.param(["--ids", "1", "--model", "XX"], "--model: Expected one of", id="model"),
        pytest.param(["--baud", "12345"], "--baud: Expected a Dynamixel baud rate", id="baud"),
        pytest.param(["--tcp", "host:x"], r"--tcp: Expected \[HOST:\]PORT", id="tcp"),
        pytest.param(["--tcp", "70000"], "--tcp: Expected a port", id="tcp-port"),
        pytest.param(["--hwerror", "3:melting@1"], "hwerror: Expected a kind", id="hwerror"),
    ],
)
def test_bad_options_raise_config_errors(argv, match):
    with pytest.raises(ConfigError, match=match):
        sim_cli.run(parse(*argv))


def _start(*argv: str) -> tuple[subprocess.Popen, str]:
    """Start ``retarget sim`` as a process and return it with the first line it prints (what to open).

    The read of that line is bounded, so a server that never prints fails the test instead of hanging it.
    """
    proc = subprocess.Popen(
        [sys.executable, "-m", "retarget", "sim", *argv],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    ready, _, _ = select.select([proc.stdout], [], [], 30.0)
    if not ready:
        proc.kill()
        pytest.fail(f"retarget sim printed nothing in 30 s: {proc.communicate()[1]}")
    where = proc.stdout.readline().strip()
    assert where, proc.stderr.read()
    return proc, where


def _stop(proc: subprocess.Popen) -> None:
    proc.send_signal(signal.SIGTERM)
    assert proc.wait(timeout=10) == 0
    assert "stopped" in proc.stderr.read()


def test_serves_on_loopback_tcp_until_sigterm():
    proc, url = _start("--ids", "1-2", "--tcp", "127.0.0.1:0")
    try:
        assert url.startswith("socket://127.0.0.1:")
        port = serial.serial_for_url(url, timeout=5)
        port.write(build_instruction(2, 0x01))
        assert [p.id for p in PacketParser().feed(port.read(14))] == [2]
        port.close()
    finally:
        _stop(proc)


@pytest.mark.pty
@pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs a POSIX pseudo-terminal")
def test_serves_on_a_pty_for_the_plain_sdk_port(patient_sdk):
    proc, path = _start("--arm", "wx250s", "--rdt", "0")
    try:
        port = PortHandler(path)
        assert port.setBaudRate(1_000_000)
        assert PacketHandler(2.0).ping(port, 9)[:2] == (1060, COMM_SUCCESS)
        port.closePort()
    finally:
        _stop(proc)
