"""The steps of ``retarget calibrate``, each a function of the prompter, the servos and the arm.

1. :func:`connect_step`: ping and check every servo, then torque off (after the user holds the arm);
2. :func:`reference_step`: the user sets the calibration pose; every servo's raw position is read;
3. :func:`direction_step` (arms whose servos may sit either way): the user turns each joint a little in its
   positive direction; :func:`servo_calibrations` then puts each servo's zero where the pose reads as its angles;
4. :func:`range_step` and :func:`check_ranges`: each joint through its whole range by hand, live angles shown;
   the ranges seen against the limits, narrowed if the user agrees;
5. :func:`verify_step`: torque on, slowly, to home, the calibration pose and rest, one at a time.

Angles are radians inside, degrees in what the user reads.  Raw positions are the servos' actual shaft pulses
(:meth:`~retarget.calibrate.servos.ServoLink.read_actual`).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Mapping

import numpy as np

from drivers import DynamixelBus
from drivers.control_table import PULSES_PER_REV, RAD_PER_PULSE
from retarget.arm.calibration import ServoCalibration
from retarget.arm.model import Arm, Joint
from retarget.calibrate.hands import Hands
from retarget.calibrate.prompts import Prompter
from retarget.calibrate.servos import ServoInfo, ServoLink
from retarget.control.clock import Clock
from retarget.errors import RetargetError

log = logging.getLogger(__name__)

MIN_NUDGE_PULSES = 20  #: a nudge must turn every servo of the joint this far (about 1.8 deg) to tell its direction
NUDGE = math.radians(20.0)  #: how far the scripted hand nudges a joint
RANGE_TOLERANCE = math.radians(3.0)  #: a limit counts as reached within this
MIN_RANGE = math.radians(5.0)  #: a joint turned less than this was not moved: its range is not checked
SHADOW_TOLERANCE = math.radians(5.0)  #: a shadow servo may read this far from its primary while turned by hand
VERIFY_SPEED = 0.35  #: rad/s (20 deg/s), the servos' Profile Velocity during the verification moves
VERIFY_ACCEL = 2.0  #: rad/s^2, their Profile Acceleration
VERIFY_TOLERANCE = math.radians(2.0)  #: a verification pose counts as reached within this


class CalibrationError(RetargetError):
    """A step could not measure what it needs (a joint that did not move when asked)."""


def deg(x: float) -> str:
    return f"{math.degrees(x):+.1f}"


def wrap(pulses: float) -> float:
    """A pulse difference in -2048..2047: the shortest way round one turn.

    >>> wrap(4000), wrap(-100), wrap(2048)
    (-96, -100, -2048)
    """
    half = PULSES_PER_REV // 2
    return (pulses + half) % PULSES_PER_REV - half


def calibration_pose(arm: Arm) -> np.ndarray:
    return arm.calibration_pose if arm.calibration_pose is not None else arm.home


# ------------------------------------------------------------------------------------------------ 1. connect


def connect_step(io: Prompter, link: ServoLink) -> dict[int, ServoInfo]:
    """Ping every servo, compare the models with the arm file, then (after Enter) torque off."""
    arm = link.arm
    io.say(f"Step 1/5: connect to the {arm.title or arm.name} on {link.port_name} at {link.baud} baud")
    info = link.check()
    for i in info.values():
        io.say(f"  servo {i.id:>3}  {i.model:<11} firmware {i.firmware}")
    io.enter("Hold the arm: its torque goes off next and it goes limp")
    link.torque_off()
    io.say("  torque is off")
    return info


# ------------------------------------------------------------------------------------------------ 2. reference


def reference_step(io: Prompter, link: ServoLink, hands: Hands | None) -> dict[int, int]:
    """Ask for the calibration pose (each joint's angle and hint), then read every servo's raw position."""
    arm = link.arm
    pose = calibration_pose(arm)
    io.say("Step 2/5: put the arm in its calibration pose")
    for joint, q in zip(arm.joints, pose, strict=True):
        hint = f"  ({joint.calibration_hint})" if joint.calibration_hint else ""
        io.say(f"  {joint.name:<14} {deg(q):>7} deg{hint}")
    if hands is not None:
        hands.place(pose)
    io.enter("Hold it there, still")
    return link.read_actual()


# ------------------------------------------------------------------------------------------------ 3. directions


def direction_step(
    io: Prompter, link: ServoLink, ref: Mapping[int, int], hands: Hands | None, *, tries: int = 5
) -> dict[int, int]:
    """Each joint turned a little in its positive direction: every servo's direction from the sign of its turn
    (shadows too).  CalibrationError after ``tries`` nudges too small to tell."""
    arm = link.arm
    pose = calibration_pose(arm)
    io.say("Step 3/5: directions (each joint a little in its positive direction, towards its upper limit)")
    directions = {}
    for j, joint in enumerate(arm.joints):
        deltas = _nudge(io, link, joint, ref, hands, tries, min(pose[j] + NUDGE, joint.upper), j)
        for s in joint.servos:
            directions[s.id] = 1 if deltas[s.id] > 0 else -1
        words = ", ".join(f"servo {s.id} {'normal' if directions[s.id] > 0 else 'reverse'}" for s in joint.servos)
        io.say(f"  {joint.name}: {words}")
    return directions


def _nudge(
    io: Prompter,
    link: ServoLink,
    joint: Joint,
    ref: Mapping[int, int],
    hands: Hands | None,
    tries: int,
    target: float,
    j: int,
) -> dict[int, float]:
    ids = tuple(s.id for s in joint.servos)
    for _ in range(tries):
        if hands is not None:
            hands.nudge(j, target)
        io.enter(f"Turn {joint.name} 10-30 deg towards its upper limit ({deg(joint.upper)} deg), hold it")
        now = link.read_actual(ids)
        deltas = {i: wrap(now[i] - ref[i]) for i in ids}
        small = [i for i in ids if abs(deltas[i]) < MIN_NUDGE_PULSES]
        if not small:
            return deltas
        io.say(f"  {joint.name} hardly turned (servo {', '.join(map(str, small))}): again, a little further")
    raise CalibrationError(f"{joint.name} did not turn when asked: cannot tell its servos' directions")


def servo_calibrations(
    arm: Arm, ref: Mapping[int, int], directions: Mapping[int, int], info: Mapping[int, ServoInfo]
) -> tuple[ServoCalibration, ...]:
    """Each servo's offset so that the raw positions ``ref`` read as the calibration pose, with ``directions``.

    The driver sets Drive Mode bit 0 to the direction, so a reversed servo reports ``4096 - actual``; its offset
    is counted in that frame (``0 rad = 2048 + offset``), within -2048..2047.
    """
    out = []
    for joint, q in zip(arm.joints, calibration_pose(arm), strict=True):
        for s in joint.servos:
            d = directions[s.id]
            actual = ref[s.id] % PULSES_PER_REV
            present = actual if d > 0 else (PULSES_PER_REV - actual) % PULSES_PER_REV
            offset = int(wrap(round(present - 2048 - q / RAD_PER_PULSE)))
            out.append(ServoCalibration(s.id, joint.name, offset, d, info[s.id].firmware))
    return tuple(out)


def single_turn_notes(arm: Arm, servos: tuple[ServoCalibration, ...]) -> list[str]:
    """Where a servo's single turn (0..4095 pulses) cannot hold a joint's whole range at its new offset: the
    driver clips the limits there (the "positions that underflow" of a badly mounted horn)."""
    notes = []
    by_id = {s.id: s for s in servos}
    for joint in arm.joints:
        for s in joint.servos:
            off = by_id[s.id].offset
            lo = max(joint.lower, (0 - 2048 - off) * RAD_PER_PULSE)
            hi = min(joint.upper, (PULSES_PER_REV - 1 - 2048 - off) * RAD_PER_PULSE)
            if lo > joint.lower + RANGE_TOLERANCE or hi < joint.upper - RANGE_TOLERANCE:
                notes.append(
                    f"{joint.name}: servo {s.id}'s single turn covers only {deg(lo)}..{deg(hi)} deg of the limits "
                    f"{deg(joint.lower)}..{deg(joint.upper)} at this mounting (re-seat its horn to use them all)"
                )
    return notes


# ------------------------------------------------------------------------------------------------ 4. ranges


class Angles:
    """Raw positions to joint angles with the new calibration, relative to the reference reading (so a servo
    that counts past one turn while limp reads right)."""

    def __init__(self, arm: Arm, ref: Mapping[int, int], directions: Mapping[int, int]):
        pose = calibration_pose(arm)
        self.zero = {s.id: (ref[s.id], directions[s.id], float(pose[j])) for j, jt in enumerate(arm.joints)
                     for s in jt.servos}  # fmt: skip

    def of(self, readings: Mapping[int, int]) -> dict[int, float]:
        """Servo ID -> its joint's angle, rad."""
        out = {}
        for i, r in readings.items():
            r0, d, q0 = self.zero[i]
            out[i] = q0 + d * wrap(r - r0) * RAD_PER_PULSE
        return out


def range_step(
    io: Prompter, link: ServoLink, angles: Angles, hands: Hands | None, *, auto: bool = False
) -> dict[str, tuple[float, float]]:
    """Each joint turned by hand through its whole range, the live angle and limits shown: the range seen per
    joint (rad).  ``auto`` without ``hands`` (``--yes`` on a real arm): nobody turns it, nothing is measured."""
    arm = link.arm
    io.say("Step 4/5: ranges (turn each joint by hand from one end to the other and back)")
    if auto and hands is None:
        io.say("  skipped: --yes on a real arm (nobody turns the joints)")
        return {}
    measured = {}
    for j, joint in enumerate(arm.joints):
        ids = tuple(s.id for s in joint.servos)
        seen = [math.inf, -math.inf, 0.0]  # lowest, highest, worst shadow gap

        def sample(joint: Joint = joint, ids: tuple[int, ...] = ids, seen: list[float] = seen) -> str:
            a = angles.of(link.read_actual(ids))
            q = a[ids[0]]
            seen[0], seen[1] = min(seen[0], q), max(seen[1], q)
            seen[2] = max([seen[2]] + [abs(a[i] - q) for i in ids[1:]])
            return (
                f"  {joint.name:<14} {deg(q):>7} deg   seen {deg(seen[0])} .. {deg(seen[1])}   "
                f"limits {deg(joint.lower)} .. {deg(joint.upper)}"
            )

        step: Callable[[], bool] | None = hands.sweep(j, joint.lower, joint.upper) if hands is not None else None
        io.watch(f"Turn {joint.name} through its whole range, both ways", sample, step)
        if seen[2] > SHADOW_TOLERANCE:
            io.say(f"  warning: {joint.name}'s servos disagree by {math.degrees(seen[2]):.1f} deg: a shadow servo's "
                   "direction or offset is wrong (calibrate again)")  # fmt: skip
        measured[joint.name] = (seen[0], seen[1])
    return measured


def check_ranges(io: Prompter, arm: Arm, measured: Mapping[str, tuple[float, float]]) -> dict[str, tuple[float, float]]:
    """The ranges seen against the arm file's limits: a warning per limit the arm could not reach (or went past);
    the narrowed limits (rad) of the joints that fell short, when the user agrees."""
    short = {}
    for joint in arm.joints:
        if joint.name not in measured:
            continue
        lo, hi = measured[joint.name]
        if hi - lo < MIN_RANGE:
            io.say(f"  {joint.name}: hardly turned ({deg(lo)}..{deg(hi)} deg): its range is not checked")
            continue
        if lo < joint.lower - RANGE_TOLERANCE or hi > joint.upper + RANGE_TOLERANCE:
            io.say(f"  {joint.name}: turned to {deg(lo)}..{deg(hi)} deg, past its limits "
                   f"{deg(joint.lower)}..{deg(joint.upper)} (the limits stay)")  # fmt: skip
        if lo > joint.lower + RANGE_TOLERANCE or hi < joint.upper - RANGE_TOLERANCE:
            io.say(f"  warning: {joint.name} reached only {deg(lo)}..{deg(hi)} deg of its limits "
                   f"{deg(joint.lower)}..{deg(joint.upper)}")  # fmt: skip
            short[joint.name] = (max(joint.lower, lo), min(joint.upper, hi))
    if not short:
        io.say("  every joint reached its limits")
        return {}
    if io.confirm(f"Narrow the limits of {', '.join(short)} to what was seen?", default=True):
        return short
    return {}


# ------------------------------------------------------------------------------------------------ 5. verify


def verify_step(io: Prompter, arm: Arm, port: str, clock: Clock, *, baud: int | None = None) -> bool:
    """Torque on at low speed; home, the calibration pose and rest, each after Enter, each confirmed by the user.
    False at the first pose the user says looks wrong (torque goes off: shutdown OFF)."""
    io.say(f"Step 5/5: verify (torque on, {math.degrees(VERIFY_SPEED):.0f} deg/s at most)")
    io.enter("Keep clear of the arm: its torque goes on now, holding it where it is")
    bus = DynamixelBus(
        arm,
        port,
        baud=baud,
        shutdown="off",
        profile_velocity=VERIFY_SPEED,
        profile_acceleration=VERIFY_ACCEL,
        clock=clock,
    )
    with bus:
        for name, pose in (("home", arm.home), ("calibration", calibration_pose(arm)), ("rest", arm.rest)):
            angles = " ".join(deg(q) for q in pose)
            io.enter(f"Move to {name} ({angles} deg)")
            _move(io, bus, arm.clip(np.asarray(pose)), clock)
            if not io.confirm(f"Does the arm look like its {name} pose?", default=True):
                io.say("  the calibration is wrong: torque goes off; put the arm in its calibration pose again")
                return False
    io.say("  torque is off")
    return True


def _move(io: Prompter, bus: DynamixelBus, pose: np.ndarray, clock: Clock) -> None:
    q = bus.read_positions()
    bus.write_goals(pose)
    deadline = clock.now() + float(np.max(np.abs(pose - q))) / VERIFY_SPEED * 1.5 + 3.0
    while True:
        q = bus.read_positions()
        error = float(np.max(np.abs(q - pose)))
        if error < VERIFY_TOLERANCE:
            return
        if clock.now() > deadline:
            io.say(f"  warning: still {math.degrees(error):.1f} deg away: blocked, or a wrong offset")
            return
        clock.sleep_until(clock.now() + 0.05)


__all__ = [
    "Angles",
    "CalibrationError",
    "check_ranges",
    "connect_step",
    "direction_step",
    "range_step",
    "reference_step",
    "servo_calibrations",
    "single_turn_notes",
    "verify_step",
    "wrap",
]
