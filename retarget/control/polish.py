"""The look-ahead IK pass's last step, batched: one damped least squares step on every tick at once.

:func:`~retarget.control.plan.solve_and_plan` solves a clip's ticks one by one, warm-started.  The solver's
early-out leaves each tick anywhere within its tolerance (1 mm), so the error saws from tick to tick and joints the
plan passes through unchanged jerk with it.  Solving each tick to 0.3 of the tolerance cures that with 28 % more
sweeps (motion_dance left, wx250s: 2 219 against 1 734; the IK pass's CPU time ~8 % more), and a rig's IK pass did
not.  Here the pass solves to the solver's own tolerance and :class:`Polish` then takes one more DLS step on every
converged tick together (:mod:`~retarget.ik.dls`'s step, ``dq = W J' (J W J' + lambda^2 I)^-1 (t -
e)``, with the Jacobians the plan needs anyway): the error left is the step's linearisation error, microns.

Ticks the step would not be safe on keep their IK pose: one the solver did not converge or stopped short of a
collision on, one whose clearance is within :data:`CLEARANCE_MARGIN` of the model's, and one whose target is within
the solver's ``base_radius`` of the base axis (the solver damps the waist there on purpose).  Pure numpy.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from retarget.ik.result import IKResult

__all__ = ["CLEARANCE_MARGIN", "Polish"]

Array = npt.NDArray[np.float64]

#: metres above the collision model's clearance a tick's IK pose must keep to be polished: twice the largest
#: step (the tolerance, 1 mm) the polish moves the tool point by
CLEARANCE_MARGIN = 2e-3


@dataclass(frozen=True)
class Polish:
    """What the step takes from the IK solver: the per-joint ``weights`` ``(n_joints,)`` (0 locks a joint), the
    ``damping`` (lambda, metres), the base axis's ``base_pivot`` ``(3,)`` m and ``base_radius`` m (0: none), and
    the collision model's clearance in metres (None: no model).

    >>> import retarget
    >>> from retarget.ik import CCDSolver
    >>> arm = retarget.load_arm("wx250s")
    >>> polish = Polish.of(CCDSolver(arm))
    >>> polish is not None and polish.damping
    0.01
    """

    weights: Array
    damping: float
    base_pivot: Array
    base_radius: float
    clearance: float | None

    @classmethod
    def of(cls, solver: object) -> Polish | None:
        """The polish of a :class:`~retarget.ik.CCDSolver`-like ``solver``; None when it lacks a member."""
        try:
            weights, damping = solver.weights, solver.damping  # type: ignore[attr-defined]
            pivot, radius = solver.base_pivot, solver.base_radius  # type: ignore[attr-defined]
        except AttributeError:
            return None
        model = getattr(solver, "collision", None)
        clearance = None if model is None else float(model.clearance)
        w = np.asarray(weights, dtype=np.float64)
        return cls(w, float(damping), np.asarray(pivot, dtype=np.float64), float(radius), clearance)

    def safe(self, results: Sequence[IKResult], targets: Array) -> npt.NDArray[np.bool_]:
        """``(n,)``: the ticks the step may move (see the module docstring), of the IK ``results`` for the
        ``targets`` ``(n, 3)`` m."""
        ok = np.array([r.converged and not r.blocked and r.error > 0.0 for r in results], dtype=bool)
        if self.clearance is not None:
            clear = np.array([r.clearance for r in results], dtype=np.float64)
            ok &= ~(clear < self.clearance + CLEARANCE_MARGIN)  # (nan: unknown, the model did not measure it)
        if self.base_radius > 0.0:
            off_axis = np.hypot(*(targets[:, :2] - self.base_pivot[:2]).T)
            ok &= off_axis >= self.base_radius
        return ok

    def step(
        self, q: Array, jacobians: Array, residuals: Array, ok: npt.NDArray[np.bool_], lower: Array, upper: Array
    ) -> tuple[Array, Array]:
        """The poses ``q`` ``(n, n_joints)`` rad after one DLS step on the ticks ``ok`` ``(n,)``, within ``lower``
        .. ``upper``, and their residuals ``(n, 3)`` m, linearised: ``residuals`` (tool point minus target) plus
        ``jacobians`` ``(n, 3, n_joints)`` times the step.  The other ticks are returned as they are."""
        q, residuals = q.copy(), residuals.copy()
        J, r = jacobians[ok], residuals[ok]
        JW = J * self.weights
        A = JW @ J.transpose(0, 2, 1)
        A[:, np.arange(3), np.arange(3)] += self.damping * self.damping
        x = np.linalg.solve(A, -r[:, :, None])[:, :, 0]
        moved = np.clip(q[ok] + np.einsum("tdj,td->tj", JW, x), lower, upper)
        residuals[ok] = r + np.einsum("tdj,tj->td", J, moved - q[ok])
        q[ok] = moved
        return q, residuals
