"""Target filters: the zero-phase low-pass of a whole clip (before the workspace clamp; by default at the cutoff
chosen from the clip, retarget.mapping.cutoff) and the One-Euro filter of a live stream."""

from __future__ import annotations

import numpy as np
import pytest

import retarget
from retarget.errors import ConfigError
from retarget.mapping import Targets, Workspace, retarget_targets
from retarget.mapping.config import MappingConfig
from retarget.mapping.cutoff import auto_cutoff
from retarget.mapping.filter import AUTO, OneEuro, _butterworth2, _one_pass, zero_phase
from retarget.mapping.targets import filter_targets
from tests.helpers import SHARED_BVH

CLIP = SHARED_BVH / "motion_dance.bvh"
needs_clip = pytest.mark.skipif(not CLIP.is_file(), reason=f"{CLIP} not found (set RETARGET_SHARED_BVH)")


def _rms_jerk(x: np.ndarray, rate: float) -> float:
    return float(np.sqrt(np.mean(np.sum((np.diff(x, 3, axis=0) * rate**3) ** 2, axis=-1))))


def _unfiltered(arm: retarget.Arm, **overrides: object) -> MappingConfig:
    return MappingConfig.from_table(arm.mapping, overrides={"cutoff_hz": 0, **overrides})


@needs_clip
def test_noisy_clip_filtered_at_its_auto_cutoff_has_50x_less_jerk_no_lag_and_half_the_error_of_6_hz() -> None:
    arm = retarget.load_arm("wx250s")
    clean = retarget_targets(retarget.load_bvh(CLIP), arm, _unfiltered(arm)).raw
    rate = 120.0
    noisy = clean + np.random.default_rng(7).normal(0.0, 0.002, clean.shape)  # 2 mm of sensor noise
    assert auto_cutoff(clean, rate) == 0.0  # the clip alone: a clean capture, left as it is
    cutoff = auto_cutoff(noisy, rate)
    assert 10.0 < cutoff < 13.0  # measured 11.5 Hz
    smooth = zero_phase(noisy, rate, cutoff)
    assert _rms_jerk(smooth, rate) * 50 < _rms_jerk(noisy, rate)  # measured 56x (6 Hz: 134x, 4 Hz: 220x)
    # nearer the clean clip than the noise was, and nearer than a fixed 6 Hz or 4 Hz, which cut the dance's own fast
    # moves: measured 0.98 mm RMS against 1.89 and 4.06 (and 2.0 unfiltered)
    error = {c: float(np.sqrt(np.mean((zero_phase(noisy, rate, c) - clean) ** 2))) for c in (cutoff, 6.0, 4.0)}
    assert error[cutoff] < 0.0011 and error[cutoff] * 1.7 < error[6.0] and error[6.0] * 2 < error[4.0]
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
    for f, gain in ((6.0, 0.5), (1.0, 1.0), (24.0, 0.0)):
        y = zero_phase(np.sin(2 * np.pi * f * t), 120.0, 6.0)
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
def test_retarget_targets_filters_at_the_auto_cutoff_by_default_and_filter_targets_matches(arm) -> None:
    motion = retarget.load_bvh(CLIP)
    default = retarget_targets(motion, arm)  # the arm file has no cutoff_hz: the default, auto
    clean = retarget_targets(motion, arm, _unfiltered(arm))
    assert MappingConfig().cutoff_hz == AUTO and default.cutoff_auto and not clean.cutoff_auto
    # a clean optical capture: auto leaves it unfiltered
    assert default.cutoff_hz == 0.0 and default.unfiltered is None and clean.unfiltered is None
    np.testing.assert_array_equal(default.raw, clean.raw)
    # with 2 mm of noise, auto filters it (at the cutoff auto_cutoff chooses), as filter_targets does
    noisy = Targets.from_raw(clean.raw + np.random.default_rng(7).normal(0.0, 0.002, clean.raw.shape),
                             frame_time=clean.frame_time, workspace=clean.workspace, cutoff_hz=AUTO)  # fmt: skip
    assert noisy.cutoff_auto and noisy.cutoff_hz == auto_cutoff(noisy.unfiltered, 1.0 / clean.frame_time) > 10.0
    again = filter_targets(Targets.from_raw(noisy.unfiltered, frame_time=clean.frame_time, workspace=clean.workspace))
    np.testing.assert_array_equal(again.raw, noisy.raw)
    np.testing.assert_array_equal(again.positions, noisy.positions)
    six = retarget_targets(motion, arm, _unfiltered(arm, cutoff_hz=6.0))
    np.testing.assert_array_equal(filter_targets(clean, 6.0).raw, six.raw)
    np.testing.assert_allclose(six.raw, zero_phase(clean.raw, 1.0 / clean.frame_time, 6.0))
    assert filter_targets(clean, 0.0) is clean
    with pytest.raises(ValueError, match="Expected unfiltered targets, got targets filtered at 6 Hz"):
        filter_targets(six)


@needs_clip
def test_orientation_targets_are_filtered_and_stay_rotations(arm) -> None:
    motion = retarget.load_bvh(CLIP)
    raw = retarget_targets(motion, arm, _unfiltered(arm, orientation_weight=0.5)).rotations
    smooth = retarget_targets(motion, arm, _unfiltered(arm, orientation_weight=0.5, cutoff_hz=6.0))
    R = smooth.rotations
    assert raw is not None and R is not None
    np.testing.assert_allclose(R @ R.transpose(0, 2, 1), np.broadcast_to(np.eye(3), R.shape), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(R), 1.0)
    step = np.linalg.norm(np.diff(R, 2, axis=0), axis=(1, 2))  # frame-to-frame change of the turning rate
    raw_step = np.linalg.norm(np.diff(raw, 2, axis=0), axis=(1, 2))
    assert np.sqrt(np.mean(step**2)) * 3 < np.sqrt(np.mean(raw_step**2))
    assert np.max(np.linalg.norm(R - raw, axis=(1, 2))) < 0.5  # smoothed, not another orientation


@pytest.mark.parametrize(
    ("value", "ok"),
    [(0, 0.0), (0.1, 0.1), (6, 6.0), (100, 100.0), ("auto", AUTO), (" Auto ", AUTO), ("12", 12.0), (0.05, None),
     (101, None), (-1, None), ("automatic", None), (True, None)],
    ids=["off", "lowest", "6Hz", "highest", "auto", "Auto", "text-12", "too-low", "too-high", "negative", "word",
         "bool"],
)  # fmt: skip
def test_the_cutoff_is_checked(value: object, ok: object) -> None:
    if ok is not None:
        assert MappingConfig.from_table({"cutoff_hz": value}).cutoff_hz == ok
        return
    with pytest.raises(
        ConfigError, match=r"^arm\.toml: mapping\.cutoff_hz: Expected 'auto', a cutoff from 0\.1 to 100 Hz, or 0"
    ):
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
