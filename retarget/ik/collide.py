"""Collision-aware IK: the :class:`~retarget.ik.ccd.CCDSolver`'s pose verified against a collision model.

A solver built with ``collision=model`` (a :class:`~retarget.collision.CollisionModel`) never returns a pose
closer than ``model.clearance`` to a collision (link-link, link-table, link-keep-out)
unless no such pose was found from the seed (then ``blocked``).  The fast path costs one check:

1. solve as without a model, then check the final pose once (``model.min_clearance``);
2. only when it is not clear, **back off** (of the free solutions for points spaced along the line from the
   seed's tool point to the target, the farthest whose pose is clear; none when even the nearest is not, or
   when the seed is already against an obstacle, as after a blocked tick), then **re-solve from there with
   per-joint shortening**: base first, each joint
   takes its CCD update (the same closed-form minimiser, weights and short-lever damping), clamped to the
   limits, and when the pose it leads to is not clear the step is **shortened** to the longest clear one of
   its halvings (``bisections`` of them), the way a joint limit clamps it: each candidate is one one-pose
   query, and the clearance values pick which halving to try (a joint against the obstacle costs one query);
3. the re-solve ends at the target (converged, clear), or where no joint can bring the tool closer: then the
   free solution from home is tried (a seed folded against an obstacle, say after a target below the table,
   keeps the warm solves in its trap once the target is reachable again), and taken when it reaches the
   target clear; else the nearest safe pose found, reported ``converged=False, blocked=True`` in the
   :class:`~retarget.ik.IKResult`.

Every pose returned was measured clear (or bounded clear near a measured pose).  A seed that is itself not clear
starts the re-solve from the first clear pose of (seed, home, rest); when none is clear the seed comes back,
``blocked``, and the caller (the control loop) refuses to send it.  Orientation targets re-solve a sweep at a
time: each sweep's step is bisected as a whole (a straight line in joint space).  A re-solve that ended at its
own seed (or got no closer) is returned again, without the work, for the same target from the pose it returned
(a held target the arm is stuck against, tick after tick: the same answer), and likewise for a position target
within ``HELD`` tolerances of it from a seed within ``HELD_STEP`` of that pose (a target that drifts by less
than the tolerance behind an obstacle: the re-solve would get no closer; its error is the new target's).

Arrays: ``q`` ``(n_joints,)`` float64 radians; targets ``(3,)`` metres, base frame.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from retarget.ik.bound import HORIZON, shared_bound
from retarget.ik.dls import Chain
from retarget.ik.result import IKResult

if TYPE_CHECKING:
    from retarget.arm.model import Arm
    from retarget.collision import CollisionModel


class Solver(Chain, Protocol):
    """What the guard uses of :class:`~retarget.ik.ccd.CCDSolver`: the forward pass and bounds the DLS steps use
    (:class:`~retarget.ik.dls.Chain`), plus its free solve; a protocol, so this module does not import the
    solver's (which imports this one)."""

    arm: Arm
    weights: tuple[float, ...]
    _lever2: float

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
_MAX_CHECKS = 60  #: a blocked re-solve stops after this many checks: a tick's budget, not a search
_BACK_OFF_SWEEPS = 8  #: the sweep budget of each free solve of the back-off (warm from the seed: a few do)
_AGAINST = 1e-3  #: metres: a start within this of the clearance is against an obstacle (no back-off, see there)
HELD = 0.25  #: tolerances: a position target this near the one a re-solve got stuck on gets its answer again
HELD_STEP = 1e-3  #: radians: and from a seed this near (per joint) the pose it returned
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
        #: the last blocked re-solve that made no progress: (target, the pose it returned, rotation, tol, budget)
        #: and its result, for the next call from that pose (see resolve)
        self._fixed: tuple[tuple[Any, ...], IKResult] | None = None

    def clear(self, q: Sequence[float] | np.ndarray) -> tuple[bool, float]:
        """Whether pose ``q`` (radians) keeps the clearance, and its min clearance (metres; a lower bound when the
        pose is near the last one queried: no query then)."""
        bound = self.bound
        m = bound.quick(q)  # (the same as lower_bound)
        if m >= self.clearance:
            return True, m
        m = bound.quick_previous(q)  # (the motion may have swung back near the note before)
        if m >= self.clearance:
            return True, m
        m = bound.recall(q)  # (or near an earlier one: the loop's, or where the clip was before)
        if m >= self.clearance:
            return True, m
        d = self.model.pair_bounds(np.array(q), self._reach)  # exact near the clearance: its min is, when below
        bound.note(q, d)
        m = float(d.min()) if d.size else math.inf
        return m >= self.clearance, m

    def measure(self, q: Sequence[float] | np.ndarray) -> float:
        """The min clearance of pose ``q`` (radians; metres) where it decides: the bound near the last pose queried
        when that keeps the clearance (a lower bound), else the model's one-pose value (exact; no note: the
        re-solve's candidates are many, its result is noted once)."""
        m = self.bound.quick(q)
        return m if m >= self.clearance else self.model.min_clearance(np.array(q))

    def ok(self, q: Sequence[float] | np.ndarray) -> bool:
        """Whether pose ``q`` (radians) keeps the clearance (:meth:`measure`)."""
        return self.measure(q) >= self.clearance

    def check(self, q: np.ndarray) -> tuple[bool, float]:
        """Step 1: whether a solver's result ``q`` ``(n_joints,)`` rad is clear, and its clearance (metres): a
        query of the pose, or (near the last pose queried) a lower bound of it
        (:class:`~retarget.ik.bound.ClearanceBound`).  When it is not clear the solver calls :meth:`resolve`."""
        return self.clear(q)

    # -----------------------------------------------------------------------------------------------------------
    def _start(self, seed: list[float]) -> tuple[list[float], float] | None:
        """The first clear pose of (seed, home, rest), inside the solve's bounds, and its clearance; None: none."""
        s = self.solver
        arm = s.arm
        for q in (seed, arm.home.tolist(), arm.rest.tolist()):
            q = [lo if v < lo else hi if v > hi else v for v, lo, hi in zip(q, s._lo, s._hi, strict=True)]
            m = self.measure(q)
            if m >= self.clearance:
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
        """The shortened re-solve from ``seed`` (see the module docstring).  A blocked re-solve that got the tool
        no closer than its seed was (by 1% of the tolerance) is kept: the next call for the same target (a position
        target: within ``HELD`` tolerances of it) from the pose it returned (within ``HELD_STEP`` rad per joint)
        gets that pose back at once (a held target the arm is stuck against, tick after tick: the same answer,
        and no creeping along the obstacle)."""
        fixed = self._fixed
        if fixed is not None and self._held(fixed[0], target, seed, rotation, tol, budget):
            r = fixed[1]
            err = r.error if target == fixed[0][0] else math.dist(self.solver.tool_point(r.q), target)
            return IKResult(r.q.copy(), err, r.iterations, r.converged, r.orientation_error, r.restarts,
                            blocked=r.blocked, clearance=r.clearance)  # fmt: skip
        result = self._resolve(target, seed, rotation, tol, budget)
        q = result.q.tolist()
        stuck = result.blocked and (
            q == seed
            or rotation is None
            and math.dist(self.solver.tool_point(seed), target) - result.error < 0.01 * tol
        )
        self._fixed = ((target, q, rotation, tol, budget), result) if stuck else None
        return result

    @staticmethod
    def _held(
        key: tuple[Any, ...],
        target: tuple[float, float, float],
        seed: list[float],
        rotation: tuple[tuple[float, ...], ...] | None,
        tol: float,
        budget: int,
    ) -> bool:
        """Whether a call is the stuck re-solve ``key`` again: from the pose it returned, with the same settings,
        for its target (a position target: one within ``HELD`` tolerances of it)."""
        stuck_target, q, stuck_rotation, stuck_tol, stuck_budget = key
        if rotation != stuck_rotation or tol != stuck_tol or budget != stuck_budget:
            return False
        if seed != q and max(abs(a - b) for a, b in zip(seed, q, strict=True)) > HELD_STEP:
            return False
        if rotation is not None:
            return bool(target == stuck_target)
        return math.dist(target, stuck_target) <= HELD * tol

    def _resolve(
        self,
        target: tuple[float, float, float],
        seed: list[float],
        rotation: tuple[tuple[float, ...], ...] | None,
        tol: float,
        budget: int,
    ) -> IKResult:
        start = self._start(seed)
        if start is None:
            err = math.dist(self.solver.tool_point(seed), target)
            _, m = self.clear(seed)
            return IKResult(np.array(seed), err, 0, False, blocked=True, clearance=m)
        q, m = self._back_off(*start, target, rotation, tol, budget)
        if rotation is None:
            result = self._resolve_position(q, m, target, tol, budget)
        else:
            result = self._resolve_pose(q, target, rotation, tol, budget)
        return result if result.converged else self._from_home(result, target, rotation, tol, budget)

    def _from_home(
        self,
        blocked: IKResult,
        target: tuple[float, float, float],
        rotation: tuple[tuple[float, ...], ...] | None,
        tol: float,
        budget: int,
    ) -> IKResult:
        """The free solution from home when it reaches the target clear, else ``blocked``: a seed folded against an
        obstacle (after a target below the table, say) leads the warm solves into it even once the target is
        reachable again; the loop then checks the way there like any move."""
        s = self.solver
        lower, upper = s._lo, s._hi
        rot = None if rotation is None else np.array(rotation)
        r = s._solve_free(target, s.arm.home, rot, tolerance=tol, max_iterations=budget, max_step=None)
        s._lo, s._hi = lower, upper
        if not r.converged:
            return blocked
        q = r.q.tolist()
        if any(v < lo or v > hi for v, lo, hi in zip(q, lower, upper, strict=True)):
            return blocked  # outside the solve's bounds (a trust region around the seed)
        m = self.measure(q)
        if m < self.clearance:
            return blocked
        return IKResult(np.array(q), r.error, r.iterations, True, r.orientation_error, r.restarts, clearance=m)

    def _back_off(
        self,
        q: list[float],
        m: float,
        target: tuple[float, float, float],
        rotation: tuple[tuple[float, ...], ...] | None,
        tol: float,
        budget: int,
    ) -> tuple[list[float], float]:
        """The clear pose ``q`` (clearance ``m``) moved toward ``target``, and its clearance: of the free solutions
        for the points at ``k / back_off`` of the line from ``q``'s tool point to the target, the farthest whose
        pose is clear.  ``q`` itself when even the nearest is not (one free solve), or without a solve when ``q``
        is within ``_AGAINST`` of the clearance: against an obstacle, as after a blocked tick, where the nearest
        one seldom is."""
        s = self.solver
        lower, upper = s._lo, s._hi
        rot = None if rotation is None else np.array(rotation)
        e0 = s.tool_point(q)
        sweeps = min(budget, _BACK_OFF_SWEEPS)

        def trial(k: int) -> list[float]:
            f = k / self.back_off
            point = [a + f * (b - a) for a, b in zip(e0, target, strict=True)]
            found = s._solve_free(point, q, rot, tolerance=tol, max_iterations=sweeps, max_step=None).q.tolist()
            return [min(max(v, lo), hi) for v, lo, hi in zip(found, lower, upper, strict=True)]

        if m < self.clearance + _AGAINST:  # q is against an obstacle (the last tick was blocked): none would be
            return q, m
        best = q, m
        nearest = trial(1)
        m_near = self.measure(nearest)
        if m_near >= self.clearance:
            best = nearest, m_near
            for k in range(self.back_off, 1, -1):  # the farthest first
                pose = trial(k)
                m_k = self.measure(pose)
                if m_k >= self.clearance:
                    best = pose, m_k
                    break
        s._lo, s._hi = lower, upper
        return best

    def _step(self, q: list[float], j: int, new: float, m: float, checks: list[int]) -> float:
        """Move joint ``j`` of the clear pose ``q`` (clearance ``m``) toward ``new`` as far as stays clear; returns
        the clearance of the pose ``q`` ends at.  The full step, else the longest of its halvings (``bisections`` of
        them, down to ``2**-bisections`` of it) that stays clear, guided by the values: the clearance falls from
        ``m`` to ``m_f`` over a fraction ``f`` of the step, so the longest halving within ``f (m - c) / (m - m_f)``
        of it (where a linear fall would reach the clearance ``c``) is tried next.  A pose against the obstacle
        in that direction (``m`` at ``c``) stays after one check."""
        old, c = q[j], self.clearance
        q[j] = new
        checks[0] += 1
        m_f = self.measure(q)
        if m_f >= c:
            return m_f
        d, f, smallest = new - old, 1.0, 0.5**self.bisections
        while True:
            reach = f * (m - c) / (m - m_f)  # m >= c > m_f
            if reach < smallest:
                q[j] = old
                return m
            f = 0.5 ** math.ceil(-math.log2(reach))  # the longest halving within reach (< f: reach < f)
            q[j] = old + f * d
            checks[0] += 1
            m_f = self.measure(q)
            if m_f >= c:
                return m_f

    def _resolve_position(
        self, q: list[float], m: float, target: tuple[float, float, float], tol: float, budget: int
    ) -> IKResult:
        s = self.solver
        tx, ty, tz = target
        lower, upper, w, lev2 = s._lo, s._hi, s.weights, s._lever2
        px, py, pz, ax, ay, az = s._px, s._py, s._pz, s._ax, s._ay, s._az
        fk = s._fk
        c, checks = self.clearance, [0]
        f, stale = fk(q), False
        err = math.dist(f[:3], target)
        sweeps = 0
        while err > tol and sweeps < min(budget, _MAX_SWEEPS) and checks[0] < _MAX_CHECKS:
            sweeps += 1
            before = err
            for j in range(s.n):
                if stale:  # the chain after the last joint's (maybe shortened) step; the buffers hold it
                    f, stale = fk(q), False
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
                    old = q[j]
                    m = self._step(q, j, new, m, checks)
                    stale = q[j] != old
            if stale:
                f, stale = fk(q), False
            err = math.dist(f[:3], target)
            if before - err < 0.01 * tol:  # no joint brings the tool closer without a collision
                break
        converged = err <= tol
        if self.bound.quick(q) < c:  # not near the last note: noted for the loop's goal check (and measured)
            _, m = self.clear(q)
        return IKResult(np.array(q), err, sweeps, converged, blocked=not converged, clearance=m)

    def _resolve_pose(
        self,
        q: list[float],
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
            if not self.ok(trial):
                for _ in range(self.bisections):
                    mid = 0.5 * (lo_t + hi_t)
                    checks[0] += 1
                    if self.ok([a + mid * d for a, d in zip(q, step, strict=True)]):
                        lo_t = mid
                    else:
                        hi_t = mid
                if lo_t == 0.0:
                    break
                trial = [a + lo_t * d for a, d in zip(q, step, strict=True)]
            r_new = s._solve_free(target, trial, rot, tolerance=tol, max_iterations=0, max_step=None)
            new_cost = r_new.error + 0.1 * r_new.orientation_error
            if new_cost >= cost - 0.01 * tol:
                if new_cost < cost:
                    q, r = trial, r_new
                break
            q, r, cost = trial, r_new, new_cost
        s._lo, s._hi = lower, upper
        _, m = self.clear(q)  # clear (every pose it moved to was): its clearance, noted for the loop's goal check
        return IKResult(np.array(q), r.error, sweeps, r.converged, r.orientation_error, blocked=not r.converged,
                        clearance=m)  # fmt: skip
