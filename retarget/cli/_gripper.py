"""The ``--gripper`` option of replay and teleop: what drives the gripper, and how its readings reach telemetry."""

from __future__ import annotations

import argparse
import logging
from collections.abc import Callable
from pathlib import Path

from retarget.arm.model import Arm
from retarget.bvh.motion import Motion
from retarget.control.gripper import GripperBus, GripperFeed
from retarget.control.loop import TickRecord
from retarget.errors import ConfigError, RetargetError
from retarget.mapping.gripper import GripperTrack, hand_gripper_track

log = logging.getLogger(__name__)

REPLAY_HELP = (
    "what drives the gripper: auto (default: the clip's hand, thumb-index pinch or finger curl, when the skeleton "
    "has fingers), off, a fixed closure 0 (open)..1 (closed), open, close, or a CSV of time_s,closure rows"
)
TELEOP_HELP = "gripper closure to start with: open, close or 0 (open)..1 (closed); messages change it with g"


def parse_closure(text: str, *, key: str = "gripper") -> float:
    """``open`` -> 0, ``close``/``closed`` -> 1, else a number 0..1; ConfigError naming ``key`` otherwise.

    >>> parse_closure("close"), parse_closure("0.25")
    (1.0, 0.25)
    """
    word = text.strip().lower()
    if word == "open":
        return 0.0
    if word in ("close", "closed"):
        return 1.0
    try:
        value = float(word)
    except ValueError:
        value = float("nan")
    if not 0.0 <= value <= 1.0:
        raise ConfigError("Expected open, close or a closure from 0 (open) to 1 (closed)", key=key, value=text)
    return value


def clip_track(text: str | None, arm: Arm, motion: Motion, side: str) -> GripperTrack | None:
    """The replay's gripper track from ``--gripper`` (None: auto); None when nothing drives the gripper."""
    word = (text or "auto").strip()
    if arm.gripper is None:
        if text is not None and word != "off":
            raise ConfigError(f"Expected an arm with a [gripper], got {arm.name}", key="gripper", value=text)
        return None
    if word == "off":
        return None
    if word == "auto":
        try:
            track = hand_gripper_track(motion, motion.arm_points(side))
        except RetargetError as exc:  # no arm chain: retarget_targets reports it
            log.debug("no gripper from the hand: %s", exc)
            return None
        if track is None:
            log.info("the %s hand has no fingers: the gripper is not driven (--gripper sets it)", side)
        return track
    if word.lower().endswith(".csv") or Path(word).is_file():
        return GripperTrack.from_csv(word)
    return GripperTrack.constant(parse_closure(word))


def gripper_on_tick(
    track: Callable[[float], float | None] | None,
    bus: object | None,
    on_tick: Callable[[TickRecord], None] | None,
) -> Callable[[TickRecord], None] | None:
    """``on_tick`` wrapped in a :class:`GripperFeed` when something drives the gripper, else as it was."""
    if track is None:
        return on_tick
    return GripperFeed(track, bus=as_gripper_bus(bus), on_tick=on_tick)


def add_replay_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--gripper", default=None, metavar="auto|off|0..1|FILE.csv", help=REPLAY_HELP)


def as_gripper_bus(bus: object | None) -> GripperBus | None:
    """``bus`` when it drives a gripper (``set_gripper``/``gripper_reading``), else None."""
    if bus is not None and hasattr(bus, "set_gripper") and hasattr(bus, "gripper_reading"):
        return bus
    return None
