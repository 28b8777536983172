"""Vectorised distance functions between segments, points, boxes and spheres (metres, any shared frame).

Every function broadcasts over leading axes: arguments are ``(..., 3)`` points (or ``(...)`` radii) and the
result is ``(...)``.  Capsule distances are the segment distances minus the radii; a negative value is a
penetration.

>>> import numpy as np
>>> float(segment_segment(np.array([0., 0, 0]), np.array([1., 0, 0]), np.array([0.5, 1, 0]), np.array([0.5, 2, 0])))
1.0
>>> float(segment_box(np.array([0., 0, 2]), np.array([0., 0, 3]), np.zeros(3), np.ones(3)))
1.0
"""

from __future__ import annotations

import numpy as np

__all__ = ["point_box", "point_segment", "segment_box", "segment_segment", "segment_points"]

_EPS = 1e-18  # m^4 or m^2: below this a length or a determinant counts as zero


def _dot(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    out: np.ndarray = np.einsum("...k,...k->...", u, v)
    return out


def segment_points(p1: np.ndarray, q1: np.ndarray, p2: np.ndarray, q2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Parameters ``(s, t)`` in [0, 1] of the closest points of segments ``p1-q1`` and ``p2-q2`` (Ericson,
    *Real-Time Collision Detection* 5.1.9, branch-free over a batch)."""
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    a, e, b = _dot(d1, d1), _dot(d2, d2), _dot(d1, d2)
    c, f = _dot(d1, r), _dot(d2, r)
    a_ok, e_ok = a > _EPS, e > _EPS
    a_safe, e_safe = np.where(a_ok, a, 1.0), np.where(e_ok, e, 1.0)
    denom = a * e - b * b
    d_ok = denom > 1e-12 * a * e
    s = np.where(d_ok, np.clip((b * f - c * e) / np.where(d_ok, denom, 1.0), 0.0, 1.0), 0.0)
    t = np.where(e_ok, (b * s + f) / e_safe, 0.0)
    s = np.where(t <= 0.0, np.clip(-c / a_safe, 0.0, 1.0), np.where(t >= 1.0, np.clip((b - c) / a_safe, 0.0, 1.0), s))
    s = np.where(a_ok, s, 0.0)
    t = np.clip(t, 0.0, 1.0)
    return s, t


def segment_segment(p1: np.ndarray, q1: np.ndarray, p2: np.ndarray, q2: np.ndarray) -> np.ndarray:
    """Distance between segments ``p1-q1`` and ``p2-q2`` ``(..., 3)`` -> ``(...)``."""
    s, t = segment_points(p1, q1, p2, q2)
    gap = p1 + (q1 - p1) * s[..., None] - p2 - (q2 - p2) * t[..., None]
    out: np.ndarray = np.sqrt(_dot(gap, gap))
    return out


def point_segment(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance from points ``p`` to segments ``a-b`` ``(..., 3)`` -> ``(...)``."""
    d = b - a
    dd = _dot(d, d)
    t = np.clip(_dot(p - a, d) / np.where(dd > _EPS, dd, 1.0), 0.0, 1.0)
    gap = a + d * t[..., None] - p
    out: np.ndarray = np.sqrt(_dot(gap, gap))
    return out


def point_box(p: np.ndarray, center: np.ndarray, half: np.ndarray) -> np.ndarray:
    """Signed distance from points ``p`` to axis-aligned boxes ``(center, half)`` (negative inside)."""
    q = np.abs(p - center) - half
    outside = np.sqrt(_dot(np.maximum(q, 0.0), np.maximum(q, 0.0)))
    out: np.ndarray = outside + np.minimum(q.max(axis=-1), 0.0)
    return out


def segment_box(a: np.ndarray, b: np.ndarray, center: np.ndarray, half: np.ndarray) -> np.ndarray:
    """Signed distance from segments ``a-b`` to axis-aligned boxes ``(center, half)`` ``(..., 3)`` -> ``(...)``.

    Exact when the segment stays outside the box: the squared distance along the segment is a convex piecewise
    quadratic whose pieces end where the segment crosses a face plane, so its minimum is at an end, a crossing or
    one piece's stationary point, all of which are tried.  Negative when the segment enters the box (the depth
    is then a lower bound of the deepest point's, within the box).
    """
    u = np.asarray(a - center, dtype=np.float64)
    d = np.asarray(b - a, dtype=np.float64)
    half = np.broadcast_to(half, u.shape)
    with np.errstate(divide="ignore", invalid="ignore"):
        cross = np.concatenate(((half - u) / d, (-half - u) / d), axis=-1)
    cross = np.clip(np.where(np.isfinite(cross), cross, 0.0), 0.0, 1.0)
    ends = np.broadcast_to(np.array([0.0, 1.0]), (*u.shape[:-1], 2))
    knots = np.sort(np.concatenate((ends, cross), axis=-1), axis=-1)  # (..., 8)
    lo, hi = knots[..., :-1], knots[..., 1:]
    mid = 0.5 * (lo + hi)  # (..., 7)
    v = u[..., None, :] + mid[..., None] * d[..., None, :]  # (..., 7, 3)
    h = half[..., None, :]
    bound = np.where(v > h, h, np.where(v < -h, -h, np.nan))
    active = ~np.isnan(bound)
    w = np.where(active, u[..., None, :] - np.nan_to_num(bound), 0.0)
    dk = np.where(active, d[..., None, :], 0.0)
    den = _dot(dk, dk)
    stationary = np.where(den > _EPS, -_dot(w, dk) / np.where(den > _EPS, den, 1.0), mid)
    stationary = np.clip(stationary, lo, hi)
    t = np.concatenate((knots, stationary), axis=-1)  # (..., 15)
    p = u[..., None, :] + t[..., None] * d[..., None, :]
    out: np.ndarray = point_box(p, np.zeros(3), h).min(axis=-1)
    return out
