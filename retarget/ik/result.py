"""The outcome of one IK solve: :class:`IKResult` (its own module, so the solver and its collision check share it)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["IKResult"]


@dataclass(eq=False, slots=True)
class IKResult:
    """The outcome of one solve.

    ``q``: ``(n_joints,)`` float64 radians, always inside the limits;
    ``error``: distance tool point -> target, metres;
    ``iterations``: sweeps run (0 when the start was already within tolerance);
    ``converged``: ``error <= tolerance`` (and, with a rotation target, ``orientation_error <=
    orientation_tolerance``); ``orientation_error``: radians, ``nan`` without a rotation target;
    ``restarts``: seeds tried after stalls.  With a collision model (``CCDSolver(collision=...)``):
    ``blocked`` when no clear pose reached the target (``q`` is then the nearest clear pose found, see
    :mod:`~retarget.ik.collide`), ``clearance`` metres, the pose's min clearance or a lower bound of it (``nan``
    without a model).

    A result to read, not to change.  It is not frozen: a solve builds one per tick, and a frozen dataclass takes
    ~5x as long to build (2 us against 0.4 us, a twentieth of a warm solve).
    """

    q: np.ndarray
    error: float
    iterations: int
    converged: bool
    orientation_error: float = math.nan
    restarts: int = 0
    blocked: bool = False
    clearance: float = math.nan
