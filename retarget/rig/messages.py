"""A rig's teleop messages: one target per arm in one line or datagram, in the rig's world frame.

Forms (arm names are the rig's; either arm may be left out; positions metres, angles degrees)::

    left 0.3 0.35 0.2 right 0.3 -0.35 0.2                 NAME x y z [roll pitch yaw], spaces and/or commas
    left 0.3,0.35,0.2,0,90,0                              one arm only: the others keep their targets
    {"left": {"x": 0.3, "y": 0.35, "z": 0.2}, "right": {"x": 0.3, "y": -0.35, "z": 0.2, "rpy": [0, 90, 0]}}

Each arm's part is parsed as one arm's message (:func:`~retarget.teleop.gate.parse_message`, the same
:class:`~retarget.teleop.rejects.Reject` reasons), then :class:`RigGate` turns it into that arm's base frame
(its rig placement, a :class:`~retarget.teleop.gate.BasePose`) and checks it with that arm's own gate, so the
box, the reach and the blocked zones are each arm's own.

A message is taken whole or not at all: ``OVERSIZE``, ``MALFORMED`` (not one of the forms, an unknown arm name, an
arm named twice, no arm at all) and ``NON_FINITE`` are counted for the message (:attr:`RigGate.rejects`);
``OUT_OF_BOX``, ``OUT_OF_REACH`` and ``BLOCKED`` for the arm whose part failed (its gate's counter), and the
other arms' parts of that message are dropped too.  A rejected message never moves any arm.

Math only: no sockets, drivers or simulator.
"""

from __future__ import annotations

import json
import re
import threading
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from retarget.errors import ConfigError
from retarget.teleop.gate import (
    MAX_MESSAGE_BYTES,
    BasePose,
    Message,
    RejectCounter,
    Target,
    TargetBounds,
    TargetGate,
    json_values,
    message_of,
    message_text,
    parse_message,
)
from retarget.teleop.rejects import Reject, TargetRejected

if TYPE_CHECKING:
    from retarget.collision import CollisionModel
    from retarget.control.clock import Clock
    from retarget.rig.spec import Rig, RigArm

__all__ = ["RigGate", "base_pose", "parse_rig_message"]

_SPLIT = re.compile(r"[\s,]+")
_WORD = re.compile(r"^[A-Za-z][A-Za-z0-9_-]*$")
_NUMBER_WORDS = frozenset({"nan", "inf", "infinity"})
_FORMS = 'Expected \'NAME x y z [roll pitch yaw] ...\' or {"NAME": {"x": .., "y": .., "z": ..}, ...}'


def parse_rig_message(
    data: str | bytes, names: Sequence[str], *, max_bytes: int = MAX_MESSAGE_BYTES, key: str = "target"
) -> dict[str, Message] | None:
    """One line or datagram -> ``{arm name: Message}`` (world frame, in message order); None for a blank line or a
    ``#`` comment.  ``names``: the rig's arms.  Raises :class:`~retarget.teleop.rejects.TargetRejected`
    (``OVERSIZE``, ``MALFORMED`` or ``NON_FINITE``) whose ``key`` is ``target``, or ``target.<arm>`` for one arm's part.

    >>> m = parse_rig_message("left 0.3 0.35 0.2 right 0.3,-0.35,0.2", ("left", "right"))
    >>> {name: part.position.tolist() for name, part in m.items()}
    {'left': [0.3, 0.35, 0.2], 'right': [0.3, -0.35, 0.2]}
    >>> parse_rig_message('{"middle": {"x": 0, "y": 0, "z": 0}}', ("left", "right"))
    Traceback (most recent call last):
    ...
    retarget.teleop.rejects.TargetRejected: target: Expected an arm of the rig (left, right) (got 'middle')
    """
    text = message_text(data, max_bytes=max_bytes, key=key)
    if text is None:
        return None
    if text.startswith("{"):
        return _json_message(text, names, key)
    return _text_message(text, names, key)


def _arm_name(word: str, names: Sequence[str], seen: Mapping[str, object], key: str, text: str) -> str:
    """``word`` as an arm name not seen yet, else MALFORMED."""
    if word not in names:
        raise TargetRejected(Reject.MALFORMED, f"Expected an arm of the rig ({', '.join(names)})", key=key, value=word)
    if word in seen:
        raise TargetRejected(Reject.MALFORMED, f"Expected each arm at most once, got {word} twice", key=key, value=text)
    return word


def _text_message(text: str, names: Sequence[str], key: str) -> dict[str, Message]:
    """``NAME x y z [r p y] NAME ...`` -> each arm's Message."""
    groups: dict[str, list[str]] = {}
    current: list[str] | None = None
    for token in (t for t in _SPLIT.split(text) if t):
        if token in names or (_WORD.match(token) and token.lower() not in _NUMBER_WORDS):
            current = groups[_arm_name(token, names, groups, key, text)] = []
        elif current is None:
            raise TargetRejected(Reject.MALFORMED, _FORMS, key=key, value=text)
        else:
            current.append(token)
    out: dict[str, Message] = {}
    for name, tokens in groups.items():
        message = parse_message(" ".join(tokens), max_bytes=len(text) + 1, key=f"{key}.{name}") if tokens else None
        if message is None:  # a name with no numbers
            raise TargetRejected(Reject.MALFORMED, f"Expected x y z after {name}", key=f"{key}.{name}", value=text)
        out[name] = message
    return out


def _json_message(text: str, names: Sequence[str], key: str) -> dict[str, Message]:
    """``{"NAME": {"x": .., "y": .., "z": ..}, ...}`` -> each arm's Message (a key twice is MALFORMED)."""

    def pairs(items: list[tuple[str, object]]) -> dict[str, object]:
        obj: dict[str, object] = {}
        for name, value in items:
            if name in obj:
                raise TargetRejected(Reject.MALFORMED, f"Expected each key once, got {name!r} twice", key=key,
                                     value=text)  # fmt: skip
            obj[name] = value
        return obj

    try:
        obj = json.loads(text, object_pairs_hook=pairs)
    except TargetRejected:
        raise
    except (ValueError, RecursionError):
        raise TargetRejected(Reject.MALFORMED, "Expected a JSON object", key=key, value=text) from None
    if not isinstance(obj, dict) or not obj:
        raise TargetRejected(Reject.MALFORMED, _FORMS, key=key, value=text)
    out: dict[str, Message] = {}
    for name, part in obj.items():
        name = _arm_name(name, names, out, key, text)
        part_key = f"{key}.{name}"
        out[name] = message_of(json_values(part, key=part_key, text=text), key=part_key, text=text)
    return out


def base_pose(rig_arm: RigArm) -> BasePose:
    """The arm's placement in the rig as a gate's :class:`~retarget.teleop.gate.BasePose` (world from base)."""
    T = rig_arm.placement.matrix
    return BasePose(np.array(T[:3, :3]), np.array(T[:3, 3]))


class RigGate:
    """Parse a rig's messages and pass each arm's part through that arm's :class:`~retarget.teleop.gate.TargetGate`
    (see the module docstring); counts the message-level rejects in :attr:`rejects`, each arm's in its gate's.

    ``gates``: arm name -> its gate (with the arm's placement as ``frame_pose``), in rig order; build them with
    :meth:`for_rig`.

    >>> from retarget.control.clock import VirtualClock
    >>> from retarget.rig import load_rig
    >>> gate = RigGate.for_rig(load_rig("wx250s-pair"), clock=VirtualClock())
    >>> targets = gate.accept("left 0.3 0.35 0.2 right 0.3 -0.35 0.2")
    >>> {name: t.position.round(6).tolist() for name, t in targets.items()}  # each in its arm's base frame
    {'left': [0.3, 0.05, 0.2], 'right': [0.3, -0.05, 0.2]}
    >>> gate.accept("left 0.3 0.35 0.2 right 3 0 0.2"), gate.arm_counts("right")["out_of_box"]  # all or nothing
    (None, 1)
    """

    def __init__(
        self,
        gates: Mapping[str, TargetGate],
        *,
        max_bytes: int = MAX_MESSAGE_BYTES,
        counter: RejectCounter | None = None,
    ):
        if not gates:
            raise ValueError("Expected the gate of at least one arm, got none")
        if max_bytes < 1:
            raise ConfigError("Expected a size limit of at least 1 byte", key="max_bytes", value=max_bytes)
        self.gates: dict[str, TargetGate] = dict(gates)
        self.names: tuple[str, ...] = tuple(self.gates)
        self.max_bytes = int(max_bytes)
        self.rejects = counter if counter is not None else RejectCounter()  #: the message-level rejects
        self.accepted = 0  #: messages accepted
        self._lock = threading.Lock()

    @classmethod
    def for_rig(
        cls,
        rig: Rig,
        *,
        clock: Clock,
        margin: float = 0.2,
        models: Mapping[str, CollisionModel] | None = None,
        max_bytes: int = MAX_MESSAGE_BYTES,
    ) -> RigGate:
        """Each arm's gate: its reach + ``margin`` metres, its collision model's blocked zones (``models`` by arm
        name; None: none), its placement as the frame; targets stamped on ``clock`` (the loop's)."""
        gates = {}
        for a in rig.arms:
            bounds = TargetBounds.for_arm(a.arm, margin=margin, collision=None if models is None else models[a.name])
            gates[a.name] = TargetGate(bounds, clock=clock, frame_pose=base_pose(a), max_bytes=max_bytes)
        return cls(gates, max_bytes=max_bytes)

    def accept(self, data: str | bytes, *, source: str = "") -> dict[str, Target] | None:
        """One raw message -> ``{arm name: Target}`` (base frames), or None (blank, or rejected and counted)."""
        try:
            messages = parse_rig_message(data, self.names, max_bytes=self.max_bytes)
        except TargetRejected as exc:
            self.rejects.add(exc, source)
            return None
        if messages is None:
            return None
        converted = {}
        for name, message in messages.items():
            gate = self.gates[name]
            try:
                converted[name] = gate.convert(message, key=f"target.{name}")
            except TargetRejected as exc:
                gate.rejects.add(exc, f"{source} {name}".strip())
                return None
        return self._stamp(converted, {})

    def one_shot(self, text: str, *, key: str = "to") -> dict[str, Target]:
        """A single message given up front (``--to``): raises :class:`~retarget.teleop.rejects.TargetRejected`
        (``key``) instead of counting.  A part inside a blocked zone is not refused: that arm steers to the nearest
        safe point instead (``Target.aim``) and never reaches it; counted ``BLOCKED`` for the arm."""
        messages = parse_rig_message(text, self.names, max_bytes=self.max_bytes, key=key)
        if not messages:
            raise TargetRejected(Reject.MALFORMED, _FORMS, key=key, value=text)
        converted, aims = {}, {}
        for name, message in messages.items():
            gate = self.gates[name]
            converted[name] = position, _ = gate.convert(message, key=f"{key}.{name}", blocked=False)
            collision = gate.bounds.collision
            if collision is not None and gate.bounds.is_blocked(position):
                aims[name] = np.asarray(collision.push_out(position), dtype=np.float64)
                gate.reject(Reject.BLOCKED, "Expected a point clear of the table, the keep-out zones and the base; "
                            "going to the nearest safe point", source=name, value=text)  # fmt: skip
        return self._stamp(converted, aims)

    def _stamp(
        self,
        converted: Mapping[str, tuple[npt.NDArray[np.float64], npt.NDArray[np.float64] | None]],
        aims: Mapping[str, npt.NDArray[np.float64]],
    ) -> dict[str, Target]:
        with self._lock:
            self.accepted += 1
            out = {}
            for name, (position, rotation) in converted.items():
                gate = self.gates[name]
                out[name] = Target(position, rotation, gate.clock.now(), gate.accepted, aims.get(name))
                gate.accepted += 1
        return out

    def reject(self, reason: Reject, message: str, *, source: str = "", value: object = None) -> None:
        """Count a message-level rejection found while reading (a line or datagram over the size limit)."""
        self.rejects.add(TargetRejected(reason, message, value=value), source)

    def counts(self) -> dict[str, int]:
        """The message-level rejects by reason (zeros included)."""
        return self.rejects.counts()

    def arm_counts(self, name: str) -> dict[str, int]:
        """Arm ``name``'s rejects by reason (its part out of its box, reach or blocked; zeros included)."""
        return self.gates[name].rejects.counts()

    def totals(self) -> dict[str, int]:
        """Every reject by reason: the message's and every arm's."""
        out = self.counts()
        for name in self.names:
            for reason, n in self.arm_counts(name).items():
                out[reason] += n
        return out
