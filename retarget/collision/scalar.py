"""Plain-float distance kernels for one pair at a time (the few pairs a one-pose check has to measure exactly).

A pair in plain Python costs about a microsecond, as much as a single numpy call on a small array, so once the
bounds have ruled out most pairs, the rest are measured here.  Same results as the numpy kernels of
:mod:`retarget.collision.fast` (to rounding).

>>> round(segment_segment((0, 0, 0), (1, 0, 0), (0.5, 1, 0), (0.5, 2, 0), 1.0, 1.0), 12)
1.0
>>> round(segment_box((0, 0, 2), (0, 0, 1), (1, 1, 1)), 12)  # from (0, 0, 2) to (0, 0, 3), the unit box
1.0
"""

from __future__ import annotations

import math
from collections.abc import Sequence

__all__ = ["point_box", "segment_box", "segment_segment"]

Vec = Sequence[float]


def segment_segment(p1: Vec, q1: Vec, p2: Vec, q2: Vec, inv_a: float, inv_e: float) -> float:
    """Distance between segments ``p1-q1`` and ``p2-q2`` (metres); ``inv_a``, ``inv_e``: one over their squared
    lengths (0 for a point).  Ericson's closest points, clamped three times."""
    d1x, d1y, d1z = q1[0] - p1[0], q1[1] - p1[1], q1[2] - p1[2]
    d2x, d2y, d2z = q2[0] - p2[0], q2[1] - p2[1], q2[2] - p2[2]
    rx, ry, rz = p1[0] - p2[0], p1[1] - p2[1], p1[2] - p2[2]
    b = d1x * d2x + d1y * d2y + d1z * d2z
    c = d1x * rx + d1y * ry + d1z * rz
    f = d2x * rx + d2y * ry + d2z * rz
    a = d1x * d1x + d1y * d1y + d1z * d1z if inv_a else 0.0
    e = d2x * d2x + d2y * d2y + d2z * d2z if inv_e else 0.0
    den = a * e - b * b
    s = (b * f - c * e) / den if den > 1e-12 * a * e + 1e-300 else 0.0
    s = 0.0 if s < 0.0 else 1.0 if s > 1.0 else s
    t = (b * s + f) * inv_e
    t = 0.0 if t < 0.0 else 1.0 if t > 1.0 else t
    s = (b * t - c) * inv_a
    s = 0.0 if s < 0.0 else 1.0 if s > 1.0 else s
    gx, gy, gz = rx + s * d1x - t * d2x, ry + s * d1y - t * d2y, rz + s * d1z - t * d2z
    return math.sqrt(gx * gx + gy * gy + gz * gz)


def point_box(x: float, y: float, z: float, h: Vec) -> float:
    """Signed distance from the point ``(x, y, z)`` to the box ``[-h, h]`` (negative inside)."""
    qx, qy, qz = abs(x) - h[0], abs(y) - h[1], abs(z) - h[2]
    ox, oy, oz = max(qx, 0.0), max(qy, 0.0), max(qz, 0.0)
    return math.sqrt(ox * ox + oy * oy + oz * oz) + min(max(qx, qy, qz), 0.0)


def segment_box(u: Vec, d: Vec, h: Vec) -> float:
    """Signed distance from the segment ``u + t d`` (t in 0..1) to the box ``[-h, h]`` (its frame, metres).

    Outside: exact, the root of the derivative of the squared distance (convex, piecewise quadratic; linear
    between the face-plane crossings, which are tried in order).  Entering the box: the signed distance of the
    least of its ends and the middle of its slab interval (negative), as in :mod:`retarget.collision.fast`.
    """
    knots = [0.0, 1.0]
    t_in, t_out = -math.inf, math.inf
    for k in range(3):
        ds = d[k] + 1e-300  # as the numpy kernel: a zero component divides to a huge finite number
        t1, t2 = (-h[k] - u[k]) / ds, (h[k] - u[k]) / ds
        if t1 > t2:
            t1, t2 = t2, t1
        t_in, t_out = max(t_in, t1), min(t_out, t2)
        knots += [t for t in (t1, t2) if 0.0 < t < 1.0]
    if t_in <= t_out and t_in <= 1.0 and t_out >= 0.0:  # enters the box
        mid = min(max(0.5 * (t_in + t_out), 0.0), 1.0)
        return min(point_box(u[0] + t * d[0], u[1] + t * d[1], u[2] + t * d[2], h) for t in (0.0, 1.0, mid))
    knots.sort()
    prev_t, prev_g = 0.0, 0.0
    best = 1.0
    for i, t in enumerate(knots):
        g = _slope(u, d, h, t)
        if g >= 0.0:
            best = t if i == 0 else prev_t - prev_g * (t - prev_t) / (g - prev_g)
            break
        prev_t, prev_g = t, g
    return point_box(u[0] + best * d[0], u[1] + best * d[1], u[2] + best * d[2], h)


def _slope(u: Vec, d: Vec, h: Vec, t: float) -> float:
    """Half the derivative in ``t`` of the squared distance from ``u + t d`` to the box ``[-h, h]``."""
    g = 0.0
    for k in range(3):
        x = u[k] + t * d[k]
        if x > h[k]:
            g += d[k] * (x - h[k])
        elif x < -h[k]:
            g += d[k] * (x + h[k])
    return g
