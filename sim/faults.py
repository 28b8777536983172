"""Fault injection for the simulated bus: lost, corrupted and late replies, unplugged servos, hardware errors,
and the wire-time model.

A :class:`Faults` holds them all.  Reply faults apply to the whole bus or to one servo (a per-servo value
replaces the bus-wide one).  Times (``unplug``, ``hardware``) are seconds after the bus was built, on its
clock.  The same options are spelled alike in code, in ``sim://`` URLs and on the ``retarget sim`` command
line::

    drop=0.1            drop 10 % of all replies        drop=3:0.5     drop half of servo 3's replies
    corrupt=0.01        flip a CRC bit in 1 % of them   corrupt=3:1    every reply of servo 3 is corrupt
    delay_ms=2          every reply 2 ms late           delay_ms=3:40  servo 3's replies 40 ms late
    unplug=4@1.5        servo 4 stops answering 1.5 s after start
    hwerror=3:overload@2    servo 3 raises an overload error 2 s after start (overload, overheating,
                            input_voltage, electrical_shock, motor_encoder)
    wire=1              model the wire time: 10 bits per byte at the bus baud rate, both directions
    seed=1              seed of the random draws (drop, corrupt); default 0, so runs repeat

Several values of one option are separated by commas (``unplug=4@1.5,5@3``) or given as repeated options.
"""

from __future__ import annotations

import random
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field

from drivers.control_table import MAX_ID, HardwareError
from retarget.errors import ConfigError

BITS_PER_BYTE = 10  #: 8N1: start bit, 8 data bits, stop bit


MAX_SECONDS = 86400.0  #: a fault's time or delay; NaN, inf and negative values are errors


def wire_time(n_bytes: int, baud: int) -> float:
    """Seconds ``n_bytes`` take on a ``baud`` bps 8N1 line."""
    return n_bytes * BITS_PER_BYTE / baud


@dataclass(frozen=True)
class ReplyFaults:
    """What happens to one servo's status packets: probabilities of loss and corruption, a fixed delay (s)."""

    drop: float = 0.0
    corrupt: float = 0.0
    delay: float = 0.0

    def __post_init__(self) -> None:
        for name in ("drop", "corrupt"):
            p = getattr(self, name)
            if not 0.0 <= p <= 1.0:
                raise ConfigError("Expected a fraction in [0, 1]", key=name, value=p)
        if not 0.0 <= self.delay <= MAX_SECONDS:
            raise ConfigError(f"Expected a delay from 0 to {MAX_SECONDS:g} s", key="delay", value=self.delay)


@dataclass(frozen=True)
class HardwareFault:
    """Servo ``id`` raises ``bits`` (HardwareError flags) ``at`` seconds after the bus started."""

    id: int
    bits: int
    at: float


@dataclass
class Faults:
    """Every fault of one bus.  Build in code, or with :meth:`from_options` from URL/CLI strings."""

    bus: ReplyFaults = field(default_factory=ReplyFaults)
    servos: dict[int, ReplyFaults] = field(default_factory=dict)
    unplug: dict[int, float] = field(default_factory=dict)  #: servo ID -> seconds after start
    hardware: list[HardwareFault] = field(default_factory=list)
    wire: bool = False
    seed: int = 0

    def __post_init__(self) -> None:
        self.rng = random.Random(self.seed)

    def for_servo(self, dxl_id: int) -> ReplyFaults:
        return self.servos.get(dxl_id, self.bus)

    def roll(self, probability: float) -> bool:
        """A seeded draw that is True with ``probability`` (no draw is spent when it is 0 or 1)."""
        if probability <= 0.0:
            return False
        if probability >= 1.0:
            return True
        return self.rng.random() < probability

    @property
    def active(self) -> bool:
        return bool(self.servos or self.unplug or self.hardware or self.bus != ReplyFaults())

    # ------------------------------------------------------------------ parsing

    @classmethod
    def from_options(
        cls,
        *,
        drop: Iterable[str] = (),
        corrupt: Iterable[str] = (),
        delay_ms: Iterable[str] = (),
        unplug: Iterable[str] = (),
        hwerror: Iterable[str] = (),
        wire: bool | str = False,
        seed: int | str = 0,
        source: str | None = None,
    ) -> Faults:
        """Parse the option strings documented in the module docstring.

        ConfigError on a bad value: its ``key`` is the option ("drop", "hwerror", ...), its ``path`` is
        ``source`` (the ``sim://`` URL the options came from, or None).

        >>> faults = Faults.from_options(drop=["0.1", "3:0.5"], unplug=["4@1.5"], wire=True)
        >>> faults.for_servo(1).drop, faults.for_servo(3).drop, faults.unplug, faults.wire
        (0.1, 0.5, {4: 1.5}, True)
        >>> Faults.from_options(hwerror=["3:melting@2"])  # doctest: +ELLIPSIS
        Traceback (most recent call last):
        ...
        retarget.errors.ConfigError: hwerror: Expected a kind among input_voltage, ... (got '3:melting@2')
        """
        bus_values: dict[str, float] = {}
        per_servo: dict[int, dict[str, float]] = {}
        for key, values, scale in (("drop", drop, 1.0), ("corrupt", corrupt, 1.0), ("delay_ms", delay_ms, 1e-3)):
            name = "delay" if key == "delay_ms" else key
            for item in _split(values):
                sid, _, number = item.rpartition(":")
                value = _number(number, source, key, item) * scale
                if sid:
                    per_servo.setdefault(_servo_id(sid, source, key, item), {})[name] = value
                else:
                    bus_values[name] = value
        try:
            bus = ReplyFaults(**bus_values)
            servos = {sid: ReplyFaults(**{**bus_values, **vals}) for sid, vals in per_servo.items()}
        except ConfigError as exc:
            raise ConfigError(exc.message, path=source, key=exc.key, value=exc.value) from None
        unplugs: dict[int, float] = {}
        for item in _split(unplug):
            sid, sep, at = item.partition("@")
            if not sep:
                raise ConfigError("Expected ID@SECONDS", path=source, key="unplug", value=item)
            unplugs[_servo_id(sid, source, "unplug", item)] = _number(at, source, "unplug", item)
        hardware: list[HardwareFault] = []
        for item in _split(hwerror):
            head, sep, at = item.partition("@")
            sid, sep2, kind = head.partition(":")
            if not (sep and sep2):
                raise ConfigError("Expected ID:KIND@SECONDS", path=source, key="hwerror", value=item)
            try:
                bits = HardwareError[kind.strip().upper()]
            except KeyError:
                kinds = ", ".join(str(e.name).lower() for e in HardwareError)
                raise ConfigError(f"Expected a kind among {kinds}", path=source, key="hwerror", value=item) from None
            hardware.append(
                HardwareFault(_servo_id(sid, source, "hwerror", item), int(bits), _number(at, source, "hwerror", item))
            )
        wire_on = _flag(wire, source)
        try:
            seed_value = int(seed)
        except ValueError:
            raise ConfigError("Expected an integer", path=source, key="seed", value=seed) from None
        return cls(bus, servos, unplugs, hardware, wire_on, seed_value)

    @classmethod
    def from_query(cls, query: Mapping[str, Sequence[str]], *, source: str | None = None) -> Faults:
        """From a parsed URL query (``urllib.parse.parse_qs``); unknown keys are left to the caller."""

        def values(key: str) -> list[str]:
            return list(query.get(key, ()))

        wire = values("wire")
        seed = values("seed")
        return cls.from_options(
            drop=values("drop"),
            corrupt=values("corrupt"),
            delay_ms=values("delay_ms"),
            unplug=values("unplug"),
            hwerror=values("hwerror"),
            wire=wire[-1] if wire else False,
            seed=seed[-1] if seed else 0,
            source=source,
        )


QUERY_KEYS = frozenset({"drop", "corrupt", "delay_ms", "unplug", "hwerror", "wire", "seed"})


def _split(values: Iterable[str]) -> list[str]:
    return [part.strip() for v in values for part in str(v).split(",") if part.strip()]


def _number(text: str, source: str | None, key: str, item: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise ConfigError("Expected a number", path=source, key=key, value=item) from None
    if not 0.0 <= value <= MAX_SECONDS * 1000.0:  # milliseconds for delay_ms, seconds for the times: both far
        raise ConfigError("Expected a finite value >= 0", path=source, key=key, value=item)
    return value


def _servo_id(text: str, source: str | None, key: str, item: str) -> int:
    try:
        sid = int(text)
    except ValueError:
        raise ConfigError(f"Expected a servo ID 0..{MAX_ID}", path=source, key=key, value=item) from None
    if not 0 <= sid <= MAX_ID:
        raise ConfigError(f"Expected a servo ID 0..{MAX_ID}", path=source, key=key, value=item)
    return sid


def _flag(value: bool | str, source: str | None) -> bool:
    if isinstance(value, bool):
        return value
    text = str(value).strip().lower()
    if text in ("1", "true", "yes", "on", ""):
        return True
    if text in ("0", "false", "no", "off"):
        return False
    raise ConfigError("Expected 0 or 1", path=source, key="wire", value=value)
