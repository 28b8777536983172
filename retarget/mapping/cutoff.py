"""The zero-phase filter's cutoff chosen from the clip itself: :func:`auto_cutoff` (``cutoff_hz = "auto"``).

A fixed cutoff is a guess at where a clip's motion ends and its noise begins, and no one guess fits every source.
Winter's 4-6 Hz for human kinematics cuts a clean optical capture's own fast moves: a hand dribbling a ball
(``motion_basket.bvh``) loses p95 2.1 mm of its path at 6 Hz, more than its noise by ten times.  A noisy source
(an IMU suit, a pose estimated from video) needs a lower one.  So the default reads the clip:

1. **the noise level** ``s`` per axis (:func:`noise_level`): the white noise that the clip's 4th differences
   show, robustly (the median absolute deviation, so that a few fast moves do not count as noise).  A smooth
   motion's 4th differences at 60-120 Hz are tiny; white noise of ``s`` gives them ``s sqrt(70)``;
2. **the risk of each cutoff** ``fc``: Stein's unbiased risk estimate (SURE; C. M. Stein, "Estimation of the mean
   of a multivariate normal distribution", Ann. Statist. 1981; for a linear smoother it is Mallows' Cp) of the
   filtered clip's mean squared error against the noise-free motion:

       risk(fc) = mean (x - y)^2 - s^2 + 2 s^2 tr(S) / n

   with ``y = S x`` the filtered clip.  The first term is what the filter takes away (noise and motion); the last
   is the noise it lets through.  Both come from one FFT of the clip (mirrored, so that its ends do not jump):
   the filter's gain at each frequency is the Butterworth's squared (forward and backward), so the residual is a
   weighted sum of the clip's spectrum and ``tr(S) / n`` the gain's mean;
3. **the cutoff of least risk** on a grid from :data:`LOWEST_HZ` to 0.45 of the frame rate, or no filter when the
   noise alone (``s^2``) is less.

On the shared clips (120 Hz optical captures, 60 Hz Unity exports) it picks no filter or 40-45 Hz (noise
0.02-0.2 mm); with 2 mm of white noise added to ``motion_dance.bvh`` (wx250s mapping), 11.5 Hz, and the filtered
clip is then 0.98 mm RMS from the clean one (6 Hz: 1.89 mm, for cutting the dance's own moves too).  Like any
filter here it adds no lag (zero phase).  Cost: one FFT and a (32, 2n) product, about 1 ms a clip.  A clip played
causally reads ``"auto"`` as :data:`~retarget.mapping.filter.CAUSAL_CUTOFF_HZ` instead (the CLI does).

Arrays: ``(n, d)`` float64 samples (metres for targets), rates and cutoffs in Hz.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

__all__ = ["LOWEST_HZ", "auto_cutoff", "noise_level"]

Array = npt.NDArray[np.float64]

LOWEST_HZ = 1.0  #: Hz, the lowest cutoff :func:`auto_cutoff` may choose
_GRID = 32  #: cutoffs tried, geometrically spaced from LOWEST_HZ to 0.45 x the rate
_MAD = 1.4826  #: the median absolute deviation of a normal variable, in standard deviations: 1 / 0.6745
_FOURTH = math.sqrt(70.0)  #: white noise of sd 1 has 4th differences of sd sqrt(1 + 16 + 36 + 16 + 1)


def noise_level(x: npt.ArrayLike) -> Array:
    """The standard deviation ``(d,)`` of white noise in ``x`` ``(n, d)`` (units of ``x``), from its 4th
    differences, robustly (the median absolute deviation; 0 for fewer than 6 samples).

    >>> rng = np.random.default_rng(0)
    >>> t = np.linspace(0.0, 10.0, 1200)[:, None]
    >>> noise_level(np.sin(t) + rng.normal(0.0, 0.002, (1200, 1))).round(4).tolist()
    [0.002]
    """
    x = np.asarray(x, dtype=np.float64)
    x = x.reshape(len(x), -1)
    if len(x) < 6:
        return np.zeros(x.shape[1])
    d = np.diff(x, n=4, axis=0)
    deviation = np.median(np.abs(d - np.median(d, axis=0)), axis=0)
    return np.asarray(_MAD * deviation / _FOURTH, dtype=np.float64)


def auto_cutoff(x: npt.ArrayLike, rate_hz: float) -> float:
    """The zero-phase cutoff, Hz, of least estimated risk for ``x`` ``(n, d)`` sampled at ``rate_hz`` (see the
    module docstring); 0.0: leave it unfiltered (the noise is below what any cutoff would cost the motion).

    >>> rng = np.random.default_rng(0)
    >>> t = np.arange(1200)[:, None] / 120.0
    >>> walk = 0.2 * np.sin(2 * np.pi * 1.0 * t)
    >>> auto_cutoff(walk, 120.0), round(auto_cutoff(walk + rng.normal(0.0, 0.002, walk.shape), 120.0))
    (0.0, 10)
    """
    x = np.asarray(x, dtype=np.float64)
    x = x.reshape(len(x), -1)
    if len(x) < 16 or not rate_hz > 2.0 * LOWEST_HZ / 0.45:
        return 0.0
    s2 = noise_level(x) ** 2
    n = len(x)
    m = 1 << (2 * n - 1).bit_length()  # a fast FFT length: the mirrored clip, then its first sample held
    periodic = np.empty((m, x.shape[1]))
    periodic[:n], periodic[n : 2 * n], periodic[2 * n :] = x, x[::-1], x[0]
    periodic -= periodic.mean(axis=0)
    power = np.abs(np.fft.rfft(periodic, axis=0)) ** 2  # (m // 2 + 1, d)
    weight = np.full(len(power), 2.0)  # each rfft bin stands for itself and its negative frequency
    weight[0] = weight[-1] = 1.0
    f = np.arange(len(power)) * rate_hz / m
    cutoffs = np.geomspace(LOWEST_HZ, 0.45 * rate_hz, _GRID)
    # the bilinear Butterworth's |H|^2 at each frequency and cutoff, squared (forward and backward)
    warped = np.tan(np.pi * np.minimum(f, 0.4999 * rate_hz) / rate_hz) ** 4
    gain = 1.0 / (1.0 + np.outer(np.tan(np.pi * cutoffs / rate_hz) ** -4, warped))  # (GRID, bins)
    removed = ((weight * (1.0 - gain) ** 2) @ power) / (2 * n * m)  # (GRID, d): the mean square taken away
    passed = (gain @ weight) / m  # (GRID,): tr(S) / n
    risk = (removed - s2 + 2.0 * s2 * passed[:, None]).sum(axis=1)
    best = int(np.argmin(risk))
    return 0.0 if float(s2.sum()) <= risk[best] else float(cutoffs[best])
