"""``retarget sim``: option handling, and the server run as a real process on loopback TCP and on a pty."""

from __future__ import annotations

import argparse
import os
import re
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
        # issue 16: every numeric option has a range, and each error names its own option
        pytest.param(["--boot-ms", "-1"], r"^--boot-ms: Expected a finite number of ms from 0 to 60000", id="boot-neg"),
        pytest.param(["--boot-ms", "nan"], r"^--boot-ms: Expected a finite number", id="boot-nan"),
        pytest.param(["--boot-ms", "inf"], r"^--boot-ms: Expected a finite number", id="boot-inf"),
        pytest.param(["--delay-ms", "inf"], r"^--delay-ms: Expected a finite number from 0 to 10000", id="delay-inf"),
        pytest.param(["--delay-ms", "3:nan"], r"^--delay-ms: Expected a finite number .*'3:nan'", id="delay-id-nan"),
        pytest.param(["--drop", "nan"], r"^--drop: Expected a finite number >= 0", id="drop-nan"),
        pytest.param(["--corrupt", "1.5"], r"corrupt: Expected a fraction", id="corrupt"),
        pytest.param(["--unplug", "4@nan"], r"^--unplug: Expected a finite number .*'4@nan'", id="unplug-nan"),
        pytest.param(["--unplug", "4@-1"], r"^--unplug: Expected a finite number", id="unplug-negative"),
        pytest.param(["--hwerror", "3:overload@inf"], r"^--hwerror: Expected a finite number", id="hwerror-inf"),
        pytest.param(["--rdt", "-1"], r"^--rdt: Expected a Return Delay Time 0\.\.254", id="rdt-negative"),
        pytest.param(["--rdt", "255"], r"^--rdt: Expected a Return Delay Time 0\.\.254", id="rdt-255"),
        pytest.param(["--unplug", "99@1"], r"^--unplug: Expected a servo ID on the bus \(1, 2, .*'99'", id="unplug-id"),
        pytest.param(["--drop", "42:0.1"], r"^--drop: Expected a servo ID on the bus", id="drop-id"),
        pytest.param(
            ["--ids", "1-3", "--hwerror", "7:overload@1"],
            r"^--hwerror: Expected a servo ID on the bus \(1, 2, 3\)",
            id="hwerror-id-with-ids",
        ),  # fmt: skip
    ],
)
def test_bad_options_raise_config_errors(argv, match):
    with pytest.raises(ConfigError, match=match):
        sim_cli.run(parse(*argv))


def test_options_at_the_ends_of_their_ranges_build_a_bus():
    bus = sim_cli.build_bus(
        parse("--boot-ms", "60000", "--rdt", "254", "--delay-ms", "10000", "--unplug", "9@86400", "--drop", "1")
    )
    assert bus.ids == tuple(range(1, 10))


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


def _stop(proc: subprocess.Popen) -> str:
    """SIGTERM: a clean stop (exit 0, "stopped"); returns what it printed on stderr."""
    proc.send_signal(signal.SIGTERM)
    assert proc.wait(timeout=10) == 0
    err = proc.stderr.read()
    assert "stopped" in err
    return err


def test_serves_on_loopback_tcp_until_sigterm():
    proc, url = _start("--ids", "1-2", "--tcp", "127.0.0.1:0")
    try:
        assert url.startswith("socket://127.0.0.1:")
        port = serial.serial_for_url(url, timeout=5)
        port.write(build_instruction(2, 0x01))
        assert [p.id for p in PacketParser().feed(port.read(14))] == [2]
        port.close()
    finally:
        err = _stop(proc)
    # with the wire model (the default) it says how punctually the replies left: one reply here
    assert re.search(r"retarget sim: 1 reply, [01] \([\d.]+ %\) later than 0\.5 ms after their wire time", err), err


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
