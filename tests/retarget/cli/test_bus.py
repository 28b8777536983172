"""The driver ``build_bus`` makes for ``replay`` and ``teleop``: its own speed limits follow the run's config
(``--rate``, ``--velocity-scale``), checked in the simulated servos' registers and goals."""

from __future__ import annotations

import argparse
import math

import numpy as np
import pytest

from drivers.units import pulses_to_rad, rad_s_to_velocity_units
from retarget.cli import main
from retarget.cli._bus import build_bus, servo_limits
from retarget.control import LoopConfig


def joint_servo_ids(arm) -> list[int]:
    return [s.id for j in arm.joints for s in j.servos]


def profile_velocities(simbus, arm) -> list[int]:
    return [simbus.servo(i).get("Profile Velocity") for i in joint_servo_ids(arm)]


@pytest.mark.parametrize(
    ("config", "expected"),
    [
        (None, {}),
        (LoopConfig(), {"dt": 0.01, "profile_velocity": None}),
        (LoopConfig(rate=50.0, velocity_scale=0.2), {"dt": 0.02, "profile_velocity": 0.2 * math.pi}),
    ],
    ids=["no-config", "full-speed", "scaled"],
)
def test_servo_limits(arm, config, expected):
    limits = servo_limits(arm, config)
    assert limits.keys() == expected.keys()
    for key, value in expected.items():
        assert limits[key] == (None if value is None else pytest.approx(value))


def test_build_bus_gives_the_driver_the_runs_limits(arm, registered):
    simbus, url = registered
    args = argparse.Namespace(port=url, fast=True, shutdown="hold")
    setup = build_bus(args, arm, LoopConfig(rate=50.0, velocity_scale=0.25))
    bus = setup.bus
    assert setup.clock is simbus.clock
    np.testing.assert_allclose(bus.max_step, arm.max_velocity / 50.0)  # the driver's own step limit is on
    with bus:
        # the servos' profile runs at the scaled speed
        assert profile_velocities(simbus, arm) == [int(rad_s_to_velocity_units(0.25 * math.pi))] * 8
        q0 = bus.read_positions()
        bus.write_goals(q0 + np.array([0.5, 0, 0, 0, 0, 0]))  # a goal 0.5 rad away: one step of the limit only
        waist = arm.joints[0].servos[0]
        goal = float(pulses_to_rad(simbus.servo(waist.id).get("Goal Position"), offset=waist.offset))
        assert goal - q0[0] == pytest.approx(math.pi / 50.0, abs=2 * math.pi / 4096)


@pytest.mark.parametrize(
    ("command", "scale"),
    [
        (["replay", "--end", "0.5"], "0.25"),
        (["teleop", "--to", "0.3,0,0.2"], "0.25"),
        (["replay", "--end", "0.5"], "1"),
    ],
    ids=["replay", "teleop", "replay-full-speed"],
)
def test_velocity_scale_reaches_the_servos_profile(arm, registered, capsys, command, scale):
    simbus, url = registered
    code = main([*command, "--port", url, "--fast", "--shutdown", "hold", "--velocity-scale", scale])
    assert code == 0, capsys.readouterr().err
    expected = int(rad_s_to_velocity_units(float(scale) * math.pi))  # wx250s: every joint 3.14 rad/s
    assert profile_velocities(simbus, arm) == [expected] * 8


def test_a_sim_name_with_no_bus_is_one_line(capsys):
    assert main(["replay", "--port", "sim://@nobus", "--fast"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("retarget: --port: no SimBus registered as 'nobus' (registered: ")
    assert err.endswith(") (got 'sim://@nobus')\n") and err.count("\n") == 1
