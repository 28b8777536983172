"""Target filters: the zero-phase low-pass of a whole clip and the One-Euro filter of a live stream."""

from __future__ import annotations

import numpy as np
import pytest

import retarget
from retarget.mapping import retarget_targets
from retarget.mapping.config import MappingConfig
from retarget.mapping.filter import OneEuro, filter_targets, zero_phase
from tests.helpers import SHARED_BVH

CLIP = SHARED_BVH / "motion_dance.bvh"
needs_clip = pytest.mark.skipif(not CLIP.is_file(), reason=f"{CLIP} not found (set RETARGET_SHARED_BVH)")


def _rms_jerk(x: np.ndarray, rate: float) -> float:
    return float(np.sqrt(np.mean(np.sum((np.diff(x, 3, axis=0) * rate**3) ** 2, axis=-1))))


@needs_clip
def test_noisy_clip_filtered_has_20x_less_jerk_and_no_lag() -> None:
    arm = retarget.load_arm("wx250s")
    motion = retarget.load_bvh(CLIP)
    targets = retarget_targets(motion, arm, MappingConfig.from_table(arm.mapping))
    rate = 1.0 / targets.frame_time
    clean = targets.raw
    noisy = clean + np.random.default_rng(7).normal(0.0, 0.002, clean.shape)  # 2 mm of sensor noise
    smooth = zero_phase(noisy, rate)
    assert _rms_jerk(smooth, rate) * 20 < _rms_jerk(noisy, rate)  # measured: ~40x lower
    assert np.sqrt(np.mean((smooth - clean) ** 2)) < 0.002  # closer to the clean clip than the noise
    # zero phase: the lag that best aligns the filtered clip with the clean one is 0 frames
    lags = range(-5, 6)
    errors = [np.mean((np.roll(smooth, k, axis=0) - clean)[10:-10] ** 2) for k in lags]
    assert list(lags)[int(np.argmin(errors))] == 0


@needs_clip
def test_filter_targets_keeps_the_workspace_and_zero_turns_it_off() -> None:
    arm = retarget.load_arm("wx250s")
    targets = retarget_targets(retarget.load_bvh(CLIP), arm, MappingConfig.from_table(arm.mapping))
    assert filter_targets(targets, 0.0) is targets
    filtered = filter_targets(targets, 4.0)
    positions, _, _ = filtered.sample(np.linspace(0.0, 5.0, 50))
    assert np.array_equal(filtered.workspace.clamp(positions)[0], positions)
    assert not np.allclose(filtered.raw, targets.raw)


def test_zero_phase_passes_a_constant_and_a_ramp_unchanged() -> None:
    ramp = np.stack([np.linspace(0.0, 1.0, 100), np.full(100, 0.3), np.zeros(100)], axis=-1)
    np.testing.assert_allclose(zero_phase(ramp, 100.0, 5.0), ramp, atol=1e-7)  # 10 nm
    np.testing.assert_array_equal(zero_phase(ramp, 100.0, 0.0), ramp)  # 0: off


@pytest.mark.parametrize(("speed", "lag_ms"), [(0.05, 31.1), (0.2, 14.7), (1.0, 5.1)], ids=["still", "slow", "fast"])
def test_one_euro_lag_at_steady_speed(speed: float, lag_ms: float) -> None:
    """Lag (the distance behind a ramp over its speed) as the module docstring states."""
    f = OneEuro()
    rate = 100.0
    out = None
    for k in range(300):
        x = np.array([speed * k / rate, 0.0, 0.0])
        out = f(x, k / rate)
    assert out is not None
    assert 1000.0 * (x[0] - out[0]) / speed == pytest.approx(lag_ms, abs=0.1)


def test_one_euro_smooths_a_still_noisy_hand() -> None:
    rng = np.random.default_rng(3)
    f = OneEuro()
    noisy = 0.3 + rng.normal(0.0, 0.002, (500, 3))
    out = np.array([f(x, k / 100.0) for k, x in enumerate(noisy)])
    assert out[100:].std() * 4 < noisy[100:].std()  # measured: 4.4x


def test_one_euro_rejects_bad_parameters() -> None:
    with pytest.raises(ValueError, match="Expected min_cutoff > 0"):
        OneEuro(min_cutoff=0.0)
