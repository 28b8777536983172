"""How a simulated servo checks and carries out a write: access, ranges, limits, the e-Manual's special rules.

:class:`WriteRules` is a part of :class:`sim.servo.SimServo` (a mixin, kept apart to keep each module short); the
rules are in the module docstrings of :mod:`sim.servo` (access, ranges, limits) and :mod:`sim.rules` (Protocol
Type, Bus Watchdog, Indirect Data).  A failed write changes nothing; a write through Indirect Data is checked as
the same bytes written to the targets, and refused as a whole when any target refuses.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable

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

_POSITION_MODES = (OperatingMode.POSITION, OperatingMode.EXTENDED_POSITION, OperatingMode.CURRENT_BASED_POSITION)
_TORQUE_ENABLE = common_register("Torque Enable").address
_DRIVE_MODE = common_register("Drive Mode").address
_SHUTDOWN = common_register("Shutdown").address
_HARDWARE_ERROR_STATUS = common_register("Hardware Error Status").address
_BUS_WATCHDOG = common_register("Bus Watchdog").address


class WriteRules:
    """Write validation and effects of :class:`sim.servo.SimServo` (which provides the attributes below)."""

    model: Model
    writes: deque[tuple[float, int, bytes]]
    _mem: bytearray
    _t: float
    _fresh: float | None
    _indirect_used: bool
    _state: tuple[float, float, float]
    _trajectory: Trajectory
    _watchdog: BusWatchdog

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

    def _validate(self, address: int, data: bytes) -> tuple[int, list[Register]]:
        """``(error, registers covered)``: the items' own rules, then those of any Indirect Data targets."""
        error, regs = self._validate_items(address, data)
        if error or not self._indirect_used:
            return error, regs
        for target, run in self._indirect_runs(address, data, regs):
            target_error, _ = self._validate_items(target, run)
            if target_error:
                return target_error, []
        return StatusError.NONE, regs

    def _indirect_runs(self, address: int, data: bytes, regs: list[Register]) -> list[tuple[int, bytes]]:
        writes = [(r.address, data[r.address - address]) for r in regs if rules.is_indirect_data(r)]
        if not writes:
            return []
        return rules.indirect_runs(rules.indirect_targets(self.model, self._mem), writes)

    def _validate_items(self, address: int, data: bytes) -> tuple[int, list[Register]]:
        if not data:
            return StatusError.DATA_LENGTH, []
        end = address + len(data)
        if address < 0 or end > len(self._mem):
            return StatusError.ACCESS, []
        regs = self.model.covering(address, len(data))
        if not regs:
            return StatusError.ACCESS, []
        for reg in regs:
            if reg.address < address or reg.end > end:
                return StatusError.DATA_LENGTH, []
        for reg in regs:
            if not reg.writable:
                return StatusError.ACCESS, []
            if reg.eeprom and self._mem[_TORQUE_ENABLE]:
                return StatusError.ACCESS, []
        new = {r.name: r.decode(data[r.address - address : r.end - address]) for r in regs}
        for reg in regs:
            error = self._check_value(reg, new)
            if error:
                return error, []
        return StatusError.NONE, regs

    def _check_value(self, reg: Register, new: dict[str, int]) -> int:
        """The error writing ``new[reg.name]`` to ``reg`` answers, with the other ``new`` values written alongside."""

        def value(name: str) -> int:
            return new[name] if name in new else self._get(name)

        v = new[reg.name]
        if not reg.in_range(v):
            return StatusError.DATA_RANGE
        if reg.name == "Operating Mode" and v not in self.model.operating_modes:
            return StatusError.DATA_RANGE
        if reg.name == "Protocol Type" and v != rules.PROTOCOL_TYPE_SUPPORTED:
            return StatusError.DATA_RANGE  # the simulator speaks Protocol 2.0 only (sim.rules)
        if reg.name in rules.WATCHDOG_LOCKED and self._mem[_BUS_WATCHDOG] == WATCHDOG_ERROR:
            return StatusError.DATA_RANGE  # goals are read-only after a Bus Watchdog trip (sim.watchdog)
        position_mode = value("Operating Mode") == OperatingMode.POSITION
        if reg.limit is not None and (reg.name != "Goal Position" or position_mode):
            lo_name, hi_name = reg.limit
            lo = -value(lo_name[1:]) if lo_name.startswith("-") else value(lo_name)
            if not lo <= v <= value(hi_name):
                return StatusError.DATA_LIMIT
        return StatusError.NONE

    # ------------------------------------------------------------------ effects

    def _apply(self, address: int, data: bytes, regs: list[Register]) -> None:
        self._fresh = None
        self.writes.append((self._t, address, data))
        runs = self._indirect_runs(address, data, regs) if self._indirect_used else []
        effects: list[Callable[[], None]] = []
        for reg in regs:
            raw = data[reg.address - address : reg.end - address]
            old = self._mem[reg.address : reg.end]
            self._mem[reg.address : reg.end] = raw
            effect = self._effect(reg, raw, old)
            if effect is not None:
                effects.append(effect)
        for effect in effects:
            effect()
        for target, run in runs:
            self._apply(target, run, self.model.covering(target, len(run)))
        self._refresh_present(self._t)

    def _effect(self, reg: Register, raw: bytes, old: bytes | bytearray) -> Callable[[], None] | None:
        """What storing ``raw`` (was ``old``) in ``reg`` sets off, to run once every item of the write is stored."""
        name = reg.name
        torque = self._mem[_TORQUE_ENABLE]
        mode = self._mode()
        if name == "Torque Enable":
            return self._torque_effect(raw[0], old[0])
        if name == "Goal Position":
            if not torque and self._mem[_DRIVE_MODE] & DriveMode.TORQUE_ON_BY_GOAL and not self._shut_down():
                self._mem[_TORQUE_ENABLE] = torque = 1
            return self._plan_goal if torque and mode in _POSITION_MODES else None
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
