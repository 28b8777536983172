"""Why a teleop message was rejected: :class:`Reject` (the key of the gate's counts) and :class:`TargetRejected`.

Kept apart from :mod:`~retarget.teleop.gate` so that the message parts it parses (the gripper's ``g`` field,
:mod:`~retarget.teleop.gripper`) raise the same error without importing the gate.

>>> TargetRejected(Reject.MALFORMED, "Expected x y z", value="1 2").reason.value
'malformed'
"""

from __future__ import annotations

import enum

from retarget.errors import ConfigError

__all__ = ["Reject", "TargetRejected"]


class Reject(enum.Enum):
    """Why a message was rejected (the key of the counts)."""

    OVERSIZE = "oversize"
    MALFORMED = "malformed"
    NON_FINITE = "non_finite"
    OUT_OF_BOX = "out_of_box"
    OUT_OF_REACH = "out_of_reach"
    BLOCKED = "blocked"  #: below the table, inside a keep-out zone or the base (a collision model's blocked zones)


class TargetRejected(ConfigError):
    """A message that is not an acceptable target; ``reason`` says why.  ``key`` names the input (a parameter
    such as ``position``, or ``target`` for a message of a stream)."""

    def __init__(self, reason: Reject, message: str, *, key: str = "target", value: object = None):
        self.reason = reason
        if value is None:
            super().__init__(message, key=key)
        else:
            super().__init__(message, key=key, value=_short(value))


def _short(value: object, limit: int = 60) -> object:
    if isinstance(value, bytes) and len(value) > limit:
        return value[:limit] + b"..."
    if isinstance(value, str) and len(value) > limit:
        return value[:limit] + "..."
    return value
