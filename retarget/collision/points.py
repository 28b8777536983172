"""Target points against the blocked zones of a :class:`~retarget.collision.model.CollisionModel`: the table,
keep-out zones and the shapes on the base frame (``point_margin``, ``point_blocked``, ``push_out``).

>>> import retarget
>>> from retarget.collision import CollisionModel
>>> model = CollisionModel.for_arm(retarget.load_arm("wx250s"))
>>> model.point_blocked([0.3, 0.0, -0.05]), model.push_out([0.3, 0.0, -0.05]).round(3).tolist()
(True, [0.3, 0.0, 0.01])
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from retarget.collision.distance import point_box, point_segment
from retarget.collision.shapes import BASE_FRAME, World

__all__ = ["TargetPoints"]


class TargetPoints:
    """The target-point queries of :class:`~retarget.collision.model.CollisionModel` (a base class: it reads
    the model's zones and base shapes)."""

    world: World
    clearance: float
    _sph_c: np.ndarray
    _sph_r: np.ndarray
    _kb_c: np.ndarray
    _kb_h: np.ndarray
    _box_frame: np.ndarray
    _box_c: np.ndarray
    _box_h: np.ndarray
    _cap_frame: np.ndarray
    _cap_local: np.ndarray
    _cap_r: np.ndarray

    def point_margin(self, p: np.ndarray | Sequence[float]) -> float:
        """Signed distance (metres) of a point ``(3,)`` in the base frame to the blocked zones: below the table,
        inside a keep-out zone, inside a shape on the base frame (negative inside; inf when there are none)."""
        point = np.asarray(p, dtype=np.float64)
        if point.shape != (3,) or not np.all(np.isfinite(point)):
            raise ValueError(f"Expected a finite point of shape (3,), got {p!r}")
        return float(self._margins(point).min(initial=math.inf))

    def point_margins(self, points: np.ndarray) -> np.ndarray:
        """:meth:`point_margin` of many points ``(n, 3)`` (base frame, metres) at once: ``(n,)`` metres.

        >>> import retarget
        >>> from retarget.collision import CollisionModel
        >>> model = CollisionModel.for_arm(retarget.load_arm("wx250s"), clearance=0.0)
        >>> model.point_margins(np.array([[0.3, 0.0, 0.2], [0.3, 0.0, -0.05]])).round(3).tolist()  # above, below
        [0.2, -0.05]
        """
        p = np.asarray(points, dtype=np.float64)
        if p.ndim != 2 or p.shape[1] != 3:
            raise ValueError(f"Expected points of shape (n, 3), got {p.shape}")
        bad = np.flatnonzero(~np.isfinite(p).all(axis=1))
        if bad.size:
            raise ValueError(f"Expected finite points, got {p[bad[0]].tolist()} (point {int(bad[0])})")
        margins: np.ndarray = self._margins(p).min(axis=-1, initial=math.inf)
        return margins

    def _margins(self, p: np.ndarray) -> np.ndarray:
        """Each zone's signed distance of points ``p`` ``(..., 3)``: ``(..., n_zones)`` metres."""
        at = p[..., None, :]  # (..., 1, 3): against every zone of a kind at once
        parts = [p[..., 2:3]] if self.world.table else []
        if len(self._sph_c):
            parts.append(np.linalg.norm(at - self._sph_c, axis=-1) - self._sph_r)
        if len(self._kb_c):
            parts.append(point_box(at, self._kb_c, self._kb_h))
        fixed_boxes = self._box_frame == BASE_FRAME
        if fixed_boxes.any():
            parts.append(point_box(at, self._box_c[fixed_boxes], self._box_h[fixed_boxes]))
        fixed = np.flatnonzero(self._cap_frame == BASE_FRAME)
        if fixed.size:
            a, b = self._cap_local[fixed, 0], self._cap_local[fixed, 1]
            parts.append(point_segment(at, a, b) - self._cap_r[fixed])
        return np.concatenate(parts, axis=-1) if parts else np.empty((*p.shape[:-1], 0))

    def point_blocked(self, p: np.ndarray | Sequence[float]) -> bool:
        """True when the point ``(3,)`` (base frame, metres) is closer than the clearance to a blocked zone."""
        return self.point_margin(p) < self.clearance

    def push_out(self, p: np.ndarray | Sequence[float]) -> np.ndarray:
        """The point ``(3,)`` itself when free, else a nearby point with ``point_margin >= clearance`` (base frame,
        metres): each zone in turn pushes it straight out to the clearance, repeated while zones overlap; if they
        keep it trapped, it is lifted above every zone instead.

        >>> from retarget.arm.load import load_arm
        >>> from retarget.collision import CollisionModel, Sphere, World
        >>> model = CollisionModel.for_arm(load_arm("wx250s"), world=World(keep_out=(Sphere((0.3, 0, 0.2), 0.05),)))
        >>> model.push_out([0.3, 0.0, 0.21]).round(3).tolist()
        [0.3, 0.0, 0.26]
        """
        point = np.array(p, dtype=np.float64)
        m = self.clearance
        for _ in range(32):
            if self.point_margin(point) >= m - 1e-12:
                return point
            point = self._push_once(point, m)
        point[2] = max(point[2], self._top() + m)
        return point

    def _push_once(self, p: np.ndarray, m: float) -> np.ndarray:
        if self.world.table and p[2] < m:
            p[2] = m
        for c, r in zip(self._sph_c, self._sph_r, strict=True):
            p = _out_of_ball(p, c, r + m)
        fixed_boxes = self._box_frame == BASE_FRAME
        boxes = [*zip(self._kb_c, self._kb_h, strict=True)]
        boxes += [*zip(self._box_c[fixed_boxes], self._box_h[fixed_boxes], strict=True)]
        for c, h in boxes:
            p = _out_of_box(p, c, h, m)
        for k in np.flatnonzero(self._cap_frame == BASE_FRAME):
            a, b = self._cap_local[k]
            d = b - a
            t = float(np.clip((p - a) @ d / max(float(d @ d), 1e-18), 0.0, 1.0))
            p = _out_of_ball(p, a + t * d, float(self._cap_r[k]) + m)
        return p

    def _top(self) -> float:
        """The highest z of any zone or base shape, metres."""
        tops = [0.0, *(self._sph_c[:, 2] + self._sph_r), *(self._kb_c[:, 2] + self._kb_h[:, 2])]
        fixed_boxes = self._box_frame == BASE_FRAME
        tops += [*(self._box_c[fixed_boxes, 2] + self._box_h[fixed_boxes, 2])]
        fixed = np.flatnonzero(self._cap_frame == BASE_FRAME)
        tops += [*(self._cap_local[fixed, :, 2].max(axis=1, initial=0.0) + self._cap_r[fixed])]
        return float(max(tops))


def _out_of_ball(p: np.ndarray, c: np.ndarray, r: float) -> np.ndarray:
    """``p`` moved radially out to distance ``r`` from ``c`` when closer (straight up when ``p == c``)."""
    gap = p - c
    dist = float(np.linalg.norm(gap))
    if dist >= r:
        return p
    direction = gap / dist if dist > 1e-12 else np.array([0.0, 0.0, 1.0])
    out: np.ndarray = c + direction * r
    return out


def _out_of_box(p: np.ndarray, c: np.ndarray, h: np.ndarray, m: float) -> np.ndarray:
    """``p`` moved to distance ``m`` from the box ``(c, h)`` when closer: out through the nearest face from
    inside, along the outward normal from outside."""
    q = p - c
    inside = h - np.abs(q)
    if np.all(inside >= 0):  # inside (or on the surface): leave through the nearest face
        k = int(np.argmin(inside))
        q[k] = math.copysign(h[k] + m, q[k] if q[k] != 0 else 1.0)
        out: np.ndarray = c + q
        return out
    nearest = np.clip(q, -h, h)
    out = c + _out_of_ball(q, nearest, m)
    return out
