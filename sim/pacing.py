"""Real-time helpers of the served simulator (``sim.server``): the record of how punctually replies left
(:class:`Pacing`), a fine timer slack for the serving thread, kernel receive timestamps on TCP, and garbage
collection kept out of the replies' way (:class:`Collections`).

>>> p = Pacing()
>>> p.note(0.0001); p.note(0.003)
>>> (p.replies, p.late, round(p.worst, 4))
(2, 1, 0.003)
"""

from __future__ import annotations

import ctypes
import gc
import math
import socket
import struct
import sys
from dataclasses import dataclass, field
from types import TracebackType
from typing import Self

__all__ = [
    "ANCILLARY_SIZE",
    "LATE_S",
    "SO_TIMESTAMPNS",
    "TIMESPEC",
    "Collections",
    "Pacing",
    "fine_timer_slack",
    "kernel_time",
    "timestamps_on",
]

LATE_S = 0.5e-3  #: s after its time past which a reply counts as late in :class:`Pacing`
_PR_SET_TIMERSLACK = 29  #: prctl option (linux/prctl.h)
#: :class:`Pacing`'s lateness histogram: 1 us bins up to 1 ms, then 100 us bins up to 100 ms, then one for the rest
_FINE, _COARSE = 1000, 990


def _bin(lateness: float) -> int:
    """The histogram bin of a lateness in s (early or on time: bin 0)."""
    us = lateness * 1e6
    if us < _FINE:
        return max(0, int(us))
    return min(_FINE + _COARSE, _FINE + int((us - _FINE) / 100.0))


def _upper_edge(index: int) -> float:
    """The lateness in s that every entry of bin ``index`` is below (but the last bin's)."""
    if index < _FINE:
        return (index + 1) * 1e-6
    return (_FINE + (index - _FINE + 1) * 100.0) * 1e-6


def _duration(seconds: float) -> str:
    return f"{1e6 * seconds:.0f} us" if seconds < 1e-3 else f"{1e3 * seconds:.1f} ms"


@dataclass
class Pacing:
    """How punctually a server sent its replies (real clock only): counts, the worst lateness in seconds, and a
    histogram of the lateness for its quantiles (:meth:`quantile`).

    >>> p = Pacing(replies=200, late=1, worst=0.0021)
    >>> p.summary()
    '200 replies, 1 (0.5 %) later than 0.5 ms after their wire time (worst 2.1 ms)'
    >>> p = Pacing()
    >>> for lateness in [0.0] * 97 + [30e-6, 120e-6, 2.1e-3]:
    ...     p.note(lateness)
    >>> p.summary()
    '100 replies, 1 (1.0 %) later than 0.5 ms after their wire time (median 1 us, 99 % within 121 us, worst 2.1 ms)'
    """

    replies: int = 0  #: replies sent
    late: int = 0  #: of them, sent more than LATE_S after they were due
    worst: float = 0.0  #: s, the latest one's delay past its time
    #: replies noted per lateness bin: 1 us wide up to 1 ms, 100 us up to 100 ms, the last one for later ones
    histogram: list[int] = field(default_factory=lambda: [0] * (_FINE + _COARSE + 1), repr=False)

    def note(self, lateness: float) -> None:
        """One reply sent ``lateness`` s after its time (negative: early)."""
        self.replies += 1
        if lateness > LATE_S:
            self.late += 1
        if lateness > self.worst:
            self.worst = lateness
        self.histogram[_bin(lateness)] += 1

    def quantile(self, q: float) -> float:
        """The lateness in s that a share ``q`` (0..1) of the noted replies stayed within: the upper edge of its
        histogram bin (1 us up to 1 ms, 100 us up to 100 ms; :attr:`worst` beyond), at most :attr:`worst` when that
        is later than 0; nan when none were noted.

        >>> p = Pacing()
        >>> for lateness in (-2e-6, 0.5e-6, 3.2e-6, 0.004):
        ...     p.note(lateness)
        >>> [round(1e6 * p.quantile(q), 1) for q in (0.25, 0.5, 0.75, 1.0)]
        [1.0, 1.0, 4.0, 4000.0]
        """
        total = sum(self.histogram)
        if total == 0:
            return math.nan
        rank, seen = max(1, math.ceil(q * total)), 0
        for index, count in enumerate(self.histogram):
            seen += count
            if seen >= rank:
                edge = self.worst if index == len(self.histogram) - 1 else _upper_edge(index)
                return min(edge, self.worst) if self.worst > 0 else edge
        return self.worst  # pragma: no cover - the counts add up to total

    def summary(self) -> str:
        """One line for a person: replies, late ones, the median and 99th percentile lateness (when noted here), the
        worst."""
        share = 100.0 * self.late / self.replies if self.replies else 0.0
        noun = "reply" if self.replies == 1 else "replies"
        spread = ""
        if any(self.histogram):
            spread = f"median {_duration(self.quantile(0.5))}, 99 % within {_duration(self.quantile(0.99))}, "
        return (
            f"{self.replies} {noun}, {self.late} ({share:.1f} %) later than {1e3 * LATE_S:g} ms after their wire "
            f"time ({spread}worst {_duration(self.worst)})"
        )


_NEVER = 1 << 30  #: a generation-2 GC threshold the interpreter's own count never reaches


class Collections:
    """Full garbage collections only where the serving loop allows them (``sim.server``: when nothing is due).

    CPython's cyclic collector visits every tracked object in a full (generation 2) collection: in a served simulator
    the bus's instruction log (up to 100 000 entries), the servos and everything imported.  The interpreter starts
    one when a quarter of its objects are new since the last, which for a simulator logging every packet is every
    ~25 000 packets; measured on the 2-core VM (``bench/bench_rig.py``, ``retarget sim --rig``): 20-140 ms each, as
    many ms of late replies.  The simulator makes no cyclic garbage (a full collection after 80 000 packets found
    none), so inside this context the interpreter makes only its young (generation 0 and 1) collections, what was
    allocated before (modules, servos) is frozen (``gc.freeze``: full collections no longer visit it), and
    :meth:`idle` runs a full collection at a moment the loop chooses: after a quiet spell, or ``every_s`` into
    steady traffic.  Exit restores the thresholds and unfreezes.

    ``enabled`` False: nothing changes (a server thread in someone else's process: its collector is not the
    server's to tune).

    >>> with Collections(enabled=True, every_s=60.0) as collections:
    ...     gc.get_threshold()[2] > 1_000_000
    True
    >>> gc.get_threshold()[2] < 1_000_000
    True
    """

    def __init__(self, *, enabled: bool, every_s: float = 60.0):
        self.enabled = enabled
        self.every_s = every_s  #: s of steady traffic between full collections
        self.full = 0  #: full collections run by :meth:`idle`
        self._last = -math.inf  #: clock time of the last full collection (-inf: none yet)
        self._dirty = False  #: traffic since the last full collection
        self._thresholds = gc.get_threshold()

    def __enter__(self) -> Self:
        if self.enabled:
            gc.collect()
            gc.freeze()
            self._thresholds = gc.get_threshold()
            gc.set_threshold(self._thresholds[0], self._thresholds[1], _NEVER)
        return self

    def __exit__(self, kind: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None) -> None:
        if self.enabled:
            gc.set_threshold(*self._thresholds)
            gc.unfreeze()

    def traffic(self) -> None:
        """Something was served since the last full collection."""
        self._dirty = True

    def idle(self, now: float, *, quiet: bool) -> bool:
        """Nothing is due at clock time ``now``: run a full collection if there was traffic since the last one and
        it is ``quiet`` (no traffic for a while) or ``every_s`` passed since the last one.  True if it ran one."""
        if not self.enabled or not self._dirty:
            return False
        if self._last == -math.inf:
            self._last = now  # steady traffic counts from the first idle moment
        if not quiet and now - self._last < self.every_s:
            return False
        gc.collect()
        self._last, self._dirty = now, False
        self.full += 1
        return True


def fine_timer_slack() -> bool:
    """Ask Linux for a 1 ns timer slack on the calling thread, so its sleeps end on time (module docstring).
    False where that is not available (not Linux, no libc)."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)  # the symbols already loaded: libc
        return bool(libc.prctl(_PR_SET_TIMERSLACK, 1, 0, 0, 0) == 0)
    except (OSError, AttributeError):
        return False


SO_TIMESTAMPNS = 35  #: Linux's SO_TIMESTAMPNS (= SCM_TIMESTAMPNS); the socket module does not export it
TIMESPEC = struct.Struct("qq")  #: struct timespec on 64-bit Linux: seconds, nanoseconds


#: recvmsg's ancillary buffer for one SCM_TIMESTAMPNS (0 where the platform has no CMSG_SPACE)
ANCILLARY_SIZE = socket.CMSG_SPACE(TIMESPEC.size) if hasattr(socket, "CMSG_SPACE") else 0


def timestamps_on(sock: socket.socket) -> bool:
    """Turn on kernel receive timestamps (SO_TIMESTAMPNS) on ``sock``: False where unsupported (not Linux)."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        sock.setsockopt(socket.SOL_SOCKET, SO_TIMESTAMPNS, 1)
    except OSError:
        return False
    return True


def kernel_time(ancillary: list[tuple[int, int, bytes]]) -> float | None:
    """The SCM_TIMESTAMPNS time in ``recvmsg``'s ancillary data, s since the epoch; None without one."""
    for level, kind, data in ancillary:
        if level == socket.SOL_SOCKET and kind == SO_TIMESTAMPNS and len(data) >= TIMESPEC.size:
            seconds, nanoseconds = TIMESPEC.unpack_from(data)
            return float(seconds) + float(nanoseconds) * 1e-9
    return None
