"""The zero-phase cutoff chosen from a clip's own noise (``cutoff_hz = "auto"``): the noise level from the 4th
differences, and the cutoff of least estimated risk, checked against the true error on seeded paths."""

from __future__ import annotations

import numpy as np
import pytest

from retarget.mapping.cutoff import LOWEST_HZ, auto_cutoff, noise_level
from retarget.mapping.filter import zero_phase

RATE = 120.0  #: Hz, as the shared optical clips


def _hand_path(seed: int, seconds: float = 12.0) -> np.ndarray:
    """A hand-like path ``(n, 3)`` metres: 40 sines from 0.2 to 8 Hz, amplitudes falling as 1 / f^2 (a smooth,
    human-like spectrum; about 0.1 m overall), random phases."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(seconds * RATE))[:, None] / RATE
    f = rng.uniform(0.2, 8.0, (40, 3))
    amplitude = 0.004 / f**2
    return np.sum(amplitude * np.sin(2 * np.pi * f * t[:, :, None] + rng.uniform(0, 2 * np.pi, (40, 3))), axis=1)


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x**2)))


@pytest.mark.parametrize("sigma", [0.0005, 0.002, 0.008], ids=["0.5mm", "2mm", "8mm"])
def test_noise_level_reads_white_noise_through_the_motion(sigma: float) -> None:
    path = _hand_path(1)
    noisy = path + np.random.default_rng(2).normal(0.0, sigma, path.shape)
    np.testing.assert_allclose(noise_level(noisy), sigma, rtol=0.06)
    assert noise_level(path).max() < 2e-5  # the motion alone: 4th differences of a smooth path, ~nothing


def test_noise_level_of_too_few_samples_is_zero() -> None:
    assert noise_level(np.ones((5, 3))).tolist() == [0.0, 0.0, 0.0]


@pytest.mark.parametrize("seed", [1, 2, 3], ids=lambda s: f"path-{s}")
def test_a_clean_path_stays_unfiltered(seed: int) -> None:
    assert auto_cutoff(_hand_path(seed), RATE) == 0.0


@pytest.mark.parametrize("seed", [1, 2, 3], ids=lambda s: f"path-{s}")
def test_more_noise_a_lower_cutoff_and_each_near_the_best_one(seed: int) -> None:
    """The cutoff falls as the noise rises, and the filtered path is within 10 % (RMS) of the best any cutoff of a
    fine grid gives (the risk estimate's own accuracy: measured within 4 %)."""
    path = _hand_path(seed)
    grid = np.geomspace(LOWEST_HZ, 0.45 * RATE, 120)
    chosen = []
    for sigma in (0.0005, 0.002, 0.008):
        noisy = path + np.random.default_rng(seed + 10).normal(0.0, sigma, path.shape)
        cutoff = auto_cutoff(noisy, RATE)
        assert LOWEST_HZ <= cutoff < 0.45 * RATE
        best = min(_rms(zero_phase(noisy, RATE, c) - path) for c in grid)
        error = _rms(zero_phase(noisy, RATE, cutoff) - path)
        assert best <= error < 1.1 * best and error < 0.7 * _rms(noisy - path)  # and well under the noise
        chosen.append(cutoff)
    assert chosen[0] > chosen[1] > chosen[2]


@pytest.mark.parametrize(
    ("samples", "rate"), [(15, RATE), (1, RATE), (500, 4.0)], ids=["15-samples", "1-sample", "4-Hz-rate"]
)
def test_too_short_or_too_slow_a_clip_is_left_unfiltered(samples: int, rate: float) -> None:
    noisy = np.random.default_rng(0).normal(0.0, 0.01, (samples, 3))
    assert auto_cutoff(noisy, rate) == 0.0
