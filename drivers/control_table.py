"""Dynamixel X-series control tables, kept as data: the one source of truth for the driver and the simulator.

Each :class:`Model` maps register names, spelled as in the ROBOTIS e-Manual ("Goal Position"), to a
:class:`Register` (address, size, access, EEPROM or RAM, default, data range, signedness, unit).
Models: XL430-W250 (1060), XM430-W350 (1020), XL330-M288 (1200), XM540-W270 (1120); the names equal
``retarget.arm.SERVO_MODELS``.

Sources: the e-Manual pages ``docs/en/dxl/x/{xl430-w250,xm430-w350,xl330-m288,xm540-w270}.md`` (control
tables of the EEPROM and RAM areas) and ``docs/en/dxl/protocol2.md`` (instructions, status errors).

Two kinds of bound, as the servo checks them on a write:

* ``minimum``/``maximum``: the static data range; a value outside it answers **Data Range** error (4).
* ``limit``: a pair of register names bounding the value at run time, e.g. Goal Position within
  ("Min Position Limit", "Max Position Limit"); a leading ``-`` negates, so Goal Velocity is within
  ("-Velocity Limit", "Velocity Limit").  A value outside answers **Data Limit** error (6).

EEPROM registers (address < 64) are writable only while Torque Enable is 0, else **Access** error (7).
XL430-W250 has no current sensing: address 126 is "Present Load" (0.1 %) and it has no Current Limit
and Goal Current; use :attr:`Model.load_register` for the name.

It also holds the one parser of servo ID lists (:func:`parse_ids`), for the scan and the simulator alike, and the
Protocol 2.0 CRC (:func:`crc16`), for the driver's packets and the simulator's.

This module imports nothing beyond the standard library and :mod:`retarget.errors`, so ``drivers`` and ``sim``
may both use it (``sim`` imports nothing else of ``drivers``).
"""

from __future__ import annotations

import enum
import math
import struct
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from functools import cache
from types import MappingProxyType

from retarget.errors import ConfigError

# --------------------------------------------------------------------------- protocol constants


class Instruction(enum.IntEnum):
    """Protocol 2.0 instruction bytes."""

    PING = 0x01
    READ = 0x02
    WRITE = 0x03
    REG_WRITE = 0x04
    ACTION = 0x05
    FACTORY_RESET = 0x06
    REBOOT = 0x08
    CLEAR = 0x10
    CONTROL_TABLE_BACKUP = 0x20
    STATUS = 0x55
    SYNC_READ = 0x82
    SYNC_WRITE = 0x83
    FAST_SYNC_READ = 0x8A
    BULK_READ = 0x92
    BULK_WRITE = 0x93
    FAST_BULK_READ = 0x9A


class StatusError(enum.IntEnum):
    """The error *number* in bits 0-6 of a status packet's ERR byte (bit 7 is :data:`ALERT_BIT`)."""

    NONE = 0
    RESULT_FAIL = 1  #: failed to process the instruction
    INSTRUCTION = 2  #: undefined instruction, or ACTION without REG_WRITE
    CRC = 3  #: CRC of the instruction does not match
    DATA_RANGE = 4  #: value outside the register's range
    DATA_LENGTH = 5  #: data shorter than the register, or a length that does not fit
    DATA_LIMIT = 6  #: value outside a limit register (e.g. Goal Position vs Position Limits)
    ACCESS = 7  #: read-only / undefined address, or an EEPROM write with torque on


#: Bit 7 of the ERR byte: the device has a hardware error; read Hardware Error Status (70).
ALERT_BIT = 0x80

BROADCAST_ID = 0xFE
MAX_ID = 252


class HardwareError(enum.IntFlag):
    """Bits of Hardware Error Status (70) and of the Shutdown (63) mask."""

    INPUT_VOLTAGE = 0x01
    OVERHEATING = 0x04
    MOTOR_ENCODER = 0x08
    ELECTRICAL_SHOCK = 0x10
    OVERLOAD = 0x20


def hardware_error_names(bits: int) -> tuple[str, ...]:
    """``0x24 -> ("overheating", "overload")``: the lower-case names of the set bits, lowest first."""
    return tuple(str(e.name).lower() for e in HardwareError if bits & e.value)


class OperatingMode(enum.IntEnum):
    """Operating Mode (11)."""

    CURRENT = 0
    VELOCITY = 1
    POSITION = 3
    EXTENDED_POSITION = 4
    CURRENT_BASED_POSITION = 5
    PWM = 16


class DriveMode(enum.IntFlag):
    """Bits of Drive Mode (10)."""

    REVERSE = 0x01  #: CCW negative, CW positive: Goal/Present Position (and velocity, current) invert
    DUAL_SLAVE = 0x02  #: X540 dual joint slave (driven by the master's sync cable)
    TIME_BASED_PROFILE = 0x04  #: Profile Acceleration/Velocity are times in ms instead of rates
    TORQUE_ON_BY_GOAL = 0x08  #: a goal write turns torque on (newer firmware)


class FactoryReset(enum.IntEnum):
    """The parameter of FACTORY_RESET (0x06)."""

    ALL = 0xFF  #: reset every item, ID and Baud Rate included
    EXCEPT_ID = 0x01  #: keep the ID
    EXCEPT_ID_AND_BAUD = 0x02  #: keep the ID and the Baud Rate


#: Baud Rate (8) register value -> bits per second.
BAUD_RATES: Mapping[int, int] = MappingProxyType(
    {0: 9600, 1: 57600, 2: 115200, 3: 1_000_000, 4: 2_000_000, 5: 3_000_000, 6: 4_000_000, 7: 4_500_000}
)
#: bits per second -> Baud Rate (8) register value.
BAUD_CODES: Mapping[int, int] = MappingProxyType({bps: code for code, bps in BAUD_RATES.items()})

# --------------------------------------------------------------------------- units

PULSES_PER_REV = 4096
RAD_PER_PULSE = 2.0 * math.pi / PULSES_PER_REV  #: Present/Goal Position unit, ~0.088 deg
RPM_PER_VELOCITY_UNIT = 0.229  #: Velocity Limit, Goal/Present Velocity, Profile Velocity unit
RPM2_PER_ACCEL_UNIT = 214.577  #: Profile Acceleration unit (velocity-based profile), rev/min^2
VOLT_PER_UNIT = 0.1  #: Present Input Voltage and the voltage limits
RETURN_DELAY_UNIT_US = 2  #: Return Delay Time (9) unit, microseconds
RETURN_DELAY_UNIT_S = RETURN_DELAY_UNIT_US * 1e-6


# --------------------------------------------------------------------------- register and model types


class Access(enum.Enum):
    R = "R"
    RW = "RW"


EEPROM_END = 64  #: addresses below this are the EEPROM area


@dataclass(frozen=True)
class Register:
    """One control-table item.

    ``default`` is the value after a factory reset (``None``: set by the device, e.g. Present Position).
    ``minimum``/``maximum`` is the static data range (``None``: the full range of the size/signedness).
    ``limit`` names the registers bounding the value at run time (see the module docstring).
    """

    name: str
    address: int
    size: int
    access: Access
    default: int | None = None
    minimum: int | None = None
    maximum: int | None = None
    signed: bool = False
    unit: str = ""
    limit: tuple[str, str] | None = None

    @property
    def eeprom(self) -> bool:
        return self.address < EEPROM_END

    @property
    def writable(self) -> bool:
        return self.access is Access.RW

    @property
    def end(self) -> int:
        """One past the last byte."""
        return self.address + self.size

    @property
    def type_min(self) -> int:
        return -(1 << (8 * self.size - 1)) if self.signed else 0

    @property
    def type_max(self) -> int:
        return (1 << (8 * self.size - 1)) - 1 if self.signed else (1 << (8 * self.size)) - 1

    def encode(self, value: int) -> bytes:
        """Little-endian bytes of ``value``; raises ValueError when it does not fit the register."""
        if not self.type_min <= value <= self.type_max:
            raise ValueError(f"{self.name}: expected {self.type_min}..{self.type_max}, got {value}")
        return int(value).to_bytes(self.size, "little", signed=self.signed)

    def decode(self, data: bytes | bytearray | memoryview) -> int:
        """The value of ``size`` little-endian bytes."""
        if len(data) != self.size:
            raise ValueError(f"{self.name}: expected {self.size} bytes, got {len(data)}")
        return int.from_bytes(bytes(data), "little", signed=self.signed)

    def in_range(self, value: int) -> bool:
        lo = self.type_min if self.minimum is None else self.minimum
        hi = self.type_max if self.maximum is None else self.maximum
        return lo <= value <= hi


@dataclass(frozen=True)
class Model:
    """One servo model: its number, registers and the few physical facts the simulator needs."""

    name: str
    number: int
    registers: Mapping[str, Register]
    no_load_rpm: float  #: at ``nominal_voltage``
    nominal_voltage: float  #: volts, the recommended supply
    stall_torque: float  #: N*m at ``nominal_voltage``
    stall_current: float  #: A at ``nominal_voltage``
    firmware: int  #: the Firmware Version (6) the simulator reports
    current_unit_ma: float | None  #: Present Current unit in mA; ``None`` when 126 is Present Load (0.1 %)
    operating_modes: tuple[OperatingMode, ...]
    max_baud_code: int = 7
    fast_read_min_firmware: int = 45  #: FAST_SYNC_READ / FAST_BULK_READ need at least this firmware
    table_size: int = 662  #: bytes of control-table memory (highest address + 1)
    _by_address: Mapping[int, Register] = field(init=False, repr=False, compare=False)
    _covering: dict[tuple[int, int], tuple[Register, ...]] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "_by_address", MappingProxyType({r.address: r for r in self.registers.values()}))
        object.__setattr__(self, "_covering", {})

    @property
    def fast_sync_read(self) -> bool:
        """Whether this firmware answers FAST_SYNC_READ and FAST_BULK_READ."""
        return self.firmware >= self.fast_read_min_firmware

    @property
    def load_register(self) -> str:
        """``"Present Current"``, or ``"Present Load"`` on models without current sensing (XL430)."""
        return "Present Current" if "Present Current" in self.registers else "Present Load"

    def register(self, name: str) -> Register:
        """The register called ``name``; KeyError naming the model and the close names otherwise."""
        try:
            return self.registers[name]
        except KeyError:
            raise KeyError(f"{self.name} has no register {name!r}") from None

    def at(self, address: int) -> Register | None:
        """The register starting at ``address``, or None."""
        return self._by_address.get(address)

    def covering(self, address: int, length: int) -> list[Register]:
        """Registers overlapping ``[address, address + length)``, by address."""
        key = (address, length)
        found = self._covering.get(key)
        if found is None:
            end = address + length
            found = tuple(
                sorted(
                    (r for r in self.registers.values() if r.address < end and address < r.end), key=lambda r: r.address
                )
            )
            if len(self._covering) < 4096:
                self._covering[key] = found
        return list(found)

    def defaults(self) -> bytearray:
        """The control-table memory after a factory reset: ``table_size`` bytes, every default encoded."""
        mem = bytearray(self.table_size)
        for reg in self.registers.values():
            if reg.default is not None:
                mem[reg.address : reg.end] = reg.encode(reg.default)
        return mem


# --------------------------------------------------------------------------- the tables

R, RW = Access.R, Access.RW


def _row(
    name: str,
    address: int,
    size: int,
    access: Access,
    default: int | None = None,
    minimum: int | None = None,
    maximum: int | None = None,
    *,
    signed: bool = False,
    unit: str = "",
    limit: tuple[str, str] | None = None,
) -> Register:
    return Register(name, address, size, access, default, minimum, maximum, signed, unit, limit)


def _x_series_common(
    *,
    model_number: int,
    firmware: int,
    baud_max: int,
    drive_mode_max: int,
    temperature_limit: int,
    voltage: tuple[int, int, int, int],  # max default, min default, range lo, range hi
    velocity_limit: tuple[int, int],  # default, max
    gains: tuple[int, int, int, int, int],  # vel I, vel P, pos D, pos I, pos P
    shutdown: int,
) -> list[Register]:
    vmax_default, vmin_default, v_lo, v_hi = voltage
    vel_default, vel_max = velocity_limit
    vi, vp, pd, pi, pp = gains
    return [
        # EEPROM area
        _row("Model Number", 0, 2, R, model_number),
        _row("Model Information", 2, 4, R, 0),
        _row("Firmware Version", 6, 1, R, firmware),
        _row("ID", 7, 1, RW, 1, 0, 252),
        _row("Baud Rate", 8, 1, RW, 1, 0, baud_max),
        _row("Return Delay Time", 9, 1, RW, 250, 0, 254, unit="2 us"),
        _row("Drive Mode", 10, 1, RW, 0, 0, drive_mode_max),
        _row("Operating Mode", 11, 1, RW, 3, 0, 16),
        _row("Secondary(Shadow) ID", 12, 1, RW, 255, 0, 255),
        _row("Protocol Type", 13, 1, RW, 2, 1, 2),
        _row("Homing Offset", 20, 4, RW, 0, -1_044_479, 1_044_479, signed=True, unit="pulse"),
        _row("Moving Threshold", 24, 4, RW, 10, 0, 1023, unit="0.229 rpm"),
        _row("Temperature Limit", 31, 1, RW, temperature_limit, 0, 100, unit="degC"),
        _row("Max Voltage Limit", 32, 2, RW, vmax_default, v_lo, v_hi, unit="0.1 V"),
        _row("Min Voltage Limit", 34, 2, RW, vmin_default, v_lo, v_hi, unit="0.1 V"),
        _row("PWM Limit", 36, 2, RW, 885, 0, 885, unit="0.113 %"),
        _row("Velocity Limit", 44, 4, RW, vel_default, 0, vel_max, unit="0.229 rpm"),
        _row("Max Position Limit", 48, 4, RW, 4095, 0, 4095, unit="pulse"),
        _row("Min Position Limit", 52, 4, RW, 0, 0, 4095, unit="pulse"),
        _row("Startup Configuration", 60, 1, RW, 0, 0, 3),
        _row("Shutdown", 63, 1, RW, shutdown, 0, 0x3F),
        # RAM area
        _row("Torque Enable", 64, 1, RW, 0, 0, 1),
        _row("LED", 65, 1, RW, 0, 0, 1),
        _row("Status Return Level", 68, 1, RW, 2, 0, 2),
        _row("Registered Instruction", 69, 1, R, 0),
        _row("Hardware Error Status", 70, 1, R, 0),
        _row("Velocity I Gain", 76, 2, RW, vi, 0, 16383),
        _row("Velocity P Gain", 78, 2, RW, vp, 0, 16383),
        _row("Position D Gain", 80, 2, RW, pd, 0, 16383),
        _row("Position I Gain", 82, 2, RW, pi, 0, 16383),
        _row("Position P Gain", 84, 2, RW, pp, 0, 16383),
        _row("Feedforward 2nd Gain", 88, 2, RW, 0, 0, 16383),
        _row("Feedforward 1st Gain", 90, 2, RW, 0, 0, 16383),
        _row("Bus Watchdog", 98, 1, RW, 0, 0, 127, unit="20 ms"),
        _row("Goal PWM", 100, 2, RW, 0, signed=True, unit="0.113 %", limit=("-PWM Limit", "PWM Limit")),
        _row(
            "Goal Velocity", 104, 4, RW, 0, signed=True, unit="0.229 rpm", limit=("-Velocity Limit", "Velocity Limit")
        ),
        _row("Profile Acceleration", 108, 4, RW, 0, 0, 32767, unit="214.577 rev/min^2 | ms"),
        _row("Profile Velocity", 112, 4, RW, 0, 0, 32767, unit="0.229 rpm | ms"),
        _row(
            "Goal Position",
            116,
            4,
            RW,
            None,
            -1_048_575,
            1_048_575,
            signed=True,
            unit="pulse",
            limit=("Min Position Limit", "Max Position Limit"),
        ),
        _row("Realtime Tick", 120, 2, R, 0, 0, 32767, unit="ms"),
        _row("Moving", 122, 1, R, 0),
        _row("Moving Status", 123, 1, R, 0),
        _row("Present PWM", 124, 2, R, 0, signed=True),
        _row("Present Velocity", 128, 4, R, 0, signed=True, unit="0.229 rpm"),
        _row("Present Position", 132, 4, R, None, signed=True, unit="pulse"),
        _row("Velocity Trajectory", 136, 4, R, 0, signed=True, unit="0.229 rpm"),
        _row("Position Trajectory", 140, 4, R, None, signed=True, unit="pulse"),
        _row("Present Input Voltage", 144, 2, R, None, unit="0.1 V"),
        _row("Present Temperature", 146, 1, R, None, unit="degC"),
        _row("Backup Ready", 147, 1, R, 0, 0, 1),
    ]


def _current_rows(limit_default: int, unit: str) -> list[Register]:
    return [
        _row("Current Limit", 38, 2, RW, limit_default, 0, limit_default, unit=unit),
        _row("Goal Current", 102, 2, RW, 0, signed=True, unit=unit, limit=("-Current Limit", "Current Limit")),
        _row("Present Current", 126, 2, R, 0, signed=True, unit=unit),
    ]


def _indirect_rows(n_first: int, n_second: int) -> list[Register]:
    """Indirect Address/Data: ``n_first`` pairs at 168.., and ``n_second`` more at 578.. (X430/X540 only)."""
    rows: list[Register] = []
    data1 = 168 + 2 * n_first
    for i in range(n_first):
        rows.append(_row(f"Indirect Address {i + 1}", 168 + 2 * i, 2, RW, data1 + i, 64, data1 + n_first - 1))
        rows.append(_row(f"Indirect Data {i + 1}", data1 + i, 1, RW, 0, 0, 255))
    data2 = 578 + 2 * n_second
    for i in range(n_second):
        n = n_first + i + 1
        rows.append(_row(f"Indirect Address {n}", 578 + 2 * i, 2, RW, data2 + i, 64, 661))
        rows.append(_row(f"Indirect Data {n}", data2 + i, 1, RW, 0, 0, 255))
    if n_second:  # X430/X540: any indirect address may point anywhere in 64..661
        rows = [
            Register(r.name, r.address, r.size, r.access, r.default, 64, 661)
            if r.name.startswith("Indirect Address")
            else r
            for r in rows
        ]
    return rows


def _registers(rows: Iterable[Register]) -> Mapping[str, Register]:
    """A model's registers by name, in address order."""
    return MappingProxyType({r.name: r for r in sorted(rows, key=lambda r: r.address)})


_ALL_MODES = tuple(OperatingMode)

XL430_W250 = Model(
    "XL430-W250",
    1060,
    _registers(
        [
            *_x_series_common(
                model_number=1060,
                firmware=46,
                baud_max=7,
                drive_mode_max=13,
                temperature_limit=72,
                voltage=(140, 60, 60, 140),
                velocity_limit=(265, 1023),
                gains=(1000, 100, 4000, 0, 640),
                shutdown=52,
            ),
            _row("Present Load", 126, 2, R, 0, -1000, 1000, signed=True, unit="0.1 %"),
            *_indirect_rows(28, 28),
        ]
    ),
    no_load_rpm=57.0,
    nominal_voltage=11.1,
    stall_torque=1.4,
    stall_current=1.3,
    firmware=46,
    current_unit_ma=None,
    operating_modes=(
        OperatingMode.VELOCITY,
        OperatingMode.POSITION,
        OperatingMode.EXTENDED_POSITION,
        OperatingMode.PWM,
    ),
)

XM430_W350 = Model(
    "XM430-W350",
    1020,
    _registers(
        [
            *_x_series_common(
                model_number=1020,
                firmware=46,
                baud_max=7,
                drive_mode_max=13,
                temperature_limit=80,
                voltage=(160, 95, 95, 160),
                velocity_limit=(200, 1023),
                gains=(1920, 100, 0, 0, 800),
                shutdown=52,
            ),
            *_current_rows(1193, "2.69 mA"),
            *_indirect_rows(28, 28),
        ]
    ),
    no_load_rpm=46.0,
    nominal_voltage=12.0,
    stall_torque=4.1,
    stall_current=2.3,
    firmware=46,
    current_unit_ma=2.69,
    operating_modes=_ALL_MODES,
)

XL330_M288 = Model(
    "XL330-M288",
    1200,
    _registers(
        [
            *_x_series_common(
                model_number=1200,
                firmware=46,
                baud_max=6,
                drive_mode_max=13,
                temperature_limit=70,
                voltage=(70, 35, 31, 70),
                velocity_limit=(445, 2047),
                gains=(1600, 180, 0, 0, 400),
                shutdown=53,
            ),
            _row("PWM Slope", 62, 1, RW, 140, 1, 255, unit="1.977 mV/ms"),
            *_current_rows(1750, "1 mA"),
            *_indirect_rows(20, 0),
        ]
    ),
    no_load_rpm=103.0,
    nominal_voltage=5.0,
    stall_torque=0.52,
    stall_current=1.47,
    firmware=46,
    current_unit_ma=1.0,
    operating_modes=_ALL_MODES,
    max_baud_code=6,
    fast_read_min_firmware=46,
    table_size=228,
)

XM540_W270 = Model(
    "XM540-W270",
    1120,
    _registers(
        [
            *_x_series_common(
                model_number=1120,
                firmware=46,
                baud_max=7,
                drive_mode_max=15,
                temperature_limit=80,
                voltage=(160, 95, 95, 160),
                velocity_limit=(128, 1023),
                gains=(1920, 100, 0, 0, 800),
                shutdown=52,
            ),
            *_current_rows(2047, "2.69 mA"),
            _row("External Port Mode 1", 56, 1, RW, 3, 0, 3),
            _row("External Port Mode 2", 57, 1, RW, 3, 0, 3),
            _row("External Port Mode 3", 58, 1, RW, 3, 0, 3),
            _row("External Port Data 1", 152, 2, RW, 0),
            _row("External Port Data 2", 154, 2, RW, 0),
            _row("External Port Data 3", 156, 2, RW, 0),
            *_indirect_rows(28, 28),
        ]
    ),
    no_load_rpm=30.0,
    nominal_voltage=12.0,
    stall_torque=10.6,
    stall_current=4.4,
    firmware=46,
    current_unit_ma=2.69,
    operating_modes=_ALL_MODES,
)

#: Every model by name ("XM430-W350"); the names equal ``retarget.arm.SERVO_MODELS``.
MODELS: Mapping[str, Model] = MappingProxyType({m.name: m for m in (XL430_W250, XM430_W350, XL330_M288, XM540_W270)})
#: Every model by Model Number (1020).
MODEL_BY_NUMBER: Mapping[int, Model] = MappingProxyType({m.number: m for m in MODELS.values()})


def model(name_or_number: str | int) -> Model:
    """The model called ``"XM430-W350"`` (case-insensitive) or numbered ``1020``; KeyError listing the known ones."""
    if isinstance(name_or_number, int):
        found = MODEL_BY_NUMBER.get(name_or_number)
    else:
        found = MODELS.get(str(name_or_number).upper())
    if found is None:
        known = ", ".join(f"{m.name} ({m.number})" for m in MODELS.values())
        raise KeyError(f"Expected one of {known}, got {name_or_number!r}")
    return found


@cache
def common_register(name: str) -> Register:
    """The register called ``name`` as every model that has it defines it (the same address and size).

    For code that reads raw control-table memory without a model at hand: the simulator's hot path, group
    reads planned once for a mixed arm.  KeyError when no model has it; ValueError when two models differ.
    "Present Current" is at 126 on every model with current sensing; XL430-W250 has "Present Load" there.

    >>> common_register("Goal Position").address, common_register("Goal Position").size
    (116, 4)
    """
    found = {(m.registers[name].address, m.registers[name].size) for m in MODELS.values() if name in m.registers}
    if not found:
        raise KeyError(f"no model has a register {name!r}")
    if len(found) > 1:
        raise ValueError(f"{name!r} differs between models: (address, size) {sorted(found)}")
    return next(m.registers[name] for m in MODELS.values() if name in m.registers)


# --------------------------------------------------------------------------- servo ID lists


def parse_ids(text: str) -> tuple[int, ...]:
    """Servo IDs from ``"1-6"``, ``"1,3,5"`` or both (``"1-3,8"``): the IDs, ascending.

    Each comma-separated part is one ID or an inclusive range ``LO-HI`` with ``LO <= HI``; spaces around
    numbers are allowed; every ID is within 0..252 (:data:`MAX_ID`; 253.. are reserved, 254 is broadcast) and
    appears once.  ConfigError with ``key="ids"`` otherwise, naming the bad part.

    >>> parse_ids("1-3, 8")
    (1, 2, 3, 8)
    >>> parse_ids("250-253")
    Traceback (most recent call last):
    ...
    retarget.errors.ConfigError: ids: Expected IDs within 0..252, low before high (got '250-253')
    """
    ids: list[int] = []
    for raw in text.split(","):
        part = raw.strip()
        lo_text, dash, hi_text = part.partition("-")
        try:
            lo = int(lo_text)
            hi = int(hi_text) if dash else lo
        except ValueError:
            raise ConfigError("Expected IDs like 1-6 or 1,3,5", key="ids", value=part or text) from None
        if not 0 <= lo <= hi <= MAX_ID:
            raise ConfigError(f"Expected IDs within 0..{MAX_ID}, low before high", key="ids", value=part)
        ids.extend(range(lo, hi + 1))
    if len(set(ids)) != len(ids):
        repeated = ", ".join(str(i) for i in sorted(set(ids)) if ids.count(i) > 1)
        raise ConfigError(f"Expected distinct IDs; repeated: {repeated}", key="ids", value=text)
    return tuple(sorted(ids))


#: CRC-16 of Protocol 2.0 (poly 0x8005, not reflected) of one byte: the e-Manual's and dynamixel-sdk's table
CRC_TABLE = (
    0x0000, 0x8005, 0x800F, 0x000A, 0x801B, 0x001E, 0x0014, 0x8011, 0x8033, 0x0036, 0x003C, 0x8039,
    0x0028, 0x802D, 0x8027, 0x0022, 0x8063, 0x0066, 0x006C, 0x8069, 0x0078, 0x807D, 0x8077, 0x0072,
    0x0050, 0x8055, 0x805F, 0x005A, 0x804B, 0x004E, 0x0044, 0x8041, 0x80C3, 0x00C6, 0x00CC, 0x80C9,
    0x00D8, 0x80DD, 0x80D7, 0x00D2, 0x00F0, 0x80F5, 0x80FF, 0x00FA, 0x80EB, 0x00EE, 0x00E4, 0x80E1,
    0x00A0, 0x80A5, 0x80AF, 0x00AA, 0x80BB, 0x00BE, 0x00B4, 0x80B1, 0x8093, 0x0096, 0x009C, 0x8099,
    0x0088, 0x808D, 0x8087, 0x0082, 0x8183, 0x0186, 0x018C, 0x8189, 0x0198, 0x819D, 0x8197, 0x0192,
    0x01B0, 0x81B5, 0x81BF, 0x01BA, 0x81AB, 0x01AE, 0x01A4, 0x81A1, 0x01E0, 0x81E5, 0x81EF, 0x01EA,
    0x81FB, 0x01FE, 0x01F4, 0x81F1, 0x81D3, 0x01D6, 0x01DC, 0x81D9, 0x01C8, 0x81CD, 0x81C7, 0x01C2,
    0x0140, 0x8145, 0x814F, 0x014A, 0x815B, 0x015E, 0x0154, 0x8151, 0x8173, 0x0176, 0x017C, 0x8179,
    0x0168, 0x816D, 0x8167, 0x0162, 0x8123, 0x0126, 0x012C, 0x8129, 0x0138, 0x813D, 0x8137, 0x0132,
    0x0110, 0x8115, 0x811F, 0x011A, 0x810B, 0x010E, 0x0104, 0x8101, 0x8303, 0x0306, 0x030C, 0x8309,
    0x0318, 0x831D, 0x8317, 0x0312, 0x0330, 0x8335, 0x833F, 0x033A, 0x832B, 0x032E, 0x0324, 0x8321,
    0x0360, 0x8365, 0x836F, 0x036A, 0x837B, 0x037E, 0x0374, 0x8371, 0x8353, 0x0356, 0x035C, 0x8359,
    0x0348, 0x834D, 0x8347, 0x0342, 0x03C0, 0x83C5, 0x83CF, 0x03CA, 0x83DB, 0x03DE, 0x03D4, 0x83D1,
    0x83F3, 0x03F6, 0x03FC, 0x83F9, 0x03E8, 0x83ED, 0x83E7, 0x03E2, 0x83A3, 0x03A6, 0x03AC, 0x83A9,
    0x03B8, 0x83BD, 0x83B7, 0x03B2, 0x0390, 0x8395, 0x839F, 0x039A, 0x838B, 0x038E, 0x0384, 0x8381,
    0x0280, 0x8285, 0x828F, 0x028A, 0x829B, 0x029E, 0x0294, 0x8291, 0x82B3, 0x02B6, 0x02BC, 0x82B9,
    0x02A8, 0x82AD, 0x82A7, 0x02A2, 0x82E3, 0x02E6, 0x02EC, 0x82E9, 0x02F8, 0x82FD, 0x82F7, 0x02F2,
    0x02D0, 0x82D5, 0x82DF, 0x02DA, 0x82CB, 0x02CE, 0x02C4, 0x82C1, 0x8243, 0x0246, 0x024C, 0x8249,
    0x0258, 0x825D, 0x8257, 0x0252, 0x0270, 0x8275, 0x827F, 0x027A, 0x826B, 0x026E, 0x0264, 0x8261,
    0x0220, 0x8225, 0x822F, 0x022A, 0x823B, 0x023E, 0x0234, 0x8231, 0x8213, 0x0216, 0x021C, 0x8219,
    0x0208, 0x820D, 0x8207, 0x0202,
)  # fmt: skip
#: the CRC step of a byte into the register's high half: with ``x = register ^ (b0 << 8 | b1)``, feeding b0 then b1
#: leaves ``CRC_HIGH_STEP[x >> 8] ^ CRC_TABLE[x & 0xFF]`` (the CRC is linear; two 256-entry tables stay in the cache)
CRC_HIGH_STEP = tuple(((CRC_TABLE[h] << 8) & 0xFFFF) ^ CRC_TABLE[CRC_TABLE[h] >> 8] for h in range(256))


def crc16(data: bytes | bytearray | memoryview, crc: int = 0) -> int:
    """CRC-16 (poly 0x8005, init ``crc``) of ``data``; pass a previous result as ``crc`` to continue it.

    Two bytes per step (:data:`CRC_HIGH_STEP`), the last of an odd length through the byte table: the same value as
    the byte-at-a-time loop of the e-Manual and dynamixel-sdk (``tests/sim/test_protocol.py`` and
    ``tests/drivers/test_packets.py`` compare them), in half the time.

    >>> hex(crc16(bytes.fromhex("ff ff fd 00 01 03 00 01")))  # the e-Manual's PING of servo 1: CRC bytes 19 4E
    '0x4e19'
    """
    high, table = CRC_HIGH_STEP, CRC_TABLE
    n = len(data)
    for word in struct.unpack_from(f">{n >> 1}H", data):
        x = crc ^ word
        crc = high[x >> 8] ^ table[x & 0xFF]
    if n & 1:
        crc = ((crc << 8) & 0xFF00) ^ table[(crc >> 8) ^ data[-1]]
    return crc
