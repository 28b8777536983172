"""Unit conversions between joint space (radians, seconds) and Dynamixel X-series register values.

Positions: 4096 ticks per revolution; a joint's 0 rad sits at ``2048 + offset`` ticks.  ``direction`` is a
*software* sign (+1 or -1).  :class:`drivers.DynamixelBus` reverses servos in hardware (Drive Mode bit 0), so
it encodes with ``direction=+1`` and lets the servo mirror the shaft; the argument is here for servos or
tools that have no Drive Mode.

Velocities: Profile Velocity and Velocity Limit count 0.229 rev/min.  Profile Acceleration counts
214.577 rev/min^2 (velocity-based profile).  In a time-based profile both registers hold milliseconds.

Every function is vectorized: arrays of any shape broadcast against ``offset`` and ``direction``.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

# the register units come from the one register table; this module turns joint values into register values
from drivers.control_table import PULSES_PER_REV, RPM2_PER_ACCEL_UNIT, RPM_PER_VELOCITY_UNIT

TICKS_PER_REV = PULSES_PER_REV
CENTER_TICK = 2048
MIN_TICK = 0
MAX_TICK = TICKS_PER_REV - 1  #: position mode (3) is a single turn: 0 .. 4095
RAD_PER_TICK = 2.0 * math.pi / TICKS_PER_REV  #: about 0.088 deg
RAD_S_PER_VELOCITY_UNIT = RPM_PER_VELOCITY_UNIT * 2.0 * math.pi / 60.0  #: about 0.02398 rad/s
RAD_S2_PER_ACCEL_UNIT = RPM2_PER_ACCEL_UNIT * 2.0 * math.pi / 3600.0  #: about 0.3745 rad/s^2


def rad_to_ticks(q: ArrayLike, *, offset: ArrayLike = 0, direction: ArrayLike = 1) -> np.ndarray:
    """Joint angles to Goal Position ticks, rounded to the nearest tick.

    ``q``: any shape, float, radians.  Returns int64 of the broadcast shape:
    ``2048 + offset + direction * q / RAD_PER_TICK``.
    No clamping: clamp angles to the joint limits before encoding.
    """
    q = np.asarray(q, dtype=np.float64)
    if not np.all(np.isfinite(q)):
        raise ValueError(f"Expected finite angles in radians, got {q!r}")
    ticks = CENTER_TICK + np.asarray(offset) + np.asarray(direction) * q / RAD_PER_TICK
    return np.rint(ticks).astype(np.int64)


def ticks_to_rad(ticks: ArrayLike, *, offset: ArrayLike = 0, direction: ArrayLike = 1) -> np.ndarray:
    """Present/Goal Position ticks to joint angles, float64 radians of the broadcast shape."""
    ticks = np.asarray(ticks, dtype=np.float64)
    return (ticks - CENTER_TICK - np.asarray(offset, dtype=np.float64)) * RAD_PER_TICK * np.asarray(direction)


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
