"""How a simulated servo checks and carries out a write: access, ranges, limits, the e-Manual's special rules.

:class:`WriteRules` is a part of :class:`sim.servo.SimServo` (a mixin, kept apart to keep each module short); the
rules are in the module docstrings of :mod:`sim.servo` (access, ranges, limits) and :mod:`sim.rules` (Protocol
Type, Bus Watchdog, Indirect Data).  A failed write changes nothing; a write through Indirect Data is checked as
the same bytes written to the targets, and refused as a whole when any target refuses.
"""

from __future__ import annotations

import struct
from collections import deque
from collections.abc import Callable, Sequence
from typing import NamedTuple

from drivers.control_table import (
    DriveMode,
    Model,
    OperatingMode,
    Register,
    StatusError,
    common_register,
)
from sim import rules
from sim.profile import Trajectory, rest
from sim.watchdog import WATCHDOG_ERROR, BusWatchdog

_POSITION_MODES = frozenset(
    map(int, (OperatingMode.POSITION, OperatingMode.EXTENDED_POSITION, OperatingMode.CURRENT_BASED_POSITION))
)
_TORQUE_ENABLE = common_register("Torque Enable").address
_OPERATING_MODE = common_register("Operating Mode").address
_TORQUE_ON_BY_GOAL = int(DriveMode.TORQUE_ON_BY_GOAL)  #: Drive Mode bit 3, as an int (IntFlag operations are slow)
_DRIVE_MODE = common_register("Drive Mode").address
_SHUTDOWN = common_register("Shutdown").address
_HARDWARE_ERROR_STATUS = common_register("Hardware Error Status").address
_BUS_WATCHDOG = common_register("Bus Watchdog").address
_FORMATS = {(1, False): "<B", (1, True): "<b", (2, False): "<H", (2, True): "<h", (4, False): "<I", (4, True): "<i"}
_SHAPES_MAX = 4096  #: (address, length) shapes a servo remembers
_NONE, _DATA_RANGE, _DATA_LIMIT = StatusError.NONE, StatusError.DATA_RANGE, StatusError.DATA_LIMIT
_POSITION = int(OperatingMode.POSITION)


class _Bound(NamedTuple):
    """An item bounding another at run time: its name, and how to read it from memory (None: as ``_get`` does)."""

    name: str
    reader: tuple[struct.Struct, int] | None


class _Check(NamedTuple):
    """How a value written to one item is checked (:meth:`WriteRules._check_value`), worked out once per item."""

    name: str
    low: int  #: the static data range (the item's minimum and maximum, else its type's)
    high: int
    mode: bool  #: Operating Mode: one of the model's modes
    protocol: bool  #: Protocol Type: the one the simulator speaks
    locked: bool  #: a goal: read-only after a Bus Watchdog trip
    limit: tuple[_Bound, bool, _Bound] | None  #: the items bounding it at run time: (lower, negated, upper)
    position_mode: bool  #: Goal Position: its limits hold in Position mode only


def _bound(model: Model, name: str) -> _Bound:
    reg = model.registers.get(name)
    st = None if reg is None else register_struct(reg)
    return _Bound(name, None if reg is None or st is None else (st, reg.address))


def _check(model: Model, reg: Register) -> _Check:
    low = reg.type_min if reg.minimum is None else reg.minimum
    high = reg.type_max if reg.maximum is None else reg.maximum
    limit = None
    if reg.limit is not None:
        lo_name, hi_name = reg.limit
        limit = (_bound(model, lo_name.removeprefix("-")), lo_name.startswith("-"), _bound(model, hi_name))
    name = reg.name
    return _Check(
        name,
        low,
        high,
        name == "Operating Mode",
        name == "Protocol Type",
        name in rules.WATCHDOG_LOCKED,
        limit,
        name == "Goal Position",
    )


class _Shape(NamedTuple):
    """What a write of some bytes at some address covers, for one model (it never changes, so worked out once)."""

    error: int  #: Access (nothing, or a read-only item) or Data Length (part of an item) whatever the state; else 0
    regs: tuple[Register, ...]  #: the items covered, by address
    eeprom: bool  #: whether any is in the EEPROM area (Access error while torque is on)
    fields: tuple[tuple[str, struct.Struct | None, Register, int], ...]
    #: per item: name, :func:`register_struct`, the item, its offset in the data
    checks: tuple[_Check, ...] = ()  #: per item, how its value is checked


def register_struct(reg: Register) -> struct.Struct | None:
    """The struct that reads ``reg``'s bytes as ``Register.decode`` does (little-endian, its size and sign), without
    the copies; None for a size it has no format for."""
    fmt = _FORMATS.get((reg.size, reg.signed))
    return None if fmt is None else struct.Struct(fmt)


def _decoded(st: struct.Struct | None, reg: Register, data: bytes, offset: int) -> int:
    """The value of item ``reg`` at ``offset`` in ``data`` (through ``st``, its :func:`register_struct`, if any)."""
    if st is None:
        return reg.decode(data[offset : offset + reg.size])
    value: int = st.unpack_from(data, offset)[0]
    return value


def _shape(model: Model, address: int, length: int) -> _Shape:
    regs = tuple(model.covering(address, length))
    if not regs:
        return _Shape(StatusError.ACCESS, (), False, ())
    end = address + length
    if any(reg.address < address or reg.end > end for reg in regs):
        return _Shape(StatusError.DATA_LENGTH, (), False, ())
    if not all(reg.writable for reg in regs):
        return _Shape(StatusError.ACCESS, (), False, ())
    fields = tuple((reg.name, register_struct(reg), reg, reg.address - address) for reg in regs)
    checks = tuple(_check(model, reg) for reg in regs)
    return _Shape(StatusError.NONE, regs, any(reg.eeprom for reg in regs), fields, checks)


class WriteRules:
    """Write validation and effects of :class:`sim.servo.SimServo` (which provides the attributes below)."""

    model: Model
    writes: deque[tuple[float, int, bytes]]
    _mem: bytearray
    _t: float
    _fresh: float | None
    _pending: float | None
    _indirect_used: bool
    _state: tuple[float, float, float]
    _trajectory: Trajectory
    _watchdog: BusWatchdog
    _shapes: dict[tuple[int, int], _Shape]  #: _shape by (address, length), this servo's model

    # provided by SimServo
    def _get(self, name: str) -> int:
        raise NotImplementedError

    def _mode(self) -> int:
        raise NotImplementedError

    def _torque_on(self) -> None:
        raise NotImplementedError

    def _torque_off(self) -> None:
        raise NotImplementedError

    def _plan_goal(self) -> None:
        raise NotImplementedError

    def _plan_mode(self) -> None:
        raise NotImplementedError

    def _refresh_present(self, now: float) -> None:
        raise NotImplementedError

    # ------------------------------------------------------------------ validation

    def _validate(self, address: int, data: bytes) -> tuple[int, Sequence[Register]]:
        """``(error, registers covered)``: the items' own rules, then those of any Indirect Data targets."""
        error, regs = self._validate_items(address, data)
        if error or not self._indirect_used:
            return error, regs
        for target, run in self._indirect_runs(address, data, regs):
            target_error, _ = self._validate_items(target, run)
            if target_error:
                return target_error, []
        return _NONE, regs

    def _indirect_runs(self, address: int, data: bytes, regs: Sequence[Register]) -> list[tuple[int, bytes]]:
        writes = [(r.address, data[r.address - address]) for r in regs if rules.is_indirect_data(r)]
        if not writes:
            return []
        return rules.indirect_runs(rules.indirect_targets(self.model, self._mem), writes)

    def _validate_items(self, address: int, data: bytes) -> tuple[int, Sequence[Register]]:
        if not data:
            return StatusError.DATA_LENGTH, []
        length = len(data)
        if address < 0 or address + length > len(self._mem):
            return StatusError.ACCESS, []
        shape = self._shapes.get((address, length))
        if shape is None:
            shape = _shape(self.model, address, length)
            if len(self._shapes) < _SHAPES_MAX:
                self._shapes[address, length] = shape
        if shape.error:
            return shape.error, []
        if shape.eeprom and self._mem[_TORQUE_ENABLE]:
            return StatusError.ACCESS, []
        fields = shape.fields
        if len(fields) == 1:  # one item (a sync write of goals): no comprehension to run
            name, st, reg, offset = fields[0]
            new = {name: st.unpack_from(data, offset)[0] if st is not None else _decoded(st, reg, data, offset)}
        else:
            new = {name: _decoded(st, reg, data, offset) for name, st, reg, offset in fields}
        for check in shape.checks:
            error = self._check_value(check, new)
            if error:
                return error, ()
        return _NONE, shape.regs

    def _check_value(self, check: _Check, new: dict[str, int]) -> int:
        """The error writing ``new[check.name]`` to its item answers, with the other ``new`` values written too."""
        v = new[check.name]
        if not check.low <= v <= check.high:
            return _DATA_RANGE
        if check.mode and v not in self.model.operating_modes:
            return _DATA_RANGE
        if check.protocol and v != rules.PROTOCOL_TYPE_SUPPORTED:
            return _DATA_RANGE  # the simulator speaks Protocol 2.0 only (sim.rules)
        if check.locked and self._mem[_BUS_WATCHDOG] == WATCHDOG_ERROR:
            return _DATA_RANGE  # goals are read-only after a Bus Watchdog trip (sim.watchdog)
        limit = check.limit
        if limit is None:
            return _NONE
        if check.position_mode:
            mode = new["Operating Mode"] if "Operating Mode" in new else self._mem[_OPERATING_MODE]
            if mode != _POSITION:
                return _NONE
        low, negated, high = limit
        lo = new[low.name] if low.name in new else self._value(low)
        hi = new[high.name] if high.name in new else self._value(high)
        if not (-lo if negated else lo) <= v <= hi:
            return _DATA_LIMIT
        return _NONE

    def _value(self, item: _Bound) -> int:
        """``item``'s value now."""
        reader = item.reader
        if reader is None:
            return self._get(item.name)
        value: int = reader[0].unpack_from(self._mem, reader[1])[0]
        return value

    # ------------------------------------------------------------------ effects

    def _apply(self, address: int, data: bytes, regs: Sequence[Register]) -> None:
        self._fresh = None
        self.writes.append((self._t, address, data))
        runs = self._indirect_runs(address, data, regs) if self._indirect_used else []
        effects: list[Callable[[], None]] = []
        mem = self._mem
        for reg in regs:
            start, end = reg.address, reg.address + reg.size
            raw = data[start - address : end - address]
            old = mem[start:end]
            mem[start:end] = raw
            effect = self._effect(reg, raw, old)
            if effect is not None:
                effects.append(effect)
        for effect in effects:
            effect()
        for target, run in runs:
            self._apply(target, run, self.model.covering(target, len(run)))
        if self._indirect_used:
            self._refresh_present(self._t)
        else:  # _refresh_present's lazy branch, inline
            self._fresh = self._pending = self._t

    def _effect(self, reg: Register, raw: bytes, old: bytes | bytearray) -> Callable[[], None] | None:
        """What storing ``raw`` (was ``old``) in ``reg`` sets off, to run once every item of the write is stored."""
        name = reg.name
        torque = self._mem[_TORQUE_ENABLE]
        mode = self._mem[_OPERATING_MODE]
        if name == "Goal Position":
            if not torque and self._mem[_DRIVE_MODE] & _TORQUE_ON_BY_GOAL and not self._shut_down():
                self._mem[_TORQUE_ENABLE] = torque = 1
            return self._plan_goal if torque and mode in _POSITION_MODES else None
        if name == "Torque Enable":
            return self._torque_effect(raw[0], old[0])
        if name in ("Goal Velocity", "Goal PWM") or (name == "Goal Current" and mode == OperatingMode.CURRENT):
            return self._plan_mode if torque else None
        if name == "Goal Current" and mode == OperatingMode.CURRENT_BASED_POSITION and torque:
            return self._plan_goal  # a new current bound reshapes the move
        if name == "Operating Mode" and raw != old:
            return lambda: setattr(self, "_trajectory", rest(self._state[0]))
        if name == "Bus Watchdog":
            self._watchdog.packet(self._t)  # (re)armed: the interval starts now
        elif name.startswith("Indirect Address"):
            self._indirect_used = True
        return None

    def _torque_effect(self, new: int, old: int) -> Callable[[], None] | None:
        if new and not old:
            if self._shut_down():
                self._mem[_TORQUE_ENABLE] = 0  # shut down: only REBOOT brings torque back
                return None
            self._watchdog.packet(self._t)  # the watchdog watches from torque on
            return self._torque_on
        if not new and old:
            return self._torque_off
        return None

    def _shut_down(self) -> bool:
        return bool(self._mem[_HARDWARE_ERROR_STATUS] & self._mem[_SHUTDOWN])
