"""Teleoperation target sources: where accepted targets arrive from (stdin, UDP, one shot, fed by hand).

A source passes each raw message (one line of stdin, one datagram of UDP, the one-shot target) through a
:class:`~retarget.teleop.gate.TargetGate`, which parses, frame-changes and bound-checks it
(:mod:`retarget.teleop.gate`).  Each accepted :class:`~retarget.teleop.gate.Target`
is stamped with its receive time on the *loop's* clock; a source keeps the latest one (:meth:`Source.latest`)
and queues every accepted one in order (:meth:`Source.drain`), so a follower can visit a fast stream's
points in order, and can decide staleness (no target for ``timeout`` seconds).  Network input binds to
loopback unless the user names another address, which is warned about loudly.

This module is I/O only: it imports neither ``drivers``, ``sim`` nor ``serial``.
"""

from __future__ import annotations

import collections
import ipaddress
import logging
import math
import socket
import sys
import threading
from collections.abc import Callable
from typing import IO, Self

import numpy as np

from retarget.errors import ConfigError
from retarget.teleop.gate import MAX_RPY_DEG, Message, Reject, Target, TargetGate, TargetRejected, parse_message

__all__ = [
    "DEFAULT_UDP_HOST",
    "QUEUE_LENGTH",
    "OneShotSource",
    "Source",
    "StdinSource",
    "UdpSource",
    "is_loopback",
    "parse_address",
]

log = logging.getLogger(__name__)

DEFAULT_UDP_HOST = "127.0.0.1"
QUEUE_LENGTH = 1024  #: accepted targets waiting to be followed; the oldest is dropped (and counted) beyond


class Source:
    """A target source: the latest target, the queue of accepted ones, closed, a condition.

    The base of the stdin, UDP, one-shot and key sources; usable on its own as a source an
    application (or a test) feeds with :meth:`feed`.  ``latest()``/``drain()``/``wait()`` may be
    called from the control loop while another thread feeds.
    """

    name = "source"

    def __init__(self, gate: TargetGate, *, queue_length: int = QUEUE_LENGTH):
        self.gate = gate
        self._queue: collections.deque[Target] = collections.deque()
        self._queue_length = queue_length
        self._latest: Target | None = None
        self._closed = False
        self._cond = threading.Condition()
        self.dropped = 0  #: accepted targets dropped from a full queue (oldest first)

    # -- producer side
    def _push(self, target: Target) -> None:
        with self._cond:
            if len(self._queue) >= self._queue_length:
                self._queue.popleft()
                self.dropped += 1
            self._queue.append(target)
            self._latest = target
            self._cond.notify_all()

    def feed(self, data: str | bytes) -> None:
        """Pass one raw message through the gate; queue it when accepted (a reject is counted)."""
        target = self.gate.accept(data, source=self.name)
        if target is not None:
            self._push(target)
        else:
            with self._cond:
                self._cond.notify_all()

    def _finish(self) -> None:
        with self._cond:
            self._closed = True
            self._cond.notify_all()

    # -- consumer side
    def latest(self) -> Target | None:
        """The most recent accepted target (with its receive time), or None before the first."""
        with self._cond:
            return self._latest

    def drain(self) -> list[Target]:
        """Every target accepted since the last call, oldest first."""
        with self._cond:
            out = list(self._queue)
            self._queue.clear()
            return out

    @property
    def queued(self) -> int:
        """Accepted targets not drained yet."""
        with self._cond:
            return len(self._queue)

    @property
    def closed(self) -> bool:
        """True once no more targets can come (end of input, or closed)."""
        with self._cond:
            return self._closed

    def wait(self, timeout: float) -> bool:
        """Block up to ``timeout`` real seconds until a target is queued or the source closes; True if so."""
        with self._cond:
            return self._cond.wait_for(lambda: bool(self._queue) or self._closed, timeout)

    def is_stale(self, now: float, timeout: float) -> bool:
        """True when the latest target is older than ``timeout`` seconds at ``now`` (loop clock), or none came."""
        latest = self.latest()
        return latest is None or now - latest.received > timeout

    @property
    def rejects(self) -> dict[str, int]:
        return self.gate.rejects.counts()

    def close(self) -> None:
        self._finish()

    def __enter__(self) -> Self:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    def start(self) -> Self:
        """Start taking input (a reader thread, for the stdin and UDP sources); returns the source."""
        return self


class OneShotSource(Source):
    """A single target, already accepted; closed from the start.

    ``position`` is ``"X,Y,Z"`` metres, ``rpy`` optionally ``"R,P,Y"`` degrees (the tool frame's orientation).
    A bad one raises :class:`~retarget.teleop.gate.TargetRejected` whose ``key`` is ``position`` or ``rpy``.
    """

    name = "one-shot"

    def __init__(self, gate: TargetGate, position: str, *, rpy: str | None = None):
        super().__init__(gate)
        message = parse_message(position, max_bytes=gate.max_bytes, key="position")
        if message is None:
            raise TargetRejected(Reject.MALFORMED, "Expected X,Y,Z metres", key="position", value=position)
        if message.rpy is not None:
            message_text = "Expected X,Y,Z metres only (the orientation comes apart, as R,P,Y)"
            raise TargetRejected(Reject.MALFORMED, message_text, key="position", value=position)
        if rpy is not None:
            angles = parse_message(rpy, max_bytes=gate.max_bytes, key="rpy")
            if angles is None:
                raise TargetRejected(Reject.MALFORMED, "Expected R,P,Y degrees", key="rpy", value=rpy)
            if not all(abs(float(v)) <= MAX_RPY_DEG for v in angles.position):
                message_text = f"Expected R,P,Y from {-MAX_RPY_DEG:g} to {MAX_RPY_DEG:g} degrees"
                raise TargetRejected(Reject.MALFORMED, message_text, key="rpy", value=rpy)
            message = Message(message.position, angles.position * (math.pi / 180.0))
        position_m, rotation = gate.convert(message, key="position", blocked=False)
        aim = None
        if gate.bounds.is_blocked(position_m):  # counted, and steered to the nearest safe point: never reached
            assert gate.bounds.collision is not None
            aim = np.asarray(gate.bounds.collision.push_out(position_m), dtype=np.float64)
            gate.reject(Reject.BLOCKED, "Expected a point clear of the table, the keep-out zones and the base; "
                        "going to the nearest safe point", source=self.name, value=position)  # fmt: skip
        gate.accepted += 1
        self._push(Target(position_m, rotation, gate.clock.now(), 0, aim))
        self._finish()


class _ThreadSource(Source):
    def __init__(self, gate: TargetGate, *, queue_length: int = QUEUE_LENGTH):
        super().__init__(gate, queue_length=queue_length)
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()

    def start(self) -> Self:
        """Start the reader thread (idempotent)."""
        if self._thread is None:
            self._thread = threading.Thread(target=self._run_guarded, name=f"retarget-{self.name}", daemon=True)
            self._thread.start()
        return self

    def _run_guarded(self) -> None:
        try:
            self._run()
        except Exception:  # a reader must never die silently: say why, then behave like end of input
            log.exception("%s reader failed; no more targets", self.name)
        finally:
            self._finish()

    def _run(self) -> None:
        raise NotImplementedError

    def join(self, timeout: float | None = None) -> None:
        if self._thread is not None:
            self._thread.join(timeout)


class StdinSource(_ThreadSource):
    """Targets from lines of a stream (default ``sys.stdin``'s bytes), read by a daemon thread.

    End of input closes the source.  A line longer than the gate's ``max_bytes`` is rejected
    (``OVERSIZE``) without being held in memory whole.  :meth:`close` stops taking lines; a
    thread blocked reading a terminal stays blocked until the next line (it is a daemon thread).
    """

    name = "stdin"

    def __init__(
        self, gate: TargetGate, stream: IO[bytes] | IO[str] | None = None, *, queue_length: int = QUEUE_LENGTH
    ):
        super().__init__(gate, queue_length=queue_length)
        if stream is None:
            stream = getattr(sys.stdin, "buffer", sys.stdin)
        self.stream = stream
        self.lines = 0  #: lines read, blank ones included

    def _run(self) -> None:
        limit = self.gate.max_bytes
        readline: Callable[[int], bytes | str] = self.stream.readline
        while not self._stop.is_set():
            line = readline(limit + 2)  # room for "\r\n"
            if not line:
                return
            self.lines += 1
            if not _ends_line(line) and len(line) > limit:  # over the limit: skip the rest of this line
                while line and not _ends_line(line):
                    line = readline(limit + 2)
                self.gate.reject(Reject.OVERSIZE, f"Expected a line of at most {limit} bytes", source=self.name)
                continue
            if self._stop.is_set():
                return
            self.feed(_without_newline(line))

    def close(self) -> None:
        self._stop.set()
        super().close()


def _ends_line(line: bytes | str) -> bool:
    return line.endswith(b"\n") if isinstance(line, bytes) else line.endswith("\n")


def _without_newline(line: bytes | str) -> bytes | str:
    if isinstance(line, bytes):
        return line.rstrip(b"\n").rstrip(b"\r")
    return line.rstrip("\n").rstrip("\r")


def parse_address(text: str, *, default_host: str = DEFAULT_UDP_HOST, key: str = "address") -> tuple[str, int]:
    """``"PORT"``, ``"HOST:PORT"`` or ``"[V6]:PORT"`` -> ``(host, port)``; the host defaults to loopback.

    A bad one raises ``ConfigError`` naming ``key``.
    """
    text = text.strip()
    host, sep, port_text = text.rpartition(":")
    if not sep:
        host, port_text = default_host, text
    elif host.startswith("[") and host.endswith("]"):
        host = host[1:-1]
    elif ":" in host:
        raise ConfigError("Expected [HOST:]PORT (an IPv6 host in brackets: [::1]:PORT)", key=key, value=text)
    host = host or default_host
    try:
        port = int(port_text)
    except ValueError:
        raise ConfigError("Expected [HOST:]PORT with a numeric port", key=key, value=text) from None
    if not 0 <= port <= 65535:
        raise ConfigError("Expected a port in 0..65535", key=key, value=port)
    return host, port


def is_loopback(host: str) -> bool:
    """True for a loopback address or ``localhost``."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


class UdpSource(_ThreadSource):
    """Targets from UDP datagrams, one message each, on ``host:port`` (default loopback).

    Binding another address than loopback, which the user must name, logs a loud warning: anyone
    who can reach it can move the arm.  A datagram over ``max_bytes`` is rejected (``OVERSIZE``).
    ``port=0`` binds an ephemeral port; :attr:`address` is the bound one.
    """

    name = "udp"
    poll = 0.05  #: seconds between checks of the stop flag while no datagram comes

    def __init__(
        self, gate: TargetGate, host: str = DEFAULT_UDP_HOST, port: int = 0, *, queue_length: int = QUEUE_LENGTH
    ):
        super().__init__(gate, queue_length=queue_length)
        if not is_loopback(host):  # said before binding, so the warning stands even when the bind fails
            log.warning(
                "UDP target input on %s:%d is NOT loopback: anyone who can reach this address can move the arm",
                host,
                port,
            )
        family = socket.AF_INET6 if ":" in host else socket.AF_INET
        sock = socket.socket(family, socket.SOCK_DGRAM)
        try:
            sock.bind((host, port))
        except OSError as exc:
            sock.close()
            raise ConfigError(f"cannot bind UDP {host}:{port}: {exc.strerror or exc}", key="address",
                              value=f"{host}:{port}") from exc  # fmt: skip
        sock.settimeout(self.poll)
        self._sock = sock
        self.address: tuple[str, int] = sock.getsockname()[:2]
        self.datagrams = 0

    def _run(self) -> None:
        limit = self.gate.max_bytes
        while not self._stop.is_set():
            try:
                data, peer = self._sock.recvfrom(limit + 1)
            except TimeoutError:
                continue
            except OSError:
                if self._stop.is_set():
                    return
                raise
            self.datagrams += 1
            if len(data) > limit:
                self.gate.reject(Reject.OVERSIZE, f"Expected a datagram of at most {limit} bytes", source=self.name)
                continue
            self.feed(data)

    def close(self) -> None:
        self._stop.set()
        self.join(timeout=2 * self.poll + 1.0)
        self._sock.close()
        super().close()
