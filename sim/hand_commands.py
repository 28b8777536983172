"""Hand commands for a limp servo, from the command line and the control socket of ``retarget sim``.

A hand turns a servo's horn while its torque is off (:meth:`sim.servo.SimServo.move_by_hand`): that is how a
person calibrates an arm (LeRobot's ``lerobot-calibrate`` records each joint's range while it is turned by
hand).  Three gestures, in pulses (4096 per turn, Present Position's frame) and seconds:

============================  ==========================================  ==========================================
``retarget sim --hand``        control socket line                         what the hand does
============================  ==========================================  ==========================================
``ID:sweep:LO-HI:SECONDS``     ``hand ID sweep LO HI SECONDS``             back and forth between LO and HI, SECONDS
                                                                           per pass, until released (from where the
                                                                           joint is: first to the nearer end)
``ID:to:PULSES:SECONDS``       ``hand ID to PULSES SECONDS``               turn to PULSES in SECONDS, then hold there
``ID:release``                 ``release ID``                              let go: the joint stays where it was left
============================  ==========================================  ==========================================

A ``--hand`` item may end in ``@START``: seconds after the simulator started (default 0), as ``--unplug`` does.
With torque on the motor wins (the hand's path is ignored) until torque goes off again.

>>> parse_hand("2:sweep:1024-3072:2.5@1")
HandCommand(id=2, action=<HandAction.SWEEP: 'sweep'>, values=(1024.0, 3072.0), seconds=2.5, at=1.0)
>>> parse_words(["hand", "3", "to", "3000", "1"]).describe()
'to 3000 in 1 s'
>>> path = sweep_path(t0=0.0, start=2048.0, lo=1024.0, hi=3072.0, seconds=2.0)
>>> [round(path(t)) for t in (0.0, 1.0, 3.0, 5.0, 7.0)]  # to LO (half a pass away), to HI, back to LO, to HI
[2048, 1024, 3072, 1024, 3072]
"""

from __future__ import annotations

import enum
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass

from drivers.control_table import MAX_ID
from retarget.errors import ConfigError
from sim.bus import SimBus
from sim.hand import HandPath, smoothstep_path
from sim.servo import SimServo

__all__ = ["HandAction", "HandCommand", "HandSchedule", "parse_hand", "parse_words", "sweep_path"]

MAX_PULSES = 1_048_575  #: |pulses| a hand may turn to (the extended-position range of Goal Position)
MAX_HAND_SECONDS = 3600.0  #: one pass or turn
MAX_START_S = 86_400.0  #: START of a --hand item, seconds after the simulator started
_RANGE = re.compile(r"^\s*(-?\d+)\s*-\s*(-?\d+)\s*$")

CLI_FORMS = "ID:sweep:LO-HI:SECONDS, ID:to:PULSES:SECONDS or ID:release, each with an optional @START"
SOCKET_FORMS = "hand ID sweep LO HI SECONDS | hand ID to PULSES SECONDS | release ID"


class HandAction(enum.Enum):
    SWEEP = "sweep"
    TO = "to"
    RELEASE = "release"


@dataclass(frozen=True)
class HandCommand:
    """One gesture for servo ``id``: ``values`` are (LO, HI) for SWEEP, (PULSES,) for TO, () for RELEASE (pulses);
    ``seconds`` per pass or turn; ``at`` seconds after the simulator started (``--hand`` only)."""

    id: int
    action: HandAction
    values: tuple[float, ...] = ()
    seconds: float = 0.0
    at: float = 0.0

    def describe(self) -> str:
        """The gesture in words (the control socket's ``status`` reports it)."""
        if self.action is HandAction.SWEEP:
            return f"sweep {self.values[0]:g}..{self.values[1]:g}, {self.seconds:g} s per pass"
        if self.action is HandAction.TO:
            return f"to {self.values[0]:g} in {self.seconds:g} s"
        return "released"

    def apply(self, servo: SimServo, now: float) -> None:
        """Put the hand on ``servo`` at clock time ``now`` (or take it off)."""
        if self.action is HandAction.RELEASE:
            servo.move_by_hand(None)
        elif self.action is HandAction.TO:
            servo.turn_by_hand(self.values[0], duration=self.seconds, now=now)
        else:
            start = float(servo.get("Present Position"))
            lo, hi = self.values
            servo.move_by_hand(sweep_path(t0=now, start=start, lo=lo, hi=hi, seconds=self.seconds))


def sweep_path(*, t0: float, start: float, lo: float, hi: float, seconds: float) -> HandPath:
    """Back and forth between ``lo`` and ``hi`` (pulses), ``seconds`` per pass, easing in and out at each end.

    From ``start`` at clock time ``t0`` it goes first to the nearer end, in the share of a pass that distance is
    (at least a tenth of one), then sweeps on without end.
    """
    if not seconds > 0:
        raise ValueError(f"Expected seconds > 0, got {seconds}")
    span = abs(hi - lo) or 1.0
    first, second = (lo, hi) if abs(start - lo) <= abs(start - hi) else (hi, lo)
    lead = seconds * max(0.1, min(1.0, abs(start - first) / span)) if start != first else 0.0
    approach = smoothstep_path(t0=t0, start=start, end=first, duration=lead)
    t_sweep = t0 + lead

    def path(t: float) -> float:
        if t < t_sweep:
            return approach(t)
        passes, u = divmod((t - t_sweep) / seconds, 1.0)
        a, b = (first, second) if int(passes) % 2 == 0 else (second, first)
        return a + (b - a) * u * u * (3.0 - 2.0 * u)

    return path


# ------------------------------------------------------------------ parsing


def _error(message: str, key: str, value: str) -> ConfigError:
    return ConfigError(message, key=key, value=value)


def _servo_id(text: str, key: str, item: str) -> int:
    try:
        sid = int(text)
    except ValueError:
        raise _error(f"Expected a servo ID 0..{MAX_ID}", key, item) from None
    if not 0 <= sid <= MAX_ID:
        raise _error(f"Expected a servo ID 0..{MAX_ID}", key, item)
    return sid


def _pulses(text: str, key: str, item: str) -> float:
    try:
        value = int(text)
    except ValueError:
        raise _error(f"Expected whole pulses -{MAX_PULSES}..{MAX_PULSES}", key, item) from None
    if abs(value) > MAX_PULSES:
        raise _error(f"Expected whole pulses -{MAX_PULSES}..{MAX_PULSES}", key, item)
    return float(value)


def _seconds(text: str, key: str, item: str, *, hi: float, what: str, positive: bool = False) -> float:
    """``text`` as seconds in ``0..hi`` (``0 < s`` with ``positive``), else ConfigError "Expected ``what``"."""
    try:
        value = float(text)
    except ValueError:
        raise _error(f"Expected {what}", key, item) from None
    if not (math.isfinite(value) and 0.0 <= value <= hi) or (positive and value == 0.0):
        raise _error(f"Expected {what}", key, item)
    return value


def _duration(text: str, key: str, item: str) -> float:
    return _seconds(
        text, key, item, hi=MAX_HAND_SECONDS, what=f"seconds > 0 and <= {MAX_HAND_SECONDS:g}", positive=True
    )


def _command(sid: int, action: str, args: Sequence[str], key: str, item: str, at: float) -> HandCommand:
    """The gesture ``action`` with its arguments (pulses then seconds)."""
    name = action.strip().lower()
    if name == "sweep" and len(args) == 3:
        lo, hi = _pulses(args[0], key, item), _pulses(args[1], key, item)
        if lo == hi:
            raise _error("Expected LO and HI to differ", key, item)
        return HandCommand(sid, HandAction.SWEEP, (min(lo, hi), max(lo, hi)), _duration(args[2], key, item), at)
    if name == "to" and len(args) == 2:
        return HandCommand(sid, HandAction.TO, (_pulses(args[0], key, item),), _duration(args[1], key, item), at)
    if name == "release" and not args:
        return HandCommand(sid, HandAction.RELEASE, at=at)
    forms = CLI_FORMS if key == "--hand" else SOCKET_FORMS
    raise _error(f"Expected {forms}", key, item)


def parse_hand(text: str) -> HandCommand:
    """One ``--hand`` item (grammar in the module docstring); ConfigError keyed ``--hand`` quoting it otherwise.

    >>> parse_hand("4:to:1000:0.5").values
    (1000.0,)
    >>> parse_hand("4:wiggle")
    Traceback (most recent call last):
    ...
    retarget.errors.ConfigError: --hand: Expected ID:sweep:LO-HI:SECONDS, ID:to:PULSES:SECONDS or ID:release, each \
with an optional @START (got '4:wiggle')
    """
    key, item = "--hand", text.strip()
    body, sep, start = item.rpartition("@")
    if not sep:
        body = item
    at = _seconds(start, key, item, hi=MAX_START_S, what=f"@START seconds 0..{MAX_START_S:g}") if sep else 0.0
    parts = body.split(":")
    if len(parts) < 2:
        raise _error(f"Expected {CLI_FORMS}", key, item)
    sid = _servo_id(parts[0], key, item)
    args = parts[2:]
    if parts[1].strip().lower() == "sweep" and len(args) == 2:
        match = _RANGE.match(args[0])
        if match is None:
            raise _error("Expected a range LO-HI in pulses, e.g. 1024-3072", key, item)
        args = [match.group(1), match.group(2), args[1]]
    return _command(sid, parts[1], args, key, item, at)


def parse_words(words: Sequence[str]) -> HandCommand:
    """A control-socket ``hand ...`` or ``release ID`` line, split into words; ConfigError keyed ``hand``.

    >>> parse_words(["release", "2"]).action
    <HandAction.RELEASE: 'release'>
    """
    line = " ".join(words)
    if len(words) == 2 and words[0].lower() == "release":
        return HandCommand(_servo_id(words[1], "release", line), HandAction.RELEASE)
    if len(words) >= 3 and words[0].lower() == "hand":
        return _command(_servo_id(words[1], "hand", line), words[2], words[3:], "hand", line, 0.0)
    raise _error(f"Expected {SOCKET_FORMS}", words[0] if words else "hand", line)


# ------------------------------------------------------------------ scheduled hands (retarget sim --hand)


class HandSchedule:
    """The ``--hand`` commands of a bus, each applied when the bus clock passes ``bus.t_start + at``.

    A :class:`sim.server.ServerHook`: the serving loop calls :meth:`service` between packets.  Commands for one
    servo replace each other in time order.  :attr:`gestures` says what each servo's hand does now.

    >>> from retarget.control.clock import VirtualClock
    >>> from sim.bus import SimBus
    >>> bus = SimBus.from_ids([1, 2], clock=VirtualClock())
    >>> hands = HandSchedule(bus, [parse_hand("2:to:3072:1@0.5")])
    >>> hands.service((), bus.clock.now()); hands.gestures
    {}
    >>> bus.clock.advance(0.5); hands.service((), bus.clock.now()); hands.gestures
    {2: 'to 3072 in 1 s'}
    >>> bus.clock.advance(1.0); bus.servo(2).get("Present Position")
    3072
    """

    def __init__(self, bus: SimBus, commands: Sequence[HandCommand]):
        for command in commands:
            bus.servo(command.id)  # KeyError naming the bus's IDs
        self.bus = bus
        self._queue = sorted(commands, key=lambda c: c.at)
        self.gestures: dict[int, str] = {}  #: servo ID -> the gesture its hand is making (released: absent)

    def fds(self) -> Sequence[int]:
        return ()

    def due(self) -> float:
        return self.bus.t_start + self._queue[0].at if self._queue else math.inf

    def service(self, ready: Sequence[int], now: float) -> None:
        while self._queue and self.bus.t_start + self._queue[0].at <= now:
            command = self._queue.pop(0)
            self.apply(command, max(now, self.bus.t_start + command.at))

    def apply(self, command: HandCommand, now: float) -> None:
        """Apply ``command`` to its servo at clock time ``now`` at once (the control socket's path)."""
        command.apply(self.bus.servo(command.id), now)
        if command.action is HandAction.RELEASE:
            self.gestures.pop(command.id, None)
        else:
            self.gestures[command.id] = command.describe()
