"""Scripted hands (``retarget sim --hand``): the grammar, the sweep path, the schedule, and a limp joint swept over a
pty while the plain dynamixel-sdk reads it, as ``lerobot-calibrate`` records a joint's range."""

from __future__ import annotations

import argparse
import random
import time

import pytest
from dynamixel_sdk import COMM_SUCCESS, PacketHandler, PortHandler

import sim
from retarget.cli import sim as sim_cli
from retarget.control.clock import MonotonicClock, VirtualClock
from retarget.errors import ConfigError
from sim.hand_commands import HandAction, HandCommand, HandSchedule, parse_hand, parse_words, sweep_path
from sim.server import PtyServer
from tests.helpers import address, needs_pty


def parse(*argv: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="retarget")
    sim_cli.add_parser(parser.add_subparsers(dest="command"))
    return parser.parse_args(["sim", *argv])


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        pytest.param("2:sweep:1024-3072:2", HandCommand(2, HandAction.SWEEP, (1024, 3072), 2.0), id="sweep"),
        pytest.param("2:sweep:3072-1024:2", HandCommand(2, HandAction.SWEEP, (1024, 3072), 2.0), id="sweep-reversed"),
        pytest.param("2:sweep:-500-500:1.5@3", HandCommand(2, HandAction.SWEEP, (-500, 500), 1.5, 3.0), id="negative"),
        pytest.param("5:to:3000:0.5", HandCommand(5, HandAction.TO, (3000,), 0.5), id="to"),
        pytest.param("5:TO:3000:0.5@10", HandCommand(5, HandAction.TO, (3000,), 0.5, 10.0), id="to-at"),
        pytest.param("5:release@4", HandCommand(5, HandAction.RELEASE, (), 0.0, 4.0), id="release"),
    ],
)
def test_hand_items_parse(text, expected):
    assert parse_hand(text) == expected


@pytest.mark.parametrize(
    ("text", "match"),
    [
        pytest.param("2", r"^--hand: Expected ID:sweep:LO-HI:SECONDS, .* \(got '2'\)", id="no-gesture"),
        pytest.param("2:wiggle:1:2", r"^--hand: Expected ID:sweep", id="unknown-gesture"),
        pytest.param("x:to:1:1", r"^--hand: Expected a servo ID 0\.\.252", id="id"),
        pytest.param("300:to:1:1", r"^--hand: Expected a servo ID 0\.\.252", id="id-range"),
        pytest.param("2:sweep:1024:2", r"^--hand: Expected a range LO-HI in pulses", id="range"),
        pytest.param("2:sweep:1024-1024:2", r"^--hand: Expected LO and HI to differ", id="empty-range"),
        pytest.param("2:to:1.5:1", r"^--hand: Expected whole pulses", id="fraction"),
        pytest.param("2:to:9999999:1", r"^--hand: Expected whole pulses", id="far"),
        pytest.param("2:to:100:0", r"^--hand: Expected seconds > 0 and <= 3600", id="zero-seconds"),
        pytest.param("2:to:100:nan", r"^--hand: Expected seconds > 0", id="nan-seconds"),
        pytest.param("2:to:100:1@-1", r"^--hand: Expected @START seconds 0\.\.86400", id="start"),
        pytest.param("2:to:100", r"^--hand: Expected ID:sweep", id="missing-seconds"),
        pytest.param("2:release:1", r"^--hand: Expected ID:sweep", id="release-args"),
    ],
)
def test_bad_hand_items_are_one_line_errors(text, match):
    with pytest.raises(ConfigError, match=match):
        parse_hand(text)


@pytest.mark.parametrize(
    ("words", "match"),
    [
        pytest.param(["hand", "2"], r"^hand: Expected hand ID sweep LO HI SECONDS", id="short"),
        pytest.param(["hand", "2", "sweep", "1", "2"], r"^hand: Expected hand ID sweep", id="sweep-args"),
        pytest.param(["release", "x"], r"^release: Expected a servo ID", id="release-id"),
        pytest.param(["wave", "2"], r"^wave: Expected hand ID", id="verb"),
    ],
)
def test_bad_socket_hand_lines_are_errors(words, match):
    with pytest.raises(ConfigError, match=match):
        parse_words(words)


def test_cli_hand_errors_name_the_option_and_the_bus_ids():
    with pytest.raises(ConfigError, match=r"^--hand: Expected a servo ID on the bus \(1, 2\) \(got '7'\)"):
        sim_cli.run(parse("--ids", "1-2", "--hand", "7:to:100:1"))
    with pytest.raises(ConfigError, match=r"^--hand: Expected a range LO-HI"):
        sim_cli.run(parse("--hand", "2:sweep:x:1"))


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_sweep_stays_between_its_ends_and_reaches_both(seed):
    rng = random.Random(seed)
    lo, hi = sorted(rng.sample(range(-2000, 6000), 2))
    start, seconds = rng.uniform(-3000, 7000), rng.uniform(0.2, 3.0)
    path = sweep_path(t0=10.0, start=start, lo=lo, hi=hi, seconds=seconds)
    assert path(10.0) == pytest.approx(start)
    # the approach to the nearer end takes at most one pass; then 8 passes, sampled 200 times each
    samples = [path(10.0 + seconds + k * seconds / 200) for k in range(1600)]
    assert all(lo - 1e-9 <= p <= hi + 1e-9 for p in samples)
    assert min(samples) == pytest.approx(lo, abs=1e-3 * (hi - lo)) and max(samples) == pytest.approx(
        hi, abs=1e-3 * (hi - lo)
    )
    nearer = lo if abs(start - lo) <= abs(start - hi) else hi
    first_end = next(
        p for p in (path(10.0 + k * seconds / 1000) for k in range(2000)) if min(abs(p - lo), abs(p - hi)) < 1.0
    )
    assert abs(first_end - nearer) < 1.0  # it goes to the nearer end first


def test_the_schedule_applies_each_gesture_at_its_time_and_replaces_the_last():
    clock = VirtualClock()
    bus = sim.SimBus.from_ids([1, 2], clock=clock)
    hands = HandSchedule(bus, [parse_hand(t) for t in ("1:to:1000:1@2", "1:sweep:0-4000:1", "1:release@4")])
    hands.service((), clock.now())
    assert hands.gestures == {1: "sweep 0..4000, 1 s per pass"} and hands.due() == bus.t_start + 2
    clock.advance(2.0)
    hands.service((), clock.now())
    assert hands.gestures == {1: "to 1000 in 1 s"}
    clock.advance(1.0)
    assert bus.servo(1).get("Present Position") == 1000
    clock.advance(1.0)
    hands.service((), clock.now())
    assert hands.gestures == {} and hands.due() == float("inf")
    assert bus.servo(2).get("Present Position") == 2048  # no hand on servo 2


def test_a_hand_does_not_move_a_servo_under_torque():
    clock = VirtualClock()
    bus = sim.SimBus.from_ids([1], clock=clock)
    bus.servo(1).set("Torque Enable", 1)
    HandSchedule(bus, [parse_hand("1:to:3000:0.5")]).service((), clock.now())
    clock.advance(1.0)
    assert bus.servo(1).get("Present Position") == 2048


@pytest.mark.pty
@needs_pty
def test_a_swept_limp_joint_shows_its_range_to_the_plain_sdk_over_a_pty(patient_sdk):
    """What lerobot-calibrate does: torque off, read Present Position while a person turns the joint, keep min/max."""
    bus = sim.SimBus.from_ids([1, 2], "XL430-W250", clock=MonotonicClock(), baud=57600)
    server = PtyServer(bus)
    server.add_hook(HandSchedule(bus, [parse_hand("2:sweep:1000-3000:0.3")]))
    server.start()
    port, ph = PortHandler(server.path), PacketHandler(2.0)
    try:
        assert port.setBaudRate(57600)
        seen, moving = [], set()
        end = time.monotonic() + 1.2  # 0.15 s to the nearer end, then 3+ passes
        while time.monotonic() < end:
            value, result, error = ph.read4ByteTxRx(port, 2, address("Present Position"))
            assert (result, error) == (COMM_SUCCESS, 0)
            seen.append(value)
            moving.add(ph.read1ByteTxRx(port, 2, address("Moving"))[0])
        still, result, _ = ph.read4ByteTxRx(port, 1, address("Present Position"))
    finally:
        port.closePort()
        server.close()
    assert result == COMM_SUCCESS and still == 2048
    assert 1000 <= min(seen) < 1150 and 2850 < max(seen) <= 3000, (min(seen), max(seen))
    assert 1 in moving


@pytest.mark.parametrize(
    "argv",
    [
        pytest.param(["--hand", "2:wiggle"], id="hand"),
        pytest.param(["--ids", "1", "--hand", "5:to:100:1"], id="hand-id"),
        pytest.param(["--control", "host:x"], id="control"),
    ],
)
def test_bad_hand_and_control_options_exit_2_with_one_line(capsys, argv):
    from retarget.cli import main

    assert main(["sim", *argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(("retarget: --hand: ", "retarget: --control: ")), err
