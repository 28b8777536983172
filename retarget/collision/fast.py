"""The one-pose path of :class:`~retarget.collision.model.CollisionModel`: every pair's clearance for one pose in a
fixed, small number of numpy calls (about 80, whatever the number of pairs), on buffers allocated once.

A numpy call on a few hundred numbers costs about as much as one on ten, so the pose is checked in a handful of
wide passes rather than pair by pair:

1. forward kinematics: every joint's local transform from one matrix-vector product (``[sin q, cos q, 1]``
   against the precomputed Rodrigues terms), then one 4x4 product per joint down the chain;
2. every point of the geometry (capsule ends, box corners and centres, keep-out zones) in the base frame from one
   matrix product, and in each moving box's frame from one more;
3. one segment/segment closest-point pass (Ericson, *Real-Time Collision Detection* 5.1.9, clamped three times,
   the squared lengths precomputed: the shapes are rigid) over every capsule/capsule and capsule/sphere pair and
   every segment against the twelve edges of every box it is paired with;
4. segment/box: the segment outside the box is exactly as far as the nearest of its two ends (point/box) and the
   box's twelve edges (step 3); a segment that enters the box is caught by the middle of its slab interval,
   which then lies inside (its signed depth, negative, is reported; a lower bound of nothing in particular, as
   the batch path's depth of a penetrating segment is: both are <= 0 and neither is used as a distance);
5. the table: the lowest end point (or box corner) of each moving shape.

The values equal the batch path's (:func:`~retarget.collision.distance.segment_segment` and friends) to rounding
(1e-12 m), except the (negative) depth of a segment inside a box.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from retarget.collision.kernels import boxes, seg_data, segments
from retarget.collision.scalar import segment_box, segment_segment
from retarget.collision.shapes import BASE_FRAME

#: a :class:`~retarget.collision.model.CollisionModel` (not imported: the model imports this module); its pair
#: arrays (``_cc``, ``_cb``, ``_mcap``, ...) are read once, at construction
Model = Any

__all__ = ["OnePose"]

#: the corners of a box, ``k = 4 ix + 2 iy + iz`` (bit set: +half size), and its twelve edges
_SIGNS = np.array([[1 if k & 4 else -1, 1 if k & 2 else -1, 1 if k & 1 else -1] for k in range(8)], dtype=np.float64)
_EDGES = [(k, k | bit) for bit in (1, 2, 4) for k in range(8) if not k & bit]
#: the bounding-box gap of two segments a1-b1, a2-b2 per axis is (|a1 + b1 - a2 - b2| - |b1 - a1| - |b2 - a2|) / 2
_SPAN = np.array([[1.0, 1.0, -1.0, -1.0], [-1.0, 1.0, 0.0, 0.0], [0.0, 0.0, -1.0, 1.0]])
_GAP, _ONES = np.array([1.0, -1.0, -1.0]), np.ones(3)


class _Points:
    """The points of the geometry, each fixed in one frame: ``add`` returns their indices."""

    def __init__(self) -> None:
        self.local: list[tuple[float, float, float]] = []
        self.frame: list[int] = []

    def add(self, frame: int, pts: np.ndarray) -> list[int]:
        start = len(self.local)
        for p in np.asarray(pts, dtype=np.float64).reshape(-1, 3):
            self.local.append((float(p[0]), float(p[1]), float(p[2])))
            self.frame.append(int(frame))
        return list(range(start, len(self.local)))


class OnePose:
    """Every pair's clearance of ``model`` for one pose: :meth:`values` (internal order; ``[perm]`` gives the
    model's pair order).  Not thread-safe (shared buffers); each model owns one."""

    def __init__(self, model: Model) -> None:
        self.n_pairs = len(model.pair_names)
        self.pose = b""  #: the pose (its bytes) whose points the buffers hold
        self._fk(model)
        pts = _Points()
        cap_pts = [pts.add(f, ends) for f, ends in zip(model._cap_frame, model._cap_local, strict=True)]
        box_corner = [
            pts.add(f, c + _SIGNS * h) for f, c, h in zip(model._box_frame, model._box_c, model._box_h, strict=True)
        ]
        box_centre = [pts.add(f, c)[0] for f, c in zip(model._box_frame, model._box_c, strict=True)]
        sph_pt = [pts.add(BASE_FRAME, c)[0] for c in model._sph_c]
        kb_corner = [pts.add(BASE_FRAME, c + _SIGNS * h) for c, h in zip(model._kb_c, model._kb_h, strict=True)]
        # each joint's origin and the tip of its unit axis (fixed in its child frame): for slopes (joint_points)
        axes = model._K[:, [2, 0, 1], [1, 2, 0]]  # (n, 3): the axes back from their cross-product matrices
        axes = axes / np.linalg.norm(axes, axis=1, keepdims=True)
        self._cap_pts = cap_pts
        self._joint_pts = [pts.add(j + 1, np.array([np.zeros(3), axes[j]])) for j in range(model._n)]
        # (p, q, p2, q2, offset, pair) segment pairs; (p, q, box frame, centre, half, corners, offset, pair) boxes
        seg: list[tuple[Any, ...]] = []
        box: list[tuple[Any, ...]] = []
        table: list[tuple[Any, ...]] = []
        k = 0
        for (u, v), off in zip(model._cc, model._cc_r, strict=True):
            seg.append((*cap_pts[u], *cap_pts[v], float(off), k))
            k += 1
        for (u, b), off in zip(model._cb, model._cb_r, strict=True):
            box.append(
                (*cap_pts[u], int(model._box_frame[b]), model._box_c[b], model._box_h[b], box_corner[b], float(off), k)
            )
            k += 1
        mc, mb = model._mcap.tolist(), model._mbox.tolist()
        if model.world.table:
            for c in mc:
                table.append((cap_pts[c] * 4, float(model._cap_r[c]), k))
                k += 1
            for b in mb:
                table.append((box_corner[b], 0.0, k))
                k += 1
        for s, rad in zip(sph_pt, model._sph_r, strict=True):
            for c in mc:
                seg.append((*cap_pts[c], s, s, float(model._cap_r[c] + rad), k))
                k += 1
            for b in mb:
                frame = int(model._box_frame[b])
                box.append((s, s, frame, model._box_c[b], model._box_h[b], box_corner[b], float(rad), k))
                k += 1
        for corners, c_kb, h_kb in zip(kb_corner, model._kb_c, model._kb_h, strict=True):
            for c in mc:
                box.append((*cap_pts[c], BASE_FRAME, c_kb, h_kb, corners, float(model._cap_r[c]), k))
                k += 1
            for b in mb:  # a moving box against a keep-out box: its bounding sphere (conservative)
                ctr = box_centre[b]
                box.append((ctr, ctr, BASE_FRAME, c_kb, h_kb, corners, float(np.linalg.norm(model._box_h[b])), k))
                k += 1
        assert k == self.n_pairs  # noqa: S101 - the pair lists above follow CollisionModel.pair_names
        self._layout(pts, seg, box, table)

    # -- construction -------------------------------------------------------------------------------------------
    def _fk(self, model: Model) -> None:
        n = self._n = model._n
        T0 = np.zeros((n, 4, 4))
        T0[:, :3, :3], T0[:, :3, 3], T0[:, 3, 3] = model._rot0, model._trans0, 1.0
        Kh, K2h = np.zeros((n, 4, 4)), np.zeros((n, 4, 4))
        Kh[:, :3, :3], K2h[:, :3, :3] = model._K, model._K2
        # local_i = T0_i @ (I + sin q K + (1 - cos q) K^2) = [T0 K | -T0 K^2 | T0 + T0 K^2] @ [sin q, cos q, 1]
        sk, ck = T0 @ Kh, T0 @ K2h
        self._S = np.zeros((n * 16, 2 * n + 1))  # gives each local transform transposed (points are rows)
        for i in range(n):
            rows = slice(16 * i, 16 * i + 16)
            self._S[rows, i], self._S[rows, n + i] = sk[i].T.ravel(), -ck[i].T.ravel()
            self._S[rows, 2 * n] = (T0[i] + ck[i]).T.ravel()
        # the inverse, spin(q)^-1 @ T0_i^-1 = (I - sin q K + (1 - cos q) K^2) @ T0_i^-1, is linear in them too
        T0i = np.linalg.inv(T0)
        ski, cki = Kh @ T0i, K2h @ T0i
        self._Sinv = np.zeros((n * 16, 2 * n + 1))
        for i in range(n):
            rows = slice(16 * i, 16 * i + 16)
            self._Sinv[rows, i], self._Sinv[rows, n + i] = -ski[i].ravel(), -cki[i].ravel()
            self._Sinv[rows, 2 * n] = (T0i[i] + cki[i]).ravel()
        self._v = np.zeros(2 * n + 1)
        self._v[2 * n] = 1.0
        self._local = np.empty((n, 4, 4))  # transposed
        self._local_inv = np.empty((n, 4, 4))
        self._inverse = np.zeros((n + 1, 4, 4))  # frame k's inverse (only those up to the last moving box frame)
        self._inverse[0] = np.eye(4)

    def _layout(
        self, pts: _Points, seg: list[tuple[Any, ...]], box: list[tuple[Any, ...]], table: list[tuple[Any, ...]]
    ) -> None:
        n_pts, n = len(pts.local), self._n
        local = np.array(pts.local, dtype=np.float64).reshape(-1, 3)
        frame = np.array(pts.frame, dtype=np.intp)
        # `_buf` (flat): every point's homogeneous base-frame coordinates (a row of 4 each, the points ordered by
        # frame, last frame first), then its coordinates in each moving box's frame (a row of 3 per such frame)
        moving = sorted({b[2] for b in box} - {BASE_FRAME})
        self._moving, n_mov = moving, len(moving)
        order = np.argsort(-frame, kind="stable")
        rowpos = np.empty(n_pts, dtype=np.intp)
        rowpos[order] = np.arange(n_pts)
        self._buf = np.empty(n_pts * (4 + 3 * n_mov))
        world = self._buf[: 4 * n_pts].reshape(n_pts, 4)
        self._in_frame = self._buf[4 * n_pts :].reshape(n_pts, 3 * n_mov)
        self._inv_rows = np.empty((3 * n_mov, 4))
        # Horner down the chain: the rows on frames >= k go from frame k to frame k - 1 (joint k - 1's transform)
        counts = [int((frame >= k).sum()) for k in range(n, 0, -1)]
        steps = [(k - 1, c) for k, c in zip(range(n, 0, -1), counts, strict=True) if c]
        scratch = np.empty((n_pts, 4))
        bufs = [world, scratch] if len(steps) % 2 == 0 else [scratch, world]
        self._rows_local = np.hstack([local[order], np.ones((n_pts, 1))])  # copied in before each pose
        self._scratch = scratch
        self._steps = [(j, bufs[i % 2][:c], bufs[(i + 1) % 2][:c]) for i, (j, c) in enumerate(steps)]
        self._world = world
        row0 = {BASE_FRAME: 0, **{f: 4 + 3 * j for j, f in enumerate(moving)}}

        def flat(point: np.ndarray, row: int | np.ndarray) -> np.ndarray:  # (3, ...) indices of coordinates
            point = np.asarray(point)
            row = np.broadcast_to(np.asarray(row), point.shape)
            at_base = row == 0
            base = np.where(at_base, rowpos[point] * 4, 4 * n_pts + rowpos[point] * 3 * n_mov + row - 4)
            out: np.ndarray = base[None] + np.arange(3).reshape(3, *([1] * point.ndim))
            return out

        self._Lh = np.vstack([local.T, np.ones(n_pts)])
        # segment pairs: the plain ones; then each box pair's segment against its box's twelve edges
        self._ms, self._mb, self._mt = len(seg), len(box), len(table)
        self._plain = seg_data([s[:4] for s in seg], self._Lh[:3].T, flat)
        edges = [(b[0], b[1], b[5][i], b[5][j]) for b in box for i, j in _EDGES]
        self._edges = seg_data(edges, self._Lh[:3].T, flat)
        self._seg_off = np.array([s[4] for s in seg], dtype=np.float64)
        # box pairs: the segment's ends in the box's frame, minus the box centre
        if box:
            ends = np.array([[b[0], b[1]] for b in box], dtype=np.intp).T  # (2, mb)
            rows = np.array([row0[b[2]] for b in box], dtype=np.intp)
            self._box_idx = flat(ends, rows[None])  # (3, 2, mb)
            self._box_c = np.array([b[3] for b in box], dtype=np.float64).T[:, None, :]  # (3, 1, mb)
            h = np.array([b[4] for b in box], dtype=np.float64).T  # (3, mb)
            self._box_h, self._box_hh = h[:, None, :], np.stack([-h, h])  # (3, 1, mb), (2, 3, mb)
            self._box_off = np.array([b[6] for b in box], dtype=np.float64)
            self._cand = np.zeros((3, len(box)))  # slab parameters tried: 0, 1, the middle of the slab interval
            self._cand[1] = 1.0
        self._bounds(seg, box, row0, flat)
        self._joint_idx = flat(np.array(self._joint_pts, dtype=np.intp).reshape(-1, 2), 0)  # (3, n, 2)
        self._cap_idx = flat(np.array(self._cap_pts, dtype=np.intp).reshape(-1, 2), 0)  # (3, n_caps, 2)
        self._tab_idx = flat(np.array([t[0] for t in table], dtype=np.intp).reshape(-1, 8).T, 0)[2]  # (8, n_table)
        self._tab_r = np.array([t[1] for t in table], dtype=np.float64)
        slots = [s[5] for s in seg] + [b[7] for b in box] + [t[2] for t in table]
        self.perm = np.argsort(np.array(slots, dtype=np.intp))
        self._res = np.empty(self.n_pairs)

    def _bounds(
        self,
        seg: list[tuple[Any, ...]],
        box: list[tuple[Any, ...]],
        row0: dict[int, int],
        flat: Callable[..., np.ndarray],
    ) -> None:
        """Per pair, the four points whose two bounding boxes bound it from below, and the plain-float data of
        its exact measure (:mod:`~retarget.collision.scalar`)."""
        ends = [(s[0], s[1], s[2], s[3]) for s in seg] + [(b[0], b[1], b[5][0], b[5][7]) for b in box]
        rows = [0] * len(seg) + [row0[b[2]] for b in box]
        pts = np.array(ends, dtype=np.intp).reshape(-1, 4).T  # (4, m)
        self._lb_idx = np.ascontiguousarray(np.moveaxis(flat(pts, np.array(rows, dtype=np.intp)[None]), 0, 1))
        self._lb_off = np.concatenate([self._seg_off, np.array([b[6] for b in box], dtype=np.float64)])
        _, _, _, inv_a, inv_e = self._plain[1] if seg else np.zeros((5, 0))
        self._py_seg = [(float(ia), float(ie)) for ia, ie in zip(inv_a, inv_e, strict=True)]
        self._py_box = [(tuple(b[3].tolist()), tuple(b[4].tolist())) for b in box]
        self._py_off: list[float] = self._lb_off.tolist()
        self._reach_for, self._reach_sq = math.nan, self._lb_off
        #: below this least clearance, a box pair whose segment touches the box's bounds may be the least
        self._box_floor = float(-np.min(self._lb_off[len(seg) :], initial=math.inf))

    def joint_points(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """For pose ``q`` (rad): each joint's origin ``(3, n)`` and unit axis ``(3, n)``, and each capsule's two
        ends ``(3, n_caps, 2)``, base frame, metres (from the shared buffers: one forward pass unless they hold
        ``q`` already)."""
        if self.pose != q.tobytes():
            self._frames_and_points(q)
        joints = self._buf.take(self._joint_idx)  # (3, n, 2)
        origin = joints[:, :, 0]
        return origin, joints[:, :, 1] - origin, self._buf.take(self._cap_idx)

    # -- one pose, bounded ---------------------------------------------------------------------------------------
    def _gaps(self) -> tuple[np.ndarray, np.ndarray]:
        """Each non-table pair's four points ``(4, 3, m)`` (the segment's ends, then the other segment's ends or the
        box's least and greatest corner, in the box's frame for a box) and four times the squared gap between the
        two sides' bounding boxes ``(m,)``: the pair's clearance is at least half its root minus the pair's offset
        (a box pair's only while the gap is not 0: a segment inside its box has a depth, of any size)."""
        X = self._buf.take(self._lb_idx)  # (4, 3, m)
        m = X.shape[2]
        Y = np.abs(np.dot(_SPAN, X.reshape(4, -1)))  # |2 (mid1 - mid2)|, |b1 - a1|, |b2 - a2|  (3, 3m)
        gap = np.dot(_GAP, Y)
        np.maximum(gap, 0.0, out=gap)
        gap *= gap
        return X, np.dot(_ONES, gap.reshape(3, m))

    def _table(self) -> float:
        """The least table clearance, metres (inf without the table)."""
        if not self._mt:
            return math.inf
        z = self._buf.take(self._tab_idx)  # (8, n_table): each moving shape's lowest points
        z -= self._tab_r
        return float(z.min())

    def _exact(self, k: int, pts: list[list[float]]) -> float:
        """Pair ``k``'s clearance in plain floats from its four points (as :meth:`_gaps`)."""
        if k < self._ms:
            inv_a, inv_e = self._py_seg[k]
            return segment_segment(pts[0], pts[1], pts[2], pts[3], inv_a, inv_e) - self._py_off[k]
        c, h = self._py_box[k - self._ms]
        pa, pb = pts[0], pts[1]
        u = (pa[0] - c[0], pa[1] - c[1], pa[2] - c[2])
        return segment_box(u, (pb[0] - pa[0], pb[1] - pa[1], pb[2] - pa[2]), h) - self._py_off[k]

    def least(self, q: np.ndarray) -> float:
        """The least clearance over every pair (metres; inf without pairs), exactly ``values(q).min()``: the pairs
        whose bound is below the table's clearance are measured, each while its bound is below the least so far."""
        self._frames_and_points(q)
        best = self._table()
        if not self._lb_off.size:
            return best
        X, gsq = self._gaps()
        lb = np.sqrt(gsq)
        lb *= 0.5
        lb -= self._lb_off
        near = np.flatnonzero(lb < best)
        if near.size:
            bounds = lb.tolist()
            for k, p in zip(near.tolist(), X.transpose(2, 0, 1)[near].tolist(), strict=True):
                if bounds[k] < best:
                    best = min(best, self._exact(k, p))
        if best <= self._box_floor:  # a box pair whose segment touches the box's bounds may be deeper still
            touch = np.flatnonzero(gsq[self._ms :] == 0.0) + self._ms
            for k, p in zip(touch.tolist(), X.transpose(2, 0, 1)[touch].tolist(), strict=True):
                best = min(best, self._exact(k, p))
        return best

    def clear(self, q: np.ndarray, clearance: float) -> bool:
        """True when every pair keeps ``clearance`` metres: only pairs whose bound is below it are measured."""
        self._frames_and_points(q)
        if self._table() < clearance:
            return False
        if not self._lb_off.size:
            return True
        if clearance != self._reach_for:
            reach = clearance + self._lb_off
            self._reach_sq = np.where(reach > 0, 4.0 * reach * reach, -1.0)
            self._reach_sq[self._ms :] = np.maximum(self._reach_sq[self._ms :], 0.0)  # a box: its depth
            self._reach_for = clearance
        X, gsq = self._gaps()
        near = np.flatnonzero(gsq <= self._reach_sq)
        if not near.size:
            return True
        pts = X.transpose(2, 0, 1)[near].tolist()
        return all(self._exact(k, p) >= clearance for k, p in zip(near.tolist(), pts, strict=True))

    def bounds(self, q: np.ndarray, reach: float) -> np.ndarray:
        """Lower bounds of every pair's clearance, metres, in the internal order (a shared buffer: copy it at once):
        exact for each pair whose bounding-box bound is below ``reach`` (and every table pair), at least ``reach``
        for the others.  Cheaper than :meth:`values` when few pairs come near ``reach``."""
        self._frames_and_points(q)
        res, ms, mb = self._res, self._ms, self._mb
        if self._mt:
            np.subtract(self._buf.take(self._tab_idx).min(axis=0), self._tab_r, out=res[ms + mb :])
        if self._lb_off.size:
            X, gsq = self._gaps()
            lb = res[: ms + mb]
            np.sqrt(gsq, out=lb)
            lb *= 0.5
            lb -= self._lb_off  # a box pair whose segment touches its box has gap 0: below reach, measured
            near = np.flatnonzero(lb < reach)
            if near.size:
                for k, p in zip(near.tolist(), X.transpose(2, 0, 1)[near].tolist(), strict=True):
                    res[k] = self._exact(k, p)
        return res

    # -- one pose -----------------------------------------------------------------------------------------------
    def values(self, q: np.ndarray, cutoff: float | None = None) -> np.ndarray:
        """Every pair's clearance, metres, in the internal order (a shared buffer: copy or reduce it at once).

        With ``cutoff`` (metres), box pairs are exact only when some box pair may come closer than ``min(cutoff,
        every other pair)``; otherwise they hold a lower bound (the gap between the segment's bounding box and
        the box) that is at least that, so the minimum over all pairs is still exact (when below ``cutoff``).
        """
        self._frames_and_points(q)
        buf, res, ms, mb = self._buf, self._res, self._ms, self._mb
        if ms:
            np.subtract(segments(buf, *self._plain), self._seg_off, out=res[:ms])
        if self._mt:
            np.subtract(buf.take(self._tab_idx).min(axis=0), self._tab_r, out=res[ms + mb :])
        if mb:
            ab = buf.take(self._box_idx)
            ab -= self._box_c  # (3, 2, mb) the segment's ends in the box's frame, from the box centre
            box = res[ms : ms + mb]
            if cutoff is not None:
                reach = min(cutoff, float(res[:ms].min(initial=cutoff)), float(res[ms + mb :].min(initial=cutoff)))
                gap = np.maximum(np.maximum(ab.min(axis=1), -ab.max(axis=1)) - self._box_h[:, 0], 0.0)
                gap *= gap
                gap = gap[0] + gap[1] + gap[2]
                np.subtract(np.sqrt(gap), self._box_off, out=box)
                if box.min() >= reach and gap.min() > 0.0:  # (a segment touching its box: depth needed)
                    return res
            edge = segments(buf, *self._edges).reshape(mb, len(_EDGES)).min(axis=1)
            np.subtract(
                np.minimum(boxes(ab, self._box_hh, self._box_h, self._cand), edge, out=edge), self._box_off, out=box
            )
        return res

    def _frames_and_points(self, q: np.ndarray) -> None:
        """Every point in the base frame and in each moving box's frame (``_buf``), by Horner down the chain."""
        self.pose = q.tobytes()  # what `_buf` holds now
        n, L, v = self._n, self._local, self._v
        np.sin(q, out=v[:n])
        np.cos(q, out=v[n : 2 * n])
        np.dot(self._S, v, out=L.reshape(-1))
        np.copyto(self._world, self._rows_local)  # each step's newly included rows must hold local coordinates
        np.copyto(self._scratch, self._rows_local)
        for j, src, dst in self._steps:
            np.dot(src, L[j], out=dst)
        if self._moving == [1]:  # (the usual case: a box on the first joint's frame, the inverse of its local)
            np.dot(self._Sinv[:16], v, out=self._local_inv[0].reshape(-1))
            np.dot(self._world, self._local_inv[0, :3].T, out=self._in_frame)
        elif self._moving:  # frame k's inverse: local_{k-1}^-1 @ ... @ local_0^-1
            G, Li = self._inverse, self._local_inv
            np.dot(self._Sinv, v, out=Li.reshape(-1))
            G[1] = Li[0]
            for i in range(1, self._moving[-1]):
                Li[i].dot(G[i], out=G[i + 1])
            rows = self._inv_rows
            for j, f in enumerate(self._moving):
                rows[3 * j : 3 * j + 3] = G[f, :3]
            np.dot(self._world, rows.T, out=self._in_frame)
