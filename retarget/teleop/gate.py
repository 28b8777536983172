"""Teleoperation targets: parsing and validation of messages into base-frame targets.

A *message* is one line (of stdin) or one datagram (UDP), at most ``max_bytes`` long::

    0.30 0 0.20                                  x y z            (spaces and/or commas)
    0.30,0,0.20,0,90,0                           x y z roll pitch yaw
    {"x": 0.30, "y": 0, "z": 0.20}               JSON; optionally "rpy": [r, p, y] or "roll"/"pitch"/"yaw"

Positions are metres (in the base frame, or the world frame through a :class:`BasePose`), angles are
degrees (the edge of the program; radians inside).  Blank lines and ``#`` comments are skipped.

Every message runs the same gate, in this order, and a failure rejects it with a :class:`Reject` reason
that is counted (:class:`RejectCounter`) and logged as a warning (rate-limited): ``OVERSIZE`` (over
``max_bytes``), ``MALFORMED`` (not a message of the forms above, not UTF-8), ``NON_FINITE`` (NaN, inf,
overflow), ``OUT_OF_BOX`` (outside the :class:`TargetBounds` box), ``OUT_OF_REACH`` (farther from the
shoulder pivot than the arm's reach + margin) and ``BLOCKED`` (with a collision model: closer than its clearance
to a blocked zone, i.e. below the table, inside a keep-out zone or inside the base).  A rejected message never
becomes a target, so it never moves the arm.

An accepted message becomes a :class:`Target` stamped with its receive time on the *loop's* clock.
The sources the messages arrive from (stdin, UDP, one shot) are in :mod:`retarget.teleop.sources`;
:func:`step_toward` is the follower's Cartesian speed limit.

This module is math only: it imports neither ``drivers``, ``sim``, ``serial`` nor sockets.
"""

from __future__ import annotations

import collections
import json
import logging
import math
import re
import threading
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from retarget.arm.kinematics import rpy_matrix
from retarget.arm.model import Arm
from retarget.control.clock import Clock
from retarget.errors import ConfigError
from retarget.mapping.workspace import arm_geometry
from retarget.teleop.gripper import split_gripper
from retarget.teleop.rejects import Reject, TargetRejected

if TYPE_CHECKING:
    from retarget.collision import CollisionModel

__all__ = [
    "BasePose",
    "MAX_MESSAGE_BYTES",
    "Message",
    "Reject",
    "RejectCounter",
    "Target",
    "TargetBounds",
    "TargetGate",
    "TargetRejected",
    "json_values",
    "message_of",
    "parse_message",
    "step_toward",
]

log = logging.getLogger(__name__)

MAX_MESSAGE_BYTES = 1024  #: default size limit of one line or datagram
MAX_RPY_DEG = 360.0  #: every roll, pitch and yaw (of a target or of the base pose) is within +-360 degrees


# --------------------------------------------------------------------------------------------------- parsing


@dataclass(frozen=True)
class Message:
    """A parsed message, before the frame change and the bounds: ``position`` ``(3,)`` metres, ``rpy`` radians."""

    position: npt.NDArray[np.float64]
    rpy: npt.NDArray[np.float64] | None = None


_NUMBER = re.compile(r"^[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?$|^[+-]?(?:nan|inf|infinity)$", re.IGNORECASE)
_SPLIT = re.compile(r"[\s,]+")
_JSON_KEYS = frozenset({"x", "y", "z", "rpy", "roll", "pitch", "yaw"})


def message_text(data: str | bytes, *, max_bytes: int = MAX_MESSAGE_BYTES, key: str = "target") -> str | None:
    """One line or datagram's text, stripped; ``None`` for a blank line or a ``#`` comment.  Raises
    :class:`TargetRejected` ``OVERSIZE`` (over ``max_bytes``) or ``MALFORMED`` (not UTF-8).

    >>> message_text(b"  0.3 0 0.2\\n"), message_text("# a comment")
    ('0.3 0 0.2', None)
    """
    size = len(data) if isinstance(data, bytes) else len(data.encode("utf-8", "surrogatepass"))
    if size > max_bytes:
        raise TargetRejected(Reject.OVERSIZE, f"Expected at most {max_bytes} bytes, got {size}", key=key)
    if isinstance(data, bytes):
        try:
            text = data.decode("utf-8")
        except UnicodeDecodeError:
            raise TargetRejected(Reject.MALFORMED, "Expected UTF-8 text", key=key, value=data) from None
    else:
        text = data
    text = text.strip()
    return None if not text or text.startswith("#") else text


def parse_message(data: str | bytes, *, max_bytes: int = MAX_MESSAGE_BYTES, key: str = "target") -> Message | None:
    """One line or datagram -> :class:`Message`; ``None`` for a blank line or a ``#`` comment.

    Raises :class:`TargetRejected` (``OVERSIZE``, ``MALFORMED`` or ``NON_FINITE``).  The bounds are
    checked later, by :class:`TargetBounds`, once the position is in the base frame.
    """
    text = message_text(data, max_bytes=max_bytes, key=key)
    if text is None:
        return None
    if text.startswith("{"):
        values = _json_values(text, key)
    else:
        tokens = [t for t in _SPLIT.split(text) if t]
        if len(tokens) not in (3, 6) or not all(_NUMBER.match(t) for t in tokens):
            raise TargetRejected(Reject.MALFORMED, "Expected 'x y z' or 'x y z roll pitch yaw' numbers", key=key,
                                 value=text)  # fmt: skip
        values = [float(t) for t in tokens]
    return message_of(values, key=key, text=text)


def message_of(values: Sequence[float], *, key: str = "target", text: object = None) -> Message:
    """x, y, z (and roll, pitch, yaw in degrees) -> :class:`Message`; ``NON_FINITE`` or ``MALFORMED`` (an angle out
    of range) naming ``key`` and ``text`` (the message as it came).  A helper of the rig's messages too."""
    if not all(math.isfinite(v) for v in values):
        raise TargetRejected(Reject.NON_FINITE, "Expected finite numbers", key=key, value=text)
    if not all(abs(v) <= MAX_RPY_DEG for v in values[3:]):
        message = f"Expected roll, pitch and yaw from {-MAX_RPY_DEG:g} to {MAX_RPY_DEG:g} degrees"
        raise TargetRejected(Reject.MALFORMED, message, key=key, value=text)
    position = np.array(values[:3], dtype=np.float64)
    rpy = np.radians(np.array(values[3:], dtype=np.float64)) if len(values) == 6 else None
    return Message(position, rpy)


def _json_values(text: str, key: str) -> list[float]:
    """x, y, z (and roll, pitch, yaw in degrees) of a JSON object message."""
    try:
        obj = json.loads(text)
    except (ValueError, RecursionError):
        raise TargetRejected(Reject.MALFORMED, "Expected a JSON object", key=key, value=text) from None
    return json_values(obj, key=key, text=text)


def json_values(obj: object, *, key: str = "target", text: object = None) -> list[float]:
    """x, y, z (and roll, pitch, yaw in degrees) of a decoded JSON object ``obj``; ``MALFORMED`` or ``NON_FINITE``
    naming ``key`` and ``text`` (the message as it came).  A helper of the rig's messages too."""
    if not isinstance(obj, dict) or not {"x", "y", "z"} <= obj.keys() or not obj.keys() <= _JSON_KEYS:
        raise TargetRejected(Reject.MALFORMED, 'Expected {"x": .., "y": .., "z": ..} (optional "rpy": [r, p, y])',
                             key=key, value=text)  # fmt: skip
    names = ["x", "y", "z"]
    raw: list[object] = [obj[n] for n in names]
    angles = {"roll", "pitch", "yaw"} & obj.keys()
    if "rpy" in obj and angles:
        raise TargetRejected(Reject.MALFORMED, 'Expected "rpy" or "roll"/"pitch"/"yaw", not both', key=key, value=text)
    if "rpy" in obj:
        if not isinstance(obj["rpy"], list) or len(obj["rpy"]) != 3:
            raise TargetRejected(Reject.MALFORMED, 'Expected "rpy": [roll, pitch, yaw]', key=key, value=text)
        raw += obj["rpy"]
    elif angles:
        raw += [obj.get(n, 0) for n in ("roll", "pitch", "yaw")]
    out = []
    for v in raw:
        if isinstance(v, bool) or not isinstance(v, int | float):
            raise TargetRejected(Reject.MALFORMED, "Expected numbers", key=key, value=text)
        try:
            out.append(float(v))
        except OverflowError:  # an integer beyond float range
            raise TargetRejected(Reject.NON_FINITE, "Expected finite numbers", key=key, value=text) from None
    return out


# --------------------------------------------------------------------------------------------------- frames, bounds


@dataclass(frozen=True)
class BasePose:
    """Where the arm's base frame sits in the world: ``p_world = rotation @ p_base + translation``.

    Arm descriptions carry no world pose, so the default is the identity (world = base).
    ``rotation`` ``(3, 3)``, ``translation`` ``(3,)`` metres.
    """

    rotation: npt.NDArray[np.float64] = field(default_factory=lambda: np.eye(3))
    translation: npt.NDArray[np.float64] = field(default_factory=lambda: np.zeros(3))

    @classmethod
    def from_xyz_rpy(cls, xyz: Sequence[float], rpy_deg: Sequence[float] = (0.0, 0.0, 0.0)) -> BasePose:
        """From a position (metres) and URDF roll-pitch-yaw (degrees, each within ``+-MAX_RPY_DEG``); a
        ConfigError with ``key="base_pose"`` for a non-finite number or an angle out of range."""
        values = [*xyz, *rpy_deg]
        if not all(math.isfinite(v) for v in values) or not all(abs(v) <= MAX_RPY_DEG for v in rpy_deg):
            message = f"Expected finite numbers, roll, pitch and yaw from {-MAX_RPY_DEG:g} to {MAX_RPY_DEG:g} degrees"
            raise ConfigError(message, key="base_pose", value=tuple(values))
        rpy = np.radians(np.asarray(rpy_deg, dtype=np.float64)).tolist()
        return cls(rpy_matrix(rpy), np.asarray(xyz, dtype=np.float64))

    def to_base(
        self, position: npt.NDArray[np.float64], rotation: npt.NDArray[np.float64] | None = None
    ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64] | None]:
        """A world-frame ``position`` ``(3,)`` (and ``rotation`` ``(3, 3)``) in the base frame."""
        R = self.rotation
        p = R.T @ (np.asarray(position, dtype=np.float64) - self.translation)
        return p, None if rotation is None else R.T @ rotation

    def to_world(self, position: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        """A base-frame ``position`` ``(3,)`` in the world frame."""
        return self.rotation @ np.asarray(position, dtype=np.float64) + self.translation


@dataclass(frozen=True, kw_only=True)
class TargetBounds:
    """Where targets may lie, base frame, metres: inside the box ``lower..upper`` and within ``max_radius``
    of ``center`` (the shoulder pivot).  Build with :meth:`for_arm`."""

    lower: npt.NDArray[np.float64]  #: ``(3,)`` box corner
    upper: npt.NDArray[np.float64]  #: ``(3,)`` box corner
    center: npt.NDArray[np.float64]  #: ``(3,)`` the shoulder pivot
    max_radius: float  #: the arm's reach from the pivot + margin
    #: blocked zones (below the table, keep-outs, the base): a point closer than its clearance is ``BLOCKED``
    collision: CollisionModel | None = field(default=None, compare=False)

    @classmethod
    def for_arm(
        cls,
        arm: Arm,
        *,
        margin: float = 0.2,
        box: Sequence[float] | None = None,
        floor: float = 0.0,
        collision: CollisionModel | None = None,
    ) -> TargetBounds:
        """Bounds of ``arm``: reach + ``margin`` metres around its shoulder pivot, and a box.

        ``box`` is ``(xmin, ymin, zmin, xmax, ymax, zmax)`` metres; by default the cube around the
        reach sphere, cut at ``z = floor`` (the base's mounting plane: no target below the table).
        Targets between the reach and reach + margin are accepted: the arm goes to the nearest
        point it can reach and reports the residual.  ``collision``: a model whose blocked zones reject
        targets too (:meth:`check`).
        """
        if not (math.isfinite(margin) and margin >= 0):
            raise ConfigError("Expected a margin >= 0 m", key="margin", value=margin)
        g = arm_geometry(arm)
        radius = g.reach + margin
        if box is None:
            lower = g.pivot - radius
            upper = g.pivot + radius
            lower[2] = max(lower[2], floor)
        else:
            values = np.asarray(box, dtype=np.float64)
            if values.shape != (6,) or not np.all(np.isfinite(values)):
                raise ConfigError("Expected 6 finite numbers xmin,ymin,zmin,xmax,ymax,zmax", key="box", value=box)
            lower, upper = values[:3], values[3:]
            if not np.all(lower < upper):
                raise ConfigError("Expected each minimum below its maximum", key="box", value=list(values))
        return cls(lower=lower, upper=upper, center=g.pivot.copy(), max_radius=float(radius), collision=collision)

    def check(self, position: npt.NDArray[np.float64], *, key: str = "target", blocked: bool = True) -> None:
        """Raise :class:`TargetRejected` (``OUT_OF_BOX``/``OUT_OF_REACH``/``BLOCKED``) unless ``position`` ``(3,)``
        is allowed (``blocked=False``: the blocked zones are not checked)."""
        p = np.asarray(position, dtype=np.float64)
        if not (np.all(p >= self.lower) and np.all(p <= self.upper)):
            lo = ",".join(f"{v:g}" for v in self.lower)
            hi = ",".join(f"{v:g}" for v in self.upper)
            raise TargetRejected(Reject.OUT_OF_BOX, f"Expected a point inside the box [{lo}]..[{hi}] m", key=key,
                                 value=_fmt(p))  # fmt: skip
        r = float(np.linalg.norm(p - self.center))
        if r > self.max_radius:
            raise TargetRejected(Reject.OUT_OF_REACH, f"Expected a point within {self.max_radius:.3f} m of the "
                                 f"shoulder (reach + margin), got {r:.3f} m", key=key, value=_fmt(p))  # fmt: skip
        if blocked and self.is_blocked(p):
            assert self.collision is not None
            margin = self.collision.point_margin(p)
            raise TargetRejected(Reject.BLOCKED, f"Expected a point {self.collision.clearance * 1e3:g} mm clear of the "
                                 f"table, the keep-out zones and the base, got {margin * 1e3:.1f} mm", key=key,
                                 value=_fmt(p))  # fmt: skip

    def is_blocked(self, position: npt.NDArray[np.float64]) -> bool:
        """True when a collision model is set and ``position`` ``(3,)`` m is within its clearance of a blocked zone."""
        return self.collision is not None and bool(self.collision.point_blocked(position))


def _fmt(p: npt.NDArray[np.float64]) -> str:
    return ",".join(f"{v:.4g}" for v in p)


# --------------------------------------------------------------------------------------------------- the gate


@dataclass(frozen=True)
class Target:
    """An accepted target: ``position`` ``(3,)`` metres and ``rotation`` ``(3, 3)`` or None, base frame;
    ``received`` seconds on the loop's clock; ``seq`` counts accepted targets from 0."""

    position: npt.NDArray[np.float64]
    rotation: npt.NDArray[np.float64] | None
    received: float
    seq: int
    #: ``(3,)`` where the arm steers instead, when ``position`` is in a blocked zone (the nearest safe point; a
    #: one-shot target only: a stream's blocked targets are rejected); None: ``position`` itself
    aim: npt.NDArray[np.float64] | None = None
    #: ``(3,)`` the position as it came in, when ``position`` is it smoothed by the follower's One-Euro filter
    #: (:class:`~retarget.mapping.filter.OneEuro`); None: not filtered
    raw: npt.NDArray[np.float64] | None = None


class RejectCounter:
    """Thread-safe counts of rejected messages by :class:`Reject` reason, with rate-limited warnings.

    The first ``loud`` rejections of each reason are logged, then every ``every``-th, so a flood
    of garbage cannot flood stderr, yet nothing is silent.
    """

    def __init__(self, *, loud: int = 3, every: int = 100):
        self._counts: collections.Counter[Reject] = collections.Counter()
        self._lock = threading.Lock()
        self.loud = loud
        self.every = every

    def add(self, exc: TargetRejected, source: str = "") -> None:
        with self._lock:
            self._counts[exc.reason] += 1
            n = self._counts[exc.reason]
        if n <= self.loud or n % self.every == 0:
            more = f" ({n} {exc.reason.value} so far)" if n > self.loud else ""
            log.warning("rejected %s message: %s%s", source or "a", exc, more)

    def counts(self) -> dict[str, int]:
        """``{reason: count}`` for every reason (zeros included), a snapshot."""
        with self._lock:
            return {r.value: self._counts[r] for r in Reject}

    @property
    def total(self) -> int:
        with self._lock:
            return sum(self._counts.values())


class TargetGate:
    """Parse, change frame and bound-check messages into :class:`Target` s, counting the rejects.

    ``clock`` stamps receive times (the loop's clock).  ``frame_pose`` turns world-frame messages
    into the base frame (None: messages are in the base frame).
    """

    def __init__(
        self,
        bounds: TargetBounds,
        *,
        clock: Clock,
        frame_pose: BasePose | None = None,
        max_bytes: int = MAX_MESSAGE_BYTES,
        counter: RejectCounter | None = None,
    ):
        if max_bytes < 1:
            raise ConfigError("Expected a size limit of at least 1 byte", key="max_bytes", value=max_bytes)
        self.bounds = bounds
        self.clock = clock
        self.frame_pose = frame_pose
        self.max_bytes = int(max_bytes)
        self.rejects = counter if counter is not None else RejectCounter()
        self.accepted = 0
        self._lock = threading.Lock()
        #: the latest gripper closure a message asked for (its ``g`` field, retarget.teleop.gripper); None: none yet
        self.gripper: float | None = None

    def convert(
        self, message: Message, *, key: str = "target", blocked: bool = True
    ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64] | None]:
        """A parsed message -> ``(position (3,), rotation (3, 3) | None)`` in the base frame, bound-checked
        (``blocked=False``: the blocked zones are left to the caller)."""
        rotation = None if message.rpy is None else rpy_matrix(message.rpy.tolist())
        position = message.position
        if self.frame_pose is not None:
            position, rotation = self.frame_pose.to_base(position, rotation)
        self.bounds.check(position, key=key, blocked=blocked)
        return position, rotation

    def accept(self, data: str | bytes, *, source: str = "") -> Target | None:
        """One raw message -> a :class:`Target`, or None (blank, or rejected and counted)."""
        try:
            if len(data) > self.max_bytes:  # before any parse, as parse_message would
                parse_message(data, max_bytes=self.max_bytes)
            closure, rest = split_gripper(data)
            message = None if rest is None else parse_message(rest, max_bytes=self.max_bytes)
            if message is not None:
                position, rotation = self.convert(message)
            if closure is not None:  # a valid message only: a rejected target does not close the gripper either
                self.gripper = closure
            if message is None:
                return None
        except TargetRejected as exc:
            self.rejects.add(exc, source)
            return None
        with self._lock:
            seq = self.accepted
            self.accepted += 1
        return Target(position, rotation, self.clock.now(), seq)

    def reject(self, reason: Reject, message: str, *, source: str = "", value: object = None) -> None:
        """Count a rejection found outside :func:`parse_message` (e.g. a line over the limit while reading)."""
        self.rejects.add(TargetRejected(reason, message, value=value), source)


# --------------------------------------------------------------------------------------------------- motion helper


def step_toward(
    current: npt.NDArray[np.float64], goal: npt.NDArray[np.float64], max_distance: float
) -> npt.NDArray[np.float64]:
    """``current`` ``(3,)`` moved toward ``goal`` ``(3,)`` by at most ``max_distance`` metres (a Cartesian speed
    limit of ``max_distance`` per tick); ``goal`` itself when it is closer.  ``inf`` means no limit."""
    current = np.asarray(current, dtype=np.float64)
    goal = np.asarray(goal, dtype=np.float64)
    d = goal - current
    dist = float(np.linalg.norm(d))
    if dist <= max_distance:
        return goal.copy()
    step: npt.NDArray[np.float64] = current + d * (max_distance / dist)
    return step
