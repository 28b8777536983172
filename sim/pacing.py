"""Real-time helpers of the served simulator (``sim.server``): the record of how punctually replies left
(:class:`Pacing`), a fine timer slack for the serving thread, and kernel receive timestamps on TCP.

>>> p = Pacing()
>>> p.note(0.0001); p.note(0.003)
>>> (p.replies, p.late, round(p.worst, 4))
(2, 1, 0.003)
"""

from __future__ import annotations

import ctypes
import socket
import struct
import sys
from dataclasses import dataclass

__all__ = ["LATE_S", "SO_TIMESTAMPNS", "TIMESPEC", "Pacing", "fine_timer_slack", "kernel_time", "timestamps_on"]

LATE_S = 0.5e-3  #: s after its time past which a reply counts as late in :class:`Pacing`
_PR_SET_TIMERSLACK = 29  #: prctl option (linux/prctl.h)


@dataclass
class Pacing:
    """How punctually a server sent its replies (real clock only): counts, and the worst lateness in seconds.

    >>> p = Pacing(replies=200, late=1, worst=0.0021)
    >>> p.summary()
    '200 replies, 1 (0.5 %) later than 0.5 ms after their wire time (worst 2.1 ms)'
    """

    replies: int = 0  #: replies sent
    late: int = 0  #: of them, sent more than LATE_S after they were due
    worst: float = 0.0  #: s, the latest one's delay past its time

    def note(self, lateness: float) -> None:
        """One reply sent ``lateness`` s after its time (negative: early)."""
        self.replies += 1
        if lateness > LATE_S:
            self.late += 1
        if lateness > self.worst:
            self.worst = lateness

    def summary(self) -> str:
        """One line for a person: replies, late ones, the worst."""
        share = 100.0 * self.late / self.replies if self.replies else 0.0
        noun = "reply" if self.replies == 1 else "replies"
        return (
            f"{self.replies} {noun}, {self.late} ({share:.1f} %) later than {1e3 * LATE_S:g} ms after their wire "
            f"time (worst {1e3 * self.worst:.1f} ms)"
        )


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
