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
import operator
import weakref
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

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


__all__ = ["ClearanceBound", "CollisionGuard", "shared_bound"]

_EPS2 = 1e-16  #: as in ccd: below this the joint cannot move the tool toward the target
_MAX_CHECKS = 60  #: a blocked re-solve stops after this many (batched) checks: a tick's budget, not a search
_BACK_OFF_SWEEPS = 8  #: the sweep budget of each free solve of the back-off (warm from the seed: a few do)
_MAX_SWEEPS = 4  #: and after this many sweeps (it slides along an obstacle; the next tick goes on from there)
#: metres beyond the clearance within which a query measures a pair exactly (farther ones keep a cheap lower bound
#: of at least this: ``CollisionModel.pair_bounds``)
HORIZON = 0.01
_SINGLES = 3  #: :meth:`ClearanceBound.quick` bounds this many of the nearest pairs one by one, the rest in bands:
_BANDS = np.array([0.0, 0.01, 0.03, 0.1])  #: where they start, metres beyond the next nearest pair's distance


class ClearanceBound:
    """A lower bound of the clearance of poses near one that was checked, so most checks can be skipped.

    A pair of shapes on frames ``a < b`` (a zone of the world is on the base frame, 0) keeps a distance that
    depends only on joints ``a .. b-1``: only the shape on frame ``b`` moves in frame ``a``.  A turn of joint
    ``j`` moves that shape's points by at most their distance from the joint's origin per radian, at most
    ``L_j = |o_{j+1}| + ... + |o_{b-1}| + extent`` (the joint origins' offsets ``o`` along the chain, and the
    shape's farthest point from its frame's origin).  So from a checked pose ``q_ref`` to ``q`` the pair's
    distance falls by at most ``sum_{a <= j < b} |q_j - q_ref_j| L_j``.  After :meth:`note` of ``q_ref`` with
    its pair distances, :meth:`lower_bound` of ``q`` is the smallest pair distance minus its fall: when it is
    still at least the clearance, ``q`` is clear without a query; and so is every pose of a straight joint-space
    segment whose two ends are (the bound is convex along the segment).  A few small numpy operations;
    :meth:`quick` is a looser bound of a few plain-float operations (the nearest pairs one by one, the rest as
    bands of distance: each band's least distance less its greatest levers' fall), enough far from a contact.

    >>> import retarget
    >>> from retarget.collision import CollisionModel
    >>> arm = retarget.load_arm("wx250s")
    >>> model = CollisionModel.for_arm(arm)
    >>> bound = ClearanceBound(model)
    >>> bound.note(arm.home.tolist(), model.distances(arm.home))
    >>> bound.lower_bound(arm.home.tolist()) == model.min_clearance(arm.home)
    True
    >>> bound.lower_bound((arm.home + 0.01).tolist()) < model.min_clearance(arm.home + 0.01)
    True
    """

    __slots__ = ("_levers", "_state", "_quick", "_previous")

    def __init__(self, model: CollisionModel):
        from retarget.collision import Box  # the shapes' types (the collision package never imports this one)

        arm = model.arm
        hops = [float(np.linalg.norm(j.origin_xyz)) for j in arm.joints]  # joint k's origin in frame k
        links = {link.name: link for link in model.geometry.links}

        def extent(name: str) -> float:
            shape = links[name].shape
            if isinstance(shape, Box):
                return float(np.linalg.norm(shape.center) + np.linalg.norm(shape.half_size))
            return float(max(np.linalg.norm(shape.a), np.linalg.norm(shape.b)) + shape.radius)

        levers = np.zeros((len(model.pair_names), arm.n_joints))
        for k, name in enumerate(model.pair_names):
            u, v = name.split("/")
            fu = links[u].frame if u in links else 0  # a world zone (table, keep-out) is on the base frame
            fv = links[v].frame if v in links else 0
            a, b, mover = (fu, fv, v) if fu <= fv else (fv, fu, u)
            for j in range(a, b):
                levers[k, j] = sum(hops[j + 1 : b]) + extent(mover)
        self._levers = levers  #: ``(n_pairs, n_joints)`` metres per radian
        #: the last pose noted ``(n_joints,)`` and its pair distances ``(n_pairs,)``; one tuple, replaced whole
        self._state: tuple[np.ndarray, np.ndarray] | None = None
        #: the last pose noted as floats and its groups' (least distance, greatest lever per joint): see quick
        self._quick: tuple[list[float], list[tuple[float, list[float]]]] = ([], [(-math.inf, [])])
        #: the note before the last (:attr:`state`, quick groups): a motion that swings back may be near it
        self._previous: tuple[tuple[np.ndarray, np.ndarray] | None, tuple[list[float], list[Any]]] = (None, self._quick)

    @property
    def previous_state(self) -> tuple[np.ndarray, np.ndarray] | None:
        """The note before the last (as :attr:`state`; None: fewer than two notes)."""
        return self._previous[0]

    @property
    def state(self) -> tuple[np.ndarray, np.ndarray] | None:
        """The last note: its pose ``(n_joints,)`` rad and pair distances ``(n_pairs,)`` metres (None: no note)."""
        return self._state

    def note(self, q: Sequence[float] | np.ndarray, distances: np.ndarray) -> None:
        """Pose ``q`` (rad) was checked: ``distances`` ``(n_pairs,)`` metres, every pair's (lower bounds will do)."""
        ref, d = np.array(q, dtype=np.float64), np.array(distances, dtype=np.float64)
        self._previous = (self._state, self._quick)
        self._state = (ref, d)
        order = np.argsort(d, kind="stable")
        ds, ls = d[order], self._levers[order]
        near = ds.tolist()
        groups = list(zip(near[:_SINGLES], ls[:_SINGLES].tolist(), strict=False))
        rest = ds[_SINGLES:]
        if rest.size:  # the rest in bands (contiguous: sorted), each its least distance and greatest levers
            cuts = np.searchsorted(rest, rest[0] + _BANDS).tolist()
            starts = sorted({c for c in cuts if c < rest.size})
            levers = np.maximum.reduceat(ls[_SINGLES:], starts, axis=0).tolist()
            groups += [(near[_SINGLES + i], row) for i, row in zip(starts, levers, strict=True)]
        self._quick = (ref.tolist(), groups)

    def quick(self, q: Sequence[float] | np.ndarray) -> float:
        """A lower bound of the min clearance (metres) of pose ``q`` (rad), at most :meth:`lower_bound`'s, in plain
        floats (about a microsecond); ``-inf`` before the first :meth:`note`, ``inf`` without pairs."""
        return self._quick_from(self._quick, q)

    def quick_previous(self, q: Sequence[float] | np.ndarray) -> float:
        """:meth:`quick` from the note before the last (``-inf`` before the second note)."""
        return self._quick_from(self._previous[1], q)

    @staticmethod
    def _quick_from(table: tuple[list[float], list[Any]], q: Sequence[float] | np.ndarray) -> float:
        ref, groups = table
        if not ref:
            return -math.inf if groups else math.inf
        moves = [abs(a - b) for a, b in zip(q, ref, strict=True)]
        low = math.inf
        mul = operator.mul
        for d, levers in groups:
            v = d - sum(map(mul, levers, moves))
            if v < low:
                low = v
        return low

    def lower_bound(self, q: Sequence[float] | np.ndarray) -> float:
        """A lower bound of the min clearance (metres) of pose ``q`` (rad); ``-inf`` before the first :meth:`note`."""
        at = self.pairs_at(q)
        return float(at.min()) if at.size else math.inf

    def pairs_at(
        self, q: Sequence[float] | np.ndarray, state: tuple[np.ndarray, np.ndarray] | None | bool = True
    ) -> np.ndarray:
        """A lower bound of every pair's distance in pose ``q`` ``(n_pairs,)`` metres (``-inf`` before a note),
        from the last note, or from ``state`` (an earlier :attr:`state`) when given."""
        if state is True:
            state = self._state
        if state is None:
            return np.full(len(self._levers), -math.inf)
        assert state is not False  # noqa: S101 - only True or a state
        ref, d = state
        fall: np.ndarray = d - self._levers @ np.abs(np.asarray(q, dtype=np.float64) - ref)
        return fall

    def segment_bound(self, q0: Sequence[float], q1: Sequence[float], at0: np.ndarray, at1: np.ndarray) -> float:
        """A lower bound of the min clearance over the straight joint-space segment ``q0`` -> ``q1``, from lower
        bounds ``at0``, ``at1`` ``(n_pairs,)`` of the pair distances at its ends: each pair's distance is within
        its fall ``L`` of both ends' along the way, so it is at least ``min(a, b)`` and ``(a + b - L) / 2``."""
        fall = self._levers @ np.abs(np.asarray(q1, dtype=np.float64) - np.asarray(q0, dtype=np.float64))
        low = np.minimum(np.minimum(at0, at1), 0.5 * (at0 + at1 - fall))
        return float(low.min()) if low.size else math.inf


_SHARED: weakref.WeakKeyDictionary[CollisionModel, ClearanceBound] = weakref.WeakKeyDictionary()


def shared_bound(model: CollisionModel) -> ClearanceBound:
    """The :class:`ClearanceBound` of ``model`` that its IK solvers and the control loop's goal check share: a pose
    one of them queried (say the IK's solution) spares the other a query of the same or a nearby pose.  Every
    note is a true measurement, so sharing is sound; not for threads that solve at the same time."""
    bound = _SHARED.get(model)
    if bound is None:
        bound = _SHARED[model] = ClearanceBound(model)
    return bound


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
        query of the pose, or (near the last pose queried) a lower bound of it (:class:`ClearanceBound`).  When it
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
