"""The collision check of a rig's goals before each write: every arm against itself and the world, and the arms
against each other, on the pose and on the joint-space segment to it.

- Each arm's own check is its :class:`~retarget.control.safety.GoalCheck` on its part of the plant's vector
  (itself, its table, its keep-outs, in its base frame).
- Arm against arm (:class:`~retarget.rig.clearance.RigClearance`), pair by pair of shapes: along a straight
  joint-space move ``dq`` no point of shape ``i`` moves more than ``motion[i] @ |dq|`` (its arm's
  :attr:`~retarget.rig.clearance.ArmShapes.motion`: only the joints before its frame, each by its lever), so the
  pair ``(i, j)`` closes by at most the sum of its two shapes' travels.  Every pair's clearance at the last pose
  measured (the reference) therefore bounds it at any pose from there; that bound is concave along a straight
  move, so a move whose ends both keep the clearance from the reference needs no query (most ticks).  Otherwise
  the goal is measured (the new reference; a goal within the clearance is refused at once), and the segment is
  bounded pair by pair from its ends' clearances ``d0``, ``d1`` (a pose held after a blocked goal: its own
  measurement, kept from when it was allowed) and the pair's travel ``M``: ``(d0 + d1 - M) / 2``; only when that
  falls short is the segment sampled, finely enough that no point moves more than half the clearance between
  samples, and only for the pairs that bound leaves at or below its ends' least (no other can be the samples'
  least, the ends being among them).

A path planned ahead (a clip's look-ahead plan) comes with its :class:`~retarget.rig.proof.RigProof`: every
segment bounded before the run, each arm's own and the arms' against each other.  A tick whose move is a segment of
it takes that segment's bounds where they keep the clearance and checks the rest as above; an arm's own check that
a proof stood in for starts again from the pose held when it is next needed.

A goal is allowed only when every check allows it.  The arms apart go first: their bookkeeping (the poses
measured) holds whatever is written, so a goal they block leaves each arm's check as it was, at the pose held.  An
arm's check that allowed its part of a goal the other arm's blocked starts again from the pose held (its
bookkeeping assumed the goal was written), so every bound stays sound.  Each check's verdict is its own sampling's
(its bounds only stand in where they prove the same), so none depends on the order or on what was checked before.

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
from retarget.rig.proof import RigProof, sample_step, travel_spread

Array = npt.NDArray[np.float64]
#: a pose the arms' clearances were measured at: the pose, each pair's clearance, their least, each shape's levers,
#: the whole rig's levers and spread (:meth:`RigGoalCheck._measured`)
_Reference = tuple[Array, Array, float, Array, list[tuple[float, float, float]]]

_RECENT = 4  #: the references :meth:`RigGoalCheck._recall` keeps

if TYPE_CHECKING:
    from retarget.collision import CollisionModel

__all__ = ["RigGoalCheck", "RigRoutes"]


class RigGoalCheck:
    """Checks each goal of a rig's run (see the module docstring), from the pose ``q_start`` (rad, the plant's).

    ``models``: each arm's own collision model, by arm name; ``between``: the arm-against-arm clearances;
    ``proof``: the bounds of the path planned ahead (:class:`~retarget.rig.proof.RigProof`), taken for its moves.
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
        *,
        proof: RigProof | None = None,
    ):
        self.plant, self.models, self.between = plant, dict(models), between
        self.proof = proof  #: the planned path's bounds (None: none)
        self._parts = [(a.name, s) for a, s in zip(plant.rig.arms, plant.slices, strict=True)]
        self._slices = dict(self._parts)
        q0 = np.asarray(q_start, dtype=np.float64)
        self._checks = {name: GoalCheck(self.models[name], q0[s]) for name, s in self._parts}
        #: the arms whose check is behind the pose written (a proof stood in, or a goal it allowed was blocked): it
        #: starts again from the pose held before its next use
        self._behind: set[str] = set()
        self._own_limit = {name: float(self.models[name].clearance) for name, _ in self._parts}
        self._limit = float(between.clearance)
        self._step = sample_step(self._limit)  # no pair closes by more than this between two samples
        self._pairs = between.pair_shapes
        self._sides = (np.unique(self._pairs[0]), np.unique(self._pairs[1]))  #: the shapes either side of any pair
        #: ``(n_shapes, n_joints)``: the second-order term of each shape's travel (see :meth:`_falls`), per rad^2
        self._spread = travel_spread(between)
        i, j = self._pairs
        self._whole_spread = (self._spread[i].max(axis=0) + self._spread[j].max(axis=0)).tolist()
        #: the last pose whose arm-against-arm clearances were measured (the bounds' reference): the pose, each pair's
        #: clearance, their least, and each shape's levers there
        self._ref = self._measured(q0)
        #: the last few poses measured (the newest first) and their references: a pose held after a blocked goal
        #: was measured when it was allowed
        self._recent: list[tuple[list[float], _Reference]] = [(q0.tolist(), self._ref)]
        self.clearance = min(self._ref[2], *(c.clearance for c in self._checks.values()))
        #: per segment of the proof: whether its bounds keep every clearance, and their least (metres)
        self._proven: list[bool] = []
        self._proven_low: list[float] = []
        if proof is not None and len(proof):
            none = [-math.inf] * len(proof)
            own = [(np.array(proof.arms.get(name, none)), self._own_limit[name]) for name, _ in self._parts]
            apart = np.array(proof.apart)
            self._proven = np.logical_and.reduce([low >= limit for low, limit in own] + [apart >= self._limit]).tolist()
            self._proven_low = np.minimum.reduce([low for low, _ in own] + [apart]).tolist()
        self._names = tuple(self._slices)

    def allows(self, q_from: Sequence[float], q_to: Sequence[float]) -> bool:
        """Whether the move ``q_from`` -> ``q_to`` (rad) keeps every clearance; sets :attr:`clearance` when it does."""
        a, b = list(q_from), list(q_to)
        proof = self.proof
        k = -1 if proof is None else proof.segment(a, b)
        if k >= 0 and self._proven[k]:  # every bound of a planned move keeps its clearance: every check is behind
            self._behind.update(self._names)
            self.clearance = self._proven_low[k]
            return True
        apart = -math.inf if proof is None or k < 0 else proof.apart[k]
        if apart < self._limit:  # the arms apart first: its bookkeeping holds whatever is written
            apart = self._segment_apart(a, b)
            if apart < self._limit:
                return False
        passed: list[str] = []
        lows: list[float] = [apart]
        for name, s in self._parts:
            own = proof.arms.get(name) if proof is not None and k >= 0 else None
            low = -math.inf if own is None else own[k]
            if low >= self._own_limit[name]:  # proven: the arm's check is behind from here
                self._behind.add(name)
            else:
                check = self._own_check(name, a)
                if not check.allows(a[s], b[s]):
                    self._behind.update(passed)
                    return False
                low = check.clearance
            passed.append(name)
            lows.append(low)
        self.clearance = min(lows)
        return True

    def _own_check(self, name: str, q_held: list[float]) -> GoalCheck:
        """Arm ``name``'s own check, started again from the plant's pose ``q_held`` (the pose written) when it is
        behind."""
        if name in self._behind:
            self._behind.discard(name)
            self._checks[name] = GoalCheck(self.models[name], np.array(q_held[self._slices[name]]))
        return self._checks[name]

    def _measured(self, q: Array) -> _Reference:
        """The reference of the plant's pose ``q``: its pairs' clearances, their least, its shapes' levers, and the
        whole rig's: per joint the greatest lever (and spread) of either side of any pair, summed, so that
        ``whole[0] @ |dq| + whole[1] @ dq^2`` bounds every pair's fall at once."""
        d, levers = self.between.measure(self.plant.split(q))
        i, j = self._sides
        lever = (levers[i].max(axis=0) + levers[j].max(axis=0)).tolist()
        whole = list(zip(lever, self._whole_spread, q.tolist(), strict=True))
        return q, d, float(d.min(initial=math.inf)), levers, whole

    def _falls(self, levers: Array, dq: Array) -> Array:
        """How far each pair may close ``(n_pairs, k)`` (metres) along ``k`` straight moves ``dq`` ``(n_joints, k)``
        (rad) from the pose whose ``levers`` these are.

        A point's speed is at most the sum over the joints of each one's speed times the point's distance from its
        axis; that distance grows at most by the point's travel relative to the joint's child frame, which only the
        joints after it make.  Integrated along the move, a shape's travel is at most ``levers @ |dq| +
        1/2 sum_{j<k} motion_k |dq_j| |dq_k|``, and ``|dq_j| |dq_k| <= (dq_j^2 + dq_k^2) / 2`` makes that a convex
        function of ``dq`` (``levers @ |dq| + spread @ dq^2``): along a straight move the bound it gives is concave,
        so its least is at an end."""
        travel = levers @ np.abs(dq) + self._spread @ (dq * dq)
        i, j = self._pairs
        out: Array = travel[i] + travel[j]
        return out

    def _segment_apart(self, q_from: list[float], q_to: list[float]) -> float:
        """The least arm-against-arm clearance along ``a`` -> ``b``, or a lower bound of it (metres).

        Most moves need no query: from the reference (``q_ref``, each pair's clearance ``d_ref``) a pose ``q``
        keeps at least ``d_ref - fall(q - q_ref)`` pair by pair (:meth:`_falls`), and that bound is concave along
        a straight move, so its least is at an end.  When it falls short, ``b`` is measured (the new reference) and
        the segment is bounded from its ends pair by pair (``(d0 + d1 - fall(a - b)) / 2``), or sampled near a
        contact: only the pairs that bound leaves at or below the ends' least (no other can be the least of the
        samples, which the ends are among), so the figure is that of all pairs sampled.  Every bound here is at
        most the samples' least, so the verdict is the sampling's whatever the reference."""
        q_ref, d_ref, least, levers, whole = self._ref
        low = least - max(_fall(whole, q_from), _fall(whole, q_to))  # the whole rig at once
        if low >= self._limit:
            return low
        a, b = np.array(q_from), np.array(q_to)
        ends = self._falls(levers, np.array([q_from, q_to]).T - q_ref[:, None])  # (n_joints, 2): each pair
        d0, low_b = d_ref - ends[:, 0], d_ref - ends[:, 1]  # d0: exact when ``a`` is the reference
        low = float(np.minimum(d0, low_b).min(initial=math.inf))
        if low >= self._limit:
            return low
        if float(d0.min(initial=math.inf)) < self._limit:  # (after a blocked goal: the pose held, measured before)
            d0 = self._recall(q_from, a)[1]
        self._ref = ref = self._measure(q_to, b)
        if ref[2] < self._limit:  # the goal itself is within the clearance: refused, as its sample would be
            return ref[2]
        fall = self._falls(ref[3], (a - b)[:, None])[:, 0]  # how far each pair may close along the move
        pairs = 0.5 * (d0 + ref[1] - fall)
        low = float(pairs.min(initial=math.inf))
        if low < self._limit and float(fall.max(initial=0.0)) > 0:
            n = max(2, math.ceil(float(fall.max()) / self._step) + 1)
            s = np.linspace(0.0, 1.0, n)[:, None]
            ends_least = min(float(d0.min(initial=math.inf)), ref[2])
            near = np.flatnonzero(~(pairs > ends_least))  # (a nan pair too)
            sampled = self.between.distances(self.plant.split(a + s * (b - a)), pairs=near)
            low = min(float(sampled.min(initial=math.inf)), ends_least)
        return low

    def _measure(self, q: list[float], pose: Array) -> _Reference:
        """:meth:`_measured` of the plant's pose ``q`` (``pose`` its array), kept among the last few measured."""
        ref = self._measured(pose)
        self._recent = [(q, ref), *self._recent[: _RECENT - 1]]
        return ref

    def _recall(self, q: list[float], pose: Array) -> _Reference:
        """The reference of the plant's pose ``q`` (``pose`` its array): one of the last few measured, else measured
        now."""
        for known, ref in self._recent:
            if known == q:
                return ref
        return self._measure(q, pose)


def _fall(whole: list[tuple[float, float, float]], q: Sequence[float]) -> float:
    """The whole rig's fall bound from the reference to ``q`` (plain floats: ``whole`` holds per joint the lever,
    the spread and the reference's angle)."""
    fall = 0.0
    for (lever, spread, ref), x in zip(whole, q, strict=True):
        dx = x - ref
        fall += lever * abs(dx) + spread * dx * dx
    return fall


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
