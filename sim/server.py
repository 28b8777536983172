"""Serve a :class:`~sim.bus.SimBus` out of process: on a pseudo-terminal or on loopback TCP.

* :class:`PtyServer` opens a pty pair in raw mode and serves the bus on the master side; any program opens
  the slave path (``/dev/pts/N``) as a serial port -- the plain ``dynamixel_sdk.PortHandler`` included.  The
  server keeps the slave open itself, so clients may come and go.  The line rate a client set on the pty
  (termios) is the ``line_baud`` of the bus: servos at another Baud Rate stay silent, as on a real wire.
* :class:`TcpServer` listens on ``host:port`` (loopback by default); pyserial reaches it as
  ``socket://127.0.0.1:PORT``.  One client at a time; the next one is accepted when it leaves.

Replies are written when the bus clock reaches their arrival time (Return Delay Time, the wire model and
delay faults); a bus on a :class:`~retarget.clock.VirtualClock` jumps its clock instead of waiting.

Real time: on a real clock with the wire model on (``retarget sim``'s default), each reply leaves when its last
byte would be on a real wire at the servos' baud rate, counted from when the instruction reached the server.  On
TCP (Linux) that is the kernel's receive time of the bytes (SO_TIMESTAMPNS), so an instruction that came while the
simulator was still busy with the previous packet, or while the machine ran something else, is still timed from its
arrival (the late work shows as late replies below); on a pty it is when the server read it.  To leave on time the
serving thread sleeps in ``select`` until :data:`SPIN_S` before the reply is due and waits out the rest on the
clock, and asks Linux for a 1 ns timer slack (the default 50 us makes every sleep end late; ``prctl``,
best effort).  Measured on the 2-core VM (Firecracker): a 1 ms ``select`` overshoots by 110 us (median) with the
default slack, 50-60 us with 1 ns (``time.sleep``, ``poll`` and ``epoll`` alike), and each timed wake-up costs ~35 us
of CPU; with SPIN_S 100 us the median reply leaves within 1 us of its time, with 40 us 17-20 us late, for no CPU
measurably saved (the spin is 20-35 us per reply; ``bench/bench_rig.py``).  :attr:`SimServer.pacing` counts the
replies sent and those that left later than :data:`sim.pacing.LATE_S` after their time, with the median and 99th
percentile lateness (the simulator did not keep up: a loaded machine, or servos whose Python took longer than the
wire); ``retarget sim`` prints it when it stops.  When the serving loop owns its process (``serve_forever`` on a
real clock in the main thread, as ``retarget sim`` runs it), the interpreter's full garbage collections, which
visit the bus's whole instruction log and came every ~25 000 packets for 20-140 ms, wait for a moment with no
reply due (:class:`sim.pacing.Collections`).

Lifecycle: ``with PtyServer(bus) as server: print(server.path)`` runs the loop in a thread until the block
exits; or call :meth:`SimServer.serve_forever` in the foreground with a ``threading.Event`` to stop it.

Hooks (:class:`ServerHook`, :meth:`SimServer.add_hook`) run in the serving thread, between packets: the scripted
hands of ``retarget sim --hand`` (:class:`sim.hand_commands.HandSchedule`) and its control socket
(:class:`sim.control.ControlServer`).  They may touch the servos without a lock, as the bus does.

The pty: a client that flushes its output right after a write (``tcflush(fd, TCOFLUSH)``, as pypot does before
each packet) can lose that write.  Linux moves the bytes a pty slave wrote to the master's input in a kernel
worker; TCOFLUSH on the slave discards what that worker has not moved yet, before any reader can see it (a real
USB adapter has sent them already).  Reading the master promptly does not prevent it; the server reads the
master whenever it is readable, sleeping only in ``select``.  Measured on a 2-core VM (``bench/bench_sim.py``):
0..47 % of the packets lost, varying with the load and with how soon the flush follows the write (20 us: 20-40 %,
500 us: under 5 %); a busy-polling reader lowered it only 2-4 times.  Clients that flush after writes should use
``--tcp`` (pyserial's ``socket://`` port has no output buffer to flush).  The master runs in packet mode (TIOCPKT)
so the server sees each flush: :attr:`PtyServer.output_flushes`, and a warning the first time.
"""

from __future__ import annotations

import contextlib
import fcntl
import logging
import math
import operator
import os
import select
import socket
import struct
import termios
import threading
import time
import tty
from collections import deque
from collections.abc import Sequence
from typing import Protocol, Self

from retarget.control.clock import Clock, VirtualClock
from sim.bus import ScheduledReply, SimBus
from sim.pacing import ANCILLARY_SIZE, Collections, Pacing, fine_timer_slack, kernel_time, timestamps_on

log = logging.getLogger(__name__)
_due = operator.attrgetter("due")

_POLL = 0.05  #: s between checks of the stop flag when idle
SPIN_S = 100e-6  #: s before a reply is due that the serving thread stops sleeping and waits on the clock

#: termios speed constants -> bps, for the rates Linux ptys carry
_TERMIOS_BAUD = {
    getattr(termios, f"B{rate}"): rate
    for rate in (9600, 19200, 38400, 57600, 115200, 230400, 460800, 500000, 576000, 921600, 1000000, 1152000,
                 2000000, 2500000, 3000000, 3500000, 4000000)
    if hasattr(termios, f"B{rate}")
}  # fmt: skip


class ServerHook(Protocol):
    """Work the serving loop does between packets, in its own thread (see the module docstring)."""

    def fds(self) -> Sequence[int]:
        """File descriptors to wait on with the port (sockets); empty for none."""
        ...

    def due(self) -> float:
        """Bus clock time of the next timed action; ``math.inf`` for none."""
        ...

    def service(self, ready: Sequence[int], now: float) -> None:
        """Handle the ``ready`` fds among :meth:`fds` and whatever is due at bus clock time ``now``."""
        ...


class SimServer:
    """The serving loop shared by the pty and TCP servers."""

    def __init__(self, bus: SimBus):
        self.bus = bus
        self.pacing = Pacing()  #: replies sent on a real clock, and how late (module docstring)
        self._fed_at = -math.inf  #: bus clock time of the last data fed to the bus (real clock)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._pending: deque[ScheduledReply] = deque()
        self._wake_r, self._wake_w = os.pipe()  #: close() writes here to end a select at once
        self._watching: tuple[int | None, list[int]] = (-1, [])  #: (port fd, the fds select waits on) without hooks
        self.hooks: list[ServerHook] = []

    def add_hook(self, hook: ServerHook) -> None:
        """Run ``hook`` in the serving loop (before :meth:`start`, or from the serving thread)."""
        self.hooks.append(hook)

    # subclasses: open resources in __init__/start, give the fd to poll, read, write, close
    def _fd(self) -> int | None:
        raise NotImplementedError

    def _recv(self) -> bytes | None:
        raise NotImplementedError

    def _send(self, data: bytes) -> None:
        raise NotImplementedError

    def _line_baud(self) -> int | None:
        return None

    def _arrival(self, clock: Clock) -> float:
        """Bus clock time the data just received reached the server: now, unless the transport knows better (TCP
        kernel timestamps); never before the last packet's."""
        self._fed_at = max(self._fed_at, clock.now())
        return self._fed_at

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
        """Serve until ``stop`` (or :meth:`close`) is set.

        On a real clock in the main thread (the process is the server's: ``retarget sim``), full garbage collections
        wait for moments with nothing due (:class:`sim.pacing.Collections`, module docstring).
        """
        stop = stop or self._stop
        clock = self.bus.clock
        virtual = isinstance(clock, VirtualClock)
        if not virtual:
            fine_timer_slack()
        own_process = not virtual and threading.current_thread() is threading.main_thread()
        with Collections(enabled=own_process) as collections:
            while not stop.is_set() and not self._stop.is_set():
                fd = self._fd()
                timeout = self._timeout(clock, virtual)
                try:
                    readable, _, _ = select.select(self._watched(fd), [], [], timeout)
                except (OSError, ValueError):  # closed under us
                    break
                try:
                    if fd is not None:
                        self._serve_once(fd in readable, clock, virtual)
                    for hook in self.hooks:
                        hook.service(readable, clock.now())
                except OSError:
                    if self._stop.is_set():  # close() released the pty or socket while this tick was under way
                        break
                    raise
                if readable:
                    collections.traffic()
                if collections.enabled and not self._pending:  # nothing due: a moment for a full collection
                    collections.idle(clock.now(), quiet=not readable and timeout >= _POLL)

    def _watched(self, fd: int | None) -> list[int]:
        """The descriptors the loop's select waits on: the port's (``fd``), the wake-up pipe, the hooks' (kept from
        one call to the next while there are no hooks and ``fd`` is the same)."""
        if self.hooks:
            hooked = [self._wake_r, *(f for hook in self.hooks for f in hook.fds())]
            return hooked if fd is None else [fd, *hooked]
        if self._watching[0] != fd:
            self._watching = (fd, [self._wake_r] if fd is None else [fd, self._wake_r])
        return self._watching[1]

    def _timeout(self, clock: Clock, virtual: bool) -> float:
        """How long the next select may wait: until the next hook action is due, or SPIN_S before the next reply
        is (the rest is waited out in :meth:`_serve_once`); at most _POLL."""
        if virtual:
            return 0.0 if self._pending else _POLL
        due = self._pending[0].due - SPIN_S if self._pending else math.inf
        for hook in self.hooks:
            due = min(due, hook.due())
        return min(_POLL, max(0.0, due - clock.now()))

    def _serve_once(self, readable: bool, clock: Clock, virtual: bool) -> None:
        """Feed what arrived to the bus, then send the replies that are due."""
        if readable:
            data = self._recv()
            if data:
                self.bus.line_baud = self._line_baud()
                replies = self.bus.feed(data, None if virtual else self._arrival(clock))
                if replies:
                    self._pending.extend(replies)
                    if len(self._pending) > 1:
                        self._pending = deque(sorted(self._pending, key=_due))
        while self._pending:
            due = self._pending[0].due
            if virtual:
                clock.sleep_until(due)
            else:
                now = clock.now()
                if due - now > SPIN_S:
                    break
                while now < due:  # the last SPIN_S: a sleep would end late (module docstring)
                    now = clock.now()
                self.pacing.note(now - due)
            self._send(self._pending.popleft().data)


class PtyServer(SimServer):
    """A bus on a pseudo-terminal; :attr:`path` is the device to open.

    :attr:`output_flushes` counts the client's TCOFLUSHes (the master runs in packet mode, TIOCPKT, to see them);
    the first one logs a warning that writes may have been lost (module docstring).
    """

    def __init__(self, bus: SimBus):
        super().__init__(bus)
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)
        tty.setraw(self._master)
        self.path = os.ttyname(self._slave)
        os.set_blocking(self._master, False)
        self._packet_mode = _packet_mode(self._master)
        self.output_flushes = 0  #: TCOFLUSHes the client did on the slave (packet mode only)

    def _fd(self) -> int | None:
        return self._master

    def _recv(self) -> bytes | None:
        try:
            data = os.read(self._master, 4097)
        except (BlockingIOError, InterruptedError):
            return b""
        if not self._packet_mode or not data:
            return data
        if data[0] == termios.TIOCPKT_DATA:
            return data[1:]
        if data[0] & termios.TIOCPKT_FLUSHWRITE:
            self._note_flush()
        return b""

    def _note_flush(self) -> None:
        self.output_flushes += 1
        if self.output_flushes == 1:
            log.warning(
                "the client flushed its output (tcflush TCOFLUSH) on %s: on a pty Linux drops written bytes it has "
                "not yet passed on, so an instruction written just before may be lost (a real adapter has sent it); "
                "serve such clients on TCP (retarget sim --tcp)",
                self.path,
            )

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


def _packet_mode(master: int) -> bool:
    """Put a pty master in packet mode (TIOCPKT): reads then say when the slave flushed.  False where unsupported."""
    request = getattr(termios, "TIOCPKT", None)
    if request is None:
        return False
    try:
        fcntl.ioctl(master, request, struct.pack("i", 1))
    except OSError:
        return False
    return True


class TcpServer(SimServer):
    """A bus on a TCP socket; :attr:`address` is the ``(host, port)`` it listens on (port 0 picks one)."""

    def __init__(self, bus: SimBus, host: str = "127.0.0.1", port: int = 0):
        super().__init__(bus)
        self._listener = socket.create_server((host, port))
        self._listener.setblocking(False)
        self.address: tuple[str, int] = self._listener.getsockname()[:2]
        self._client: socket.socket | None = None
        self._stamped = False  #: the client's socket has kernel receive timestamps on (Linux)
        self._stamp: float | None = None  #: the last data's kernel receive time, s since the epoch

    @property
    def url(self) -> str:
        return f"socket://{self.address[0]}:{self.address[1]}"

    def _fd(self) -> int | None:
        return self._client.fileno() if self._client is not None else self._listener.fileno()

    def _recv(self) -> bytes | None:
        if self._client is None:  # the listener is readable: a client is knocking
            with contextlib.suppress(BlockingIOError):
                self._client, peer = self._listener.accept()
                self._client.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
                self._stamped = timestamps_on(self._client)
                self.bus.reset()
                log.info("client connected from %s:%d", *peer[:2])
            return b""
        self._stamp = None
        try:
            if self._stamped:
                data, ancillary, _, _ = self._client.recvmsg(4096, ANCILLARY_SIZE)
                self._stamp = kernel_time(ancillary)
            else:
                data = self._client.recv(4096)
        except (ConnectionError, OSError):
            data = b""
        if not data:
            log.info("client left")
            self._client.close()
            self._client = None
            self._pending.clear()
        return data

    def _arrival(self, clock: Clock) -> float:
        """The kernel's receive time of the data just read (its last segment's), on the bus clock, when known."""
        if self._stamp is not None:
            age = time.time() - self._stamp  # CLOCK_REALTIME, as the kernel stamps; now on the bus clock:
            if 0.0 <= age < 1.0:
                self._fed_at = max(self._fed_at, clock.now() - age)
                return self._fed_at
        return super()._arrival(clock)

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
