"""Target filters: zero-phase for whole clips, One-Euro for live streams.  Pure numpy.

* :func:`zero_phase` (:func:`~retarget.mapping.targets.filter_targets` on a clip's targets): a whole clip is
  known in advance, so its targets are low-passed forward and backward with a 2nd-order Butterworth filter
  (Winter's choice for motion-capture kinematics, *Biomechanics and Motor Control of Human Movement*, 4-6 Hz):
  the two passes cancel each other's phase,
  so it adds **no lag**, and the gain is that of a 4th-order filter (-6 dB at the cutoff).  The ends are
  padded with an odd reflection (as scipy's ``filtfilt``) so a clip's first and last frames stay put.
  :func:`~retarget.mapping.retarget_targets` filters a clip's mapped points at ``MappingConfig.cutoff_hz``
  *before* the workspace clamp and the collision push-out, so every filtered target is still reachable.  By
  default (:data:`DEFAULT_CUTOFF`, ``"auto"``) the cutoff is chosen from the clip's own noise
  (:func:`~retarget.mapping.cutoff.auto_cutoff`: none for a clean capture, lower the noisier it is); a number
  sets it; ``cutoff_hz = 0`` (``--no-filter``) turns it off.  The CLI's causal runs (``--loop``,
  ``--no-look-ahead``) read ``"auto"`` as :data:`CAUSAL_CUTOFF_HZ` (``retarget.cli._rig_run.played_mapping``); a
  library caller chooses for itself.  A cutoff at or above the clip's Nyquist frequency
  (half its frame rate) filters nothing.
* :class:`OneEuro`: a causal filter for targets that arrive live (Casiez, Roussel and Vogel, "1 Euro filter:
  a simple speed-based low-pass filter for noisy input in interactive systems", CHI 2012): a one-pole low-pass
  whose cutoff rises with the speed, ``min_cutoff + beta x |speed|``, so it smooths a still hand hard and a
  fast one little.  Its lag at steady speed, about ``1 / (2 pi cutoff)`` plus the sample interval's share,
  with the defaults (1 Hz, beta 20 Hz per m/s) at 100 Hz: 31 ms at 0.05 m/s, 15 ms at 0.2 m/s, 8 ms at
  0.5 m/s, 5 ms at 1 m/s (measured in ``tests/retarget/mapping/test_filter.py``).  On by default for teleop's
  streams (:class:`~retarget.teleop.Follower` ``smoothing``; stdin, UDP), filtering each target as it arrives;
  not for a one-shot ``--to`` or the keys, where there is no noise to smooth and a lag would only slow the arm.

Arrays: targets ``(n, 3)`` float64 metres in the arm's base frame; rates and cutoffs in Hz.
"""

from __future__ import annotations

import functools
import math
from typing import Literal

import numpy as np
import numpy.typing as npt

from retarget.errors import require_positive

__all__ = [
    "AUTO",
    "CAUSAL_CUTOFF_HZ",
    "DEFAULT_BETA",
    "DEFAULT_CUTOFF",
    "DEFAULT_MIN_CUTOFF_HZ",
    "Cutoff",
    "OneEuro",
    "zero_phase",
]

AUTO: Literal["auto"] = "auto"  #: ``cutoff_hz``: chosen from the clip (:func:`~retarget.mapping.cutoff.auto_cutoff`)
Cutoff = float | Literal["auto"]  #: a zero-phase cutoff: Hz (0: none), or :data:`AUTO`
#: the zero-phase cutoff of a clip's targets.  The filter only has to keep the capture's noise out: the look-ahead
#: plan (retarget.control.plan) keeps the motion within the joints' speed and acceleration.  A fixed one cuts a
#: clean capture's own fast moves: Winter's 6 Hz for human kinematics took p95 2.1 mm off the path of wx250s on
#: motion_basket right (bench/bench_smooth.py), while its noise is 0.2 mm
DEFAULT_CUTOFF: Cutoff = AUTO
#: Hz, what ``"auto"`` means for a clip played causally (replay ``--loop``, ``--no-look-ahead``): Winter's cutoff for
#: human kinematics.  The causal limiter cannot start early for a move, so a clean clip's own fast moves cost it more
#: in lag than the filter takes off them: wx250s on motion_dance right, p95 37 mm at 6 Hz against 64 unfiltered,
#: unity_walk_random left 3.0 against 7.2 (bench/bench_smooth.py --flags=--no-look-ahead)
CAUSAL_CUTOFF_HZ = 6.0
DEFAULT_MIN_CUTOFF_HZ = 1.0  #: Hz, the One-Euro cutoff of a still hand (Casiez et al.'s starting point)
DEFAULT_BETA = 20.0  #: Hz per m/s, how fast the One-Euro cutoff rises with the hand's speed

Array = npt.NDArray[np.float64]


def _butterworth2(rate_hz: float, cutoff_hz: float) -> tuple[tuple[float, float, float], tuple[float, float]]:
    """``(b0, b1, b2), (a1, a2)`` of a 2nd-order Butterworth low-pass (bilinear transform, prewarped)."""
    k = math.tan(math.pi * cutoff_hz / rate_hz)
    norm = 1.0 / (1.0 + math.sqrt(2.0) * k + k * k)
    b0 = k * k * norm
    a1 = 2.0 * (k * k - 1.0) * norm
    a2 = (1.0 - math.sqrt(2.0) * k + k * k) * norm
    return (b0, 2.0 * b0, b0), (a1, a2)


_BLOCK = 64  #: samples per block of the vectorised recursion


@functools.lru_cache(maxsize=16)
def _block_response(a1: float, a2: float) -> tuple[Array, Array]:
    """The recursion ``y[i] = u[i] - a1 y[i-1] - a2 y[i-2]`` over one block of :data:`_BLOCK` samples as matrices:
    ``y = H @ u + G @ (y[-1], y[-2])``; ``H`` ``(B, B)`` lower-triangular Toeplitz (the impulse response),
    ``G`` ``(B, 2)`` the response to the state the block starts from."""
    n = _BLOCK
    h, g = np.zeros(n), np.zeros((n, 2))
    h1 = h2 = 0.0
    y1, y2 = np.array([1.0, 0.0]), np.array([0.0, 1.0])  # columns: unit y[-1], unit y[-2]
    for i in range(n):
        hi = (1.0 if i == 0 else 0.0) - a1 * h1 - a2 * h2
        h[i], h1, h2 = hi, hi, h1
        gi = -a1 * y1 - a2 * y2
        g[i], y1, y2 = gi, gi, y1
    lag = np.subtract.outer(np.arange(n), np.arange(n))
    return np.where(lag >= 0, h[np.maximum(lag, 0)], 0.0), g


def _one_pass(x: Array, b: tuple[float, float, float], a: tuple[float, float]) -> Array:
    """The biquad over ``x`` ``(n, m)`` along axis 0, started in its steady state at ``x[0]``.

    Vectorised: the feed-forward part at once, the recursion a block at a time by :func:`_block_response`
    (about 50x faster than a loop over samples, and equal to it to rounding)."""
    b0, b1, b2 = b
    xp = np.concatenate([x[:1], x[:1], x])
    u = b0 * xp[2:] + b1 * xp[1:-1] + b2 * xp[:-2]
    H, G = _block_response(*a)
    y = np.empty_like(x)
    y1 = y2 = x[0]  # unit DC gain: a constant input passes unchanged
    for s in range(0, len(x), _BLOCK):
        m = min(_BLOCK, len(x) - s)
        block = H[:m, :m] @ u[s : s + m] + np.outer(G[:m, 0], y1) + np.outer(G[:m, 1], y2)
        y[s : s + m] = block
        y1, y2 = block[-1], (block[-2] if m > 1 else y1)
    return y


def zero_phase(x: npt.ArrayLike, rate_hz: float, cutoff_hz: float) -> Array:
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


class OneEuro:
    """The One-Euro filter of a live target stream: ``filter(x, t)`` -> the smoothed ``(3,)`` m (see the module).

    ``min_cutoff`` Hz, ``beta`` Hz per m/s, ``d_cutoff`` Hz (the speed estimate's own low-pass).  Samples may
    come at any times ``t`` (s, increasing); a repeated time returns the last output.

    >>> f = OneEuro(min_cutoff=1.0, beta=20.0)
    >>> [f(np.array([0.3, 0.0, 0.2]), t).round(3).tolist() for t in (0.0, 0.01)]
    [[0.3, 0.0, 0.2], [0.3, 0.0, 0.2]]
    """

    def __init__(self, *, min_cutoff: float = DEFAULT_MIN_CUTOFF_HZ, beta: float = DEFAULT_BETA, d_cutoff: float = 1.0):
        self.min_cutoff = require_positive(min_cutoff, "min_cutoff")
        self.beta = require_positive(beta, "beta", zero=True)
        self.d_cutoff = require_positive(d_cutoff, "d_cutoff")
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
