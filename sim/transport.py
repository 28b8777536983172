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
                                      sim.attach(bus) registers it and returns the URL

    OPTIONS (ARM and ids forms):
      baud=BPS          the servos' Baud Rate item (default: the arm's, or the port's baud rate)
      rdt=N             the servos' Return Delay Time item, 2 us units (default 250, the factory value)
      boot_ms=MS        how long a servo stays silent after REBOOT (default 0)
      clock=virtual     the bus runs on its own VirtualClock: waiting for a reply costs no real time,
                        the clock jumps to its arrival (default: clock=real, time.perf_counter)
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
from urllib.parse import parse_qs, urlsplit

from serial.serialutil import PortNotOpenError, SerialBase, SerialException

from retarget.control.clock import MonotonicClock, VirtualClock
from retarget.errors import ConfigError, RetargetError
from sim.bus import Reply, SimBus
from sim.faults import QUERY_KEYS, Faults

log = logging.getLogger(__name__)

_REGISTRY: dict[str, SimBus] = {}
_REGISTRY_LOCK = threading.Lock()
_NAMES = itertools.count(1)
_BUS_KEYS = frozenset({"ids", "model", "baud", "rdt", "boot_ms", "clock"})


def register(name: str, bus: SimBus) -> str:
    """Make ``bus`` reachable as ``sim://@name``; returns that URL.  Replaces a bus of the same name."""
    if not name or "/" in name or "?" in name:
        raise ValueError(f"Expected a name without '/' or '?', got {name!r}")
    with _REGISTRY_LOCK:
        _REGISTRY[name] = bus
    return f"sim://@{name}"


def attach(bus: SimBus) -> str:
    """Register ``bus`` under a fresh name and return its ``sim://@...`` URL."""
    return register(f"bus{next(_NAMES)}", bus)


def unregister(name: str) -> None:
    with _REGISTRY_LOCK:
        _REGISTRY.pop(name, None)


def registered(name: str) -> SimBus:
    with _REGISTRY_LOCK:
        try:
            return _REGISTRY[name]
        except KeyError:
            known = ", ".join(sorted(_REGISTRY)) or "none"
            raise KeyError(f"no SimBus registered as {name!r} (registered: {known})") from None


def parse_ids(text: str) -> list[int]:
    """``"1-6,8"`` -> ``[1, 2, 3, 4, 5, 6, 8]``; ConfigError on anything else."""
    ids: list[int] = []
    try:
        for part in text.split(","):
            part = part.strip()
            if not part:
                continue
            lo, sep, hi = part.partition("-")
            ids.extend(range(int(lo), int(hi) + 1) if sep else [int(lo)])
    except ValueError:
        raise ConfigError("Expected IDs like 1-6,8", key="ids", value=text) from None
    if not ids or any(not 0 <= i <= 252 for i in ids) or len(set(ids)) != len(ids):
        raise ConfigError("Expected distinct IDs in 0..252, like 1-6,8", key="ids", value=text)
    return ids


def bus_from_url(url: str, *, port_baud: int | None = None) -> SimBus:
    """Build (or look up, for ``sim://@NAME``) the bus a ``sim://`` URL names.  ConfigError/KeyError on bad input."""
    parts = urlsplit(url)
    if parts.scheme.lower() != "sim":
        raise ConfigError("Expected a URL starting with sim://", key="url", value=url)
    where = parts.netloc + parts.path.rstrip("/")
    query = parse_qs(parts.query, keep_blank_values=True)
    unknown = set(query) - _BUS_KEYS - QUERY_KEYS
    if unknown:
        known = ", ".join(sorted(_BUS_KEYS | QUERY_KEYS))
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
    clock = VirtualClock() if clock_name == "virtual" else MonotonicClock()
    faults = Faults.from_query(query, source=url)
    baud_text, rdt_text, boot_text = last("baud"), last("rdt"), last("boot_ms")
    try:
        baud = int(baud_text) if baud_text else None
        rdt = int(rdt_text) if rdt_text else None
        boot = float(boot_text) / 1000.0 if boot_text else 0.0
    except ValueError:
        raise ConfigError("Expected numbers for baud, rdt and boot_ms", key="url", value=url) from None
    if where:
        if "ids" in query or "model" in query:
            raise ConfigError("give either an arm name or ids=/model=, not both", key="url", value=url)
        return SimBus.from_arm(where, clock=clock, baud=baud, return_delay_time=rdt, boot_time=boot, faults=faults)
    ids_text = last("ids")
    if not ids_text:
        raise ConfigError("Expected sim://ARM, sim://?ids=1-6&model=..., or sim://@NAME", key="url", value=url)
    baud = baud or port_baud or 1_000_000
    return SimBus.from_ids(
        parse_ids(ids_text),
        last("model", "XL430-W250") or "XL430-W250",
        clock=clock,
        baud=baud,
        return_delay_time=rdt,
        boot_time=boot,
        faults=faults,
    )


class Serial(SerialBase):
    """A pyserial port on a simulated bus; see the module docstring for URLs and timing."""

    BAUDRATES = (9600, 19200, 38400, 57600, 115200, 230400, 460800, 500000, 576000, 921600, 1000000, 1152000,
                 2000000, 2500000, 3000000, 3500000, 4000000, 4500000)  # fmt: skip

    def __init__(self, *args: object, **kwargs: object):
        self.bus: SimBus | None = None
        self._virtual = False  #: the bus runs on a VirtualClock: waiting for a reply advances it
        self._rx = bytearray()
        self._pending: deque[Reply] = deque()
        super().__init__(*args, **kwargs)  # type: ignore[arg-type]

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
        if not self._pending:
            return
        now = self.bus.clock.now()  # type: ignore[union-attr]
        while self._pending and self._pending[0].due <= now:
            self._rx += self._pending.popleft().data

    def write(self, data: bytes | bytearray | memoryview) -> int:
        if not self.is_open or self.bus is None:
            raise PortNotOpenError()
        data = bytes(data)
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
            out = bytes(rx[:size])
            del rx[:size]
            return out
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
                self.bus.clock.sleep_until(self._pending[0].due)  # waiting on a virtual wire is free
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
