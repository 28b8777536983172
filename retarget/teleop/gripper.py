"""The gripper field of teleoperation messages: ``g`` = closure 0 (open) .. 1 (closed).

In a text message, a ``g=V`` token (anywhere; ``g=open``/``g=close`` too); in JSON, a ``"g"`` key::

    0.30 0 0.20 g=1                   move and close
    g=0.5                             the gripper alone (no target: the arm holds its course)
    {"x": 0.3, "y": 0, "z": 0.2, "g": 0}

:func:`split_gripper` takes it out of the message before the target parse sees it.  A bad value rejects the whole
message (``MALFORMED``, or ``NON_FINITE``) so a typo never moves anything.

>>> split_gripper("0.3 0 0.2 g=1")
(1.0, '0.3 0 0.2')
>>> split_gripper('{"g": 0.25}')
(0.25, None)
>>> split_gripper("0.3 0 0.2")
(None, '0.3 0 0.2')
"""

from __future__ import annotations

import json
import math
import re

from retarget.teleop.rejects import Reject, TargetRejected

__all__ = ["split_gripper"]

_TOKEN = re.compile(r"(?:^|[\s,])g\s*[=:]\s*([^\s,]+)", re.IGNORECASE)
_WORDS = {"open": 0.0, "close": 1.0, "closed": 1.0}


def split_gripper(data: str | bytes, *, key: str = "target") -> tuple[float | None, str | bytes | None]:
    """``(closure or None, the message without it, or None when nothing else is left)``; TargetRejected for a
    bad value.  Data that is not UTF-8 is passed on untouched (the target parse rejects it)."""
    if isinstance(data, bytes):
        try:
            text = data.decode("utf-8")
        except UnicodeDecodeError:
            return None, data
    else:
        text = data
    stripped = text.strip()
    if stripped.startswith("{"):
        return _from_json(stripped, data, key)
    m = _TOKEN.search(stripped)
    if m is None:
        return None, data
    closure = _closure(m.group(1), key, stripped)
    rest = (stripped[: m.start()] + " " + stripped[m.end() :]).strip(" ,")
    return closure, rest or None


def _from_json(text: str, data: str | bytes, key: str) -> tuple[float | None, str | bytes | None]:
    try:
        obj = json.loads(text)
    except (ValueError, RecursionError):
        return None, data  # the target parse rejects it
    if not isinstance(obj, dict) or "g" not in obj:
        return None, data
    value = obj.pop("g")
    if isinstance(value, bool) or not isinstance(value, int | float | str):
        raise TargetRejected(Reject.MALFORMED, 'Expected "g": a number 0..1, "open" or "close"', key=key, value=text)
    closure = _closure(str(value), key, text)
    return closure, (json.dumps(obj) if obj else None)


def _closure(token: str, key: str, text: str) -> float:
    word = token.strip().lower()
    if word in _WORDS:
        return _WORDS[word]
    try:
        value = float(word)
    except ValueError:
        raise TargetRejected(Reject.MALFORMED, "Expected g=0..1, g=open or g=close", key=key, value=text) from None
    if not math.isfinite(value):
        raise TargetRejected(Reject.NON_FINITE, "Expected a finite gripper closure", key=key, value=text)
    if not 0.0 <= value <= 1.0:
        raise TargetRejected(Reject.MALFORMED, "Expected a gripper closure g from 0 (open) to 1 (closed)", key=key,
                             value=text)  # fmt: skip
    return value
