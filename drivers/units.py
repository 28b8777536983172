"""Unit conversions between joint space (radians, seconds) and Dynamixel X-series register values.

Positions: 4096 pulses per revolution (the e-Manual's unit of Goal and Present Position); a joint's 0 rad sits
at ``2048 + offset`` pulses.  ``direction`` is a
*software* sign (+1 or -1).  :class:`drivers.DynamixelBus` reverses servos in hardware (Drive Mode bit 0), so
it encodes with ``direction=+1`` and lets the servo mirror the shaft; the argument is here for servos or
tools that have no Drive Mode.

Velocities: Profile Velocity and Velocity Limit count 0.229 rev/min.  Profile Acceleration counts
214.577 rev/min^2 (velocity-based profile).  In a time-based profile both registers hold milliseconds.

Every function is vectorized: arrays of any shape broadcast against ``offset`` and ``direction``.

"Tick" in this project is a control cycle; the encoder count is a *pulse*.  The names of the first release
(``rad_to_ticks``, ``ticks_to_rad``, ``TICKS_PER_REV``, ``CENTER_TICK``, ``MIN_TICK``, ``MAX_TICK``,
``RAD_PER_TICK``) remain as aliases.

>>> int(rad_to_pulses(math.pi / 2))
3072
>>> float(pulses_to_rad(1024, offset=0, direction=-1))
1.5707963267948966
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

# the register units come from the one register table; this module turns joint values into register values
from drivers.control_table import PULSES_PER_REV, RAD_PER_PULSE, RPM2_PER_ACCEL_UNIT, RPM_PER_VELOCITY_UNIT

__all__ = [
    "CENTER_PULSE",
    "MAX_PULSE",
    "MIN_PULSE",
    "PULSES_PER_REV",
    "RAD_PER_PULSE",
    "RAD_S2_PER_ACCEL_UNIT",
    "RAD_S_PER_VELOCITY_UNIT",
    "accel_units_to_rad_s2",
    "pulses_to_rad",
    "rad_s2_to_accel_units",
    "rad_s_to_velocity_units",
    "rad_to_pulses",
    "seconds_to_ms",
    "signed32",
    "to_unsigned32",
    "velocity_units_to_rad_s",
]

CENTER_PULSE = 2048  #: the pulse of a joint's 0 rad (before its offset)
MIN_PULSE = 0
MAX_PULSE = PULSES_PER_REV - 1  #: position mode (3) is a single turn: 0 .. 4095
RAD_S_PER_VELOCITY_UNIT = RPM_PER_VELOCITY_UNIT * 2.0 * math.pi / 60.0  #: about 0.02398 rad/s
RAD_S2_PER_ACCEL_UNIT = RPM2_PER_ACCEL_UNIT * 2.0 * math.pi / 3600.0  #: about 0.3745 rad/s^2


def rad_to_pulses(q: ArrayLike, *, offset: ArrayLike = 0, direction: ArrayLike = 1) -> np.ndarray:
    """Joint angles to Goal Position pulses, rounded to the nearest pulse.

    ``q``: any shape, float, radians.  Returns int64 of the broadcast shape:
    ``2048 + offset + direction * q / RAD_PER_PULSE``.
    No clamping: clamp angles to the joint limits before encoding.
    """
    angles = np.asarray(q, dtype=np.float64)
    if not np.all(np.isfinite(angles)):
        raise ValueError(f"Expected finite angles in radians, got {angles!r}")
    pulses = CENTER_PULSE + np.asarray(offset) + np.asarray(direction) * angles / RAD_PER_PULSE
    rounded: np.ndarray = np.rint(pulses).astype(np.int64)
    return rounded


def pulses_to_rad(pulses: ArrayLike, *, offset: ArrayLike = 0, direction: ArrayLike = 1) -> np.ndarray:
    """Present/Goal Position pulses to joint angles, float64 radians of the broadcast shape."""
    values = np.asarray(pulses, dtype=np.float64)
    angles: np.ndarray = (
        (values - CENTER_PULSE - np.asarray(offset, dtype=np.float64)) * RAD_PER_PULSE * np.asarray(direction)
    )
    return angles


def signed32(value: int) -> int:
    """A 4-byte register read as unsigned (the SDK's ``getData``) to its signed value (Present Position is signed)."""
    value &= 0xFFFFFFFF
    return value - (1 << 32) if value & 0x80000000 else value


def to_unsigned32(value: int) -> int:
    """A signed value to the 4 little-endian bytes' unsigned int for a 4-byte write."""
    return int(value) & 0xFFFFFFFF


def rad_s_to_velocity_units(w: ArrayLike) -> np.ndarray:
    """Angular speed ``rad/s`` (>= 0) to 0.229 rpm units, int64.

    Rounded down, so a limit is never exceeded, but at least 1 for any positive speed: the register reads 0
    as *unlimited*, so only an input of exactly 0 gives 0.
    """
    w = np.asarray(w, dtype=np.float64)
    if np.any(w < 0) or not np.all(np.isfinite(w)):
        raise ValueError(f"Expected finite speeds >= 0 rad/s, got {w!r}")
    units = np.floor(w / RAD_S_PER_VELOCITY_UNIT + 1e-9).astype(np.int64)
    return np.where(w > 0, np.maximum(units, 1), 0)


def velocity_units_to_rad_s(units: ArrayLike) -> np.ndarray:
    """0.229 rpm units to rad/s, float64."""
    return np.asarray(units, dtype=np.float64) * RAD_S_PER_VELOCITY_UNIT


def rad_s2_to_accel_units(a: ArrayLike) -> np.ndarray:
    """Angular acceleration ``rad/s^2`` (>= 0) to 214.577 rev/min^2 units, int64; rounded down, at least 1
    for any positive value (0 means unlimited)."""
    a = np.asarray(a, dtype=np.float64)
    if np.any(a < 0) or not np.all(np.isfinite(a)):
        raise ValueError(f"Expected finite accelerations >= 0 rad/s^2, got {a!r}")
    units = np.floor(a / RAD_S2_PER_ACCEL_UNIT + 1e-9).astype(np.int64)
    return np.where(a > 0, np.maximum(units, 1), 0)


def accel_units_to_rad_s2(units: ArrayLike) -> np.ndarray:
    """214.577 rev/min^2 units to rad/s^2, float64."""
    return np.asarray(units, dtype=np.float64) * RAD_S2_PER_ACCEL_UNIT


def seconds_to_ms(t: ArrayLike) -> np.ndarray:
    """Seconds to the millisecond units of a time-based profile, int64, rounded to nearest (>= 0)."""
    t = np.asarray(t, dtype=np.float64)
    if np.any(t < 0) or not np.all(np.isfinite(t)):
        raise ValueError(f"Expected finite durations >= 0 s, got {t!r}")
    return np.rint(t * 1000.0).astype(np.int64)


# the names of the first release, where "tick" meant the encoder count (it is the control cycle now)
TICKS_PER_REV = PULSES_PER_REV
CENTER_TICK = CENTER_PULSE
MIN_TICK = MIN_PULSE
MAX_TICK = MAX_PULSE
RAD_PER_TICK = RAD_PER_PULSE
rad_to_ticks = rad_to_pulses
ticks_to_rad = pulses_to_rad
