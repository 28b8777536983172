"""Look-ahead planning of a whole joint path within the velocity, acceleration and joint limits: :func:`plan_path`.

The tick loop's :class:`~retarget.control.limits.StepLimiter` is causal: it follows each tick's goal with a
trapezoidal profile (:mod:`~retarget.control.profile`), so when the goal moves faster or turns harder than the
joint may, the joint **lags** it and then catches up.  When the whole path is known in advance (a clip played
offline, or planned before the run on a bus) the joint can start early instead.  :func:`plan_path` does this for
all joints at once, on the goal path ``g`` ``(n, n_joints)``:

1. a joint whose goal path is already within its limits (from ``q_start`` at rest) is passed through unchanged
   and costs nothing;
2. the others get the path ``q`` nearest their goals in the least-squares sense, with every step within the
   velocity limit and every change of step within the acceleration limit, a soft cost on speeds above
   ``easy_speed`` of the limit (``speed_cost``: a joint reaches its full speed only where the goal really needs
   it, not wherever it would help a little) and one on the change of acceleration (``jerk_cost``: the
   acceleration does not flip between its limits from one slot to the next to win a fraction of a millimetre,
   :data:`JERK_COST`):

       minimise  1/2 sum (q - g)^2 + speed_cost/2 sum max(0, |dq| / vmax - easy_speed)^2
                                   + jerk_cost/2 sum (d^3 q / amax)^2
       subject to |dq| <= vmax,  |d^2 q| <= 0.97 amax   (room for step 3 to catch up: ``ACCEL_SHARE``),

   by ADMM (:mod:`~retarget.control.fit`).  Unlike a pass of the profile that only follows, it turns early for a
   peak *and* reaches as far toward it as the limits allow (the profile's forward and backward passes averaged,
   this module's earlier method, fell short of fast reversals: wx250s on ``motion_dance.bvh`` left, tracking p95
   49 mm against ~30 with this fit, 23 with the next).  Given the task's ``jacobians`` (the tool point's, a clip
   played position only: :func:`solve_and_plan`), the first term is the tool point's error instead, linearised at
   the goals, and every joint that moves plans with the others: where one must fall behind its goal, the others
   make up for it (the arm's redundancy, which a fit joint by joint leaves unused).  wx250s, tracking p95 with the
   joints' fit -> the task's (targets unfiltered, bench_smooth.py): motion_dance right 13.3 -> 9.3 mm, left
   29.9 -> 23.2; motion_walk left 19.7 -> 10.2; unity_walk_random right 12.5 -> 5.3; motion_basket right 2.6 ->
   1.8;
   With a collision-aware IK pass, :func:`solve_and_plan` keeps the fitted path clear of the world where it comes
   near it (:mod:`~retarget.control.keepclear`: the clearance linearised at those planned poses, as ``halfspaces``
   the fit meets, for a few rounds), and ticks whose IK stopped short of a collision have no task: their goal is
   the IK's nearest clear pose;
3. a last forward pass of the profile over that path from the start pose at rest: the plan's first step starts
   from rest at ``q_start``, and the result is exactly what the profile allows (ADMM's few sweeps leave the
   constraints nearly but not exactly met), so the loop's own limiter, fed the plan tick by tick, reproduces it.

The cost: on ``motion_dance.bvh`` (1 559 ticks, three or four joints to plan) the joints' fit takes 6-7 ms in all
(20 sweeps of a few numpy passes and one FFT pair each), the task's 8-10 ms (20 sweeps, a ``k x k`` product per
tick in each, and the Jacobians), then the last pass (about 0.3 us per joint and tick where the profile has work to
do; the slots where the joint stays on its goal are copied, :func:`_follow`).  A limit of the method: a clip that
starts in a motion which keeps a joint at its acceleration limit from the first tick on (the plan itself starts at
rest) may see that joint a quarter period late until the motion eases; the shared clips start still.

**Guarantee**: every step of the plan, from ``q_start`` at rest, is within ``max_step``, every change of step
within ``max_accel``, and every pose within ``lower..upper`` (the last pass is the profile itself, which brakes
in time for the joint limits).  Units are slots as in :mod:`~retarget.control.profile`: rad, rad per slot, rad
per slot^2.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass
from functools import partial
from typing import Protocol

import numpy as np
import numpy.typing as npt

from retarget.arm.kinematics import Chain
from retarget.control.fit import Costs, Halfspaces, check_task, fit_joints, fit_task, joint_task, task_of
from retarget.control.keepclear import MARGIN, keep_clear
from retarget.control.polish import Polish
from retarget.control.profile import stop_speed
from retarget.ik.bound import State, shared_bound
from retarget.ik.result import IKResult

__all__ = ["PathPlan", "plan_path", "solve_and_plan", "tool_task"]

Array = npt.NDArray[np.float64]

ITERATIONS = 20  #: ADMM sweeps (the task fit: 30 gain ~0.1 mm p95 on the shared clips, 10 lose 0.2-40 mm)
SPEED_COST = 0.2  #: the soft cost on speeds above ``easy_speed`` of the limit, per (share of the limit)^2 and slot
EASY_SPEED = 0.85  #: the fraction of each joint's velocity limit above which speed costs
#: the soft cost on the change of acceleration per slot, per (share of the acceleration limit)^2 and slot.  Without
#: it a fit that follows a clip as closely as the limits allow flips the acceleration between the limits tick to tick
#: where the clip moves fast.  wx250s, commanded jerk RMS (rad/s^3) and tracking p95 (mm) by the cost: motion_basket
#: right 0: 2334, 1.28 (1.04 after 50 sweeps, 0.99 after 300); 1e-5: 1120, 1.40; 1e-4: 314, 1.67; 3e-4: 230, 1.80;
#: 1e-3: 185, 1.99; 3e-3: 165, 2.21.  motion_dance right 0: 1643, 9.4; 3e-4: 518, 9.3; 3e-3: 360, 9.6.  (The fit per
#: joint with the fixed 6 Hz filter, before: basket 169, 2.8; dance 375, 13.5.  TODAY, unlimited: 4427 and 4339.)
JERK_COST = 3e-4
#: the look-ahead IK pass's tolerance with an orientation target, a share of the solver's own
#: (``CCDSolver.tolerance``, 1 mm: the causal loop's).  The early-out leaves a tick anywhere within the tolerance (a
#: DLS step aims at a quarter of it), and the plan follows those solutions where the limits allow, so at 1 mm the
#: error saws between ~0 and 0.25 mm from tick to tick and the joints jerk with it.  Commanded jerk RMS (rad/s^3,
#: wx250s), share 1 / 0.5 / 0.3: demo clip right 439 / 288 / 226, left (a hand that hardly moves) 1310 / 185 / 23;
#: motion_walk right 227 / 165 / 157; motion_dance right 443 / 394 / 387 (0.1: no further).  A position target is
#: solved to the full tolerance and then polished, every tick at once (:mod:`~retarget.control.polish`: jerk 222
#: and 24 on the demo clip; motion_dance left 22 % fewer sweeps, 2 219 -> 1 734, the IK pass ~70 -> ~65 ms CPU)
PLAN_TOLERANCE = 0.3


def plan_path(
    goals: npt.ArrayLike,
    q_start: npt.ArrayLike,
    *,
    lower: npt.ArrayLike,
    upper: npt.ArrayLike,
    max_step: npt.ArrayLike,
    max_accel: npt.ArrayLike,
    iterations: int = ITERATIONS,
    speed_cost: float = SPEED_COST,
    easy_speed: float = EASY_SPEED,
    jerk_cost: float = JERK_COST,
    jacobians: npt.ArrayLike | None = None,
    residuals: npt.ArrayLike | None = None,
    halfspaces: Halfspaces | None = None,
) -> Array:
    """The joint path ``(n, n_joints)`` rad nearest ``goals`` ``(n, n_joints)`` rad that the limits allow, looking
    ahead (see the module docstring).

    ``q_start`` ``(n_joints,)`` rad: the pose before the first goal, at rest (inside the limits);
    ``lower``/``upper`` ``(n_joints,)`` rad: the joint limits; ``max_step`` ``(n_joints,)`` rad per slot (> 0):
    the velocity limit; ``max_accel`` ``(n_joints,)`` rad per slot^2 (> 0): the acceleration limit;
    ``iterations`` (>= 0) ADMM sweeps (0: the profile follows the goals, causally); ``speed_cost`` (>= 0) and
    ``easy_speed`` (0..1): the soft cost on speeds above that fraction of the limit.  Never exceeds the limits (from
    ``q_start`` at rest); goals outside the joint limits are followed to the limit.

    ``jacobians`` ``(n, d, n_joints)`` (metres per rad: how the task point moves with each joint at each goal) and
    ``residuals`` ``(n, d)`` metres (the task point of each goal minus its target): the fit is then to the task, not
    the joints (:func:`fit_task`): a joint that falls behind its goal is made up for by the others where
    they can, and every joint that moves and matters to the task is planned with the ones that must be.
    ``halfspaces`` (:class:`~retarget.control.fit.Halfspaces` over all the joints): linear constraints the fit meets
    on single ticks (a clearance kept, :mod:`~retarget.control.keepclear`); like the limits to ADMM's few sweeps,
    nearly.  Without ``jacobians`` the fit is then the task fit's with the joints' own cost
    (:func:`~retarget.control.fit.joint_task`).

    A step of 1 rad in one joint, at most 0.1 rad per slot and 0.02 rad per slot^2: the plan starts before the
    step (at slot 20) and ends after it, symmetrically (the causal limiter would only start at the step); like any
    least-squares fit of a jump it dips and overshoots a little on either side (here 2 %):

    >>> goals = np.r_[np.zeros(20), np.ones(20)][:, None]
    >>> p = plan_path(goals, [0.0], lower=[-2.0], upper=[2.0], max_step=[0.1], max_accel=[0.02])
    >>> bool(p[15, 0] > 0.05), round(float(p[19, 0] + p[20, 0]), 1), round(float(p[-1, 0]), 2)
    (True, 1.0, 1.0)
    >>> round(float(p[:, 0].min()), 2), round(float(p[:, 0].max()), 2)
    (-0.02, 1.02)
    >>> bool(np.abs(np.diff(np.r_[[[0.0]], p], axis=0)).max() <= 0.1 + 1e-12)
    True
    """
    g = np.array(goals, dtype=np.float64)
    if g.ndim != 2:
        raise ValueError(f"Expected goals of shape (n, n_joints), got {g.shape}")
    n, m = g.shape
    q0, lo, hi, vmax, amax = (np.broadcast_to(np.asarray(x, dtype=np.float64), (m,)) for x in
                              (q_start, lower, upper, max_step, max_accel))  # fmt: skip
    if iterations < 0:
        raise ValueError(f"Expected iterations >= 0, got {iterations}")
    if np.any(vmax <= 0) or np.any(amax <= 0):
        raise ValueError("Expected max_step and max_accel > 0")
    if speed_cost < 0 or not 0.0 < easy_speed <= 1.0:
        raise ValueError(f"Expected speed_cost >= 0 and 0 < easy_speed <= 1, got {speed_cost} and {easy_speed}")
    if not jerk_cost >= 0:
        raise ValueError(f"Expected jerk_cost >= 0, got {jerk_cost}")
    costs = Costs(speed_cost, easy_speed, jerk_cost)
    arrays = check_task(jacobians, residuals, n, m)
    out = g.copy()
    if n == 0:
        return out
    limits = [(float(vmax[j]), float(amax[j]), float(lo[j]), float(hi[j])) for j in range(m)]
    hard = [j for j in range(m) if not _feasible(g[:, j], float(q0[j]), limits[j])]
    if not hard:
        return out
    task = None if arrays is None else task_of(g, *arrays, hard)
    if task is None and halfspaces is not None:  # no task, or every tick's Jacobian zero: the joints' own cost
        task = joint_task(hard, n)
    if task is not None:
        hard = task.joints
    aims = g[:, hard].T
    if iterations > 0 and task is not None:
        kept = None if halfspaces is None else halfspaces.over(hard, g)
        aims = fit_task(aims, q0[hard], vmax[hard], amax[hard], iterations, costs, task, kept)
    elif iterations > 0:
        aims = fit_joints(aims, q0[hard], vmax[hard], amax[hard], iterations, costs)
    for row, j in zip(aims.tolist(), hard, strict=True):
        out[:, j] = _follow(row, float(q0[j]), limits[j])
    return out


def _feasible(path: Array, q0: float, limits: tuple[float, float, float, float]) -> bool:
    """Whether ``path`` from ``q0`` at rest keeps every step, change of step and pose within ``limits`` (with the
    profile's braking bound near the joint limits, approximately: a joint near one is planned anyway)."""
    vmax, amax, lo, hi = limits
    q = np.concatenate([[q0, q0], path])
    v = np.diff(q)
    if np.abs(v).max() > vmax or np.abs(np.diff(v)).max() > amax:
        return False
    far = vmax * vmax / (2.0 * amax) + vmax + amax  # profile.braking_run: farther off a limit never binds
    return bool(path.min() - lo > far and hi - path.max() > far)


def _follow(goal: list[float], q: float, limits: tuple[float, float, float, float], *, jump: bool = True
            ) -> list[float]:  # fmt: skip
    """The poses of one joint following ``goal`` (rad per slot) from ``q`` at rest with the trapezoidal profile
    (:func:`~retarget.control.profile.profile_step`, inlined as in the StepLimiter; the goal's own step fed
    forward); the loop's limiter run over a whole path at once.  :func:`~retarget.control.profile.stop_speed` is
    inlined too where it runs every slot (the same expressions, so the same floats; near a joint limit it is
    called).

    A step that reaches the goal, not cut by a limit, lands on it exactly (the goal itself, not ``q + w``, which
    may differ from it in the last bit).  Then the joint is *on* the goal: at it, moving at the goal's own step.
    From there it stays on as long as each next slot's goal step is within the velocity limit and within the
    acceleration limit of the one before, and the goal keeps off the joint limits' braking runs (:func:`_steady`,
    on the whole path at once): with ``jump`` those slots are copied from the goal, the same floats the steps would
    give, instead of being stepped (most of a clip's slots: the profile runs where it has work to do)."""
    vmax, a, lo, hi = limits
    far = vmax * vmax / (2.0 * a) + vmax + a
    sqrt, floor = math.sqrt, math.floor
    n_slots = len(goal)
    out: list[float] = []
    append = out.append
    steady_until = _steady(goal, limits) if jump else [k + 1 for k in range(n_slots)]
    v = 0.0
    last = goal[0] if goal else 0.0  # the first goal's own step is 0 (g - g)
    k = 0
    while k < n_slots:
        g = goal[k]
        step = g - last
        last = g
        u = vmax if step > vmax else -vmax if step < -vmax else step
        d = g - q - u
        reach = True  # (the step below reaches g: u + d)
        if -0.5 * a < d < 0.5 * a:  # stop_speed's n is 0 (|d| < a): it gives d itself, the same float
            w = u + d
        elif d > 0.0:  # u + stop_speed(d, a)
            n = floor((sqrt(1.0 + 8.0 * d / a) - 1.0) * 0.5)
            w = u + (d + a * n * (n + 1) * 0.5) / (n + 1)
            reach = n == 0
        else:  # u - stop_speed(-d, a)
            d = -d
            n = floor((sqrt(1.0 + 8.0 * d / a) - 1.0) * 0.5)
            w = u - (d + a * n * (n + 1) * 0.5) / (n + 1)
            reach = n == 0
        free = w
        low, high = v - a, v + a
        if low < -vmax:
            low = -vmax
        if high > vmax:
            high = vmax
        if q - lo < far:
            low = max(low, -stop_speed(q - lo, a))
        if hi - q < far:
            high = min(high, stop_speed(hi - q, a))
        if low > high:
            w = v - a if v > 0.0 else v + a
        elif w < low:
            w = low
        elif w > high:
            w = high
        y = g if reach and w == free else q + w
        q = lo if y < lo else hi if y > hi else y
        v = w
        append(q)
        k += 1
        if q == g and w == step and steady_until[k - 1] > k:  # on the goal: copy it while it stays steady
            stop = steady_until[k - 1]
            out += goal[k:stop]
            q = last = goal[stop - 1]
            v = w = last - goal[stop - 2]
            k = stop
    return out


def _steady(goal: list[float], limits: tuple[float, float, float, float]) -> list[int]:
    """Per slot ``k`` of ``goal`` (rad), the first slot after it at which a joint on the goal at ``k`` (at
    ``goal[k]``, its last step ``goal[k] - goal[k - 1]``) would stop being on it, by :func:`_follow`'s steps: a goal
    step beyond the velocity limit or beyond the acceleration limit of the step before, a slot that starts within
    a joint limit's braking run, or a goal outside the limits (the same float expressions as the steps)."""
    vmax, a, lo, hi = limits
    far = vmax * vmax / (2.0 * a) + vmax + a
    g = np.asarray(goal, dtype=np.float64)
    n = len(g)
    if n < 2:
        return [k + 1 for k in range(n)]
    step = np.empty(n)
    step[0] = g[0] - g[0]
    step[1:] = g[1:] - g[:-1]
    before = step[:-1]  # the step the joint on the goal at slot j - 1 moves at
    low = np.maximum(before - a, -vmax)
    high = np.minimum(before + a, vmax)
    s, at = step[1:], g[:-1]
    keeps = ((s <= vmax) & (s >= -vmax) & (s >= low) & (s <= high) & (at - lo >= far) & (hi - at >= far)
             & (g[1:] >= lo) & (g[1:] <= hi))  # fmt: skip
    # slot j (1..n-1) keeps a joint on the goal at j - 1 on it when keeps[j - 1]; the first j > k that does not
    breaks = np.append(np.flatnonzero(~keeps) + 1, n)  # (n: the path's end)
    until: list[int] = breaks[np.searchsorted(breaks, np.arange(n), side="right")].tolist()
    return until


class _Solver(Protocol):
    """The IK a clip's path is solved with (:class:`~retarget.control.source.TickSolver`, the loop's own; with a
    ``tolerance`` attribute, as :class:`~retarget.ik.CCDSolver`, it is also given ``tolerance=`` per call)."""

    def solve(self, target: Array, q0: Array, rotation: Array | None = None) -> IKResult: ...


@dataclass(frozen=True)
class PathPlan:
    """A clip's ticks solved and planned ahead: what :class:`~retarget.control.replay.ControlLoop` plays."""

    q: Array  #: ``(n, n_joints)`` rad, the planned poses (within the limits, :func:`plan_path`)
    ik: tuple[IKResult, ...]  #: ``n`` IK solutions the plan was made from (their error, sweeps, ... per tick)
    positions: Array  #: ``(n, 3)`` metres, base frame: each tick's target
    clamped: tuple[bool, ...]  #: ``n``: the target was pulled into the workspace
    seconds: float  #: real seconds the IK pass and the plan took

    def __len__(self) -> int:
        return len(self.ik)


def solve_and_plan(
    solver: _Solver,
    positions: Array,
    rotations: Array | None,
    clamped: npt.NDArray[np.bool_],
    q_start: Array,
    *,
    lower: Array,
    upper: Array,
    max_step: Array,
    max_accel: Array,
    chain: Chain | None = None,
    jerk_cost: float = JERK_COST,
) -> PathPlan:
    """IK of every target ``positions`` ``(n, 3)`` m (``rotations`` ``(n, 3, 3)`` or None), each warm-started from
    the last solution (the first from ``q_start`` ``(n_joints,)`` rad), then :func:`plan_path` of the solutions from
    ``q_start`` at rest (limits and ``jerk_cost`` as there, per slot).  With the arm's ``chain`` and no rotations
    the plan fits the tool point, not the joints (:func:`plan_path`'s ``jacobians`` and ``residuals``, at the
    solutions; an orientation target keeps the joints' fit, which holds the whole pose).  With a collision-aware
    solver (its ``collision`` model) each planned move, from ``q_start`` then tick to tick, is bounded from the notes
    its IK pass made (:meth:`~retarget.ik.bound.ClearanceBound.prove`): the loop's goal check takes a move's bound
    when it keeps the clearance and checks the move itself otherwise.  Position only, with a
    :class:`~retarget.ik.CCDSolver`-like solver, the IK pass solves to the solver's own tolerance and every safe
    tick then takes one more DLS step, all at once (:class:`~retarget.control.polish.Polish`); an orientation target
    is solved to :data:`PLAN_TOLERANCE` of it."""
    t0 = time.perf_counter()
    model = getattr(solver, "collision", None)  # (a CCDSolver's collision model; None: none)
    bound = None if model is None else shared_bound(model)
    notes = None if bound is None else bound.record()
    try:
        polish = None if chain is None or rotations is not None else Polish.of(solver)
        share = 1.0 if polish is not None else PLAN_TOLERANCE
        results, index = _solve(solver, positions, rotations, q_start, notes, max_step, share)
        qs = np.array([r.q for r in results], dtype=np.float64).reshape(len(results), len(q_start))
        jacobians = residuals = None
        if chain is not None and rotations is None:  # position only: plan to the tool point
            qs, jacobians, residuals = _tool_goals(chain, polish, results, qs, positions, lower, upper)

        def plan(halfspaces: Halfspaces | None) -> Array:
            return plan_path(qs, q_start, lower=lower, upper=upper, max_step=max_step, max_accel=max_accel,
                             jerk_cost=jerk_cost, jacobians=jacobians, residuals=residuals,
                             halfspaces=halfspaces)  # fmt: skip

        if model is None or bound is None or notes is None:
            planned = plan(None)
        else:  # kept clear of the world where the notes the IK pass made do not bound a planned pose clear
            lows_of = partial(bound.pose_lows, notes=notes, index=index, reach=MARGIN)
            planned = keep_clear(model, plan, lows_of, qs)
    except BaseException:
        if bound is not None:
            bound.record(False)
        raise
    if bound is not None and notes is not None:  # the plan's moves bounded from the notes the IK pass made
        starts = np.vstack([np.asarray(q_start, dtype=np.float64)[None], planned[:-1]])
        bound.prove(starts, planned, notes, index)
    seconds = time.perf_counter() - t0
    return PathPlan(planned, results, np.asarray(positions), tuple(clamped.tolist()), seconds)


def _tool_goals(
    chain: Chain,
    polish: Polish | None,
    results: Sequence[IKResult],
    qs: Array,
    positions: Array,
    lower: Array,
    upper: Array,
) -> tuple[Array, Array, Array]:
    """The IK poses ``qs`` ``(n, n_joints)`` rad polished (when ``polish``), their tool point's Jacobians
    ``(n, 3, n_joints)`` and residuals ``(n, 3)`` m (:func:`tool_task`), zero on the ticks whose IK stopped short of
    a collision (``results``' ``blocked``): the goal there is the IK's nearest clear pose, not the target."""
    blocked = np.array([[r.blocked] for r in results], dtype=bool).reshape(len(results), 1)
    jacobians, residuals = tool_task([(chain, slice(None))], qs, positions, blocked)
    if polish is not None:  # (never on a blocked tick)
        qs, residuals = polish.step(qs, jacobians, residuals, polish.safe(results, positions), lower, upper)
    return qs, jacobians, residuals


def tool_task(
    parts: Sequence[tuple[Chain, slice]], q: Array, targets: Array, held: npt.NDArray[np.bool_] | None = None
) -> tuple[Array, Array]:
    """:func:`plan_path`'s ``jacobians`` ``(n, 3 n_parts, n_joints)`` and ``residuals`` ``(n, 3 n_parts)`` m for
    the poses ``q`` ``(n, n_joints)`` rad and the targets ``(n, 3 n_parts)`` m (base frames), one tool point per
    part: each ``(chain, joints)`` (one arm: ``slice(None)``; a rig: each arm's slice of the joint vector) gives its
    tool point's Jacobian in its own three rows and its own joints (block-diagonal: an arm's joints move only its
    own tool), and its residual, the tool point minus its target.  ``held`` ``(n, n_parts)``: the ticks where a part
    has no task, its rows zero (its IK stopped short of a collision: the goal there is the nearest clear pose).

    >>> from retarget.arm.load import load_arm
    >>> arm = load_arm("wx250s")
    >>> J, r = tool_task([(arm.chain, slice(None))], arm.home[None], np.zeros((1, 3)))
    >>> J.shape, bool(np.allclose(r, arm.chain.tool_points(arm.home[None])))
    ((1, 3, 6), True)
    """
    jacobians, residuals = np.zeros((len(q), 3 * len(parts), q.shape[1])), np.empty((len(q), 3 * len(parts)))
    for k, (chain, joints) in enumerate(parts):
        rows = slice(3 * k, 3 * k + 3)
        tool, jacobians[:, rows, joints] = chain.tool_jacobians(q[:, joints])
        residuals[:, rows] = tool - targets[:, rows]
        if held is not None:
            jacobians[held[:, k], rows], residuals[held[:, k], rows] = 0.0, 0.0
    return jacobians, residuals


def solve_path(solver: _Solver, positions: Array, rotations: Array | None, q_start: Array) -> tuple[IKResult, ...]:
    """IK of every target ``positions`` ``(n, 3)`` m (``rotations`` ``(n, 3, 3)`` or None), each warm-started from
    the last solution, the first from ``q_start`` ``(n_joints,)`` rad: the unplanned joint path, one result a tick."""
    return _solve(solver, positions, rotations, q_start, None)[0]


def _solve(
    solver: _Solver,
    positions: Array,
    rotations: Array | None,
    q_start: Array,
    notes: list[State] | None,
    max_step: Array | None = None,
    share: float = PLAN_TOLERANCE,
) -> tuple[tuple[IKResult, ...], list[int]]:
    """:func:`solve_path`, and per tick the index in ``notes`` (a list the collision bound appends its notes to,
    :meth:`~retarget.ik.bound.ClearanceBound.record`; None: no indices) of the last note after its solve.

    With ``rotations`` and ``max_step`` ``(n_joints,)`` rad per slot, each tick is warm-started from the last seed
    moved toward the last solution by at most ``max_step``: where a joint at full speed would be, as the causal loop
    seeds it.  Seeded from the last solution itself, the roll joints wind up near the wrist singularity (the roll
    axes aligned) until they reach their limits and the IK stalls there: the demo clip at orientation weight 0.5
    converged on 44 % of ticks, tracking p95 291 mm; seeded so, 99.7 % and 18 mm.  Position-only paths keep the
    last solution (on the shared clips a speed-limited seed tracked no better and took more sweeps)."""
    solve, q = solver.solve, np.asarray(q_start, dtype=np.float64)
    own = getattr(solver, "tolerance", None)
    if own is not None:
        solve = partial(solver.solve, tolerance=share * own)  # type: ignore[call-arg]
    results = []
    index: list[int] = []
    for i in range(len(positions)):
        result = solve(positions[i], q, None if rotations is None else rotations[i])
        results.append(result)
        if notes is not None:
            index.append(len(notes) - 1)
        if rotations is None or max_step is None:
            q = result.q
        else:  # the next seed: where an arm at max speed toward this solution would be
            q = q + np.clip(result.q - q, -max_step, max_step)
    return tuple(results), index
