"""drivers.units: radians <-> pulses and the speed units, with seeded round trips."""

from __future__ import annotations

import math

import numpy as np
import pytest

from drivers import units


@pytest.mark.parametrize(
    ("q", "offset", "direction", "pulses"),
    [
        (0.0, 0, 1, 2048),
        (math.pi / 2, 0, 1, 3072),
        (-math.pi / 2, 0, 1, 1024),
        (math.pi / 2, 0, -1, 1024),
        (0.0, 100, 1, 2148),
        (math.radians(-100), 0, 1, 910),  # Interbotix wx250s wrist_angle Min Position Limit
        (math.radians(123), 0, 1, 3447),  # ... and Max
    ],
    ids=["zero", "quarter", "minus-quarter", "reversed", "offset", "wx250s-wrist-min", "wx250s-wrist-max"],
)
def test_rad_to_pulses_known_values(q, offset, direction, pulses):
    assert units.rad_to_pulses(q, offset=offset, direction=direction) == pulses
    assert units.pulses_to_rad(pulses, offset=offset, direction=direction) == pytest.approx(q, abs=units.RAD_PER_PULSE)


def test_round_trip_is_within_half_a_pulse_seeded():
    rng = np.random.default_rng(1234)
    q = rng.uniform(-math.pi, math.pi, size=(200, 6))
    offset = rng.integers(-300, 300, size=6)
    direction = rng.choice([-1, 1], size=6)
    pulses = units.rad_to_pulses(q, offset=offset, direction=direction)
    assert pulses.shape == (200, 6) and pulses.dtype == np.int64
    back = units.pulses_to_rad(pulses, offset=offset, direction=direction)
    assert np.max(np.abs(back - q)) <= units.RAD_PER_PULSE / 2 + 1e-12
    # and pulses -> rad -> pulses is exact
    assert np.array_equal(units.rad_to_pulses(back, offset=offset, direction=direction), pulses)


def test_rad_to_pulses_rejects_non_finite():
    with pytest.raises(ValueError, match="Expected finite angles"):
        units.rad_to_pulses([0.0, math.nan])


@pytest.mark.parametrize(
    ("value", "signed"),
    [(0, 0), (4095, 4095), (0xFFFFFFFF, -1), (0x80000000, -(2**31)), (0x7FFFFFFF, 2**31 - 1)],
    ids=["zero", "4095", "minus-one", "min", "max"],
)
def test_signed32(value, signed):
    assert units.signed32(value) == signed
    assert units.to_unsigned32(signed) == value


def test_velocity_units_interbotix_limit():
    # Interbotix: Velocity_Limit 131 x 0.229 rpm = pi rad/s (floor: never above the asked speed)
    assert units.rad_s_to_velocity_units(math.pi) == 131
    assert units.velocity_units_to_rad_s(131) == pytest.approx(math.pi, rel=1e-3)


def test_velocity_units_round_down_but_never_to_unlimited():
    assert units.rad_s_to_velocity_units(0.0) == 0
    assert units.rad_s_to_velocity_units(1e-6) == 1  # 0 would mean "unlimited" on the servo
    w = np.random.default_rng(7).uniform(0.05, 10.0, 100)
    assert np.all(units.velocity_units_to_rad_s(units.rad_s_to_velocity_units(w)) <= w + 1e-12)


def test_accel_units():
    assert units.rad_s2_to_accel_units(0.0) == 0
    assert units.rad_s2_to_accel_units(1e-3) == 1
    assert units.accel_units_to_rad_s2(1) == pytest.approx(214.577 * 2 * math.pi / 3600)


@pytest.mark.parametrize(
    "fn", [units.rad_s_to_velocity_units, units.rad_s2_to_accel_units, units.seconds_to_ms], ids=["vel", "acc", "ms"]
)
def test_negative_rates_rejected(fn):
    with pytest.raises(ValueError, match="Expected finite"):
        fn(-1.0)


def test_seconds_to_ms():
    assert units.seconds_to_ms(0.02) == 20


def test_the_first_release_names_are_aliases():
    """ "Tick" is the control cycle; the encoder count is a pulse.  The old names still work."""
    assert units.rad_to_ticks is units.rad_to_pulses and units.ticks_to_rad is units.pulses_to_rad
    assert (units.TICKS_PER_REV, units.CENTER_TICK, units.MIN_TICK, units.MAX_TICK) == (4096, 2048, 0, 4095)
    assert units.RAD_PER_TICK == units.RAD_PER_PULSE
