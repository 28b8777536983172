"""Serve a :class:`~sim.bus.SimBus` out of process: on a pseudo-terminal or on loopback TCP.

* :class:`PtyServer` opens a pty pair in raw mode and serves the bus on the master side; any program opens
  the slave path (``/dev/pts/N``) as a serial port -- the plain ``dynamixel_sdk.PortHandler`` included.  The
  server keeps the slave open itself, so clients may come and go.  The line rate a client set on the pty
  (termios) is the ``line_baud`` of the bus: servos at another Baud Rate stay silent, as on a real wire.
* :class:`TcpServer` listens on ``host:port`` (loopback by default); pyserial reaches it as
  ``socket://127.0.0.1:PORT``.  One client at a time; the next one is accepted when it leaves.

Replies are written when the bus clock reaches their arrival time (Return Delay Time, the wire model and
delay faults); a bus on a :class:`~retarget.clock.VirtualClock` jumps its clock instead of waiting.

Lifecycle: ``with PtyServer(bus) as server: print(server.path)`` runs the loop in a thread until the block
exits; or call :meth:`SimServer.serve_forever` in the foreground with a ``threading.Event`` to stop it.
"""

from __future__ import annotations

import contextlib
import logging
import os
import select
import socket
import termios
import threading
import tty
from collections import deque
from typing import Self

from retarget.control.clock import Clock, VirtualClock
from sim.bus import ScheduledReply, SimBus

log = logging.getLogger(__name__)

_POLL = 0.05  #: s between checks of the stop flag when idle

#: termios speed constants -> bps, for the rates Linux ptys carry
_TERMIOS_BAUD = {
    getattr(termios, f"B{rate}"): rate
    for rate in (9600, 19200, 38400, 57600, 115200, 230400, 460800, 500000, 576000, 921600, 1000000, 1152000,
                 2000000, 2500000, 3000000, 3500000, 4000000)
    if hasattr(termios, f"B{rate}")
}  # fmt: skip


class SimServer:
    """The serving loop shared by the pty and TCP servers."""

    def __init__(self, bus: SimBus):
        self.bus = bus
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._pending: deque[ScheduledReply] = deque()
        self._wake_r, self._wake_w = os.pipe()  #: close() writes here to end a select at once

    # subclasses: open resources in __init__/start, give the fd to poll, read, write, close
    def _fd(self) -> int | None:
        raise NotImplementedError

    def _recv(self) -> bytes | None:
        raise NotImplementedError

    def _send(self, data: bytes) -> None:
        raise NotImplementedError

    def _line_baud(self) -> int | None:
        return None

    def close(self) -> None:
        """Stop the loop (if running in a thread) and release the pty or socket.  Safe to call twice."""
        self._stop.set()
        with contextlib.suppress(OSError):
            os.write(self._wake_w, b"x")
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=5)
        self._thread = None
        for fd in (self._wake_r, self._wake_w):
            with contextlib.suppress(OSError):
                os.close(fd)
        self._wake_r = self._wake_w = -1

    def start(self) -> Self:
        """Run :meth:`serve_forever` in a daemon thread."""
        self._stop.clear()
        self._thread = threading.Thread(target=self.serve_forever, name=type(self).__name__, daemon=True)
        self._thread.start()
        return self

    def __enter__(self) -> Self:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    def serve_forever(self, stop: threading.Event | None = None) -> None:
        """Serve until ``stop`` (or :meth:`close`) is set."""
        stop = stop or self._stop
        clock = self.bus.clock
        virtual = isinstance(clock, VirtualClock)
        while not stop.is_set() and not self._stop.is_set():
            fd = self._fd()
            if fd is None:
                continue
            timeout = _POLL
            if self._pending:
                timeout = 0.0 if virtual else min(_POLL, max(0.0, self._pending[0].due - clock.now()))
            try:
                readable, _, _ = select.select([fd, self._wake_r], [], [], timeout)
            except (OSError, ValueError):  # closed under us
                break
            try:
                self._serve_once(fd in readable, clock, virtual)
            except OSError:
                if self._stop.is_set():  # close() released the pty or socket while this tick was under way
                    break
                raise

    def _serve_once(self, readable: bool, clock: Clock, virtual: bool) -> None:
        """Feed what arrived to the bus, then send the replies that are due."""
        if readable:
            data = self._recv()
            if data:
                self.bus.line_baud = self._line_baud()
                replies = self.bus.feed(data)
                if replies:
                    self._pending = deque(sorted([*self._pending, *replies], key=lambda r: r.due))
        while self._pending:
            if virtual:
                clock.sleep_until(self._pending[0].due)
            elif self._pending[0].due > clock.now():
                break
            self._send(self._pending.popleft().data)


class PtyServer(SimServer):
    """A bus on a pseudo-terminal; :attr:`path` is the device to open."""

    def __init__(self, bus: SimBus):
        super().__init__(bus)
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)
        tty.setraw(self._master)
        self.path = os.ttyname(self._slave)
        os.set_blocking(self._master, False)

    def _fd(self) -> int | None:
        return self._master

    def _recv(self) -> bytes | None:
        try:
            return os.read(self._master, 4096)
        except (BlockingIOError, InterruptedError):
            return b""

    def _send(self, data: bytes) -> None:
        view = memoryview(data)
        while view:
            try:
                n = os.write(self._master, view)
            except BlockingIOError:
                select.select([], [self._master], [], _POLL)
                continue
            view = view[n:]

    def _line_baud(self) -> int | None:
        try:
            return _TERMIOS_BAUD.get(termios.tcgetattr(self._slave)[4])
        except termios.error:
            return None

    def close(self) -> None:
        super().close()
        for fd in (self._master, self._slave):
            with contextlib.suppress(OSError):
                os.close(fd)
        self._master = self._slave = -1


class TcpServer(SimServer):
    """A bus on a TCP socket; :attr:`address` is the ``(host, port)`` it listens on (port 0 picks one)."""

    def __init__(self, bus: SimBus, host: str = "127.0.0.1", port: int = 0):
        super().__init__(bus)
        self._listener = socket.create_server((host, port))
        self._listener.setblocking(False)
        self.address: tuple[str, int] = self._listener.getsockname()[:2]
        self._client: socket.socket | None = None

    @property
    def url(self) -> str:
        return f"socket://{self.address[0]}:{self.address[1]}"

    def _fd(self) -> int | None:
        if self._client is not None:
            return self._client.fileno()
        listener = self._listener.fileno()
        readable, _, _ = select.select([listener, self._wake_r], [], [], _POLL)
        if listener in readable:
            with contextlib.suppress(BlockingIOError):
                self._client, peer = self._listener.accept()
                self._client.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
                self.bus.reset()
                log.info("client connected from %s:%d", *peer[:2])
        return None

    def _recv(self) -> bytes | None:
        assert self._client is not None
        try:
            data = self._client.recv(4096)
        except (ConnectionError, OSError):
            data = b""
        if not data:
            log.info("client left")
            self._client.close()
            self._client = None
            self._pending.clear()
        return data

    def _send(self, data: bytes) -> None:
        if self._client is None:
            return
        try:
            self._client.sendall(data)
        except (ConnectionError, OSError):
            self._client.close()
            self._client = None
            self._pending.clear()

    def close(self) -> None:
        super().close()
        if self._client is not None:
            self._client.close()
            self._client = None
        self._listener.close()
