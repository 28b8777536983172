"""Collision-aware IK: the :class:`~retarget.ik.ccd.CCDSolver`'s pose verified against a collision model.

A solver built with ``collision=model`` (a :class:`~retarget.collision.CollisionModel`) never returns a pose
closer than ``model.clearance`` to a collision (link-link, link-table, link-keep-out)
unless no such pose was found from the seed (then ``blocked``).  The fast path costs one check:

1. solve as without a model, then check the final pose once (``model.min_clearance``);
2. only when it is not clear, **back off** (of the free solutions for points spaced along the line from the
   seed's tool point to the target, the farthest whose pose is clear), then **re-solve from there with
   per-joint shortening**: base first, each joint
   takes its CCD update (the same closed-form minimiser, weights and short-lever damping), clamped to the
   limits, and when the pose it leads to is not clear the step is **shortened** to the longest clear one of
   its halvings (``bisections`` of them), the way a joint limit clamps it;
3. the re-solve ends at the target (converged, clear), or where no joint can bring the tool closer: the
   nearest safe pose found, reported ``converged=False, blocked=True`` in the :class:`~retarget.ik.IKResult`.

A seed that is itself not clear starts the re-solve from the first clear pose of (seed, home, rest); when none
is clear the seed comes back, ``blocked``, and the caller (the control loop) refuses to send it.  Orientation
targets re-solve a sweep at a time: each sweep's step is bisected as a whole (a straight line in joint space).

Arrays: ``q`` ``(n_joints,)`` float64 radians; targets ``(3,)`` metres, base frame.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from retarget.ik.bound import HORIZON, shared_bound
from retarget.ik.result import IKResult

if TYPE_CHECKING:
    from retarget.arm.model import Arm
    from retarget.collision import CollisionModel


class Solver(Protocol):
    """What the guard uses of :class:`~retarget.ik.ccd.CCDSolver` (its bounds, buffers and free solve); a
    protocol, so this module does not import the solver's (which imports this one)."""

    arm: Arm
    n: int
    weights: tuple[float, ...]
    _lo: tuple[float, ...]
    _hi: tuple[float, ...]
    _lever2: float
    _px: list[float]
    _py: list[float]
    _pz: list[float]
    _ax: list[float]
    _ay: list[float]
    _az: list[float]

    def _fk(self, q: list[float]) -> tuple[float, ...]: ...

    def tool_point(self, q: Sequence[float] | np.ndarray) -> tuple[float, float, float]: ...

    def _solve_free(
        self,
        target: Sequence[float] | np.ndarray,
        q0: Sequence[float] | np.ndarray,
        rotation: np.ndarray | None = None,
        *,
        tolerance: float | None = None,
        max_iterations: int | None = None,
        max_step: Any = ...,
    ) -> IKResult: ...


__all__ = ["CollisionGuard"]


_EPS2 = 1e-16  #: as in ccd: below this the joint cannot move the tool toward the target
_MAX_CHECKS = 60  #: a blocked re-solve stops after this many (batched) checks: a tick's budget, not a search
_BACK_OFF_SWEEPS = 8  #: the sweep budget of each free solve of the back-off (warm from the seed: a few do)
_MAX_SWEEPS = 4  #: and after this many sweeps (it slides along an obstacle; the next tick goes on from there)


class CollisionGuard:
    """Verifies a :class:`~retarget.ik.ccd.CCDSolver`'s result against ``model`` and re-solves when it is not
    clear (see the module docstring).  ``bisections``: halvings of a blocked joint step (default 4: the step is
    kept to within 1/16 of its length); ``back_off``: points on the line to the target tried in the first step
    of a re-solve (default 5).  Built by the solver (``CCDSolver(arm, collision=model)``).
    """

    def __init__(self, solver: Solver, model: CollisionModel, *, bisections: int = 4, back_off: int = 5):
        self.solver = solver
        self.model = model
        self.bisections = int(bisections)
        self.back_off = int(back_off)
        self.clearance = float(model.clearance)
        self.bound = shared_bound(model)  #: skips the check of a result near the last pose queried
        self._reach = self.clearance + HORIZON

    def clear(self, q: Sequence[float] | np.ndarray) -> tuple[bool, float]:
        """Whether pose ``q`` (radians) keeps the clearance, and its min clearance (metres; a lower bound when the
        pose is near the last one queried: no query then)."""
        bound = self.bound
        m = bound.quick(q)
        if m >= self.clearance:
            return True, m
        m = bound.lower_bound(q)
        if m >= self.clearance:
            return True, m
        m = bound.quick_previous(q)  # (the motion may have swung back near the note before)
        if m >= self.clearance:
            return True, m
        d = self.model.pair_bounds(np.array(q), self._reach)  # exact near the clearance: its min is, when below
        bound.note(q, d)
        m = float(d.min()) if d.size else math.inf
        return m >= self.clearance, m

    def first_clear(self, poses: list[list[float]]) -> tuple[int, float]:
        """The index of the first clear pose of ``poses`` (radians; one batched query) and its min clearance;
        ``(-1, nan)`` when none is clear."""
        d = self.model.distances(np.array(poses))
        worst = d.min(axis=1) if d.shape[1] else np.full(len(poses), math.inf)
        ok = np.flatnonzero(worst >= self.clearance)
        return (int(ok[0]), float(worst[ok[0]])) if ok.size else (-1, math.nan)

    def check(self, q: np.ndarray) -> tuple[bool, float]:
        """Step 1: whether a solver's result ``q`` ``(n_joints,)`` rad is clear, and its clearance (metres): a
        query of the pose, or (near the last pose queried) a lower bound of it (:class:`~retarget.ik.bound.ClearanceBound`).  When it
        is not clear the solver calls :meth:`resolve`."""
        return self.clear(q)

    # -----------------------------------------------------------------------------------------------------------
    def _start(self, seed: list[float]) -> tuple[list[float], float] | None:
        """The first clear pose of (seed, home, rest), inside the solve's bounds, and its clearance; None: none."""
        s = self.solver
        arm = s.arm
        for q in (seed, arm.home.tolist(), arm.rest.tolist()):
            q = [lo if v < lo else hi if v > hi else v for v, lo, hi in zip(q, s._lo, s._hi, strict=True)]
            ok, m = self.clear(q)
            if ok:
                return q, m
        return None

    def resolve(
        self,
        target: tuple[float, float, float],
        seed: list[float],
        rotation: tuple[tuple[float, ...], ...] | None,
        tol: float,
        budget: int,
    ) -> IKResult:
        """The shortened re-solve from ``seed`` (see the module docstring)."""
        start = self._start(seed)
        if start is None:
            err = math.dist(self.solver.tool_point(seed), target)
            _, m = self.clear(seed)
            return IKResult(np.array(seed), err, 0, False, blocked=True, clearance=m)
        q, m = self._back_off(start[0], start[1], target, rotation, tol, budget)
        if rotation is None:
            return self._resolve_position(q, m, target, tol, budget)
        return self._resolve_pose(q, m, target, rotation, tol, budget)

    def _back_off(
        self,
        q: list[float],
        m: float,
        target: tuple[float, float, float],
        rotation: tuple[tuple[float, ...], ...] | None,
        tol: float,
        budget: int,
    ) -> tuple[list[float], float]:
        """The clear pose ``q`` moved toward ``target``: the free solution for the farthest point, bisected along
        the line from ``q``'s tool point to the target, whose pose is clear (``back_off`` halvings)."""
        s = self.solver
        lower, upper = s._lo, s._hi
        rot = None if rotation is None else np.array(rotation)
        e0 = s.tool_point(q)
        trials = []
        for k in range(self.back_off, 0, -1):  # the points at k / back_off of the way, the farthest first
            f = k / self.back_off
            point = [a + f * (b - a) for a, b in zip(e0, target, strict=True)]
            sweeps = min(budget, _BACK_OFF_SWEEPS)
            trial = s._solve_free(point, q, rot, tolerance=tol, max_iterations=sweeps, max_step=None).q.tolist()
            trials.append([min(max(v, lo), hi) for v, lo, hi in zip(trial, lower, upper, strict=True)])
        s._lo, s._hi = lower, upper
        i, m_i = self.first_clear(trials)
        return (trials[i], m_i) if i >= 0 else (q, m)

    def _step(self, q: list[float], j: int, new: float, m: float, checks: list[int]) -> float:
        """Move joint ``j`` of the clear pose ``q`` toward ``new`` as far as stays clear: the longest clear step
        of the full one and its halvings (``bisections`` of them, one batched query); returns the clearance of
        the pose ``q`` ends at."""
        old = q[j]
        d = new - old
        q[j] = new
        checks[0] += 1
        ok, m_new = self.clear(q)  # the whole step: one pose, the cheap query
        q[j] = old
        if ok:
            q[j] = new
            return m_new
        fractions = [0.5**k for k in range(1, self.bisections + 1)]
        poses = []
        for f in fractions:
            pose = q[:]
            pose[j] = old + f * d
            poses.append(pose)
        checks[0] += 1
        i, m_i = self.first_clear(poses)
        if i < 0:
            return m
        q[j] = poses[i][j]
        return m_i

    def _resolve_position(
        self, q: list[float], m: float, target: tuple[float, float, float], tol: float, budget: int
    ) -> IKResult:
        s = self.solver
        tx, ty, tz = target
        lower, upper, w, lev2 = s._lo, s._hi, s.weights, s._lever2
        px, py, pz, ax, ay, az = s._px, s._py, s._pz, s._ax, s._ay, s._az
        fk = s._fk
        checks = [0]
        f = fk(q)
        err = math.dist(f[:3], target)
        sweeps = 0
        while err > tol and sweeps < min(budget, _MAX_SWEEPS) and checks[0] < _MAX_CHECKS:
            sweeps += 1
            before = err
            for j in range(s.n):
                f = fk(q)  # the chain after the last joint's (maybe shortened) step
                ex, ey, ez = f[0], f[1], f[2]
                x0, y0, z0 = px[j], py[j], pz[j]
                ux, uy, uz = ex - x0, ey - y0, ez - z0
                vx, vy, vz = tx - x0, ty - y0, tz - z0
                kx, ky, kz = ax[j], ay[j], az[j]
                au = kx * ux + ky * uy + kz * uz
                dot = ux * vx + uy * vy + uz * vz - au * (kx * vx + ky * vy + kz * vz)
                cx, cy, cz = ky * uz - kz * uy, kz * ux - kx * uz, kx * uy - ky * ux
                cross = cx * vx + cy * vy + cz * vz
                if dot * dot + cross * cross < _EPS2:
                    continue
                lever2 = cx * cx + cy * cy + cz * cz
                theta = w[j] * math.atan2(cross, dot) * (lever2 / lev2 if lever2 < lev2 else 1.0)
                new = min(max(q[j] + theta, lower[j]), upper[j])
                if new != q[j]:
                    m = self._step(q, j, new, m, checks)
            err = math.dist(fk(q)[:3], target)
            if before - err < 0.01 * tol:  # no joint brings the tool closer without a collision
                break
        converged = err <= tol
        return IKResult(np.array(q), err, sweeps, converged, blocked=not converged, clearance=m)

    def _resolve_pose(
        self,
        q: list[float],
        m: float,
        target: tuple[float, float, float],
        rotation: tuple[tuple[float, ...], ...],
        tol: float,
        budget: int,
    ) -> IKResult:
        s = self.solver
        lower, upper = s._lo, s._hi
        rot = np.array(rotation)
        checks = [0]
        r = s._solve_free(target, q, rot, tolerance=tol, max_iterations=0, max_step=None)
        cost = r.error + 0.1 * r.orientation_error
        sweeps = 0
        while not r.converged and sweeps < budget and checks[0] < _MAX_CHECKS:
            sweeps += 1
            trial = s._solve_free(target, q, rot, tolerance=tol, max_iterations=1, max_step=None).q.tolist()
            trial = [min(max(v, lo), hi) for v, lo, hi in zip(trial, lower, upper, strict=True)]
            lo_t, hi_t, step = 0.0, 1.0, [a - b for a, b in zip(trial, q, strict=True)]
            checks[0] += 1
            ok, m_t = self.clear(trial)
            if not ok:
                for _ in range(self.bisections):
                    mid = 0.5 * (lo_t + hi_t)
                    checks[0] += 1
                    ok_mid, m_mid = self.clear([a + mid * d for a, d in zip(q, step, strict=True)])
                    if ok_mid:
                        lo_t, m_t = mid, m_mid
                    else:
                        hi_t = mid
                if lo_t == 0.0:
                    break
                trial = [a + lo_t * d for a, d in zip(q, step, strict=True)]
            r_new = s._solve_free(target, trial, rot, tolerance=tol, max_iterations=0, max_step=None)
            new_cost = r_new.error + 0.1 * r_new.orientation_error
            if new_cost >= cost - 0.01 * tol:
                if new_cost < cost:
                    q, m, r = trial, m_t, r_new
                break
            q, m, r, cost = trial, m_t, r_new, new_cost
        s._lo, s._hi = lower, upper
        return IKResult(np.array(q), r.error, sweeps, r.converged, r.orientation_error, blocked=not r.converged,
                        clearance=m)  # fmt: skip
