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

import math
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

    ``str(exc)`` is ``"path: key: message (got value)"``; ``key`` is a key path in the file
    such as ``joints[2].limits``, or, without a path, the name of the field or parameter
    (``rate``, ``mapping.floor``): the library speaks in fields, and only the CLI knows its flags.
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
        self._value = value  # _UNSET when no value was given, so a copy keeps "(got ...)" off too
        parts = [p for p in (self.path, key) if p]
        text = message if value is _UNSET else f"{message} (got {value!r})"
        super().__init__(": ".join([*parts, text]))

    def with_key(self, key: str) -> ConfigError:
        """The same error (message, path, value) about ``key``: how the CLI names the option that set a field.

        >>> ConfigError("Expected a tick rate > 0 Hz", key="rate", value=0.0).with_key("--rate")
        ConfigError('--rate: Expected a tick rate > 0 Hz (got 0.0)')
        """
        return ConfigError(self.message, path=self.path, key=key, value=self._value)


class BusError(RetargetError, OSError):
    """A servo bus failure: no reply, a bad reply, a status error or a hardware alert.

    ``ids`` names the servos concerned (empty when the port itself failed).
    """

    def __init__(self, message: str, *, ids: Iterable[int] = ()):
        self.message = message
        self.ids = tuple(ids)
        #: what a control loop had done when it met this error: its ``TickStats`` (set by ``run_ticks``) and its
        #: ``RunSummary`` (set by ``ControlLoop.run`` and ``run_teleop``); None when no loop was running
        self.stats: object | None = None
        self.summary: object | None = None
        prefix = f"servo {', '.join(map(str, self.ids))}: " if self.ids else ""
        super().__init__(f"{prefix}{message}")

    def __str__(self) -> str:  # OSError's own __str__ would prepend errno fields
        return str(self.args[0])


def require_positive(value: object, key: str, *, zero: bool = False, inf: bool = False) -> float:
    """``value`` as a float when it is a number > 0 (``zero``: >= 0; ``inf``: may be +inf), else a ConfigError.

    ``key`` is the field's name, as the library's callers spell it (the CLI maps it to its option).

    >>> require_positive(0.5, "tolerance")
    0.5
    >>> require_positive(0, "tolerance")
    Traceback (most recent call last):
    ...
    retarget.errors.ConfigError: tolerance: Expected a finite number > 0 (got 0)
    """
    x = float(value) if isinstance(value, int | float) and not isinstance(value, bool) else math.nan
    finite = math.isfinite(x) or (inf and x == math.inf)
    if not finite or x < 0 or (x == 0 and not zero):
        bound = ">= 0" if zero else "> 0"
        raise ConfigError(f"Expected a {'' if inf else 'finite '}number {bound}", key=key, value=value)
    return x


def require_count(value: object, key: str, *, zero: bool = False) -> int:
    """``value`` when it is an integer >= 1 (``zero``: >= 0), else a ConfigError naming ``key``.

    >>> require_count(3, "max_iterations")
    3
    """
    if not isinstance(value, int) or isinstance(value, bool) or value < (0 if zero else 1):
        raise ConfigError(f"Expected an integer {'>= 0' if zero else '>= 1'}", key=key, value=value)
    return value
