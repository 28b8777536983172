"""Guess a skeleton's length unit from its size: :class:`UnitsGuess`, :func:`guess_units`, :func:`units_for_height`.

A human of 1.2-2.3 m is assumed.  The height measured is the rest pose's extent when it agrees with the height
from the bone lengths (:func:`~retarget.bvh.proportions.height_from_bones`), else the motion's when that agrees,
else the height from the bone lengths itself.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class UnitsGuess:
    """What a skeleton's size suggests about its length unit.

    ``unit`` is ``"m"``, ``"cm"``, ``"mm"``, ``"in"`` or ``"unknown"``;
    ``height`` is the standing height in file units, measured as ``basis``
    says: ``"rest pose"`` (the rest pose's extent along ``up_axis``),
    ``"motion"`` (the median extent over the frames) or ``"bone lengths"``
    (:func:`~retarget.bvh.proportions.height_from_bones`); ``metres_per_unit``
    is the scale that makes the skeleton 1.7 m tall when the unit is unknown,
    else the unit's exact size.
    """

    unit: str
    height: float
    up_axis: str
    metres_per_unit: float
    basis: str = "rest pose"


_UNITS = (("m", 1.0, 1.2, 2.3), ("cm", 0.01, 120.0, 230.0), ("mm", 0.001, 1200.0, 2300.0), ("in", 0.0254, 45.0, 90.0))
#: A measured extent counts as the standing height when within this factor of the height from bone lengths.
HEIGHT_AGREEMENT = 1.6


def _extent(extent: np.ndarray) -> tuple[float, int]:
    """``(height, up axis index)`` of an ``(3,)`` extent: Y unless much flatter than Z."""
    up = 1 if extent[1] >= 0.5 * extent.max() or extent[1] >= extent[2] else 2
    return float(extent[up]), up


def units_for_height(height: float, up_axis: str = "Y", basis: str = "rest pose") -> UnitsGuess:
    """The unit that makes ``height`` (file units) a human of 1.2-2.3 m, else ``"unknown"``.

    >>> units_for_height(172.0).unit, units_for_height(21.0).unit
    ('cm', 'unknown')
    """
    for unit, size, low, high in _UNITS:
        if low <= height <= high:
            return UnitsGuess(unit, height, up_axis, size, basis)
    return UnitsGuess("unknown", height, up_axis, 1.7 / height if height > 0 else 1.0, basis)


def guess_units(
    rest_points: np.ndarray, *, bone_height: float | None = None, frames: np.ndarray | None = None
) -> UnitsGuess:
    """Guess the unit from ``rest_points`` ``(n, 3)`` (joints and End Sites, rest pose, file units).

    Up is Y (the BVH convention) unless the skeleton is much flatter along Y
    than along Z.  A human of 1.2-2.3 m is assumed.  With ``bone_height`` (the
    height from bone lengths, :func:`~retarget.bvh.proportions.height_from_bones`),
    the rest pose's extent counts only when within a factor :data:`HEIGHT_AGREEMENT`
    (1.6) of it: a zero-rotation pose need not be upright (LAFAN lays every bone
    along X).  Then the median extent over ``frames`` ``(n_frames, n, 3)`` is
    tried the same way, and last ``bone_height`` itself.

    >>> lying = np.array([[0.0, 0, 0], [170.0, 10, 15]])   # 170 cm along X, 10 along Y
    >>> guess_units(lying).unit
    'unknown'
    >>> guess = guess_units(lying, bone_height=165.0)
    >>> guess.unit, guess.height, guess.basis
    ('cm', 165.0, 'bone lengths')
    """
    pts = np.asarray(rest_points, dtype=np.float64).reshape(-1, 3)
    if pts.shape[0] == 0:
        return UnitsGuess("unknown", 0.0, "Y", 1.0)
    height, up = _extent(pts.max(axis=0) - pts.min(axis=0))
    if bone_height is None or _agrees(height, bone_height):
        return units_for_height(height, "XYZ"[up])
    axis = "Y"
    if frames is not None and np.asarray(frames).size:
        f = np.asarray(frames, dtype=np.float64)
        moving, moving_up = _extent(np.median(f.max(axis=1) - f.min(axis=1), axis=0))
        axis = "XYZ"[moving_up]
        if _agrees(moving, bone_height):
            return units_for_height(moving, axis, "motion")
    return units_for_height(float(bone_height), axis, "bone lengths")


def _agrees(measured: float, bone_height: float) -> bool:
    return measured > 0 and bone_height > 0 and max(measured / bone_height, bone_height / measured) <= HEIGHT_AGREEMENT
