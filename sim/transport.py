"""The in-process serial port ``sim://``: a pyserial ``SerialBase`` whose wire ends in a :class:`~sim.bus.SimBus`.

``import sim`` registers the ``sim`` package with pyserial, so ``serial.serial_for_url("sim://wx250s")``
returns a :class:`Serial` that behaves like a real port: ``write`` sends an instruction to the servos,
``read`` returns their status bytes once the bus clock reached the time they are on the wire, with
pyserial's timeout semantics (``timeout=0``: return what is there, as dynamixel-sdk opens it; ``None``:
block; ``t``: wait up to ``t`` s).

URL grammar::

    sim://ARM[?OPTIONS]               every servo of a bundled arm (retarget.load_arm), e.g. sim://wx250s
    sim://?ids=1-6,8&model=XM430-W350[&OPTIONS]
                                      servos of one model (default XL430-W250) with these IDs
    sim://@NAME                       the SimBus registered in this process with sim.register(NAME, bus);
                                      sim.attach(bus) registers it and returns the URL, sim.unregister(url)
                                      forgets it

    OPTIONS (ARM and ids forms):
      baud=BPS          the servos' Baud Rate item (default: the arm's, or the port's baud rate)
      rdt=N             the servos' Return Delay Time item, 2 us units (default 250, the factory value)
      boot_ms=MS        how long a servo stays silent after REBOOT (default 0)
      clock=virtual     the bus runs on its own VirtualClock: waiting for a reply costs no real time,
                        the clock jumps to its arrival (default: clock=real, time.perf_counter)
      mount=ID:PULSES,...  reverse=ID,...
                        (ARM form) servos mounted off the arm file's zero, or the other way round (sim.mount)
      block=ID:PULSES,...  an object in servo ID's way at Present Position PULSES (sim.obstacle): the horn stops
                        there; pushing on it draws the mode's current and, too hard for too long, Overload
      drop= corrupt= delay_ms= unplug= hwerror= wire= seed=
                        faults, as documented in sim.faults (e.g. drop=0.1&seed=1, unplug=4@1.5,
                        hwerror=3:overload@2, wire=1)

A servo listens only at its own Baud Rate item, so a port opened at another rate gets no reply, as on a
real bus.  With a VirtualClock (``clock=virtual`` or a bus attached with one), a read that finds a reply
still on the wire advances the clock to its arrival instead of waiting: that is the bus time a tick
really spends.
"""

from __future__ import annotations

import itertools
import logging
import threading
import time
from collections import deque
from typing import TYPE_CHECKING, Any
from urllib.parse import parse_qs, urlsplit

from serial.serialutil import PortNotOpenError, SerialBase, SerialException

from drivers.control_table import parse_ids
from retarget.control.clock import Clock, MonotonicClock, VirtualClock
from retarget.errors import ConfigError, RetargetError
from sim.bus import ScheduledReply, SimBus
from sim.faults import QUERY_KEYS, Faults
from sim.mount import MOUNT_KEYS, Mounting
from sim.obstacle import BLOCK_KEYS, blocks_from_query

if TYPE_CHECKING:
    from _typeshed import ReadableBuffer

__all__ = ["Serial", "attach", "bus_from_url", "parse_ids", "register", "registered", "unregister"]

log = logging.getLogger(__name__)

_REGISTRY: dict[str, SimBus] = {}
_REGISTRY_LOCK = threading.Lock()
_NAMES = itertools.count(1)
_BUS_KEYS = frozenset({"ids", "model", "baud", "rdt", "boot_ms", "clock"})
_PREFIX = "sim://@"


def register(name: str, bus: SimBus) -> str:
    """Make ``bus`` reachable as ``sim://@name`` in this process; returns that URL.

    ``name``: no ``/`` or ``?`` (ValueError).  Replaces a bus registered under the same name.  Undo with
    :func:`unregister` (the URL or the name).

    >>> from retarget.control.clock import VirtualClock
    >>> url = register("doc-two-servos", SimBus.from_ids([1, 2], clock=VirtualClock()))
    >>> url, registered(url).ids
    ('sim://@doc-two-servos', (1, 2))
    >>> unregister(url)
    """
    if not name or "/" in name or "?" in name:
        raise ValueError(f"Expected a name without '/' or '?', got {name!r}")
    with _REGISTRY_LOCK:
        _REGISTRY[name] = bus
    return f"{_PREFIX}{name}"


def attach(bus: SimBus) -> str:
    """Register ``bus`` under a fresh name (``bus1``, ``bus2``, ...) and return its ``sim://@...`` URL.

    Open the URL like any port (``serial.serial_for_url``, ``drivers.DynamixelBus``); :func:`unregister` it
    when done.  The port then shares the bus object, so a test reads the servos the driver wrote::

        >>> import serial
        >>> from retarget.control.clock import VirtualClock
        >>> bus = SimBus.from_ids([3], clock=VirtualClock())
        >>> url = attach(bus)
        >>> url.startswith("sim://@bus")
        True
        >>> port = serial.serial_for_url(url, baudrate=57600, timeout=0)
        >>> port.bus is bus, bus.line_baud  # servo 3 listens at 1 Mbps: on this line it stays silent
        (True, 57600)
        >>> port.close()
        >>> unregister(url)
    """
    return register(f"bus{next(_NAMES)}", bus)


def _name(name_or_url: str) -> str:
    return name_or_url.removeprefix(_PREFIX)


def unregister(name_or_url: str) -> None:
    """Forget the bus registered as ``sim://@NAME``: give the URL :func:`register`/:func:`attach` returned, or
    ``NAME``.  Nothing happens when none is registered; ports already open keep their bus."""
    with _REGISTRY_LOCK:
        _REGISTRY.pop(_name(name_or_url), None)


def registered(name_or_url: str) -> SimBus:
    """The bus registered as ``sim://@NAME`` (the URL or ``NAME``); KeyError listing the names otherwise."""
    name = _name(name_or_url)
    with _REGISTRY_LOCK:
        try:
            return _REGISTRY[name]
        except KeyError:
            known = ", ".join(sorted(_REGISTRY)) or "none"
            raise KeyError(f"no SimBus registered as {name!r} (registered: {known})") from None


def bus_from_url(url: str, *, port_baud: int | None = None, clock: Clock | None = None) -> SimBus:
    """Build the bus a ``sim://`` URL describes (the grammar is in the module docstring), or for ``sim://@NAME``
    the registered one.

    ``port_baud``: the baud rate the port is opened at (bps), the servos' default for ``sim://?ids=...``
    without ``baud=``.  ``clock``: the bus runs on it instead of the URL's ``clock=`` (the arms of a rig share one
    virtual clock).  ConfigError naming the option on a bad value (``path`` is the URL), KeyError for an
    unknown arm, model or registered name.

    >>> bus = bus_from_url("sim://?ids=1-3&model=XM430-W350&rdt=0&clock=virtual")
    >>> bus.ids, bus.servo(1).model.name, bus.servo(1).return_delay, type(bus.clock).__name__
    ((1, 2, 3), 'XM430-W350', 0.0, 'VirtualClock')
    >>> bus_from_url("sim://wx250s?baud=57600").servo(9).baud
    57600
    >>> bus_from_url("sim://?ids=1&rdt=fast")
    Traceback (most recent call last):
    ...
    retarget.errors.ConfigError: sim://?ids=1&rdt=fast: rdt: Expected an integer (got 'fast')
    """
    parts = urlsplit(url)
    if parts.scheme.lower() != "sim":
        raise ConfigError("Expected a URL starting with sim://", key="url", value=url)
    where = parts.netloc + parts.path.rstrip("/")
    query = parse_qs(parts.query, keep_blank_values=True)
    unknown = set(query) - _BUS_KEYS - QUERY_KEYS - MOUNT_KEYS - BLOCK_KEYS
    if unknown:
        known = ", ".join(sorted(_BUS_KEYS | QUERY_KEYS | MOUNT_KEYS | BLOCK_KEYS))
        raise ConfigError(f"unknown option(s) {', '.join(sorted(unknown))}; known: {known}", key="url", value=url)
    if where.startswith("@"):
        if query:
            raise ConfigError("options cannot be given for a registered bus", key="url", value=url)
        return registered(where[1:])

    def last(key: str, default: str | None = None) -> str | None:
        values = query.get(key)
        return values[-1] if values else default

    clock_name = (last("clock", "real") or "real").lower()
    if clock_name not in ("real", "virtual"):
        raise ConfigError("Expected clock=real or clock=virtual", key="clock", value=clock_name)
    if clock is None:
        clock = VirtualClock() if clock_name == "virtual" else MonotonicClock()
    faults = Faults.from_query(query, source=url)
    mount = Mounting.from_query(query, source=url)

    def number(key: str) -> float | None:
        text = last(key)
        if not text:
            return None
        try:
            return int(text) if key != "boot_ms" else float(text)
        except ValueError:
            expected = "Expected a number of milliseconds" if key == "boot_ms" else "Expected an integer"
            raise ConfigError(expected, path=url, key=key, value=text) from None

    baud_value, rdt_value, boot_ms = number("baud"), number("rdt"), number("boot_ms")
    baud = None if baud_value is None else int(baud_value)
    rdt = None if rdt_value is None else int(rdt_value)
    if boot_ms is not None and not 0.0 <= boot_ms <= 60_000.0:
        raise ConfigError("Expected a number of milliseconds from 0 to 60000", path=url, key="boot_ms", value=boot_ms)
    boot = 0.0 if boot_ms is None else boot_ms / 1000.0
    blocks = blocks_from_query(query, source=url)
    if where:
        if "ids" in query or "model" in query:
            raise ConfigError("give either an arm name or ids=/model=, not both", key="url", value=url)
        bus = SimBus.from_arm(
            where, clock=clock, baud=baud, return_delay_time=rdt, boot_time=boot, faults=faults, mount=mount
        )
        return _with_blocks(bus, blocks, url)
    if mount.ids:
        raise ConfigError("mount= and reverse= need an arm: sim://ARM?mount=...", key="url", value=url)
    ids_text = last("ids")
    if not ids_text:
        raise ConfigError("Expected sim://ARM, sim://?ids=1-6&model=..., or sim://@NAME", key="url", value=url)
    baud = baud or port_baud or 1_000_000
    bus = SimBus.from_ids(
        parse_ids(ids_text),
        last("model", "XL430-W250") or "XL430-W250",
        clock=clock,
        baud=baud,
        return_delay_time=rdt,
        boot_time=boot,
        faults=faults,
    )
    return _with_blocks(bus, blocks, url)


def _with_blocks(bus: SimBus, blocks: dict[int, int], url: str) -> SimBus:
    """Put the ``block=`` walls in place (sim.obstacle); ConfigError for an ID not on the bus."""
    for dxl_id, pulses in blocks.items():
        if dxl_id not in bus.ids:
            raise ConfigError(f"Expected a servo ID on the bus {list(bus.ids)}", path=url, key="block", value=dxl_id)
        bus.servo(dxl_id).block_at(pulses)
    return bus


class Serial(SerialBase):
    """A pyserial port on a simulated bus; see the module docstring for URLs and timing."""

    BAUDRATES = (9600, 19200, 38400, 57600, 115200, 230400, 460800, 500000, 576000, 921600, 1000000, 1152000,
                 2000000, 2500000, 3000000, 3500000, 4000000, 4500000)  # fmt: skip

    # set by SerialBase.__init__ and its setters; the pyserial stubs declare only the public properties, and the
    # hot path (read, once per SDK poll) reads the attributes
    _port: str | None
    _baudrate: int
    _timeout: float | None

    def __init__(self, *args: Any, **kwargs: Any):
        self.bus: SimBus | None = None
        self._virtual = False  #: the bus runs on a VirtualClock: waiting for a reply advances it
        self._rx = bytearray()
        self._pending: deque[ScheduledReply] = deque()
        self._deadline = float("inf")  #: bus time after which a reply is too late for the current read
        super().__init__(*args, **kwargs)

    # ------------------------------------------------------------------ open / close

    def open(self) -> None:
        if self._port is None:
            raise SerialException("Port must be configured before it can be used.")
        if self.is_open:
            raise SerialException("Port is already open.")
        try:
            self.bus = bus_from_url(str(self._port), port_baud=self._baudrate)
        except (RetargetError, KeyError, ValueError) as exc:
            raise SerialException(f"could not open port {self._port!r}: {exc}") from exc
        self.bus.reset()
        self._virtual = isinstance(self.bus.clock, VirtualClock)
        self.is_open = True
        self._reconfigure_port()
        self.reset_input_buffer()
        self._pending.clear()
        log.debug("opened %s: %r", self._port, self.bus)

    def close(self) -> None:
        self.is_open = False
        self._pending.clear()
        self._rx.clear()
        if self.bus is not None:
            self.bus.line_baud = None
        self.bus = None

    def _reconfigure_port(self) -> None:
        if self.bus is not None and self.is_open:
            self.bus.line_baud = int(self._baudrate)

    # ------------------------------------------------------------------ data

    def _collect(self) -> None:
        """Move every reply whose last byte is on the wire by now into the receive buffer."""
        if not self._pending or self.bus is None:
            return
        now = self.bus.clock.now()
        while self._pending and self._pending[0].due <= now:
            self._rx += self._pending.popleft().data

    def reply_window(self, timeout: float) -> None:
        """The reader waits ``timeout`` s from now for its reply (``drivers.port.UrlPortHandler`` calls this with
        the SDK's packet timeout).

        On a virtual clock a read jumps the clock to a reply still on the wire, which would wait out any delay:
        a reply due after this window is not delivered to the read (the clock goes to the end of the window, the
        read returns what is there, and the SDK times out in real time); it arrives in the receive buffer once the
        clock passes its time, and the next instruction's ``clearPort`` drops it as late.  No effect on a real
        clock, where time itself does this.
        """
        if self._virtual and self.bus is not None:
            self._deadline = self.bus.clock.now() + timeout

    def write(self, b: ReadableBuffer, /) -> int:
        if not self.is_open or self.bus is None:
            raise PortNotOpenError()
        data = bytes(b)
        replies = self.bus.feed(data)
        if replies:
            merged = sorted([*self._pending, *replies], key=lambda r: r.due)
            self._pending = deque(merged)
        return len(data)

    def read(self, size: int = 1) -> bytes:
        if not self.is_open or self.bus is None:
            raise PortNotOpenError()
        timeout = self._timeout
        if timeout == 0 and not self._virtual:  # dynamixel-sdk busy-polls this way: keep each poll short
            if self._pending:
                self._collect()
            rx = self._rx
            if not rx:
                return b""
            polled = bytes(rx[:size])
            del rx[:size]
            return polled
        deadline = None if timeout is None else time.monotonic() + timeout
        out = bytearray()
        while True:
            self._collect()
            if self._rx:
                take = min(size - len(out), len(self._rx))
                out += self._rx[:take]
                del self._rx[:take]
            if len(out) >= size:
                break
            if self._pending and self._virtual:
                due = self._pending[0].due
                if due <= self._deadline:
                    self.bus.clock.sleep_until(due)  # waiting on a virtual wire is free
                    continue
                if timeout == 0:  # too late for this read: the reader times out, as on a real port, and
                    self.bus.clock.sleep_until(self._deadline)  # its wait is bus time spent
                    break
                self._deadline = float("inf")  # a blocking read waits it out
                continue
            if timeout == 0:
                break
            now = time.monotonic()
            if deadline is not None and now >= deadline:
                break
            wait = 0.0005
            if self._pending:
                wait = min(wait, max(0.0, self._pending[0].due - self.bus.clock.now()))
            if deadline is not None:
                wait = min(wait, deadline - now)
            time.sleep(max(wait, 0.0))
        return bytes(out)

    @property
    def in_waiting(self) -> int:
        if not self.is_open:
            raise PortNotOpenError()
        self._collect()
        return len(self._rx)

    @property
    def out_waiting(self) -> int:
        return 0

    def reset_input_buffer(self) -> None:
        """Discard the bytes received so far (replies still on the wire arrive later, as on a real line)."""
        if not self.is_open:
            raise PortNotOpenError()
        self._collect()
        self._rx.clear()

    def reset_output_buffer(self) -> None:
        if not self.is_open:
            raise PortNotOpenError()

    def flush(self) -> None:
        if not self.is_open:
            raise PortNotOpenError()

    def cancel_read(self) -> None:
        pass

    def cancel_write(self) -> None:
        pass

    def _update_break_state(self) -> None:
        pass

    def _update_rts_state(self) -> None:
        pass

    def _update_dtr_state(self) -> None:
        pass

    @property
    def cts(self) -> bool:
        return True

    @property
    def dsr(self) -> bool:
        return True

    @property
    def ri(self) -> bool:
        return False

    @property
    def cd(self) -> bool:
        return True
