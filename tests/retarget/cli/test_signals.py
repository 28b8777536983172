"""SIGTERM and SIGHUP stop ``replay`` and ``teleop`` as Ctrl-C does: at a tick boundary, through the bus's shutdown
sequence, with the telemetry complete and the summary printed; exit 143 and 129 (Ctrl-C 130).  A second signal
interrupts at once.  Also: ``--json`` after a bus failure, and ``--recover``."""

from __future__ import annotations

import argparse
import csv
import json
import os
import select
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from retarget.cli import main
from retarget.cli._bus import SignalInterrupt, build_bus, signals_stop
from tests.helpers import SignalAfterSyncWrites, servo_angles, torque

pytestmark = pytest.mark.skipif(
    not all(hasattr(signal, name) for name in ("SIGTERM", "SIGHUP")) or sys.platform == "win32",
    reason="needs POSIX signals (SIGTERM, SIGHUP)",
)

SIGNALS = [
    pytest.param("SIGTERM", 143, id="SIGTERM"),
    pytest.param("SIGHUP", 129, id="SIGHUP"),
    pytest.param("SIGINT", 130, id="SIGINT"),
]
ROOT = Path(__file__).resolve().parents[3]


def number(name: str) -> signal.Signals:
    return signal.Signals[name]


# --------------------------------------------------------------------------------------------- the handler


def test_the_first_signal_stops_the_second_interrupts_and_the_handlers_come_back():
    before = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)}
    calls = []
    with pytest.raises(SignalInterrupt) as info, signals_stop(lambda: calls.append(1)) as stopped:
        signal.raise_signal(signal.SIGTERM)
        assert calls == [1] and stopped.signum == signal.SIGTERM and stopped.exit_status == 143
        signal.raise_signal(signal.SIGHUP)  # a second signal, any of them: at once
    assert info.value.signum == signal.SIGHUP and isinstance(info.value, KeyboardInterrupt)
    assert {s: signal.getsignal(s) for s in before} == before
    with pytest.raises(KeyboardInterrupt) as plain, signals_stop(lambda: None) as stopped:
        signal.raise_signal(signal.SIGINT)
        assert stopped.exit_status == 130
        signal.raise_signal(signal.SIGINT)  # Ctrl-C twice: a plain KeyboardInterrupt, as before
    assert not isinstance(plain.value, SignalInterrupt)


# --------------------------------------------------------------------------------------------- in process


@pytest.mark.parametrize(("name", "status"), SIGNALS)
def test_replay_stops_through_the_rest_shutdown(arm, registered, capsys, tmp_path, name, status):
    """On the registered simulated bus: the default ``--shutdown rest`` leaves every servo at rest, torque off."""
    simbus, url = registered
    simbus.log = SignalAfterSyncWrites(40, number(name), maxlen=simbus.log.maxlen)
    path = tmp_path / "run.csv"
    before = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}  # (the defaults, unless ignored)
    code = main(["replay", "--port", url, "--fast", "--loop", "--max-ticks", "5000", "--lead-in", "0", "--json",
                 "--telemetry", str(path)])  # fmt: skip
    out, err = capsys.readouterr()
    assert code == status, err
    summary = json.loads(out)
    assert summary["interrupted"] is True and 20 <= summary["ticks"] < 5000
    assert "(interrupted)" in err and "stopping" in err
    rows = list(csv.DictReader(path.read_text().splitlines()))
    assert len(rows) == summary["ticks"] and all(None not in r.values() for r in rows)
    assert torque(simbus, arm) == [0] * 8
    np.testing.assert_allclose(servo_angles(simbus, arm), arm.rest, atol=0.06)
    assert {s: signal.getsignal(s) for s in before} == before  # the handlers were put back


@pytest.mark.parametrize(("name", "status"), SIGNALS[:2])
def test_teleop_stops_through_the_rest_shutdown(arm, registered, capsys, monkeypatch, name, status):
    from retarget.teleop import Follower

    simbus, url = registered
    observe = Follower.observe

    def observe_then_signal(self, tick, q_cmd, q_present=None):
        observe(self, tick, q_cmd, q_present)
        if tick == 50:
            os.kill(os.getpid(), number(name))

    monkeypatch.setattr(Follower, "observe", observe_then_signal)
    code = main(["teleop", "--to", "0.3,0,0.2", "--max-speed", "0.01", "--port", url, "--fast", "--shutdown", "rest",
                 "--json"])  # fmt: skip
    out, err = capsys.readouterr()
    assert code == status, err
    assert json.loads(out)["interrupted"] is True and "teleop (interrupted)" in err
    assert torque(simbus, arm) == [0] * 8
    np.testing.assert_allclose(servo_angles(simbus, arm), arm.rest, atol=0.06)


# --------------------------------------------------------------------------------------------- real processes


def _wait_for_rows(proc: subprocess.Popen, path: Path, rows: int, timeout: float = 20.0) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if path.exists() and path.read_text().count("\n") > rows:
            return
        if proc.poll() is not None:
            pytest.fail(f"the run ended early ({proc.returncode}): {proc.communicate()[1]}")
        time.sleep(0.02)
    proc.kill()
    pytest.fail(f"no {rows} telemetry rows in {timeout} s: {proc.communicate()[1]}")


def _replay(tmp_path: Path, *args: str) -> tuple[subprocess.Popen, Path]:
    path = tmp_path / "run.csv"
    argv = ["replay", "--loop", "--max-ticks", "100000", "--telemetry", str(path), *args]
    proc = subprocess.Popen(
        [sys.executable, "-m", "retarget", *argv],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=ROOT,
    )
    return proc, path


def _complete(path: Path) -> list[dict[str, str]]:
    text = path.read_text()
    assert text.endswith("\n")  # the last row fully written
    rows = list(csv.DictReader(text.splitlines()))
    assert rows and all(None not in r.values() and "" not in (r["tick"], r["waist_present_rad"]) for r in rows)
    return rows


@pytest.mark.parametrize(("name", "status"), SIGNALS)
def test_a_signal_to_a_replay_process(tmp_path, name, status):
    """A real process on the in-process simulated bus (--fast): exit status, how soon it ends, the summary and
    the telemetry."""
    proc, path = _replay(tmp_path, "--fast", "--json", "--lead-in", "0")
    _wait_for_rows(proc, path, 50)
    began = time.monotonic()
    proc.send_signal(number(name))
    out, err = proc.communicate(timeout=20)
    took = time.monotonic() - began
    assert proc.returncode == status, err
    assert took < 3.0
    assert "replay (interrupted): demo.bvh on wx250s" in err
    assert ("stopping (Ctrl-C again" if name == "SIGINT" else f"stopping on {name}") in err
    summary = json.loads(out)
    assert summary["interrupted"] is True
    assert len(_complete(path)) == summary["ticks"]


def test_a_second_sigterm_interrupts_the_shutdown_at_once(tmp_path):
    """Real time: the first SIGTERM starts the move to rest (seconds at 0.5 rad/s from the clip's pose), the
    second ends the process at once, still with 143."""
    proc, path = _replay(tmp_path, "--lead-in", "0")
    _wait_for_rows(proc, path, 100)  # 1 s: the arm is on the clip, away from rest
    proc.send_signal(signal.SIGTERM)
    ready, _, _ = select.select([proc.stderr], [], [], 10.0)
    assert ready and "stopping on SIGTERM" in proc.stderr.readline()
    time.sleep(0.3)  # the loop has ended (at the next tick boundary) and the move to rest is under way
    began = time.monotonic()
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=10)
    assert time.monotonic() - began < 1.0
    assert proc.returncode == 143
    assert err.strip().splitlines()[-1] == "retarget: interrupted"
    _complete(path)


@pytest.mark.pty
@pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs a POSIX pseudo-terminal")
@pytest.mark.parametrize(("name", "status"), SIGNALS[:2])
def test_over_a_pty_the_servos_end_at_rest_with_torque_off(arm, patient_sdk, tmp_path, name, status):
    """``retarget sim`` on a pty, ``retarget replay`` on it in real time, the signal during the lead-in (near
    rest, so the rest move is short); then the servos' registers read over the pty."""
    from dynamixel_sdk import COMM_SUCCESS, PacketHandler, PortHandler

    from drivers.units import pulses_to_rad
    from tests.helpers import address

    sim_proc = subprocess.Popen([sys.executable, "-m", "retarget", "sim", "--arm", "wx250s"], stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True, cwd=ROOT)  # fmt: skip
    try:
        ready, _, _ = select.select([sim_proc.stdout], [], [], 30.0)
        assert ready, "retarget sim printed nothing in 30 s"
        pty = sim_proc.stdout.readline().strip()
        proc, path = _replay(tmp_path, "--port", pty, "--lead-in", "0.05")
        _wait_for_rows(proc, path, 30)
        began = time.monotonic()
        proc.send_signal(number(name))
        _, err = proc.communicate(timeout=20)
        took = time.monotonic() - began
        assert proc.returncode == status, err
        assert took < 5.0 and "replay (interrupted)" in err
        rows = _complete(path)
        assert all(r["lead_in"] == "1" for r in rows)

        port, packets = PortHandler(pty), PacketHandler(2.0)
        assert port.setBaudRate(1_000_000)
        try:
            torques, angles = [], []
            for joint in arm.joints:
                servo = joint.servos[0]
                value, result, _ = packets.read1ByteTxRx(port, servo.id, address("Torque Enable"))
                assert result == COMM_SUCCESS
                torques.append(value)
                pulses, result, _ = packets.read4ByteTxRx(port, servo.id, address("Present Position"))
                assert result == COMM_SUCCESS
                angles.append(pulses_to_rad(pulses - (1 << 32) if pulses >= 1 << 31 else pulses, offset=servo.offset))
        finally:
            port.closePort()
        assert torques == [0] * arm.n_joints
        np.testing.assert_allclose(angles, arm.rest, atol=0.06)
    finally:
        sim_proc.send_signal(signal.SIGTERM)
        sim_proc.wait(timeout=10)


# --------------------------------------------------------------------------------------------- bus failures


def test_json_after_a_bus_failure_has_the_summary_and_the_error(capsys):
    code = main(["replay", "--fast", "--json", "--lead-in", "0", "--port", "sim://wx250s?unplug=4@2"])
    out, err = capsys.readouterr()
    assert code == 4
    assert err.strip().splitlines()[-1].startswith("retarget: servo 4: ")
    doc = json.loads(out)
    assert doc["error"]["kind"] == "bus" and doc["error"]["ids"] == [4]
    assert doc["error"]["message"] == err.strip().splitlines()[-1].removeprefix("retarget: ")
    assert doc["clip"] == "demo.bvh" and doc["arm"] == "wx250s" and doc["interrupted"] is False
    assert doc["ticks"] >= 150 and doc["bus_errors"] >= 1 and doc["bus_retries"] > 0

    code = main(["teleop", "--to", "0.3,0,0.2", "--fast", "--json", "--port", "sim://wx250s?unplug=4@0.2"])
    out, err = capsys.readouterr()
    assert code == 4
    doc = json.loads(out)
    assert doc["error"]["ids"] == [4] and doc["teleop"] is None and doc["ticks"] > 0


def test_recover_reaches_the_driver_and_rides_through_a_hardware_error(arm, capsys):
    setup = build_bus(argparse.Namespace(port="sim://wx250s", fast=True, shutdown="hold", recover=True), arm)
    assert setup.bus.recover is True
    setup = build_bus(argparse.Namespace(port="sim://wx250s", fast=True, shutdown="hold"), arm)
    assert setup.bus.recover is False
    url = "sim://wx250s?hwerror=3:overload@1"
    assert main(["replay", "--fast", "--end", "2", "--port", url]) == 4
    assert "hardware error: overload" in capsys.readouterr().err
    assert main(["replay", "--fast", "--end", "2", "--port", url, "--recover", "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["bus_reboots"] >= 1  # the reboot is counted in the summary
    for command in ("replay", "teleop"):
        with pytest.raises(SystemExit):
            main([command, "--help"])
        assert "--recover" in capsys.readouterr().out
