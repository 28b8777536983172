"""The collision check of a rig's goals before each write: every arm against itself and the world, and the arms
against each other, on the pose and on the joint-space segment to it.

- Each arm's own check is its :class:`~retarget.control.safety.GoalCheck` on its part of the plant's vector
  (itself, its table, its keep-outs, in its base frame).
- Arm against arm (:class:`~retarget.rig.clearance.RigClearance`) on the segment: along a straight joint-space
  move no point of arm A moves more than ``sum_j motion_per_radian_j |dq_j|`` (its collision model's bound), so
  two arms close by at most ``M``, the sum of both.  With clearances ``d0`` and ``d1`` at the ends the whole
  segment keeps ``(d0 + d1 - M) / 2``; only when that falls short is the segment sampled, finely enough that no
  point moves more than half the clearance between samples.

A goal is allowed only when every check allows it.  A check that allowed its part of a goal another part blocked
starts again from the pose held (its bookkeeping assumed the goal was written), so every bound stays sound.

Arrays: ``(n_joints,)`` radians, the plant's vector (:class:`~retarget.rig.plant.RigPlant`); clearances metres.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
import numpy.typing as npt

from retarget.control.safety import GoalCheck
from retarget.rig.clearance import RigClearance
from retarget.rig.plant import RigPlant

if TYPE_CHECKING:
    from retarget.collision import CollisionModel

__all__ = ["RigGoalCheck", "RigRoutes"]


class RigGoalCheck:
    """Checks each goal of a rig's run (see the module docstring), from the pose ``q_start`` (rad, the plant's).

    ``models``: each arm's own collision model, by arm name; ``between``: the arm-against-arm clearances.
    :attr:`clearance` is the least clearance (metres) of the last motion allowed, or a lower bound of it.

    >>> from retarget.collision import CollisionModel
    >>> from retarget.rig import load_rig
    >>> rig = load_rig("wx250s-pair")
    >>> plant = RigPlant.of(rig)
    >>> models = {a.name: CollisionModel.for_arm(a.arm) for a in rig.arms}
    >>> check = RigGoalCheck(plant, models, RigClearance(rig), plant.home)
    >>> check.allows(plant.home.tolist(), plant.rest.tolist())
    True
    """

    def __init__(
        self,
        plant: RigPlant,
        models: Mapping[str, CollisionModel],
        between: RigClearance,
        q_start: npt.NDArray[np.float64],
    ):
        self.plant, self.models, self.between = plant, dict(models), between
        self._parts = [(a.name, s) for a, s in zip(plant.rig.arms, plant.slices, strict=True)]
        q0 = np.asarray(q_start, dtype=np.float64)
        self._checks = {name: GoalCheck(self.models[name], q0[s]) for name, s in self._parts}
        #: metres per radian of each plant joint: how far a point of its arm moves (its model's bound)
        self._motion = np.concatenate([self.models[name].motion_per_radian for name, _ in self._parts])
        self._limit = float(between.clearance)
        self._step = 0.5 * max(self._limit, 1e-3)  # no point moves more than this between two samples
        #: the last pose whose arm-against-arm clearance was measured, and that clearance (the bound's reference)
        self._ref: tuple[npt.NDArray[np.float64], float] = (q0, self._arms_apart(q0))
        self.clearance = min(self._ref[1], *(c.clearance for c in self._checks.values()))

    def allows(self, q_from: Sequence[float], q_to: Sequence[float]) -> bool:
        """Whether the move ``q_from`` -> ``q_to`` (rad) keeps every clearance; sets :attr:`clearance` when it does."""
        a, b = np.asarray(q_from, dtype=np.float64), np.asarray(q_to, dtype=np.float64)
        passed: list[str] = []
        for name, s in self._parts:
            if not self._checks[name].allows(a[s].tolist(), b[s].tolist()):
                self._restart(passed, a)
                return False
            passed.append(name)
        apart = self._segment_apart(a, b)
        if apart < self._limit:
            self._restart(passed, a)
            return False
        self.clearance = min(apart, *(c.clearance for c in self._checks.values()))
        return True

    def _restart(self, names: list[str], q_held: npt.NDArray[np.float64]) -> None:
        """The checks of ``names`` start again from the pose held (they took the blocked goal as written)."""
        for name, s in self._parts:
            if name in names:
                self._checks[name] = GoalCheck(self.models[name], q_held[s])

    def _arms_apart(self, q: npt.NDArray[np.float64]) -> float:
        """The least arm-against-arm clearance of the plant's pose ``q`` (metres)."""
        return float(self.between.min_clearance(self.plant.split(q)))

    def _segment_apart(self, a: npt.NDArray[np.float64], b: npt.NDArray[np.float64]) -> float:
        """The least arm-against-arm clearance along ``a`` -> ``b``, or a lower bound of it (metres).

        Most moves need no query: from the last pose measured (``q_ref``, clearance ``d_ref``) a pose ``q`` keeps at
        least ``d_ref - |q - q_ref| . motion``, and that bound is concave along a straight move, so its least is
        at an end.  When it falls short, ``b`` is measured (the new reference) and the segment is bounded from
        its ends, or sampled near a contact."""
        q_ref, d_ref = self._ref
        motion = self._motion
        low = d_ref - max(float(np.abs(a - q_ref) @ motion), float(np.abs(b - q_ref) @ motion))
        if low >= self._limit:
            return low
        d0 = d_ref - float(np.abs(a - q_ref) @ motion)  # exact when ``a`` is the reference
        if d0 < self._limit:
            d0 = self._arms_apart(a)
        d1 = self._arms_apart(b)
        self._ref = (b, d1)
        travel = float(np.abs(b - a) @ motion)  # both arms' points together close by at most this
        low = 0.5 * (d0 + d1 - travel)
        if low < self._limit and travel > 0:
            n = max(2, math.ceil(travel / self._step) + 1)
            s = np.linspace(0.0, 1.0, n)[:, None]
            low = min(float(self.between.min_clearance(self.plant.split(a + s * (b - a))).min()), d0, d1)
        return low


class _Segment(NamedTuple):
    clear: bool


class RigRoutes:
    """A rig's arms as one model for routing a joint-space move of the plant's vector (a lead-in, through
    :func:`~retarget.control.safety.require_route`): a pose is clear when each arm is clear of itself and its world
    and the arms of each other; a straight move when :class:`RigGoalCheck` allows it from its start.

    >>> from retarget.collision import CollisionModel
    >>> from retarget.rig import load_rig
    >>> rig = load_rig("wx250s-pair")
    >>> plant = RigPlant.of(rig)
    >>> routes = RigRoutes(plant, {a.name: CollisionModel.for_arm(a.arm) for a in rig.arms}, RigClearance(rig))
    >>> routes.is_clear(plant.home), routes.segment_clear(plant.rest, plant.home).clear
    (True, True)
    """

    def __init__(self, plant: RigPlant, models: Mapping[str, CollisionModel], between: RigClearance):
        self.plant, self.models, self.between = plant, dict(models), between

    def is_clear(self, q: npt.NDArray[np.float64]) -> bool:
        parts = self.plant.split(q)
        return all(self.models[name].is_clear(part) for name, part in parts.items()) and self.between.is_clear(parts)

    def segment_clear(self, q0: npt.NDArray[np.float64], q1: npt.NDArray[np.float64]) -> _Segment:
        check = RigGoalCheck(self.plant, self.models, self.between, np.asarray(q0, dtype=np.float64))
        return _Segment(check.allows(np.asarray(q0).tolist(), np.asarray(q1).tolist()))

    def worst_pair(self, q: npt.NDArray[np.float64]) -> tuple[str, float]:
        """The nearest pair of ``q`` (an arm's own, ``"left:<pair>"``, or arm against arm) and its clearance, m."""
        parts = self.plant.split(q)
        pairs = [self.between.worst_pair(parts)]
        for name, part in parts.items():
            pair, metres = self.models[name].worst_pair(part)
            pairs.append((f"{name}:{pair}", metres))
        return min(pairs, key=lambda pair: pair[1])
