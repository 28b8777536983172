"""A look-ahead plan kept clear of collisions: the clearance as constraints of the fit, where the plan comes near.

The look-ahead IK pass is collision-aware: each tick's pose keeps the collision model's clearance (where the target
needs a colliding pose, the IK ends at the nearest clear one).  The plan then fits a path near those poses within
the limits (:func:`~retarget.control.plan.plan_path`), and nothing in that fit knew about the collisions: around a
keep-out zone in the arm's way the fitted path cut through it (the demo clip with a 5 cm sphere in the way of the
right arm: 508 planned poses inside the clearance, 61 mm deep), so the loop's goal check blocked the planned moves
and stopped the arm at once (peak acceleration 232 rad/s^2), and the rest of the plan, made for an arm that had
moved on, stayed blocked: the arm stood there until the clip ended.

So, as TrajOpt does (Schulman et al., "Motion planning with sequential convex optimization and convex collision
checking", IJRR 2014), :func:`keep_clear` re-plans with the clearance linearised at the planned poses that come
near: per such tick ``t``, ``d_t + g_t . (q_t - p_t) >= clearance + 2 MARGIN`` (``d_t`` the nearest pair's
distance at the planned pose ``p_t``, ``g_t`` its gradient by finite differences), a halfspace the fit meets
(:class:`~retarget.control.fit.Halfspaces`), for up to :data:`ROUNDS` rounds.  Only the poses the IK pass's notes
do not bound above the clearance plus :data:`MARGIN` (:meth:`~retarget.ik.bound.ClearanceBound.pose_lows`) are
measured, so a clip that stays clear of everything costs an exact check of those alone.
Pure numpy over the collision model.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Protocol

import numpy as np
import numpy.typing as npt

from retarget.control.fit import Halfspaces

__all__ = ["MARGIN", "ROUNDS", "Model", "keep_clear", "near_ticks", "linearised"]

log = logging.getLogger(__name__)

Array = npt.NDArray[np.float64]

#: metres: a planned pose moved by the fit closer than the clearance plus this is constrained to keep the clearance
#: plus twice this (room for the moves between poses and the last pass of the profile, which follows the fit's path
#: within the limits, not exactly)
MARGIN = 2e-3
ROUNDS = 3  #: re-plans at most (the demo clip's sphere needed one)
_STEP = 1e-4  #: radians: the finite differences' step


class Model(Protocol):
    """What is used of a :class:`~retarget.collision.CollisionModel`."""

    clearance: float

    def world_distances(self, q: Array) -> Array: ...


def near_ticks(model: Model, planned: Array, goals: Array, lows: npt.ArrayLike) -> tuple[npt.NDArray[np.intp], Array]:
    """The ticks whose planned pose (``planned`` ``(n, n_joints)`` rad) the fit moved off its goal (``goals``, the
    IK's clear poses) and that come closer to the world than the clearance plus :data:`MARGIN`, measured (one
    batch) where the pose's lower bound ``lows`` ``(n,)`` m (:meth:`~retarget.ik.bound.ClearanceBound.pose_lows`)
    does not rule it out; and those poses' clearances to the world, metres."""
    limit = model.clearance + MARGIN
    unproven = np.flatnonzero(np.asarray(lows, dtype=np.float64) < limit)
    moved = unproven[np.any(planned[unproven] != goals[unproven], axis=1)]
    if not len(moved):
        return moved, np.zeros(0)
    clearances = model.world_distances(planned[moved]).min(axis=1, initial=np.inf)
    near = clearances < limit
    return moved[near], clearances[near]


def linearised(model: Model, planned: Array, ticks: npt.NDArray[np.intp]) -> Halfspaces:
    """Per tick of ``ticks``, the nearest world pair's distance at the planned pose linearised (finite differences
    of :data:`_STEP` rad per joint, one batch) and required to be at least the clearance plus twice
    :data:`MARGIN`.

    >>> import retarget
    >>> from retarget.collision import CollisionModel, Sphere, World
    >>> arm = retarget.load_arm("wx250s")
    >>> model = CollisionModel.for_arm(arm, world=World(keep_out=(Sphere((0.28, -0.12, 0.40), 0.05),)))
    >>> halfspaces = linearised(model, arm.home[None], np.array([0]))
    >>> halfspaces.normals.shape, bool(halfspaces.normals @ arm.home >= halfspaces.offsets)  # home: far enough
    ((1, 6), True)
    """
    poses = planned[ticks]  # (c, m)
    c, m = poses.shape
    moved = (poses[:, None, :] + _STEP * np.eye(m)[None]).reshape(c * m, m)
    d0 = model.world_distances(poses)  # (c, n_pairs)
    nearest = d0.argmin(axis=1)
    d1 = model.world_distances(moved).reshape(c, m, -1)[np.arange(c), :, nearest]  # (c, m): the nearest pair, moved
    d = d0[np.arange(c), nearest]
    normals = (d1 - d[:, None]) / _STEP
    offsets = model.clearance + 2.0 * MARGIN - d + (normals * poses).sum(axis=1)
    return Halfspaces(ticks, normals, offsets)


def keep_clear(
    model: Model,
    plan: Callable[[Halfspaces | None], Array],
    lows_of: Callable[[Array], npt.ArrayLike],
    goals: Array,
) -> Array:
    """The path ``plan(halfspaces)`` gives (``(n, n_joints)`` rad), re-planned with the clearance linearised at the
    planned poses :func:`near_ticks` finds (``lows_of(path)``: each planned pose's lower bound, metres) until none
    is left or after :data:`ROUNDS` re-plans, then the round's path with the fewest poses within the clearance (the
    rounds need not improve on each other).  The constraints of every round are kept (a tick's latest replaces an
    earlier one, asking for what the earlier ones fell short by on top: the fit meets its constraints, and the
    profile's last pass, which makes the fit's path exactly feasible, may move a pose off them again)."""
    path = plan(None)
    kept: dict[int, tuple[Array, float]] = {}
    raised: dict[int, float] = {}  # per tick, what the rounds before fell short by: asked for again on top
    best: tuple[tuple[int, int], Array] = ((len(goals) + 1, 0), path)  # (worse than any round)
    for round_ in range(ROUNDS + 1):
        ticks, clearances = near_ticks(model, path, goals, lows_of(path))
        if not len(ticks):
            return path
        short = (model.clearance + 2.0 * MARGIN - clearances).tolist()  # what each falls short of its constraint by
        score = (sum(s > 2.0 * MARGIN for s in short), len(ticks))  # (poses within the clearance, near it)
        if score < best[0]:
            best = (score, path)
        if round_ == ROUNDS:
            break
        new = linearised(model, path, ticks)
        for t, normal, offset, s in zip(new.ticks.tolist(), new.normals, new.offsets.tolist(), short, strict=True):
            raised[t] = raised.get(t, 0.0) + s if t in kept else 0.0
            kept[t] = (normal, offset + raised[t])
        order = np.array(sorted(kept), dtype=np.intp)
        halfspaces = Halfspaces(order, np.array([kept[t][0] for t in order]), np.array([kept[t][1] for t in order]))
        log.info("look-ahead: %d planned poses within %.0f mm of the clearance, re-planned", len(ticks), MARGIN * 1e3)
        path = plan(halfspaces)
    log.info("look-ahead: %d planned poses left within the clearance (the goal check guards them)", best[0][0])
    return best[1]
