"""Target filters: zero-phase for whole clips, One-Euro for live streams.  Pure numpy.

* :func:`zero_phase` / :func:`filter_targets`: a whole clip is known in advance, so its targets are low-passed
  forward and backward with a 2nd-order Butterworth filter (Winter's choice for motion-capture kinematics,
  *Biomechanics and Motor Control of Human Movement*, 4-6 Hz): the two passes cancel each other's phase,
  so it adds **no lag**, and the gain is that of a 4th-order filter (-6 dB at the cutoff).  The ends are
  padded with an odd reflection (as scipy's ``filtfilt``) so a clip's first and last frames stay put.
  Default cutoff :data:`DEFAULT_CUTOFF_HZ`; ``cutoff_hz = 0`` (``--no-filter``) turns it off.
* :class:`OneEuro`: a causal filter for targets that arrive live (Casiez, Roussel and Vogel, "1 Euro filter:
  a simple speed-based low-pass filter for noisy input in interactive systems", CHI 2012): a one-pole low-pass
  whose cutoff rises with the speed, ``min_cutoff + beta x |speed|``, so it smooths a still hand hard and a
  fast one little.  Its lag at steady speed, about ``1 / (2 pi cutoff)`` plus the sample interval's share,
  with the defaults (1 Hz, beta 20 Hz per m/s) at 100 Hz: 31 ms at 0.05 m/s, 15 ms at 0.2 m/s, 8 ms at
  0.5 m/s, 5 ms at 1 m/s (measured in ``tests/retarget/mapping/test_filter.py``).

Arrays: targets ``(n, 3)`` float64 metres in the arm's base frame; rates and cutoffs in Hz.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import numpy.typing as npt

from retarget.mapping.targets import Targets

__all__ = ["DEFAULT_CUTOFF_HZ", "OneEuro", "filter_targets", "zero_phase"]

DEFAULT_CUTOFF_HZ = 6.0  #: Hz, the zero-phase cutoff of a clip's targets (Winter: 4-6 Hz for human kinematics)

Array = npt.NDArray[np.float64]


def _butterworth2(rate_hz: float, cutoff_hz: float) -> tuple[tuple[float, float, float], tuple[float, float]]:
    """``(b0, b1, b2), (a1, a2)`` of a 2nd-order Butterworth low-pass (bilinear transform, prewarped)."""
    k = math.tan(math.pi * cutoff_hz / rate_hz)
    norm = 1.0 / (1.0 + math.sqrt(2.0) * k + k * k)
    b0 = k * k * norm
    a1 = 2.0 * (k * k - 1.0) * norm
    a2 = (1.0 - math.sqrt(2.0) * k + k * k) * norm
    return (b0, 2.0 * b0, b0), (a1, a2)


def _one_pass(x: Array, b: tuple[float, float, float], a: tuple[float, float]) -> Array:
    """The biquad over ``x`` ``(n, m)`` along axis 0, started in its steady state at ``x[0]``."""
    b0, b1, b2 = b
    a1, a2 = a
    y = np.empty_like(x)
    x1 = x2 = x[0].copy()
    y1 = y2 = x[0].copy()  # unit DC gain: a constant input passes unchanged
    for i in range(len(x)):
        xi = x[i]
        yi = b0 * xi + b1 * x1 + b2 * x2 - a1 * y1 - a2 * y2
        y[i] = yi
        x2, x1, y2, y1 = x1, xi, y1, yi
    return y


def zero_phase(x: npt.ArrayLike, rate_hz: float, cutoff_hz: float = DEFAULT_CUTOFF_HZ) -> Array:
    """``x`` ``(n, ...)`` sampled at ``rate_hz``, low-passed forward and backward at ``cutoff_hz`` (no lag).

    ``cutoff_hz <= 0``, or at or above the Nyquist frequency, returns a copy unchanged.

    >>> t = np.arange(200) / 100.0
    >>> slow, fast = np.sin(2 * np.pi * 0.5 * t), 0.1 * np.sin(2 * np.pi * 30.0 * t)
    >>> y = zero_phase(slow + fast, 100.0, 6.0)
    >>> bool(np.max(np.abs(y - slow)[20:-20]) < 0.005), abs(round(float(y[0] - slow[0]), 3))
    (True, 0.0)
    """
    x = np.array(x, dtype=np.float64)
    if cutoff_hz <= 0 or cutoff_hz >= 0.5 * rate_hz or len(x) < 2:
        return x
    shape = x.shape
    flat = x.reshape(len(x), -1)
    pad = min(len(flat) - 1, 3 * int(math.ceil(rate_hz / cutoff_hz)))
    head = 2.0 * flat[0] - flat[pad:0:-1]
    tail = 2.0 * flat[-1] - flat[-2 : -pad - 2 : -1]
    padded = np.concatenate([head, flat, tail])
    b, a = _butterworth2(rate_hz, cutoff_hz)
    y = _one_pass(_one_pass(padded, b, a)[::-1], b, a)[::-1]
    return np.ascontiguousarray(y[pad : pad + len(flat)]).reshape(shape)


def filter_targets(targets: Targets, cutoff_hz: float = DEFAULT_CUTOFF_HZ) -> Targets:
    """``targets`` with the unclamped points (``raw``, which :meth:`~retarget.mapping.Targets.sample`
    interpolates) low-passed by :func:`zero_phase` at the clip's frame rate, and ``positions``/``clamped``
    clamped into the workspace again (rotations as they were).  ``cutoff_hz <= 0``: ``targets`` itself."""
    if cutoff_hz <= 0:
        return targets
    raw = zero_phase(targets.raw, 1.0 / targets.frame_time, cutoff_hz)
    positions, clamped = targets.workspace.clamp(raw)
    return dataclasses.replace(targets, raw=raw, positions=positions, clamped=np.asarray(clamped, dtype=bool))


class OneEuro:
    """The One-Euro filter of a live target stream: ``filter(x, t)`` -> the smoothed ``(3,)`` m (see the module).

    ``min_cutoff`` Hz, ``beta`` Hz per m/s, ``d_cutoff`` Hz (the speed estimate's own low-pass).  Samples may
    come at any times ``t`` (s, increasing); a repeated time returns the last output.

    >>> f = OneEuro(min_cutoff=1.0, beta=20.0)
    >>> [f(np.array([0.3, 0.0, 0.2]), t).round(3).tolist() for t in (0.0, 0.01)]
    [[0.3, 0.0, 0.2], [0.3, 0.0, 0.2]]
    """

    def __init__(self, *, min_cutoff: float = 1.0, beta: float = 20.0, d_cutoff: float = 1.0):
        if not (min_cutoff > 0 and beta >= 0 and d_cutoff > 0):
            raise ValueError(f"Expected min_cutoff > 0, beta >= 0, d_cutoff > 0, got {min_cutoff}, {beta}, {d_cutoff}")
        self.min_cutoff, self.beta, self.d_cutoff = min_cutoff, beta, d_cutoff
        self._x: Array | None = None  # the last output, m
        self._dx: Array = np.zeros(3)  # the filtered speed, m/s
        self._t = 0.0

    def reset(self) -> None:
        """Forget the past: the next sample passes unchanged."""
        self._x = None

    def __call__(self, x: npt.ArrayLike, t: float) -> Array:
        x = np.asarray(x, dtype=np.float64)
        if self._x is None:
            self._x, self._dx, self._t = x.copy(), np.zeros_like(x), t
            return x.copy()
        dt = t - self._t
        if dt <= 0:
            return self._x.copy()
        self._t = t
        dx = (x - self._x) / dt
        self._dx = self._dx + _alpha(self.d_cutoff, dt) * (dx - self._dx)
        cutoff = self.min_cutoff + self.beta * float(np.linalg.norm(self._dx))
        self._x = self._x + _alpha(cutoff, dt) * (x - self._x)
        return self._x.copy()


def _alpha(cutoff: float, dt: float) -> float:
    """The one-pole smoothing factor of ``cutoff`` Hz at a sample interval ``dt`` s."""
    tau = 1.0 / (2.0 * math.pi * cutoff)
    return 1.0 / (1.0 + tau / dt)
