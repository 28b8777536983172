"""The driver's Bus Watchdog option: armed with the first goal, a host silence stops the servos and ends the run with
a BusError, close() clears it; and a host process killed with SIGKILL mid-move leaves the arm stopped, not at its
goal (checked from the simulator, over a pty)."""

from __future__ import annotations

import os
import re
import select
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import sim
from drivers.watchdog import HostWatchdog, watchdog_setting
from retarget.cli import main
from retarget.control.clock import MonotonicClock
from retarget.errors import BusError, ConfigError
from sim.server import PtyServer
from tests.helpers import needs_pty

ROOT = Path(__file__).resolve().parents[2]


def watchdogs(bus: sim.SimBus) -> list[int]:
    return [s.get("Bus Watchdog") for s in bus.servos]


@pytest.mark.parametrize(
    ("period", "setting"),
    [
        pytest.param(0.02, 1, id="one-unit"),
        pytest.param(0.1, 5, id="100ms"),
        pytest.param(0.101, 6, id="rounded-up"),
        pytest.param(2.54, 127, id="max"),
    ],
)
def test_periods_round_up_to_the_20_ms_unit(period, setting):
    assert watchdog_setting(period) == setting


@pytest.mark.parametrize(
    ("period", "dt", "match"),
    [
        pytest.param(0.019, None, r"^watchdog: Expected a watchdog period from 0\.02 to 2\.54 s", id="short"),
        pytest.param(2.6, None, r"^watchdog: Expected a watchdog period from 0\.02", id="long"),
        pytest.param(float("nan"), None, r"^watchdog: Expected a watchdog period", id="nan"),
        pytest.param(0.04, 0.02, r"^watchdog: Expected a watchdog period of at least 3 control ticks \(0\.06 s\)",
                     id="under-3-ticks"),
    ],
)  # fmt: skip
def test_bad_periods_are_config_errors(period, dt, match):
    with pytest.raises(ConfigError, match=match):
        HostWatchdog(period, [1], dt=dt)


def test_armed_with_the_first_goal_and_quiet_while_ticks_flow(make_bus, url, sim_bus, clock):
    bus = make_bus(url, watchdog=0.1, dt=0.02, shutdown="off")
    bus.connect()
    assert watchdogs(sim_bus) == [0] * 9  # connecting and any pause before the first goal cannot trip it
    q = bus.read_positions()
    for k in range(50):
        bus.write_goals(q + 0.002 * k)
        bus.read_positions()
        clock.advance(0.02)
    assert watchdogs(sim_bus) == [5] * 9  # every servo, the gripper too (the sync writes reach it)
    bus.close()
    assert watchdogs(sim_bus) == [0] * 9


def test_a_host_silence_stops_the_servos_and_the_next_goal_raises(make_bus, url, sim_bus, clock):
    bus = make_bus(url, watchdog=0.1, dt=0.02, shutdown="rest")
    bus.connect()
    q = bus.read_positions()
    goal = q.copy()
    goal[0] += 0.5
    bus.write_goals(goal)  # a half-radian waist move under the servo's profile
    clock.advance(0.15)  # the host stalls mid-move, longer than the watchdog
    waist = sim_bus.servo(1)
    stopped_at = waist.get("Present Position")
    assert waist.get("Bus Watchdog") == 255 and waist.get("Moving") == 0
    assert waist.get("Goal Position") == stopped_at  # it holds where it stopped, not at the goal
    with pytest.raises(
        BusError, match=r"the Bus Watchdog stopped the servos: the host sent nothing for 0\.150 s"
    ) as info:
        bus.write_goals(goal)
    assert info.value.ids == tuple(range(1, 10))
    with pytest.raises(BusError, match="bus is faulted"):
        bus.write_goals(goal)
    bus.close()  # clears the watchdog, so the move to rest is accepted, then torque off
    assert watchdogs(sim_bus) == [0] * 9
    assert [s.torque for s in sim_bus.servos] == [False] * 9
    assert abs(waist.get("Present Position") - 2048) < 40  # back at rest


def test_without_the_option_nothing_is_written(make_bus, url, sim_bus, clock):
    bus = make_bus(url, dt=0.02, shutdown="off")
    bus.connect()
    bus.write_goals(bus.read_positions())
    clock.advance(1.0)
    bus.write_goals(bus.read_positions())
    assert watchdogs(sim_bus) == [0] * 9
    bus.close()


@pytest.mark.parametrize(
    ("argv", "match"),
    [
        pytest.param(["--watchdog-ms", "10"], r"--watchdog-ms: Expected a watchdog period from 20 to 2540", id="short"),
        pytest.param(["--watchdog-ms", "inf"], r"--watchdog-ms: Expected a watchdog period", id="inf"),
        pytest.param(["--watchdog-ms", "40", "--rate", "50"],
                     r"--watchdog-ms: Expected at least 3 control ticks \(60 ms at --rate 50\) \(got 40\.0\)",
                     id="under-3-ticks"),
    ],
)  # fmt: skip
def test_cli_watchdog_errors_are_one_line_exit_2(capsys, argv, match):
    assert main(["replay", "--fast", "--lead-in", "0", *argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and re.search(match, err[0]), err


def test_cli_replay_with_the_watchdog_runs_to_the_end(sim_bus, url, capsys):
    assert main(["replay", "--fast", "--lead-in", "0", "--max-ticks", "40", "--watchdog-ms", "100", "--port", url]) == 0
    armed = [e for e in sim_bus.log if e.instruction == 0x03 and e.params[:2] == bytes((98, 0))]
    assert {(e.id, e.params[2:]) for e in armed} >= {(i, b"\x05") for i in range(1, 10)}  # armed during the run
    assert watchdogs(sim_bus) == [0] * 9  # and cleared by the shutdown


HOST = """
import sys, time
from drivers import DynamixelBus
watchdog = float(sys.argv[2]) or None
bus = DynamixelBus("wx250s", sys.argv[1], watchdog=watchdog, dt=0.02, step_limit=False, profile_velocity=1.0,
                   shutdown="hold", check_latency=False)
bus.connect()
goal = bus.read_positions()
goal[0] += 0.6  # the waist: 0.6 rad (391 pulses) at 1 rad/s
bus.write_goals(goal)
print("moving", flush=True)
while True:
    bus.write_goals(goal)
    bus.read_positions()
    time.sleep(0.02)
"""


@pytest.mark.pty
@needs_pty
@pytest.mark.parametrize(
    ("watchdog", "stops"), [pytest.param(0.1, True, id="watchdog"), pytest.param(0.0, False, id="off")]
)
def test_a_host_killed_mid_move_leaves_the_arm_stopped(watchdog, stops):
    simbus = sim.SimBus.from_arm("wx250s", clock=MonotonicClock(), faults=sim.Faults(wire=True))
    waist = simbus.servo(1)
    with PtyServer(simbus) as server:
        env = {**os.environ, "PYTHONPATH": str(ROOT)}
        host = subprocess.Popen([sys.executable, "-c", HOST, server.path, str(watchdog)], stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True, cwd=ROOT, env=env)  # fmt: skip
        try:
            ready, _, _ = select.select([host.stdout], [], [], 30.0)
            assert ready and host.stdout.readline().strip() == "moving", host.stderr.read()
            time.sleep(0.2)
        finally:
            host.send_signal(signal.SIGKILL)
            host.wait(timeout=10)
        killed = time.monotonic()
        at_kill = waist.get("Present Position")  # the host is dead: nothing else touches the servo now
        goal = waist.get("Goal Position") if not stops else None
        time.sleep(0.25)  # the watchdog period and some
        first = waist.get("Present Position")
        time.sleep(0.6)  # a move left to run would be at its goal by now
        second = waist.get("Present Position")
        tripped = waist.get("Bus Watchdog")
    assert time.monotonic() - killed < 5
    if stops:
        assert tripped == 255 and first == second  # frozen
        # within the period: at 1 rad/s (652 pulses/s) it ran at most 0.1 s past the kill, short of its goal
        assert at_kill <= second <= at_kill + 0.1 * 652 + 2 and second < 2048 + 391 - 50
    else:
        assert tripped == 0 and second == goal == 2048 + 391  # finished its last move
    assert np.isfinite(second)
