"""Long moving capsules cut into pieces, for sharper bounds of how fast a pair can close (:class:`Pieces`).

A pair's lever about a joint (:mod:`~retarget.collision.levers`) is set by the mover's farthest point from the
joint, but the point nearest the other shape is often its near end: the upper arm's foot sits on the shoulder
axis, just above the base, while its far end swings 0.2 m from it.  Cut the mover's segment into pieces: the
pair's distance is the least of its pieces' distances, and each piece closes at most as fast as its own
(smaller) levers allow, so ``min_i (d_i - L_i . |dq|)`` bounds the pair from below, much closer to the truth
when the near piece is the slow one.  Measuring the pieces costs a few plain-float distances, so only the pairs
that come within :attr:`Pieces.reach` are measured, and cheaply: a piece is at least as far as its middle's
distance less half its length, and at least as far as its whole pair; a farther pair gives each piece the pair's
own lower bound.

Rows: the pairs that are not cut (in ``pair_names`` order), then the pieces of the cut ones; ``levers``
``(n_rows, n_joints)`` metres per radian, ``pair_of`` ``(n_rows,)`` the pair index of each row.

>>> import retarget
>>> from retarget.collision import CollisionModel
>>> model = CollisionModel.for_arm(retarget.load_arm("wx250s"))
>>> pieces = Pieces(model)
>>> home = model.arm.home
>>> rows = pieces.rows(home, model.distances(home))
>>> bool(abs(rows.min() - model.distances(home).min()) < 1e-12), len(rows) > len(model.pair_names)
(True, True)
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from retarget.collision.levers import pair_levers
from retarget.collision.scalar import point_box

if TYPE_CHECKING:
    from retarget.collision.model import CollisionModel

__all__ = ["PIECE", "Pieces"]

#: metres: a capsule segment at least twice this long is cut into pieces about this long
PIECE = 0.04
#: metres beyond the clearance within which a cut pair's pieces are measured
REACH = 0.05


class Pieces:
    """The rows of a :class:`~retarget.ik.bound.ClearanceBound` of ``model``: its pairs, the long movers cut."""

    def __init__(self, model: CollisionModel, *, length: float = PIECE, reach: float = REACH):
        self.model = model
        self.reach = float(model.clearance + reach)  #: metres: pairs below this are measured piece by piece
        one = model._one
        n_cc, n_cb = len(model._cc), len(model._cb)
        #: per cut pair: (pair, internal index, kind 0 segment / 1 box, mover slot 0 / 1, [(t0, t1), ...], its rows)
        self._cut: list[tuple[int, int, int, int, list[tuple[float, float]], slice]] = []
        movers: list[tuple[int, np.ndarray]] = []
        for k in range(len(model.pair_names)):
            spec = self._mover(model, k, n_cc, n_cb)
            if spec is None:
                continue
            kind, slot, cap = spec
            a, b = model._cap_local[cap]
            count = math.floor(float(np.linalg.norm(b - a)) / length)
            if count < 2:
                continue
            spans = [(i / count, (i + 1) / count) for i in range(count)]
            self._cut.append((k, int(one.perm[k]), kind, slot, spans, slice(len(movers), len(movers) + count)))
            movers += [(k, np.array([a + t0 * (b - a), a + t1 * (b - a)])) for t0, t1 in spans]
        cut = {c[0] for c in self._cut}
        whole = [k for k in range(len(model.pair_names)) if k not in cut]
        w = len(whole)
        self._cut = [
            (k, kk, kind, slot, spans, slice(r.start + w, r.stop + w)) for k, kk, kind, slot, spans, r in self._cut
        ]
        self._whole = np.array(whole, dtype=np.intp)
        self.pair_of = np.array(whole + [k for k, _ in movers], dtype=np.intp)
        levers = pair_levers(model)
        self.levers: np.ndarray = np.vstack([levers[whole], pair_levers(model, movers)]) if movers else levers[whole]

    @staticmethod
    def _mover(model: CollisionModel, k: int, n_cc: int, n_cb: int) -> tuple[int, int, int] | None:
        """(kind, slot, capsule index) of pair ``k``'s mover when it is a capsule the one-pose path measures as a
        segment against a segment (kind 0; slot: first or second of its four points) or a box (kind 1)."""
        frames = model._cap_frame
        if k < n_cc:
            u, v = (int(x) for x in model._cc[k])
            if frames[u] == frames[v]:
                return None
            return (0, 0, u) if frames[u] > frames[v] else (0, 1, v)
        if k < n_cc + n_cb:
            cap, box = (int(x) for x in model._cb[k - n_cc])
            return (1, 0, cap) if frames[cap] > model._box_frame[box] else None
        k -= n_cc + n_cb
        mc, mb = model._mcap.tolist(), model._mbox.tolist()
        shapes = len(mc) + len(mb)
        if model.world.table:
            if k < shapes:
                return None  # the table: its distance is its lowest end's, a piece gains nothing
            k -= shapes
        n_sph = len(model._sph_r)
        zone, i = divmod(k, shapes)
        if i >= len(mc):
            return None  # a moving box against a zone
        return (0, 0, mc[i]) if zone < n_sph else (1, 0, mc[i])

    def rows(self, q: np.ndarray | list[float], distances: np.ndarray) -> np.ndarray:
        """Every row's distance (a lower bound; metres) in pose ``q`` (rad), given every pair's (lower bounds of
        them will do; exact below :attr:`reach` for the pieces to gain): a cut pair's pieces are measured when it
        is below :attr:`reach`, else each takes the pair's."""
        d = np.asarray(distances, dtype=np.float64)
        out = d[self.pair_of]  # each row its pair's, then the pieces of the pairs within reach measured
        reach = self.reach
        near = [(c, float(d[c[0]])) for c in self._cut if d[c[0]] < reach]
        if not near:
            return out
        one = self.model._one
        pose = np.asarray(q, dtype=np.float64)
        if one.pose != pose.tobytes():
            one._frames_and_points(pose)
        buf, idx = one._buf, one._lb_idx
        for (_, kk, kind, slot, spans, rows), floor in near:
            pts = buf.take(idx[:, :, kk]).tolist()  # (4, 3): the pair's four points
            out[rows] = self._measure(kk, kind, slot, spans, pts, floor)
        return out

    def _measure(
        self, kk: int, kind: int, slot: int, spans: list[tuple[float, float]], pts: list[list[float]], floor: float
    ) -> list[float]:
        """A lower bound of the clearance of each piece of internal pair ``kk`` from its four points (as
        ``OnePose._gaps``): its middle's distance to the other shape less half its length (every point of the
        piece is within that of its middle), and at least ``floor`` (the pair's own bound)."""
        one = self.model._one
        off = one._py_off[kk]
        pa, pb = (pts[0], pts[1]) if slot == 0 else (pts[2], pts[3])
        dx, dy, dz = pb[0] - pa[0], pb[1] - pa[1], pb[2] - pa[2]
        length = math.sqrt(dx * dx + dy * dy + dz * dz)
        out = []
        if kind == 0:  # the other shape is a segment (or a point)
            oa, ob = (pts[2], pts[3]) if slot == 0 else (pts[0], pts[1])
            ex, ey, ez = ob[0] - oa[0], ob[1] - oa[1], ob[2] - oa[2]
            ee = ex * ex + ey * ey + ez * ez
            for t0, t1 in spans:
                t = 0.5 * (t0 + t1)
                rx, ry, rz = pa[0] + t * dx - oa[0], pa[1] + t * dy - oa[1], pa[2] + t * dz - oa[2]
                s = (rx * ex + ry * ey + rz * ez) / ee if ee > 0.0 else 0.0
                s = 0.0 if s < 0.0 else 1.0 if s > 1.0 else s
                gx, gy, gz = rx - s * ex, ry - s * ey, rz - s * ez
                v = math.sqrt(gx * gx + gy * gy + gz * gz) - off - 0.5 * (t1 - t0) * length
                out.append(v if v > floor else floor)
            return out
        c, h = one._py_box[kk - one._ms]
        for t0, t1 in spans:
            t = 0.5 * (t0 + t1)
            v = point_box(pa[0] + t * dx - c[0], pa[1] + t * dy - c[1], pa[2] + t * dz - c[2], h)
            v -= off + 0.5 * (t1 - t0) * length
            out.append(v if v > floor else floor)
        return out
