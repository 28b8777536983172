"""sim.mount: servos mounted off the arm file's zero or the other way round (sim://ARM?mount=&reverse=, retarget
sim --mount/--reverse), and the arm's physical joints read and turned by hand."""

from __future__ import annotations

import argparse
import math

import numpy as np
import pytest

from drivers.control_table import RAD_PER_PULSE
from retarget.arm.load import load_arm
from retarget.cli import sim as sim_cli
from retarget.errors import ConfigError
from sim.bus import SimBus
from sim.mount import Mounting
from sim.transport import bus_from_url
from tests.helpers import random_mounting


@pytest.mark.parametrize("seed", [0, 1, 2], ids=lambda s: f"seed{s}")
def test_a_mounted_servo_reads_its_offset_and_turns_its_way(seed):
    arm = load_arm("wx250s")
    mounting = random_mounting(arm, seed)
    bus = SimBus.from_arm(arm, mount=mounting, pose=np.zeros(6))
    for joint in arm.joints:
        for s in joint.servos:
            sign = -1 if s.id in mounting.reversed else 1
            # torque off, default Drive Mode: the present position is the actual shaft position
            assert (
                bus.servo(s.id).get("Present Position") == 2048 + mounting.offsets[s.id] + sign * s.direction * s.offset
            )
    q = np.array([0.3, -0.2, 0.4, -0.5, 0.6, -0.7])
    end = bus.body.turn(q, duration=0.0)
    bus.clock.sleep_until(end)
    np.testing.assert_allclose(bus.body.angles(), q, atol=RAD_PER_PULSE)
    s = arm.joints[1].servos[0]
    sign = -1 if s.id in mounting.reversed else 1
    expected = 2048 + mounting.offsets[s.id] + sign * s.direction * (q[1] / RAD_PER_PULSE)
    assert bus.servo(s.id).get("Present Position") == pytest.approx(expected, abs=1)


def test_the_body_holds_physical_positions_whatever_the_drive_mode():
    bus = bus_from_url("sim://koch?clock=virtual&reverse=2")
    bus.clock.sleep_until(bus.body.turn([0.0, 0.5, 0.0, 0.0, 0.0], duration=0.2))
    bus.servo(2).set("Drive Mode", 1)  # what the driver writes for a reversed servo: the report mirrors, not the horn
    np.testing.assert_allclose(bus.body.angles(), [0.0, 0.5, 0.0, 0.0, 0.0], atol=RAD_PER_PULSE)


def test_url_options():
    bus = bus_from_url("sim://koch?mount=1:+300,2:-150&reverse=3&clock=virtual")
    assert bus.body.mounting == Mounting({1: 300, 2: -150}, frozenset({3}))
    assert [bus.servo(i).get("Present Position") for i in (1, 2, 3)] == [2348, 1898, 2048]
    assert bus_from_url("sim://koch").body.mounting == Mounting()
    assert bus_from_url("sim://?ids=1-2").body is None


@pytest.mark.parametrize(
    "url,match",
    [
        pytest.param("sim://koch?mount=1", r"^sim://koch\?mount=1: mount: Expected ID:PULSES", id="no-pulses"),
        pytest.param(
            "sim://koch?mount=1:3000", r"mount: Expected ID:PULSES, an ID 0\.\.252 and pulses within", id="far"
        ),
        pytest.param("sim://koch?reverse=x", r"reverse: Expected a servo ID \(got 'x'\)", id="reverse"),
        pytest.param("sim://koch?mount=9:10", r"^mount: Expected joint servo IDs of koch \(got \[9\]\)", id="unknown"),
        pytest.param("sim://koch?reverse=6", r"^mount: Expected joint servo IDs of koch \(got \[6\]\)", id="gripper"),
        pytest.param("sim://?ids=1&mount=1:5", r"mount= and reverse= need an arm", id="ids"),
    ],
)
def test_bad_url_options(url, match):
    with pytest.raises(ConfigError, match=match):
        bus_from_url(url)


def parse(*argv: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="retarget")
    sim_cli.add_parser(parser.add_subparsers(dest="command"))
    return parser.parse_args(["sim", *argv])


def test_retarget_sim_mount_and_reverse():
    bus = sim_cli.build_bus(parse("--arm", "koch", "--mount", "1:+300", "--mount", "2:-150", "--reverse", "3"))
    assert bus.body.mounting == Mounting({1: 300, 2: -150}, frozenset({3}))
    assert bus.servo(1).get("Present Position") == 2348


@pytest.mark.parametrize(
    "argv,match",
    [
        pytest.param(["--arm", "koch", "--mount", "1"], r"^--mount: Expected ID:PULSES", id="format"),
        pytest.param(["--arm", "koch", "--reverse", "12"], r"^--reverse: Expected a servo ID on the bus", id="unknown"),
        pytest.param(["--ids", "1-3", "--mount", "1:5"], r"^--mount: --mount goes with an --arm, not --ids", id="ids"),
    ],
)
def test_retarget_sim_bad_mount_options(argv, match):
    with pytest.raises(ConfigError, match=match):
        sim_cli.build_bus(parse(*argv))


def test_a_mount_offset_moves_the_zero_by_that_many_pulses():
    bus = bus_from_url("sim://koch?mount=4:+512&clock=virtual")
    assert math.isclose(bus.body.angles()[3], 0.0, abs_tol=1e-9)
    assert bus.servo(4).get("Present Position") == 2560
