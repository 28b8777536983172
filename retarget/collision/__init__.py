"""Collision safety: link shapes, the world (table, keep-out zones) and vectorised clearance queries.

- :mod:`~retarget.collision.shapes`: :class:`Capsule`, :class:`Box`, :class:`Sphere`, :class:`LinkShape`,
  :class:`Geometry` (an arm's shapes and allowed pairs), :class:`World`, :data:`DEFAULT_CLEARANCE`;
- :mod:`~retarget.collision.distance`: segment/segment, segment/box, point/segment, point/box distances;
- :mod:`~retarget.collision.model`: :class:`CollisionModel` (every pair's clearance for one pose or many,
  joint-space moves) and :class:`SegmentCheck`; the pair count and what a check costs are in its docstring;
- :mod:`~retarget.collision.fast` (the one-pose path: bounds, then exact measures of the pairs within reach),
  :mod:`~retarget.collision.kernels` (its numpy kernels), :mod:`~retarget.collision.scalar` (plain-float
  kernels), :mod:`~retarget.collision.points` (target points against the blocked zones);
- :mod:`~retarget.collision.levers` (how fast each pair can close per radian of each joint) and
  :mod:`~retarget.collision.pieces` (long moving capsules cut into pieces): the data of
  :class:`~retarget.ik.bound.ClearanceBound`, the lower bound that spares most checks a query.

A math package: it imports no driver, simulator or serial code.

>>> import retarget
>>> model = CollisionModel.for_arm(retarget.load_arm("wx250s"))
>>> model.is_clear(model.arm.rest)
True
"""

from retarget.collision.shapes import (
    BASE_FRAME,
    DEFAULT_CLEARANCE,
    TABLE,
    Box,
    Capsule,
    Geometry,
    KeepOut,
    LinkShape,
    Sphere,
    World,
)

from retarget.collision.model import FALLBACK_RADIUS, CollisionModel, SegmentCheck, fallback_geometry  # isort: skip

__all__ = [
    "BASE_FRAME",
    "DEFAULT_CLEARANCE",
    "FALLBACK_RADIUS",
    "TABLE",
    "Box",
    "Capsule",
    "CollisionModel",
    "Geometry",
    "KeepOut",
    "LinkShape",
    "SegmentCheck",
    "Sphere",
    "World",
    "fallback_geometry",
]
