"""How fast each pair of a :class:`~retarget.collision.model.CollisionModel` can close per radian of each joint.

A pair of shapes on frames ``a < b`` (a zone of the world is on the base frame, 0) keeps a distance that depends
only on joints ``a .. b-1``.  When joint ``j`` alone turns by ``dq``, the two shapes turn one against the other
about joint ``j``'s axis, so their distance changes by at most ``|dq|`` times the greatest distance from that axis
of either shape's points (whichever is smaller: the motion is relative; a capsule's points are those of its
segment, since its radius is a constant offset of the distance, and a box's are its corners).  Those distances
are bounded whatever the other joints do:

- the mover (the shape on frame ``b``) about the last joint ``b - 1``: exactly, the axis is fixed in frame ``b``;
  about an earlier joint ``j``: at most ``r_j + |o_{j+2}| + ... + |o_{b-1}| + |p|`` (the joint origins' offsets
  ``o`` along the chain, ``p`` in frame ``b``, and ``r_j`` the distance of the next joint's origin from joint
  ``j``'s axis, exact: both are fixed in frame ``j + 1``; 0 for a shoulder above a turntable);
- the other shape (on frame ``a``) about the first joint ``a``: exactly, the axis is fixed in frame ``a``; about
  a later one ``j``: at most ``|p - o_a| + |o_{a+1}| + ... + |o_j|``;
- the table plane is unbounded, but a turn about an axis normal to it (a turntable's) does not move a shape
  toward it: its lever is ``|n x k|`` times the mover's.

Turning the joints one at a time from one pose to another, a pair's distance falls by at most
``sum_j |dq_j| L_j`` (:func:`pair_levers`, ``L`` in metres per radian): the bound of
:class:`~retarget.ik.bound.ClearanceBound`.

>>> import retarget
>>> from retarget.collision import CollisionModel
>>> model = CollisionModel.for_arm(retarget.load_arm("wx250s"))
>>> levers = pair_levers(model)
>>> levers.shape == (len(model.pair_names), model.arm.n_joints)
True
>>> float(levers[model.pair_names.index("fingers/table"), 0])  # the waist turns about the table's normal
0.0
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from retarget.arm.kinematics import rpy_matrix
from retarget.collision.shapes import BASE_FRAME, TABLE, Box, Capsule, Sphere

if TYPE_CHECKING:
    from retarget.collision.model import CollisionModel

__all__ = ["pair_levers"]

_ORIGIN = np.zeros(3)

_SIGNS = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=np.float64)


def _points(shape: object) -> np.ndarray:
    """``(k, 3)`` the points whose farthest from any line or point is the shape's (its radius aside)."""
    if isinstance(shape, Capsule):
        return np.array([shape.a, shape.b], dtype=np.float64)
    if isinstance(shape, Box):
        return np.asarray(shape.center, dtype=np.float64) + _SIGNS * np.asarray(shape.half_size, dtype=np.float64)
    if isinstance(shape, Sphere):
        return np.array([shape.center], dtype=np.float64)
    raise TypeError(f"Expected a Capsule, Box or Sphere, got {shape!r}")


def _from_axis(points: np.ndarray, origin: np.ndarray, axis: np.ndarray) -> float:
    """The greatest distance (metres) of ``points`` ``(k, 3)`` from the line through ``origin`` along ``axis``."""
    kx, ky, kz = (float(c) for c in axis)
    norm = math.sqrt(kx * kx + ky * ky + kz * kz)
    kx, ky, kz = kx / norm, ky / norm, kz / norm
    ox, oy, oz = (float(c) for c in origin)
    far = 0.0
    for x, y, z in points.tolist():
        rx, ry, rz = x - ox, y - oy, z - oz
        t = rx * kx + ry * ky + rz * kz
        far = max(far, math.sqrt(max(rx * rx + ry * ry + rz * rz - t * t, 0.0)))
    return far


def _from_point(points: np.ndarray, origin: np.ndarray) -> float:
    """The greatest distance (metres) of ``points`` ``(k, 3)`` from ``origin``."""
    ox, oy, oz = (float(c) for c in origin)
    return max(math.dist((x, y, z), (ox, oy, oz)) for x, y, z in points.tolist())


def pair_levers(model: CollisionModel, movers: list[tuple[int, np.ndarray]] | None = None) -> np.ndarray:
    """``(n_pairs, n_joints)`` metres per radian, pairs as ``model.pair_names``: how fast each pair's distance can
    fall per radian of each joint, whatever the pose (see the module docstring).  ``movers``: for some pairs (by
    index, one row each in that order), the points ``(k, 3)`` to take for the mover instead of its whole shape (a
    piece of its segment)."""
    arm = model.arm
    hops = [float(np.linalg.norm(j.origin_xyz)) for j in arm.joints]  # joint k's origin in frame k
    trans = [np.asarray(j.origin_xyz, dtype=np.float64) for j in arm.joints]
    axes = [np.asarray(j.axis, dtype=np.float64) for j in arm.joints]  # in the joint's child frame
    parent_axes = [rpy_matrix(j.origin_rpy) @ k for j, k in zip(arm.joints, axes, strict=True)]  # in its parent's
    shapes: dict[str, tuple[int, object]] = {link.name: (link.frame, link.shape) for link in model.geometry.links}
    shapes.update({name: (BASE_FRAME, zone) for name, zone in zip(model.world.zone_names(), model.world.keep_out,
                                                                  strict=True)})  # fmt: skip
    # the next joint's origin, from joint j's axis (both fixed in frame j + 1): what the chain adds to the reach
    hop_off = [_from_axis(trans[j + 1][None], _ORIGIN, axes[j]) for j in range(arm.n_joints - 1)]
    rows = [(k, None) for k in range(len(model.pair_names))] if movers is None else movers
    levers = np.zeros((len(rows), arm.n_joints))
    cache: dict[tuple[object, ...], float] = {}  # shapes recur across pairs: their distances once each
    points_of: dict[str, np.ndarray] = {}

    def shape_points(key: str, shape: object) -> np.ndarray:
        if key not in points_of:
            points_of[key] = _points(shape)
        return points_of[key]

    def axis_reach(key: object, pts: np.ndarray, origin: np.ndarray, axis: np.ndarray) -> float:
        if (key, "axis") not in cache:
            cache[(key, "axis")] = _from_axis(pts, origin, axis)
        return cache[(key, "axis")]

    def point_reach(key: object, pts: np.ndarray, origin: np.ndarray) -> float:
        if (key, "point") not in cache:
            cache[(key, "point")] = _from_point(pts, origin)
        return cache[(key, "point")]

    for row, (k, points) in enumerate(rows):
        name = model.pair_names[k]
        u, v = name.split("/")
        fu, su = shapes[u] if u != TABLE else (BASE_FRAME, None)
        fv, sv = shapes[v] if v != TABLE else (BASE_FRAME, None)
        (a, other, oname), (b, mover, mname) = sorted([(fu, su, u), (fv, sv, v)], key=lambda fs: fs[0])
        if mover is None:  # (the table is on the base frame: never the mover of a pair with a moving shape)
            raise ValueError(f"Expected a moving shape in pair {name!r}")
        mkey: object = mname if points is None else (row, "piece")
        mp = shape_points(mname, mover) if points is None else points
        op = None if other is None else shape_points(oname, other)
        for j in range(a, b):
            if j == b - 1:
                own = axis_reach(mkey, mp, _ORIGIN, axes[j])
            else:
                own = hop_off[j] + sum(hops[j + 2 : b]) + point_reach(mkey, mp, _ORIGIN)
            if op is None:  # the table: only a turn that tilts the mover toward its normal counts
                tilt = float(np.linalg.norm(np.cross([0.0, 0.0, 1.0], parent_axes[j]))) if j == BASE_FRAME else 1.0
                levers[row, j] = min(1.0, tilt) * own
                continue
            if j == a:
                far = axis_reach((oname, a), op, trans[a], parent_axes[a])
            else:
                far = point_reach((oname, a), op, trans[a]) + sum(hops[a + 1 : j + 1])
            levers[row, j] = min(own, far)
    if not np.all(np.isfinite(levers)):
        raise ValueError(f"Expected finite levers, got {levers!r}")
    return levers
