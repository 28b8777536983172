"""The numpy kernels of the one-pose path (:mod:`retarget.collision.fast`): every segment pair's distance, and
every segment/box pair's signed point/box candidates, in a fixed number of numpy calls over flat buffers."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

__all__ = ["boxes", "seg_data", "segments"]

_TINY = 1e-300  # added to a slab direction so that a zero component divides to a huge finite number


def segments(buf: np.ndarray, idx: np.ndarray, k: np.ndarray) -> np.ndarray:
    """``(m,)`` distances of segment pairs (Ericson's closest points, clamped three times): ``idx`` ``(8, 3,
    m)`` indices into ``buf`` (``[D1, D2, R, D1]`` as the first four minus the last four), ``k`` ``(5, m)``
    the constants ``e``, ``a e``, the parallel threshold, ``1 / a``, ``1 / e`` (0 for a point)."""
    X = buf.take(idx)
    V = X[:4] - X[4:]  # (4, 3, m): D1, D2, R, D1
    P = V[:3] * V[1:]
    bfc = P[:, 0] + P[:, 1] + P[:, 2]  # (3, m): D1.D2, D2.R, R.D1
    b, f, c = bfc
    den = np.maximum(k[1] - b * b, k[2])
    s = b * f
    s -= c * k[0]
    s /= den
    np.minimum(np.maximum(s, 0.0, out=s), 1.0, out=s)
    t = b * s
    t += f
    t *= k[4]
    np.minimum(np.maximum(t, 0.0, out=t), 1.0, out=t)
    np.multiply(b, t, out=s)
    s -= c
    s *= k[3]
    np.minimum(np.maximum(s, 0.0, out=s), 1.0, out=s)
    gap = V[2] + s * V[0]
    gap -= t * V[1]
    gap *= gap
    out: np.ndarray = np.sqrt(gap[0] + gap[1] + gap[2])
    return out


def boxes(ab: np.ndarray, hh: np.ndarray, h: np.ndarray, cand: np.ndarray) -> np.ndarray:
    """``(mb,)`` signed point/box distances, the least of each segment's two ends and the middle of its slab
    interval (inside the box when the segment enters it); ``ab`` ``(3, 2, mb)`` the ends, box frame, from the
    box centre; ``hh`` ``(2, 3, mb)`` minus and plus the half sizes, ``h`` ``(3, 1, mb)`` the half sizes, ``cand``
    ``(3, mb)`` a buffer whose first two rows hold 0 and 1."""
    u = ab[:, 0]
    d = ab[:, 1] - u
    t = (hh - u) / (d + _TINY)  # (2, 3, mb) where the segment crosses each face plane
    t_in = np.minimum(t[0], t[1]).max(axis=0)
    t_out = np.maximum(t[0], t[1]).min(axis=0)
    mid = cand[2]
    np.add(t_in, t_out, out=mid)
    mid *= 0.5
    np.minimum(np.maximum(mid, 0.0, out=mid), 1.0, out=mid)
    p = np.abs(u[:, None] + cand * d[:, None]) - h  # (3, 3, mb)
    inside = np.minimum(p.max(axis=0), 0.0)
    np.maximum(p, 0.0, out=p)
    p *= p
    out: np.ndarray = (np.sqrt(p[0] + p[1] + p[2]) + inside).min(axis=0)
    return out


def seg_data(
    pairs: list[tuple[int, int, int, int]], local: np.ndarray, flat: Callable[[np.ndarray, int], np.ndarray]
) -> tuple[np.ndarray, np.ndarray]:
    """The ``(idx, k)`` of :func:`segments` for ``(p1, q1, p2, q2)`` point index pairs (``local``:
    ``(n_points, 3)`` each point in its own frame; a segment's two ends share a frame)."""
    P1, Q1, P2, Q2 = np.array(pairs, dtype=np.intp).reshape(-1, 4).T
    idx = np.moveaxis(flat(np.stack([Q1, Q2, P1, Q1, P1, P2, P2, P1]), 0), 0, 1)  # (8, 3, m)
    a = ((local[Q1] - local[P1]) ** 2).sum(axis=1)
    e = ((local[Q2] - local[P2]) ** 2).sum(axis=1)
    inv_a = np.where(a > 1e-18, 1.0 / np.where(a > 1e-18, a, 1.0), 0.0)
    inv_e = np.where(e > 1e-18, 1.0 / np.where(e > 1e-18, e, 1.0), 0.0)
    return np.ascontiguousarray(idx), np.stack([e, a * e, 1e-12 * a * e + _TINY, inv_a, inv_e])
