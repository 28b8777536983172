"""The one small error tree of ``retarget``.

Every failure a user can cause or meet is one of these, and each carries the
context needed to fix it: a file and line for BVH input, a key path for
configuration, servo IDs for the bus.  The CLI prints ``str(exc)`` on one line
and exits non-zero; ``-v`` shows the traceback.

    RetargetError
    ├── BvhError      (also ValueError)   path, line
    ├── ConfigError   (also ValueError)   path, key, value
    └── BusError      (also OSError)      ids
"""

from __future__ import annotations

from collections.abc import Iterable
from os import PathLike

_UNSET = object()


class RetargetError(Exception):
    """Base class of every error raised on purpose by retarget, drivers and sim."""


class BvhError(RetargetError, ValueError):
    """A BVH file that cannot be read.

    ``str(exc)`` is ``"path:line: message"`` (``line`` omitted when unknown).
    """

    def __init__(self, message: str, *, path: str | PathLike[str] | None = None, line: int | None = None):
        self.message = message
        self.path = None if path is None else str(path)
        self.line = line
        where = self.path or "<bvh>"
        if line is not None:
            where = f"{where}:{line}"
        super().__init__(f"{where}: {message}")


class ConfigError(RetargetError, ValueError):
    """An arm description, mapping or option with a bad value.

    ``str(exc)`` is ``"path: key: message (got value)"``; ``key`` is a key path
    such as ``joints[2].limits``.
    """

    def __init__(
        self,
        message: str,
        *,
        path: str | PathLike[str] | None = None,
        key: str | None = None,
        value: object = _UNSET,
    ):
        self.message = message
        self.path = None if path is None else str(path)
        self.key = key
        self.value = None if value is _UNSET else value
        parts = [p for p in (self.path, key) if p]
        text = message if value is _UNSET else f"{message} (got {value!r})"
        super().__init__(": ".join([*parts, text]))


class BusError(RetargetError, OSError):
    """A servo bus failure: no reply, a bad reply, a status error or a hardware alert.

    ``ids`` names the servos concerned (empty when the port itself failed).
    """

    def __init__(self, message: str, *, ids: Iterable[int] = ()):
        self.message = message
        self.ids = tuple(ids)
        prefix = f"servo {', '.join(map(str, self.ids))}: " if self.ids else ""
        super().__init__(f"{prefix}{message}")

    def __str__(self) -> str:  # OSError's own __str__ would prepend errno fields
        return self.args[0]
