"""Target filters: the zero-phase low-pass of a whole clip (on by default, before the workspace clamp) and the
One-Euro filter of a live stream."""

from __future__ import annotations

import numpy as np
import pytest

import retarget
from retarget.errors import ConfigError
from retarget.mapping import Targets, Workspace, retarget_targets
from retarget.mapping.config import MappingConfig
from retarget.mapping.filter import DEFAULT_CUTOFF_HZ, OneEuro, _butterworth2, _one_pass, zero_phase
from retarget.mapping.targets import filter_targets
from tests.helpers import SHARED_BVH

CLIP = SHARED_BVH / "motion_dance.bvh"
needs_clip = pytest.mark.skipif(not CLIP.is_file(), reason=f"{CLIP} not found (set RETARGET_SHARED_BVH)")


def _rms_jerk(x: np.ndarray, rate: float) -> float:
    return float(np.sqrt(np.mean(np.sum((np.diff(x, 3, axis=0) * rate**3) ** 2, axis=-1))))


def _unfiltered(arm: retarget.Arm, **overrides: object) -> MappingConfig:
    return MappingConfig.from_table(arm.mapping, overrides={"cutoff_hz": 0, **overrides})


@needs_clip
def test_noisy_clip_filtered_has_100x_less_jerk_and_no_lag() -> None:
    arm = retarget.load_arm("wx250s")
    clean = retarget_targets(retarget.load_bvh(CLIP), arm, _unfiltered(arm)).raw
    rate = 120.0
    noisy = clean + np.random.default_rng(7).normal(0.0, 0.002, clean.shape)  # 2 mm of sensor noise
    smooth = zero_phase(noisy, rate)
    assert _rms_jerk(smooth, rate) * 100 < _rms_jerk(noisy, rate)  # measured at the default cutoff
    # the cut of the dance's own fast moves: 1.9 mm RMS at the default 6 Hz (under the 2 mm of noise; 4 Hz: 4.1 mm)
    assert np.sqrt(np.mean((smooth - clean) ** 2)) < 0.002
    assert np.sqrt(np.mean((zero_phase(noisy, rate, 4.0) - clean) ** 2)) < 0.005
    # zero phase: the lag that best aligns the filtered clip with the clean one is 0 frames
    lags = range(-5, 6)
    errors = [np.mean((np.roll(smooth, k, axis=0) - clean)[10:-10] ** 2) for k in lags]
    assert list(lags)[int(np.argmin(errors))] == 0


def _plain_biquad(x: np.ndarray, b: tuple[float, float, float], a: tuple[float, float]) -> np.ndarray:
    """The biquad sample by sample, started in its steady state at x[0] (the definition the fast one must meet)."""
    y = np.empty_like(x)
    x1 = x2 = y1 = y2 = x[0]
    for i, xi in enumerate(x):
        y[i] = b[0] * xi + b[1] * x1 + b[2] * x2 - a[0] * y1 - a[1] * y2
        x2, x1, y2, y1 = x1, xi, y1, y[i]
    return y


@pytest.mark.parametrize("n", [1, 2, 63, 64, 65, 129, 700], ids=lambda n: f"{n}-samples")
@pytest.mark.parametrize(("rate", "cutoff"), [(120.0, 6.0), (120.0, 0.5), (30.0, 12.0)], ids=["6Hz", "slow", "fast"])
def test_the_vectorised_pass_equals_the_recursion(n: int, rate: float, cutoff: float) -> None:
    x = np.random.default_rng(n).normal(size=(n, 3)).cumsum(axis=0)
    b, a = _butterworth2(rate, cutoff)
    np.testing.assert_allclose(_one_pass(x, b, a), _plain_biquad(x, b, a), rtol=0, atol=1e-9)


def test_the_cutoff_is_minus_6_db() -> None:
    """Forward and backward: the 2nd-order Butterworth's -3 dB twice, a gain of 0.5 at the cutoff."""
    t = np.arange(2400) / 120.0
    for f, gain in ((DEFAULT_CUTOFF_HZ, 0.5), (1.0, 1.0), (24.0, 0.0)):
        y = zero_phase(np.sin(2 * np.pi * f * t), 120.0)
        assert np.max(np.abs(y[600:-600])) == pytest.approx(gain, abs=0.01)


def test_zero_phase_passes_a_constant_and_a_ramp_unchanged() -> None:
    ramp = np.stack([np.linspace(0.0, 1.0, 100), np.full(100, 0.3), np.zeros(100)], axis=-1)
    np.testing.assert_allclose(zero_phase(ramp, 100.0, 5.0), ramp, atol=1e-7)  # 10 nm
    np.testing.assert_array_equal(zero_phase(ramp, 100.0, 0.0), ramp)  # 0: off


# ------------------------------------------------------------------ in the mapping: on by default, before the clamp


def _shell_hopping_path(arm: retarget.Arm) -> tuple[np.ndarray, Workspace]:
    """2 s at 60 fps along the workspace's outer shell, hopping out of it and back every other frame."""
    workspace = Workspace.for_arm(arm)
    t = np.arange(120) / 60.0
    direction = np.stack([np.cos(t), np.sin(t), 0.3 + 0 * t], axis=-1)
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    radius = workspace.r_max * (1.0 + 0.08 * (np.arange(120) % 2))  # on the shell, 8 % outside it
    return workspace.center + direction * radius[:, None], workspace


def test_the_filter_runs_before_the_clamp_so_every_target_is_reachable(arm) -> None:
    raw, workspace = _shell_hopping_path(arm)
    targets = Targets.from_raw(raw, frame_time=1 / 60, workspace=workspace, cutoff_hz=6.0)  # (hops built for 6 Hz)
    assert targets.cutoff_hz == 6.0 and targets.unfiltered is raw
    np.testing.assert_allclose(targets.raw, zero_phase(raw, 60.0, 6.0))
    positions, _, clamped = targets.sample(np.linspace(0.0, 2.0, 333))
    np.testing.assert_allclose(workspace.clamp(positions)[0], positions, rtol=0, atol=1e-12)  # inside already
    assert (np.linalg.norm(targets.raw - workspace.center, axis=1) > workspace.r_max).all()  # the filter alone: out
    # the filter smoothed the hops to about 4 % outside: every frame clamped, onto the shell, not jumping
    assert targets.clamped.all() and clamped.all()
    assert np.ptp(np.linalg.norm(targets.positions - workspace.center, axis=1)) < 1e-9
    # the reference (what the arm is measured against) is the unfiltered path, clamped the same way
    np.testing.assert_allclose(targets.reference(np.array([0.5])), workspace.clamp(raw[30:31])[0])


def test_no_cutoff_or_one_above_nyquist_filters_nothing(arm) -> None:
    raw, workspace = _shell_hopping_path(arm)
    for cutoff, frame_time in ((0.0, 1 / 60), (6.0, 1 / 10)):  # 10 fps: Nyquist 5 Hz
        targets = Targets.from_raw(raw, frame_time=frame_time, workspace=workspace, cutoff_hz=cutoff)
        assert targets.unfiltered is None and targets.cutoff_hz == 0.0
        assert np.array_equal(targets.raw, raw)
        times = np.linspace(0.0, 1.0, 7)
        np.testing.assert_array_equal(targets.reference(times), targets.sample(times)[0])


@needs_clip
def test_retarget_targets_filters_by_default_and_filter_targets_matches(arm) -> None:
    motion = retarget.load_bvh(CLIP)
    default = retarget_targets(motion, arm)  # the arm file has no cutoff_hz: the default
    clean = retarget_targets(motion, arm, _unfiltered(arm))
    assert MappingConfig().cutoff_hz == default.cutoff_hz == DEFAULT_CUTOFF_HZ and clean.unfiltered is None
    np.testing.assert_array_equal(default.unfiltered, clean.raw)
    np.testing.assert_allclose(default.raw, zero_phase(clean.raw, 1.0 / clean.frame_time))
    again = filter_targets(clean)
    np.testing.assert_array_equal(again.raw, default.raw)
    np.testing.assert_array_equal(again.positions, default.positions)
    assert filter_targets(clean, 0.0) is clean
    with pytest.raises(
        ValueError, match=f"Expected unfiltered targets, got targets filtered at {DEFAULT_CUTOFF_HZ:g} Hz"
    ):
        filter_targets(default)


@needs_clip
def test_orientation_targets_are_filtered_and_stay_rotations(arm) -> None:
    motion = retarget.load_bvh(CLIP)
    raw = retarget_targets(motion, arm, _unfiltered(arm, orientation_weight=0.5)).rotations
    smooth = retarget_targets(motion, arm, MappingConfig.from_table(arm.mapping, overrides={"orientation_weight": 0.5}))
    R = smooth.rotations
    assert raw is not None and R is not None
    np.testing.assert_allclose(R @ R.transpose(0, 2, 1), np.broadcast_to(np.eye(3), R.shape), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(R), 1.0)
    step = np.linalg.norm(np.diff(R, 2, axis=0), axis=(1, 2))  # frame-to-frame change of the turning rate
    raw_step = np.linalg.norm(np.diff(raw, 2, axis=0), axis=(1, 2))
    assert np.sqrt(np.mean(step**2)) * 3 < np.sqrt(np.mean(raw_step**2))
    assert np.max(np.linalg.norm(R - raw, axis=(1, 2))) < 0.5  # smoothed, not another orientation


@pytest.mark.parametrize(
    ("value", "ok"), [(0, True), (0.1, True), (6, True), (100, True), (0.05, False), (101, False), (-1, False)]
)
def test_the_cutoff_is_checked(value: float, ok: bool) -> None:
    if ok:
        assert MappingConfig.from_table({"cutoff_hz": value}).cutoff_hz == value
        return
    with pytest.raises(ConfigError, match=r"mapping\.cutoff_hz: Expected a cutoff from 0\.1 to 100 Hz, or 0"):
        MappingConfig.from_table({"cutoff_hz": value}, path="arm.toml")


# ------------------------------------------------------------------ One-Euro


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


@pytest.mark.parametrize(
    ("kwargs", "key"),
    [({"min_cutoff": 0.0}, "min_cutoff"), ({"beta": -1.0}, "beta"), ({"d_cutoff": float("nan")}, "d_cutoff")],
    ids=["min_cutoff", "beta", "d_cutoff"],
)
def test_one_euro_rejects_bad_parameters(kwargs: dict[str, float], key: str) -> None:
    with pytest.raises(ConfigError, match=rf"^{key}: Expected a finite number >=? ?0?") as info:
        OneEuro(**kwargs)
    assert info.value.key == key
