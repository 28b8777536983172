"""How the gripper servo is configured: current-based position mode with a current limit, as Interbotix and LeRobot.

A gripper closing on an object in plain position mode (3) pushes at full torque until the servo overheats or
raises Overload.  With ``[gripper] current_limit`` (mA) in the arm file the gripper runs in current-based position
mode (Operating Mode 5) with Current Limit (EEPROM) and Goal Current (RAM) at that value: it moves as in position
mode, and against an object its current stays at the limit (e-Manual, Goal Current(102): "sets a limit to current
in Current-based Position Control mode").  ``[gripper] pwm_limit`` (% of full duty) sets PWM Limit, which caps the
output in every mode: the bound for XL430 grippers, which have no current sensing and no mode 5.

>>> from drivers.control_table import model
>>> from retarget.arm.model import Gripper, Servo
>>> g = Gripper("gripper", Servo(9, "XM430-W350"), -1.0, 1.0, current_limit=650.0)
>>> gripper_registers(g, model("XM430-W350"))
({'Operating Mode': 5, 'Current Limit': 242}, {'Goal Current': 242})
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Protocol

from drivers import units
from drivers.comm import Link
from drivers.control_table import Model, OperatingMode
from retarget.arm.model import Gripper
from retarget.errors import ConfigError


class PlannedServo(Protocol):
    """What the gripper needs of its ``drivers.servo_plan.ServoPlan`` (which imports this module)."""

    @property
    def id(self) -> int: ...
    @property
    def model(self) -> Model: ...
    @property
    def offset(self) -> int: ...
    @property
    def min_pulse(self) -> int: ...
    @property
    def max_pulse(self) -> int: ...


PWM_FULL_SCALE = 885  #: PWM Limit units of 100 % duty (0.113 % each; e-Manual PWM Limit(36))


def gripper_registers(gripper: Gripper, model: Model) -> tuple[dict[str, int], dict[str, int]]:
    """``(eeprom, ram)``: the gripper's Operating Mode and limits, register name -> value.

    ConfigError (key ``gripper.current_limit``) for a current limit on a model without current sensing or above
    its Current Limit maximum.
    """
    eeprom: dict[str, int] = {"Operating Mode": int(OperatingMode.POSITION)}
    ram: dict[str, int] = {}
    if gripper.current_limit is not None:
        unit = model.current_unit_ma
        if unit is None or OperatingMode.CURRENT_BASED_POSITION not in model.operating_modes:
            raise ConfigError(
                f"Expected a model with current-based position mode, got {model.name} (use pwm_limit)",
                key="gripper.current_limit",
                value=gripper.current_limit,
            )
        units = max(1, round(gripper.current_limit / unit))
        top = model.register("Current Limit").maximum
        if top is not None and units > top:
            raise ConfigError(
                f"Expected at most {top * unit:.0f} mA for {model.name}",
                key="gripper.current_limit",
                value=gripper.current_limit,
            )
        eeprom = {"Operating Mode": int(OperatingMode.CURRENT_BASED_POSITION), "Current Limit": units}
        ram["Goal Current"] = units
    if gripper.pwm_limit is not None:
        eeprom["PWM Limit"] = max(1, min(PWM_FULL_SCALE, round(gripper.pwm_limit / 100.0 * PWM_FULL_SCALE)))
    return eeprom, ram


@dataclass(frozen=True)
class GripperReading:
    """The gripper's last command and reading: closure 0 (open) .. 1 (closed), shaft angle rad, current A."""

    command: float = math.nan  #: the last closure sent; NaN before any
    angle: float = math.nan  #: Present Position, rad of the shaft; NaN before the first reading
    current: float = math.nan  #: Present Current, A (signed); NaN on models that report load (XL430)
    load: float = math.nan  #: Present Load, fraction -1..1; NaN on models that report current


class GripperChannel:
    """The gripper's goal and readings on the tick path of :class:`~drivers.dynamixel_bus.DynamixelBus`.

    :meth:`set` only stores a closure; :meth:`service` (called by the bus before a position read's request, where
    the watch PINGs) writes it when it moved by more than ``deadband`` and, every ``read_every`` calls once a
    command was given, reads Present Current/Load .. Present Position (10 bytes) for telemetry.
    """

    def __init__(self, gripper: Gripper, plan: PlannedServo, *, read_every: int = 20, deadband: float = 0.005):
        self.gripper, self.plan = gripper, plan
        self.read_every, self.deadband = max(1, read_every), deadband
        self.reading = GripperReading()
        self._wanted: float | None = None
        self._sent: float | None = None
        self._calls = 0

    def set(self, closure: float) -> None:
        """Ask for closure ``closure`` (0 open .. 1 closed, clipped); ValueError if not finite."""
        if not math.isfinite(closure):
            raise ValueError(f"Expected a finite gripper closure 0..1, got {closure}")
        self._wanted = min(max(float(closure), 0.0), 1.0)

    def service(self, link: Link) -> None:
        """Write a changed goal (one WRITE); read the present state every ``read_every`` calls once commanded."""
        wanted = self._wanted
        if wanted is None:
            return
        g, p = self.gripper, self.plan
        if self._sent is None or abs(wanted - self._sent) > self.deadband:
            goal = int(units.rad_to_pulses(g.angle(wanted), offset=p.offset))
            link.write_register(p.id, p.model.register("Goal Position"), int(min(max(goal, p.min_pulse), p.max_pulse)))
            self._sent = wanted
            self.reading = dataclasses.replace(self.reading, command=wanted)
        if self._calls % self.read_every == 0:
            self.reading = self.read(link)
        self._calls += 1

    def read(self, link: Link) -> GripperReading:
        """One READ of Present Current/Load (126) .. Present Position (132..135)."""
        p = self.plan
        load_reg = p.model.register(p.model.load_register)
        pos_reg = p.model.register("Present Position")
        data = link.read(p.id, load_reg.address, pos_reg.end - load_reg.address, what="the gripper state").data
        raw = load_reg.decode(data[: load_reg.size])
        pulses = units.signed32(pos_reg.decode(data[pos_reg.address - load_reg.address :]))
        angle = float(units.pulses_to_rad(pulses, offset=p.offset))
        unit = p.model.current_unit_ma
        current, load = (math.nan, raw / 1000.0) if unit is None else (raw * unit / 1000.0, math.nan)
        return GripperReading(self.reading.command, angle, current, load)
