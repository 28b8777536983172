"""Limit-aware cyclic coordinate descent (CCD) inverse kinematics.

One *sweep* visits every joint once.  Joint ``j`` (unit world axis ``a`` through pivot
``p``) takes the exact minimiser of the tool-to-target distance over its own angle,
with ``u = e - p`` (tool point) and ``v = t - p`` (target)::

    theta* = atan2(a . (u x v), u . v - (a . u)(a . v))      # = atan2(a.(u⊥ x v⊥), u⊥ . v⊥)
    q_j   <- clamp(q_j + w_j theta*, lower_j, upper_j)

``theta*`` lies in ``(-pi, pi]`` and the clamp never wraps, so no joint ever jumps
through a limit or by a full turn, and since the distance is unimodal in ``q_j`` it
never grows.  The tool point (and, base-first, the rest of the chain) is then turned
about that joint incrementally, so a sweep costs one forward pass plus ``n_joints``
closed-form updates, all in plain Python floats (numpy per joint is ~9x slower at this
size).  Sweeps go base first by default (:class:`SweepOrder`).

Around that update:

- **smallest motion first** (position targets within reach): up to ``dls_steps`` damped least squares steps
  from ``q0`` (:mod:`~retarget.ik.dls`), aiming at a quarter of ``tolerance``: a warm tick ends with the
  weighted minimum-norm motion instead of CCD's exact per-joint minimisers, which swing a joint by tenths of a
  radian per millimetre near a folded elbow (the tracking error on motion_walk left fell from 97 to 30 mm p95);
  CCD takes over from where they stop when they do not converge (a jump, a joint limit, a cold solve);
- **early-out**: nothing runs when the tool is already within a quarter of ``tolerance``
  (within ``tolerance`` with ``dls_steps=0``), and a sweep stops as soon as it gets there;
- **locked joints**: a weight of 0 keeps the joint at its ``q0`` value through every step, line search and
  restart (the redundant roll joints of a position-only target, :func:`~retarget.mapping.workspace.ik_weights`);
- **the base axis**: near the base's vertical axis a small target move asks the waist for up to a half turn;
  within ``base_radius`` of it (and for a small move: the tool within ``base_radius`` of the target) the base's
  weight is scaled by ``(r / base_radius)^2`` and its step in the solve capped, so the arm keeps its branch
  (reaching over the axis) and accepts a position error of at most ``r``, the target's distance from the axis,
  wherever the other joints reach the arm's vertical plane; a real move to the other side (outside
  ``base_radius``, or a jump) still turns the waist;
- **budget**: ``max_iterations`` sweeps per call (restarts included); when it runs
  out the best pose found is returned with ``converged=False`` and its residual;
- **line search**: CCD crawls along narrow valleys (a stretched arm); after a sweep
  that leaves more than ``accel_ratio`` of the squared distance, the step it made is
  extended (x2, x4, ...) while that keeps lowering the distance;
- **escape from limit minima**: when a sweep improves the squared distance by less than
  ``1 - stall_ratio`` (typically a joint pinned on a limit) and the target is within the
  arm's reach bound, the solve restarts from a deterministic pseudo-random seed
  (``seed``): first the best pose perturbed a little, then uniform inside the limits,
  keeping the best pose;
- **short levers**: a joint whose lever ``|u⊥|`` is shorter than ``short_lever`` takes
  only ``(|u⊥| / short_lever)^2`` of its update (the Jacobian-transpose scaling), so a
  forearm roll with a straight wrist does not swing far for a millimetre;
- **trust region** (optional ``max_step``, one value or one per joint): no joint moves more than that from
  ``q0``; a control loop that passes what each joint can move this tick gets the best pose it can reach;
- **orientation** (optional ``rotation``): the Wang & Chen position + orientation
  update, ``phi* = atan2(k3, k2 - k1)``, with position terms scaled by the arm's reach so
  that ``orientation_weight`` is dimensionless; CCD crawls near a wrist singularity (the roll axes aligned),
  so when it has not converged, the last quarter of the budget (at most ``dls_steps``) polishes the best pose
  with 6-D DLS steps (demo clip at weight 0.5: 99.6 % of ticks converge, from 98.7 %);
- **unreachable targets**: the result is the closest pose found, never NaN.

Arrays: ``q`` is ``(n_joints,)`` float64 radians in ``Arm.joint_names`` order;
targets are ``(3,)`` metres in the arm's base frame; ``rotation`` is a ``(3, 3)``
rotation matrix of the tool frame in the base frame.

Use :class:`CCDSolver` in a control loop (everything constant is precomputed once);
:func:`solve_ik` builds one per arm and set of knobs and caches it on the arm.
"""

from __future__ import annotations

import enum
import math
import random
from collections.abc import Sequence
from typing import TYPE_CHECKING, TypeAlias

import numpy as np

from retarget.arm.model import Arm
from retarget.errors import ConfigError, require_count, require_positive
from retarget.ik.collide import CollisionGuard
from retarget.ik.dls import dls_pose_steps, dls_steps
from retarget.ik.result import IKResult

if TYPE_CHECKING:
    from retarget.collision import CollisionModel

__all__ = ["IKResult", "CCDSolver", "SweepOrder", "Weighting", "solve_ik", "joint_weights"]

_atan2 = math.atan2
_cos = math.cos
_sin = math.sin
_DEFAULT = object()
#: radians: the base's largest step in one solve at half ``base_radius`` from its axis is a third of this
_BASE_STEP = 0.1
#: a DLS solve aims at this fraction of the tolerance squared (a quarter of it): a warm tick then lands close to
#: its target instead of anywhere within the tolerance, so the tool point does not wander by up to the tolerance
#: from tick to tick (teleop's Cartesian speed limit held to 5.3 mm per 10 ticks at 5 cm/s, from 7.8)
_AIM2 = 0.25**2
_EPS2 = 1e-16  #: |u⊥|^2 |v⊥|^2 below this (m^4): the joint cannot move the tool toward the target

#: What ``CCDSolver._fk`` returns: the tool point ``(x, y, z)``, then the tool rotation row by row (12 floats).
_ToolPose: TypeAlias = tuple[float, float, float, float, float, float, float, float, float, float, float, float]
#: A 3x3 rotation as rows of floats.
_Rows: TypeAlias = tuple[tuple[float, ...], ...]


class Weighting(enum.Enum):
    """Per-joint CCD weights ``w_j`` scaling each joint's update (``j = 0`` is the base, ``n`` joints).

    ``UNIFORM`` (1 for every joint) is the default: it takes each joint's exact minimiser,
    which converges in the fewest sweeps, and warm starts keep the motion small.  The
    others damp the joints near the base so the motion favours the wrist:
    ``LINEAR`` ``(j+1)/n``, ``SQRT`` ``sqrt((j+1)/n)``, ``POWER`` ``((j+1)/n)**exponent``.
    """

    UNIFORM = "uniform"
    LINEAR = "linear"
    SQRT = "sqrt"
    POWER = "power"


def joint_weights(
    n: int, weights: Weighting | str | Sequence[float] | np.ndarray = Weighting.UNIFORM, *, exponent: float = 2.0
) -> tuple[float, ...]:
    """The ``(n,)`` per-joint weights of a :class:`Weighting` (or its name) or explicit values in ``[0, 1]``.

    A weight of 0 *locks* the joint: no update, line search or restart moves it (a position-only target's
    redundant roll joints, see :func:`retarget.mapping.workspace.ik_weights`); at least one must be > 0."""
    if isinstance(weights, str | Weighting):
        try:
            kind = Weighting(weights)
        except ValueError:
            names = ", ".join(w.value for w in Weighting)
            message = f"unknown weighting; expected one of {names} or {n} numbers"
            raise ConfigError(message, key="weights", value=weights) from None
        frac = [(j + 1) / n for j in range(n)]
        if kind is Weighting.UNIFORM:
            return (1.0,) * n
        if kind is Weighting.LINEAR:
            return tuple(frac)
        if kind is Weighting.SQRT:
            return tuple(math.sqrt(f) for f in frac)
        if not (math.isfinite(exponent) and exponent > 0):
            raise ConfigError("weight exponent must be a finite number > 0", key="weight_exponent", value=exponent)
        return tuple(f**exponent for f in frac)
    values = np.asarray(weights, dtype=np.float64)
    if values.shape != (n,):
        raise ConfigError(f"Expected {n} per-joint weights, got shape {values.shape}", key="weights", value=weights)
    if not np.all((values >= 0) & (values <= 1)) or not np.any(values > 0):
        raise ConfigError("per-joint weights must lie in [0, 1], one > 0", key="weights", value=values.tolist())
    return tuple(values.tolist())


class SweepOrder(enum.Enum):
    """The order a position sweep visits the joints.

    ``BASE_FIRST`` (the default) carries the rest of the chain along after each update;
    proximal joints have the longest levers, so warm-started corrections end with the
    smallest joint motion (on the wx250s benchmark path at most 0.012 rad per tick,
    against 0.03 tip-first) and cold solves need about half the sweeps.
    ``TIP_FIRST`` is the classic CCD order, a little cheaper per sweep.  Orientation
    targets always sweep tip first.
    """

    BASE_FIRST = "base-first"
    TIP_FIRST = "tip-first"


def _principal(axis: tuple[float, float, float]) -> tuple[int, float]:
    """(0|1|2, sign) when ``axis`` is +-x, +-y or +-z, else (-1, 1)."""
    for k in range(3):
        if abs(abs(axis[k]) - 1.0) < 1e-12 and all(abs(axis[i]) < 1e-12 for i in range(3) if i != k):
            return k, math.copysign(1.0, axis[k])
    return -1, 1.0


class CCDSolver:
    """A reusable CCD solver for one arm: everything constant is precomputed once.

    Keyword-only knobs (the defaults are what the control loop uses):

    - ``tolerance``: metres, position convergence (default 1 mm);
    - ``max_iterations``: sweep budget per solve, restarts included (default 100);
    - ``weights``: a :class:`Weighting`, its name, or ``n_joints`` values in ``[0, 1]`` (0 locks a joint)
      (default uniform, see :class:`Weighting`); ``weight_exponent`` for ``power`` (default 2);
    - ``order``: :class:`SweepOrder` (default base-first);
    - ``orientation_weight``: weight of the orientation terms against the (reach-scaled)
      position terms (default 0.1: it solved the most random 6-DOF poses);
      ``orientation_tolerance``: radians (default 0.01);
    - ``restarts``: how many new seeds may be tried after stalls (default 16); the first
      ``local_restarts`` (default 4) perturb the best pose so far by Gaussian noise of
      ``perturbation * k`` rad (default 0.1, k = 1, 2, ...) to stay near the current branch
      (no jumps while tracking), the rest are uniform inside the limits;
      ``stall_ratio``: a sweep that leaves more than this fraction of the squared distance
      is a stall (default 0.99); ``seed``: seeds the pseudo-random restarts, so a solve is a
      pure function of its inputs;
    - ``accel_ratio``: a sweep that leaves more than this fraction of the squared distance is
      followed by a line search along its step (default 0.5; 0 turns it off);
    - ``short_lever``: metres (default 0.2 x the arm's reach, :attr:`reach`): a joint whose
      lever ``|u⊥|`` is shorter takes ``(|u⊥| / short_lever)^2`` of its update; 0 turns it off;
    - ``max_step``: radians, a trust region: no joint moves more than this from ``q0`` in one
      solve (default None: only the limits).  A control loop may pass its per-tick velocity
      limit here (per call, one value per joint) so that the solution is reachable within the tick;
    - ``dls_steps``: damped least squares steps tried first on a position target, and at most that many
      polishing an unconverged pose target (default 8; 0: CCD only); ``damping``: their ``lambda``, metres
      (default 0.01: at most 50 rad per metre of error along a singular direction);
    - ``base_radius``: metres (default 0.1 x :attr:`reach`; 0 turns it off; 0 when the first joint is not
      the base frame's vertical axis): the waist is damped for targets this close to its axis;
    - ``collision``: a :class:`~retarget.collision.CollisionModel`: no result comes closer than its
      clearance to a collision (:mod:`~retarget.ik.collide`; ``IKResult.blocked`` when the target
      cannot be reached clear); None (default): no check.

    A solver keeps scratch buffers: use one per thread.
    """

    def __init__(
        self,
        arm: Arm,
        *,
        tolerance: float = 1e-3,
        max_iterations: int = 100,
        weights: Weighting | str | Sequence[float] | np.ndarray = Weighting.UNIFORM,
        weight_exponent: float = 2.0,
        orientation_weight: float = 0.1,
        orientation_tolerance: float = 1e-2,
        restarts: int = 16,
        local_restarts: int = 4,
        perturbation: float = 0.1,
        stall_ratio: float = 0.99,
        seed: int = 0,
        accel_ratio: float = 0.5,
        max_step: float | None = None,
        short_lever: float | None = None,
        order: SweepOrder | str = SweepOrder.BASE_FIRST,
        collision: CollisionModel | None = None,
        dls_steps: int = 8,
        damping: float = 0.01,
        base_radius: float | None = None,
    ):
        self.arm = arm
        self.dls_steps = require_count(dls_steps, "dls_steps", zero=True)
        self.damping = require_positive(damping, "damping")
        n = self.n = arm.n_joints
        self.tolerance = require_positive(tolerance, "tolerance")
        self.max_iterations = require_count(max_iterations, "max_iterations")
        self.weights = joint_weights(n, weights, exponent=weight_exponent)
        self.orientation_weight = require_positive(orientation_weight, "orientation_weight", zero=True)
        self.orientation_tolerance = require_positive(orientation_tolerance, "orientation_tolerance")
        self.restarts = require_count(restarts, "restarts", zero=True)
        self.local_restarts = require_count(local_restarts, "local_restarts", zero=True)
        self.perturbation = require_positive(perturbation, "perturbation")
        if not 0 < stall_ratio < 1:
            raise ConfigError("stall_ratio must lie in (0, 1)", key="stall_ratio", value=stall_ratio)
        self.stall_ratio = float(stall_ratio)
        self.seed = seed
        if not 0 <= accel_ratio < 1:
            raise ConfigError("accel_ratio must lie in [0, 1)", key="accel_ratio", value=accel_ratio)
        self.accel_ratio = float(accel_ratio) if accel_ratio > 0 else math.inf
        self._accel_steps = 5
        try:
            self.order = SweepOrder(order)
        except ValueError:
            names = ", ".join(o.value for o in SweepOrder)
            raise ConfigError(f"unknown sweep order; expected one of {names}", key="order", value=order) from None
        self.max_step = None if max_step is None else require_positive(max_step, "max_step")
        self.lower = tuple(float(j.lower) for j in arm.joints)
        self.upper = tuple(float(j.upper) for j in arm.joints)
        self._lo, self._hi = self.lower, self.upper  # the bounds of the current solve
        self._carried: tuple[float, float, float] = (0.0, 0.0, 0.0)  # tool point after a full base-first sweep
        # per joint: origin translation, origin rotation (None when identity), axis, principal kind/sign
        joints = []
        for j in arm.joints:
            rot = _rpy_rows(j.origin_rpy)
            kind, sign = _principal(j.axis)
            joints.append((tuple(map(float, j.origin_xyz)), rot, tuple(map(float, j.axis)), kind, sign))
        self._joints = tuple(joints)
        self._tool = tuple(map(float, arm.tool_xyz))
        self._tool_rot = _rpy_rows(arm.tool_rpy)
        # reach bound from the first pivot: a target farther than this cannot be reached
        lengths = [math.dist((0, 0, 0), jt[0]) for jt in joints[1:]] + [math.dist((0, 0, 0), self._tool)]
        self.reach = sum(lengths)
        self.base_pivot = tuple(map(float, arm.joints[0].origin_xyz))
        self.short_lever = (
            0.2 * self.reach if short_lever is None else require_positive(short_lever, "short_lever", zero=True)
        )
        self._lever2 = self.short_lever**2
        # the base joint turns about the base frame's vertical axis: damped near that axis (singular there)
        j0 = arm.joints[0]
        vertical = _rpy_rows(j0.origin_rpy) is None and self._joints[0][3] == 2  # about the base frame's z
        self.base_radius = (
            (0.1 * self.reach if base_radius is None else require_positive(base_radius, "base_radius", zero=True))
            if vertical
            else 0.0
        )
        self._w = self.weights  # the weights of the current solve (the base's damped near its axis)
        # scratch buffers, reused by every solve (a solver is not thread-safe)
        self._px = [0.0] * n
        self._py = [0.0] * n
        self._pz = [0.0] * n
        self._ax = [0.0] * n
        self._ay = [0.0] * n
        self._az = [0.0] * n
        #: the forward pass the DLS steps ended on: ``(q, tool pose, the six buffers' contents)`` (the next tick's
        #: warm start is most often that ``q``: its pass is copied back instead of run again)
        self._fk_memo: tuple[list[float], tuple[float, ...], tuple[list[float], ...]] | None = None
        #: the collision model every result is verified against (None: none, no cost)
        self.collision = collision
        self._guard = None if collision is None else CollisionGuard(self, collision)

    # ---------------------------------------------------------------------------------------------------------------
    def _fk(self, q: list[float]) -> _ToolPose:
        """Forward pass over ``q``: fills the world pivots/axes buffers and returns 12 floats,
        the tool point ``(x, y, z)`` then the tool rotation row by row."""
        px, py, pz, ax, ay, az = self._px, self._py, self._pz, self._ax, self._ay, self._az
        r00 = r11 = r22 = 1.0
        r01 = r02 = r10 = r12 = r20 = r21 = 0.0
        x = y = z = 0.0
        j = 0
        for (tx, ty, tz), rot, (kx, ky, kz), kind, sign in self._joints:
            x += r00 * tx + r01 * ty + r02 * tz
            y += r10 * tx + r11 * ty + r12 * tz
            z += r20 * tx + r21 * ty + r22 * tz
            px[j] = x
            py[j] = y
            pz[j] = z
            if rot is not None:
                r00, r01, r02, r10, r11, r12, r20, r21, r22 = _mul(r00, r01, r02, r10, r11, r12, r20, r21, r22, rot)
            t = q[j]
            c = _cos(t)
            s = _sin(t) * sign
            if kind == 0:  # about x: columns 1, 2 turn
                ax[j] = sign * r00
                ay[j] = sign * r10
                az[j] = sign * r20
                r01, r02 = r01 * c + r02 * s, r02 * c - r01 * s
                r11, r12 = r11 * c + r12 * s, r12 * c - r11 * s
                r21, r22 = r21 * c + r22 * s, r22 * c - r21 * s
            elif kind == 1:  # about y: columns 2, 0 turn
                ax[j] = sign * r01
                ay[j] = sign * r11
                az[j] = sign * r21
                r02, r00 = r02 * c + r00 * s, r00 * c - r02 * s
                r12, r10 = r12 * c + r10 * s, r10 * c - r12 * s
                r22, r20 = r22 * c + r20 * s, r20 * c - r22 * s
            elif kind == 2:  # about z: columns 0, 1 turn
                ax[j] = sign * r02
                ay[j] = sign * r12
                az[j] = sign * r22
                r00, r01 = r00 * c + r01 * s, r01 * c - r00 * s
                r10, r11 = r10 * c + r11 * s, r11 * c - r10 * s
                r20, r21 = r20 * c + r21 * s, r21 * c - r20 * s
            else:  # general axis: Rodrigues
                ax[j] = r00 * kx + r01 * ky + r02 * kz
                ay[j] = r10 * kx + r11 * ky + r12 * kz
                az[j] = r20 * kx + r21 * ky + r22 * kz
                r00, r01, r02, r10, r11, r12, r20, r21, r22 = _mul(
                    r00, r01, r02, r10, r11, r12, r20, r21, r22, _rodrigues(kx, ky, kz, t)
                )
            j += 1
        tx, ty, tz = self._tool
        x += r00 * tx + r01 * ty + r02 * tz
        y += r10 * tx + r11 * ty + r12 * tz
        z += r20 * tx + r21 * ty + r22 * tz
        if self._tool_rot is not None:
            r00, r01, r02, r10, r11, r12, r20, r21, r22 = _mul(
                r00, r01, r02, r10, r11, r12, r20, r21, r22, self._tool_rot
            )
        return x, y, z, r00, r01, r02, r10, r11, r12, r20, r21, r22

    def tool_point(self, q: Sequence[float] | np.ndarray) -> tuple[float, float, float]:
        """The tool point ``(x, y, z)`` metres, base frame, of ``q`` ``(n_joints,)`` radians."""
        return self._fk(list(map(float, q)))[:3]

    # ---------------------------------------------------------------------------------------------------------------
    def solve(
        self,
        target: Sequence[float] | np.ndarray,
        q0: Sequence[float] | np.ndarray,
        rotation: np.ndarray | None = None,
        *,
        tolerance: float | None = None,
        max_iterations: int | None = None,
        max_step: float | Sequence[float] | np.ndarray | None | object = _DEFAULT,
    ) -> IKResult:
        """Solve for the tool point at ``target`` ``(3,)`` metres (base frame), starting from ``q0``.

        ``q0``: ``(n_joints,)`` radians, clipped into the limits first.  ``rotation``: optional
        ``(3, 3)`` rotation matrix, the target orientation of the tool frame in the base frame
        (position + orientation CCD; an arm with fewer than 6 joints can rarely match a full
        orientation: it then ends at the weighted compromise with ``converged=False``).
        ``tolerance`` (metres), ``max_iterations`` (sweeps and DLS steps; 0 only measures ``q0``) and
        ``max_step`` (radians from ``q0``, one value or ``(n_joints,)``; None: only the limits) override the
        solver's defaults for this call.

        Returns an :class:`IKResult`: ``q`` ``(n_joints,)`` float64 radians, always inside the
        limits (the closest pose found when the target is out of reach; never NaN), ``error``
        metres, ``orientation_error`` radians, ``converged``, ``iterations`` (CCD sweeps plus DLS steps),
        ``restarts``.
        Raises ``ValueError`` for a bad shape or a non-finite input (or a rotation that is not a
        proper rotation matrix) and :class:`~retarget.errors.ConfigError` for a bad override.

        >>> from retarget.arm.load import load_arm
        >>> arm = load_arm("wx250s")
        >>> solver = CCDSolver(arm)
        >>> T, _ = arm.fk([0.2, -0.3, 0.4, 0.0, 0.5, 0.0])  # a reachable tool pose
        >>> result = solver.solve(T[:3, 3], arm.home)
        >>> result.converged, result.error <= solver.tolerance, result.q.shape
        (True, True, (6,))
        >>> pose = solver.solve(T[:3, 3], arm.home, T[:3, :3], max_iterations=300)  # position and orientation
        >>> pose.converged, pose.orientation_error <= solver.orientation_tolerance
        (True, True)
        >>> solver.solve([0.3, 0.0], arm.home)
        Traceback (most recent call last):
        ...
        ValueError: Expected target of shape (3,), got (2,)
        """
        result = self._solve_free(target, q0, rotation, tolerance=tolerance, max_iterations=max_iterations,
                                  max_step=max_step)  # fmt: skip
        guard = self._guard
        if guard is None:
            return result
        clear, m = guard.check(result.q)
        if clear:
            result.clearance = m  # (a result of this call, not yet seen by anyone)
            return result
        lower, upper = self._lo, self._hi
        seed = [lo if v < lo else hi if v > hi else v for v, lo, hi in zip(_joint_vector(q0, self.n), lower, upper,
                                                                           strict=True)]  # fmt: skip
        tol = self.tolerance if tolerance is None else float(tolerance)
        budget = self.max_iterations if max_iterations is None else int(max_iterations)
        rows = None if rotation is None else _rotation(rotation)
        return guard.resolve(_vec3(target, "target"), seed, rows, tol, max(budget, 1))

    def _solve_free(
        self,
        target: Sequence[float] | np.ndarray,
        q0: Sequence[float] | np.ndarray,
        rotation: np.ndarray | None = None,
        *,
        tolerance: float | None = None,
        max_iterations: int | None = None,
        max_step: float | Sequence[float] | np.ndarray | None | object = _DEFAULT,
    ) -> IKResult:
        """:meth:`solve` without the collision check."""
        n = self.n
        tx, ty, tz = _vec3(target, "target")
        q = _joint_vector(q0, n)
        lower, upper = self.lower, self.upper
        q = [lo if v < lo else hi if v > hi else v for v, lo, hi in zip(q, lower, upper, strict=True)]
        step = self.max_step if max_step is _DEFAULT else max_step
        if step is None:
            self._lo, self._hi = lower, upper
        else:  # a trust region around q0: no joint moves more than `step` (per joint) in this solve
            steps = _steps(step, n)
            self._lo = tuple(lo if v - d < lo else v - d for v, d, lo in zip(q, steps, lower, strict=True))
            self._hi = tuple(hi if v + d > hi else v + d for v, d, hi in zip(q, steps, upper, strict=True))
        tol = self.tolerance if tolerance is None else require_positive(tolerance, "tolerance")
        budget = (
            self.max_iterations
            if max_iterations is None
            else require_count(max_iterations, "max_iterations", zero=True)
        )
        self._w = self.weights
        if rotation is not None:
            return self._solve_pose(tx, ty, tz, _rotation(rotation), q, tol, budget)
        tol2 = tol * tol
        if self.base_radius > 0.0:
            self._damp_base(tx, ty, tz, q)
        bx, by, bz = self.base_pivot
        can_restart = math.dist((tx, ty, tz), (bx, by, bz)) < self.reach
        used = 0
        if self.dls_steps and budget and can_restart:  # the smallest motion first: DLS from q0, aiming past tol
            err2, used = dls_steps(self, q, tx, ty, tz, tol2 * _AIM2, min(self.dls_steps, budget), self.damping)
            if err2 <= tol2:
                return IKResult(np.array(q), math.sqrt(err2), used, True)
            budget -= used

        f = self._fk(q)
        dx, dy, dz = f[0] - tx, f[1] - ty, f[2] - tz
        err2 = dx * dx + dy * dy + dz * dz
        if err2 <= tol2 or budget == 0:
            return IKResult(np.array(q), math.sqrt(err2), used, err2 <= tol2)

        best_q, best2 = q[:], err2
        restarts = 0
        rng: random.Random | None = None
        prev2 = err2
        sweeps = 0
        sweep = self._sweep_forward if self.order is SweepOrder.BASE_FIRST else self._sweep
        stall = self.stall_ratio
        accel = self.accel_ratio
        carried = self.order is SweepOrder.BASE_FIRST  # a full base-first sweep leaves the buffers current
        fresh: tuple[float, ...] | None = f  # the pivot/axis buffers hold the forward pass of q, f[:3] the tool point
        while sweeps < budget:
            sweeps += 1
            before = q[:]
            err2 = sweep(q, tx, ty, tz, tol2, fresh)
            fresh = self._carried if carried else None
            if err2 > tol2 and err2 > prev2 * accel:  # slow progress: extrapolate along the sweep's step
                err2 = self._extrapolate(q, before, err2, tx, ty, tz)
                fresh = None
            if err2 < best2:
                best_q, best2 = q[:], err2
                if err2 <= tol2:
                    break
            if err2 > prev2 * stall:  # stalled: most often a joint pinned on a limit
                if not can_restart:  # out of reach: stop once a sweep gains less than 1% of the tolerance
                    if math.sqrt(prev2) - math.sqrt(err2) < 0.01 * tol:
                        break
                elif restarts >= self.restarts:  # out of seeds: crawl on while it gains anything
                    if err2 >= prev2:
                        break
                else:
                    restarts += 1
                    if rng is None:
                        rng = random.Random(self.seed)
                    q = self._restart_seed(rng, restarts, best_q)
                    f = fresh = self._fk(q)
                    dx, dy, dz = f[0] - tx, f[1] - ty, f[2] - tz
                    err2 = dx * dx + dy * dy + dz * dz
            prev2 = err2
        return IKResult(np.array(best_q), math.sqrt(best2), used + sweeps, best2 <= tol2, restarts=restarts)

    def _damp_base(self, tx: float, ty: float, tz: float, q: list[float]) -> None:
        """Near the base's vertical axis (the target's horizontal distance ``r`` from it below ``R = base_radius``)
        and for a small move (the tool point of ``q`` within ``R`` of the target): scale the base's weight by
        ``(r / R)^2`` and let it move at most ``_BASE_STEP (r/R)^2 / (1 - (r/R)^2)`` radians from ``q`` in this
        solve (0 on the axis, no cap at ``R``), so that a target passing near the axis does not flip the waist; the
        arm keeps its branch and the position error stays below ``r`` wherever the other joints can reach the
        arm's vertical plane.  A cold solve or a jump (the tool farther than ``R``) is not damped."""
        bx, by, _ = self.base_pivot
        radius = self.base_radius
        r2 = ((tx - bx) ** 2 + (ty - by) ** 2) / (radius * radius)
        if r2 >= 1.0:
            return
        f = self._fk(q)
        dx, dy, dz = f[0] - tx, f[1] - ty, f[2] - tz
        if dx * dx + dy * dy + dz * dz > radius * radius:
            return
        self._w = (self.weights[0] * r2, *self.weights[1:])
        cap = _BASE_STEP * r2 / (1.0 - r2)
        self._lo = (max(self._lo[0], q[0] - cap), *self._lo[1:])
        self._hi = (min(self._hi[0], q[0] + cap), *self._hi[1:])

    def _extrapolate(self, q: list[float], before: list[float], err2: float, tx: float, ty: float, tz: float) -> float:
        """Line search along the last sweep's step ``q - before``: try ``q + alpha (q - before)``, alpha = 2, 4, 8, ...

        CCD crawls along narrow valleys (a stretched arm, a folded wrist); the sweep's own
        step points along the valley.  Each trial is clamped to the limits and kept only
        while it lowers the distance, so this never makes a solve worse.  Updates ``q`` in
        place and returns the squared distance.
        """
        lower, upper = self._lo, self._hi
        step = [a - b for a, b in zip(q, before, strict=True)]
        alpha = 2.0
        for _ in range(self._accel_steps):
            trial = [
                lo if v < lo else hi if v > hi else v
                for v, lo, hi in zip([a + alpha * d for a, d in zip(q, step, strict=True)], lower, upper, strict=True)
            ]
            f = self._fk(trial)
            dx, dy, dz = f[0] - tx, f[1] - ty, f[2] - tz
            e2 = dx * dx + dy * dy + dz * dz
            if e2 >= err2:
                break
            q[:] = trial
            err2 = e2
            alpha *= 2.0
        return err2

    def _restart_seed(self, rng: random.Random, k: int, best: list[float]) -> list[float]:
        """Seed of restart ``k`` (1-based): the best pose perturbed (Gaussian, ``perturbation * k`` rad) for the
        first ``local_restarts``, so a warm solve stays on its branch; then uniform inside the limits."""
        lower, upper = self._lo, self._hi
        if k <= self.local_restarts:
            sigma = self.perturbation * k
            seed = [min(max(b + rng.gauss(0.0, sigma), lo), hi) for b, lo, hi in zip(best, lower, upper, strict=True)]
        else:
            seed = [rng.uniform(lo, hi) for lo, hi in zip(lower, upper, strict=True)]
        # locked joints and a damped base (a target near its axis) keep their value: a new seed must not flip it
        keep = [w < full or w == 0.0 for w, full in zip(self._w, self.weights, strict=True)]
        return [b if k else x for x, b, k in zip(seed, best, keep, strict=True)]

    def _sweep(
        self, q: list[float], tx: float, ty: float, tz: float, tol2: float, fresh: tuple[float, ...] | None
    ) -> float:
        """One tip-to-base sweep on ``q`` (in place); returns the squared distance after it.

        ``fresh`` is the result of ``_fk(q)`` when the buffers already hold it (saves a forward pass).
        """
        f = self._fk(q) if fresh is None else fresh
        ex, ey, ez = f[0], f[1], f[2]
        px, py, pz, ax, ay, az = self._px, self._py, self._pz, self._ax, self._ay, self._az
        lower, upper, w = self._lo, self._hi, self._w
        lev2 = self._lever2
        for j in range(self.n - 1, -1, -1):
            x0, y0, z0 = px[j], py[j], pz[j]
            ux, uy, uz = ex - x0, ey - y0, ez - z0
            vx, vy, vz = tx - x0, ty - y0, tz - z0
            kx, ky, kz = ax[j], ay[j], az[j]
            au = kx * ux + ky * uy + kz * uz
            dot = ux * vx + uy * vy + uz * vz - au * (kx * vx + ky * vy + kz * vz)
            cx, cy, cz = ky * uz - kz * uy, kz * ux - kx * uz, kx * uy - ky * ux  # a x u
            cross = cx * vx + cy * vy + cz * vz  # a . (u x v)
            if dot * dot + cross * cross < _EPS2:
                continue
            old = q[j]
            lever2 = cx * cx + cy * cy + cz * cz  # |u⊥|^2
            if lever2 < lev2:  # a short lever: damp in proportion, the joint buys little for a big swing
                new = old + w[j] * _atan2(cross, dot) * (lever2 / lev2)
            else:
                new = old + w[j] * _atan2(cross, dot)
            if new < lower[j]:
                new = lower[j]
            elif new > upper[j]:
                new = upper[j]
            d = new - old
            if d == 0.0:
                continue
            q[j] = new
            c, s = _cos(d), _sin(d)
            k = au * (1.0 - c)
            ex = x0 + ux * c + cx * s + kx * k
            ey = y0 + uy * c + cy * s + ky * k
            ez = z0 + uz * c + cz * s + kz * k
            dx, dy, dz = ex - tx, ey - ty, ez - tz
            if dx * dx + dy * dy + dz * dz <= tol2:
                break
        dx, dy, dz = ex - tx, ey - ty, ez - tz
        return dx * dx + dy * dy + dz * dz

    def _sweep_forward(
        self, q: list[float], tx: float, ty: float, tz: float, tol2: float, fresh: tuple[float, ...] | None
    ) -> float:
        """One base-to-tip sweep on ``q`` (in place); returns the squared distance after it.

        Each update also turns the pivots and axes of the joints after it, so the next
        joint sees the moved chain.  Proximal joints have the longest levers, so small
        warm-start corrections end with the smallest joint motion.
        """
        f = self._fk(q) if fresh is None else fresh
        ex, ey, ez = f[0], f[1], f[2]
        px, py, pz, ax, ay, az = self._px, self._py, self._pz, self._ax, self._ay, self._az
        lower, upper, w = self._lo, self._hi, self._w
        lev2 = self._lever2
        n = self.n
        for j in range(n):
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
            old = q[j]
            lever2 = cx * cx + cy * cy + cz * cz
            if lever2 < lev2:
                new = old + w[j] * _atan2(cross, dot) * (lever2 / lev2)
            else:
                new = old + w[j] * _atan2(cross, dot)
            if new < lower[j]:
                new = lower[j]
            elif new > upper[j]:
                new = upper[j]
            d = new - old
            if d == 0.0:
                continue
            q[j] = new
            c, s = _cos(d), _sin(d)
            k = au * (1.0 - c)
            ex = x0 + ux * c + cx * s + kx * k
            ey = y0 + uy * c + cy * s + ky * k
            ez = z0 + uz * c + cz * s + kz * k
            dx, dy, dz = ex - tx, ey - ty, ez - tz
            if dx * dx + dy * dy + dz * dz <= tol2:
                break
            c1 = 1.0 - c
            for i in range(j + 1, n):  # carry the rest of the chain along
                wx, wy, wz = px[i] - x0, py[i] - y0, pz[i] - z0
                m = (kx * wx + ky * wy + kz * wz) * c1
                px[i] = x0 + wx * c + (ky * wz - kz * wy) * s + kx * m
                py[i] = y0 + wy * c + (kz * wx - kx * wz) * s + ky * m
                pz[i] = z0 + wz * c + (kx * wy - ky * wx) * s + kz * m
                wx, wy, wz = ax[i], ay[i], az[i]
                m = (kx * wx + ky * wy + kz * wz) * c1
                ax[i] = wx * c + (ky * wz - kz * wy) * s + kx * m
                ay[i] = wy * c + (kz * wx - kx * wz) * s + ky * m
                az[i] = wz * c + (kx * wy - ky * wx) * s + kz * m
        self._carried = (ex, ey, ez)
        dx, dy, dz = ex - tx, ey - ty, ez - tz
        return dx * dx + dy * dy + dz * dz

    # ---------------------------------------------------------------------------------------------------------------
    def _solve_pose(
        self, tx: float, ty: float, tz: float, rot: _Rows, q: list[float], tol: float, budget: int
    ) -> IKResult:
        """Position + orientation CCD (Wang & Chen), with the same line search and restarts as position-only.

        Progress is measured by the cost ``(distance / reach)^2 + orientation_weight * (3 - tr(R^T R_target))``.
        """
        rtol = self.orientation_tolerance
        wo = self.orientation_weight
        inv_reach2 = 1.0 / (self.reach * self.reach)

        g = (rot[0][0], rot[1][0], rot[2][0], rot[0][1], rot[1][1], rot[2][1], rot[0][2], rot[1][2], rot[2][2])

        def score(d2: float, tr: float) -> tuple[float, float, float]:
            angle = math.acos(min(1.0, max(-1.0, (tr - 1.0) * 0.5)))
            return d2 * inv_reach2 + wo * (3.0 - tr), math.sqrt(d2), angle

        def measure(qq: list[float]) -> tuple[float, float, float]:
            f = self._fk(qq)
            dx, dy, dz = f[0] - tx, f[1] - ty, f[2] - tz
            tr = (
                f[3] * rot[0][0] + f[4] * rot[0][1] + f[5] * rot[0][2]
                + f[6] * rot[1][0] + f[7] * rot[1][1] + f[8] * rot[1][2]
                + f[9] * rot[2][0] + f[10] * rot[2][1] + f[11] * rot[2][2]
            )  # fmt: skip
            return score(dx * dx + dy * dy + dz * dz, tr)

        cost, perr, oerr = measure(q)
        best_q, best = q[:], (cost, perr, oerr)
        bx, by, bz = self.base_pivot
        can_restart = math.dist((tx, ty, tz), (bx, by, bz)) < self.reach
        sweeps = restarts = 0
        rng: random.Random | None = None
        lower, upper = self._lo, self._hi
        ccd_budget = budget - min(self.dls_steps, budget // 4)  # the rest is kept for the DLS polish
        while not (perr <= tol and oerr <= rtol) and sweeps < ccd_budget:
            sweeps += 1
            before = q[:]
            prev = cost
            cost, perr, oerr = score(*self._sweep_pose(q, tx, ty, tz, g))
            if cost > prev * self.accel_ratio:  # slow: line search along the sweep's step
                step = [a - b for a, b in zip(q, before, strict=True)]
                alpha = 2.0
                for _ in range(self._accel_steps):
                    trial = [
                        min(max(a + alpha * d, lo), hi) for a, d, lo, hi in zip(q, step, lower, upper, strict=True)
                    ]
                    m = measure(trial)
                    if m[0] >= cost:
                        break
                    q[:] = trial
                    cost, perr, oerr = m
                    alpha *= 2.0
            if cost < best[0]:
                best_q, best = q[:], (cost, perr, oerr)
            if cost > prev * self.stall_ratio and not (perr <= tol and oerr <= rtol):
                if not can_restart or restarts >= self.restarts:
                    if cost >= prev:
                        break
                else:
                    restarts += 1
                    rng = rng or random.Random(self.seed)
                    q = self._restart_seed(rng, restarts, best_q)
                    cost, perr, oerr = measure(q)
        _, perr, oerr = best
        converged = perr <= tol and oerr <= rtol
        left = min(self.dls_steps, budget - sweeps)
        if not converged and left > 0:  # CCD crawls near a wrist singularity: DLS polishes the best pose
            done, used = dls_pose_steps(self, best_q, (tx, ty, tz), rot, tol, rtol, left, self.damping)
            sweeps += used
            if used:
                cost, perr, oerr = measure(best_q)
                converged = done
        return IKResult(np.array(best_q), perr, sweeps, converged, orientation_error=oerr, restarts=restarts)

    def _sweep_pose(self, q: list[float], tx: float, ty: float, tz: float, g: tuple[float, ...]) -> tuple[float, float]:
        """One tip-to-base position + orientation sweep on ``q`` in place: ``phi* = atan2(k3, k2 - k1)``.

        ``g`` holds the desired tool axes (the target rotation's columns) as 9 floats.  Returns
        the squared distance and ``tr(R^T R_target)`` after the sweep.
        """
        f = self._fk(q)
        ex, ey, ez = f[0], f[1], f[2]
        # current tool axes h0, h1, h2: the columns of the tool rotation
        h0x, h0y, h0z, h1x, h1y, h1z, h2x, h2y, h2z = f[3], f[6], f[9], f[4], f[7], f[10], f[5], f[8], f[11]
        g0x, g0y, g0z, g1x, g1y, g1z, g2x, g2y, g2z = g
        px, py, pz, ax, ay, az = self._px, self._py, self._pz, self._ax, self._ay, self._az
        lower, upper, w = self._lo, self._hi, self.weights
        scale = 1.0 / (self.reach * self.reach)
        wo = self.orientation_weight
        sqrt = math.sqrt
        for j in range(self.n - 1, -1, -1):
            x0, y0, z0 = px[j], py[j], pz[j]
            ux, uy, uz = ex - x0, ey - y0, ez - z0
            vx, vy, vz = tx - x0, ty - y0, tz - z0
            kx, ky, kz = ax[j], ay[j], az[j]
            nu = sqrt(ux * ux + uy * uy + uz * uz)
            nv = sqrt(vx * vx + vy * vy + vz * vz)
            wp = (1.0 + (nu / nv if nu < nv else nv / nu if nu > 0.0 else 1.0)) * scale
            au = kx * ux + ky * uy + kz * uz
            ah0 = kx * h0x + ky * h0y + kz * h0z
            ah1 = kx * h1x + ky * h1y + kz * h1z
            ah2 = kx * h2x + ky * h2y + kz * h2z
            k1 = wp * (kx * vx + ky * vy + kz * vz) * au + wo * (
                (kx * g0x + ky * g0y + kz * g0z) * ah0
                + (kx * g1x + ky * g1y + kz * g1z) * ah1
                + (kx * g2x + ky * g2y + kz * g2z) * ah2
            )
            k2 = wp * (ux * vx + uy * vy + uz * vz) + wo * (
                g0x * h0x
                + g0y * h0y
                + g0z * h0z
                + g1x * h1x
                + g1y * h1y
                + g1z * h1z
                + g2x * h2x
                + g2y * h2y
                + g2z * h2z
            )
            # k3 = a . (wp u x v + wo sum h_i x g_i)
            cx = wp * (uy * vz - uz * vy) + wo * (h0y * g0z - h0z * g0y + h1y * g1z - h1z * g1y + h2y * g2z - h2z * g2y)
            cy = wp * (uz * vx - ux * vz) + wo * (h0z * g0x - h0x * g0z + h1z * g1x - h1x * g1z + h2z * g2x - h2x * g2z)
            cz = wp * (ux * vy - uy * vx) + wo * (h0x * g0y - h0y * g0x + h1x * g1y - h1y * g1x + h2x * g2y - h2y * g2x)
            old = q[j]
            new = old + w[j] * _atan2(kx * cx + ky * cy + kz * cz, k2 - k1)
            if new < lower[j]:
                new = lower[j]
            elif new > upper[j]:
                new = upper[j]
            d = new - old
            if d == 0.0:
                continue
            q[j] = new
            c, s = _cos(d), _sin(d)
            c1 = 1.0 - c
            # Rodrigues on u and the three tool axes: x c + (k x x) s + k (k . x)(1 - c)
            m = au * c1
            ex = x0 + ux * c + (ky * uz - kz * uy) * s + kx * m
            ey = y0 + uy * c + (kz * ux - kx * uz) * s + ky * m
            ez = z0 + uz * c + (kx * uy - ky * ux) * s + kz * m
            m = ah0 * c1
            h0x, h0y, h0z = (
                h0x * c + (ky * h0z - kz * h0y) * s + kx * m,
                h0y * c + (kz * h0x - kx * h0z) * s + ky * m,
                h0z * c + (kx * h0y - ky * h0x) * s + kz * m,
            )
            m = ah1 * c1
            h1x, h1y, h1z = (
                h1x * c + (ky * h1z - kz * h1y) * s + kx * m,
                h1y * c + (kz * h1x - kx * h1z) * s + ky * m,
                h1z * c + (kx * h1y - ky * h1x) * s + kz * m,
            )
            m = ah2 * c1
            h2x, h2y, h2z = (
                h2x * c + (ky * h2z - kz * h2y) * s + kx * m,
                h2y * c + (kz * h2x - kx * h2z) * s + ky * m,
                h2z * c + (kx * h2y - ky * h2x) * s + kz * m,
            )
        dx, dy, dz = ex - tx, ey - ty, ez - tz
        tr = g0x * h0x + g0y * h0y + g0z * h0z + g1x * h1x + g1y * h1y + g1z * h1z + g2x * h2x + g2y * h2y + g2z * h2z
        return dx * dx + dy * dy + dz * dz, tr


# -------------------------------------------------------------------------------------------------------------------
def solve_ik(
    arm: Arm,
    target: Sequence[float] | np.ndarray,
    q0: Sequence[float] | np.ndarray | None = None,
    *,
    rotation: np.ndarray | None = None,
    tolerance: float = 1e-3,
    max_iterations: int = 100,
    max_step: float | None = None,
    weights: Weighting | str | Sequence[float] | np.ndarray = Weighting.UNIFORM,
    weight_exponent: float = 2.0,
    order: SweepOrder | str = SweepOrder.BASE_FIRST,
    orientation_weight: float = 0.1,
    orientation_tolerance: float = 1e-2,
    restarts: int = 16,
    seed: int = 0,
) -> IKResult:
    """Solve CCD IK on ``arm`` for the tool point at ``target`` ``(3,)`` metres (base frame).

    ``q0``: the start, ``(n_joints,)`` radians (default ``arm.home``; clipped into the limits).
    ``rotation``: optional ``(3, 3)`` rotation matrix, the tool frame's target orientation in the
    base frame.  ``tolerance`` (metres), ``max_iterations`` (sweeps) and ``max_step`` (radians per
    joint from ``q0``) apply to this call; the other knobs are those of :class:`CCDSolver` (the
    module docstring has the method).  The solver is built once per arm and set of knobs and cached
    on the arm, so calling this every tick costs little more than :meth:`CCDSolver.solve`.

    Returns an :class:`IKResult`: ``q`` ``(n_joints,)`` float64 radians, always inside the limits
    (the closest pose found when the target is out of reach; never NaN), ``error`` metres,
    ``converged``, ``iterations``.  Raises ``ValueError`` for a bad shape or a non-finite input and
    :class:`~retarget.errors.ConfigError` for a bad knob.

    >>> from retarget.arm.load import load_arm
    >>> arm = load_arm("wx250s")
    >>> result = solve_ik(arm, [0.3, 0.0, 0.2])  # from home
    >>> result.converged, result.error <= 1e-3, arm.within_limits(result.q)
    (True, True, True)
    >>> far = solve_ik(arm, [2.0, 0.0, 0.5], result.q)  # out of reach: the closest pose, not converged
    >>> far.converged, round(far.error, 1), arm.within_limits(far.q)
    (False, 1.4, True)
    """
    key = (
        "ik",
        _freeze(weights),
        weight_exponent,
        order.value if isinstance(order, SweepOrder) else order,
        orientation_weight,
        orientation_tolerance,
        restarts,
        seed,
    )
    solver: CCDSolver | None = arm._cache.get(key)
    if solver is None:
        solver = arm._cache[key] = CCDSolver(
            arm,
            weights=weights,
            weight_exponent=weight_exponent,
            order=order,
            orientation_weight=orientation_weight,
            orientation_tolerance=orientation_tolerance,
            restarts=restarts,
            seed=seed,
        )
    if q0 is None:
        q0 = arm.home
    return solver.solve(target, q0, rotation, tolerance=tolerance, max_iterations=max_iterations, max_step=max_step)


# -- float helpers ------------------------------------------------------------------------------------------------
def _freeze(weights: object) -> object:
    if isinstance(weights, str | Weighting):
        return Weighting(weights) if isinstance(weights, str) and weights in Weighting._value2member_map_ else weights
    return tuple(np.asarray(weights, dtype=np.float64).ravel().tolist())


def _rpy_rows(rpy: Sequence[float]) -> _Rows | None:
    """Rows of the URDF rpy rotation, or None for the identity (the common case, skipped in the loop)."""
    r, p, y = (float(v) for v in rpy)
    if r == p == y == 0.0:
        return None
    cr, sr, cp, sp, cy, sy = _cos(r), _sin(r), _cos(p), _sin(p), _cos(y), _sin(y)
    return (
        (cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr),
        (sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr),
        (-sp, cp * sr, cp * cr),
    )


def _rodrigues(x: float, y: float, z: float, t: float) -> _Rows:
    c, s = _cos(t), _sin(t)
    k = 1.0 - c
    return (
        (k * x * x + c, k * x * y - s * z, k * x * z + s * y),
        (k * x * y + s * z, k * y * y + c, k * y * z - s * x),
        (k * x * z - s * y, k * y * z + s * x, k * z * z + c),
    )


def _mul(
    r00: float, r01: float, r02: float, r10: float, r11: float, r12: float, r20: float, r21: float, r22: float, o: _Rows
) -> tuple[float, float, float, float, float, float, float, float, float]:
    """Row-major ``R @ O`` with ``R`` as 9 floats and ``O`` as rows."""
    (o00, o01, o02), (o10, o11, o12), (o20, o21, o22) = o
    return (
        r00 * o00 + r01 * o10 + r02 * o20, r00 * o01 + r01 * o11 + r02 * o21, r00 * o02 + r01 * o12 + r02 * o22,
        r10 * o00 + r11 * o10 + r12 * o20, r10 * o01 + r11 * o11 + r12 * o21, r10 * o02 + r11 * o12 + r12 * o22,
        r20 * o00 + r21 * o10 + r22 * o20, r20 * o01 + r21 * o11 + r22 * o21, r20 * o02 + r21 * o12 + r22 * o22,
    )  # fmt: skip


def _vec3(value: Sequence[float] | np.ndarray, what: str) -> tuple[float, float, float]:
    if isinstance(value, np.ndarray) and value.shape == (3,):
        x, y, z = value.tolist()
    elif isinstance(value, list | tuple) and len(value) == 3:
        try:
            x, y, z = float(value[0]), float(value[1]), float(value[2])
        except (TypeError, ValueError):
            raise ValueError(f"Expected {what} of 3 numbers, got {value!r}") from None
    else:
        v = np.asarray(value, dtype=np.float64)
        if v.shape != (3,):
            raise ValueError(f"Expected {what} of shape (3,), got {v.shape}")
        x, y, z = v.tolist()
    if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(z)):
        raise ValueError(f"Expected a finite {what}, got {[x, y, z]}")
    return x, y, z


def _steps(value: object, n: int) -> tuple[float, ...]:
    """``max_step`` as ``n`` radians > 0: one number for every joint, or one per joint."""
    if isinstance(value, int | float):
        return (require_positive(value, "max_step"),) * n
    values = np.asarray(value, dtype=np.float64).ravel()
    if values.shape != (n,):
        raise ConfigError(f"Expected one max_step or {n}, got shape {values.shape}", key="max_step", value=value)
    return tuple(require_positive(v, "max_step") for v in values.tolist())


def _joint_vector(value: Sequence[float] | np.ndarray, n: int) -> list[float]:
    q: list[float]
    if isinstance(value, np.ndarray) and value.shape == (n,) and value.dtype == np.float64:
        q = value.tolist()
    else:
        v = np.asarray(value, dtype=np.float64)
        if v.shape != (n,):
            raise ValueError(f"Expected q0 of shape ({n},), got {v.shape}")
        q = v.tolist()
    for x in q:
        if not math.isfinite(x):
            raise ValueError(f"Expected finite joint angles q0, got {q}")
    return q


def _rotation(value: np.ndarray) -> _Rows:
    r = np.asarray(value, dtype=np.float64)
    if r.shape != (3, 3):
        raise ValueError(f"Expected rotation of shape (3, 3), got {r.shape}")
    if not np.all(np.isfinite(r)) or not np.allclose(r @ r.T, np.eye(3), atol=1e-6) or np.linalg.det(r) < 0:
        raise ValueError("Expected rotation to be a proper rotation matrix (orthonormal, det +1)")
    return tuple(tuple(row) for row in r.tolist())
