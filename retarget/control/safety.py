"""Collision safety of the commanded motion: each tick's goal, and the joint-space moves planned around the run.

- :class:`GoalCheck`: the tick loop's last word before a write.  The commanded pose and the straight
  joint-space segment from the last command to it must keep the model's clearance
  (``CollisionModel.segment_clear``); a goal that fails is not written (the arm holds) and the tick is
  counted ``blocked``.
- :func:`plan_route`: the waypoints of a joint-space move (the lead-in to a clip's first pose, the move to
  rest at shutdown): straight when that segment is clear, else through the first clear safe waypoint (home,
  then rest), else None: the caller refuses the move.

Joint angles ``(n_joints,)`` float64 radians in ``Arm.joint_names`` order; clearances metres.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

import numpy as np
import numpy.typing as npt

from retarget.control.source import JointGoal
from retarget.errors import ConfigError
from retarget.ik.bound import HORIZON, shared_bound

if TYPE_CHECKING:
    from retarget.collision import CollisionModel

__all__ = ["GoalCheck", "Leg", "Route", "RouteModel", "plan_route", "require_route"]


class _Segment(Protocol):
    @property
    def clear(self) -> bool: ...


class RouteModel(Protocol):
    """What routing a joint-space move needs of a collision model (:class:`~retarget.collision.CollisionModel` is
    one; a rig's arms together are another, ``retarget.rig.check.RigRoutes``): poses ``(n_joints,)`` rad."""

    def is_clear(self, q: npt.NDArray[np.float64]) -> bool: ...

    def segment_clear(self, q0: npt.NDArray[np.float64], q1: npt.NDArray[np.float64]) -> _Segment: ...

    def worst_pair(self, q: npt.NDArray[np.float64]) -> tuple[str, float]: ...


class Leg(Protocol):
    """One straight joint-space move of a :class:`Route` (``retarget.control.replay.LeadIn`` is one)."""

    @property
    def n_slots(self) -> int: ...

    def goal(self, slot: int) -> JointGoal: ...

    def truncated(self, n_slots: int) -> Leg: ...


@dataclass(frozen=True)
class Route:
    """Straight joint-space legs run one after the other, over slots ``-n_slots .. -1`` (each leg's own slots
    ``-leg.n_slots .. -1`` in turn): a lead-in through a safe waypoint.  Same interface as one leg."""

    legs: tuple[Leg, ...]

    @property
    def n_slots(self) -> int:
        return sum(leg.n_slots for leg in self.legs)

    def goal(self, slot: int) -> JointGoal:
        """The goal of slot ``slot`` (``-n_slots <= slot < 0``)."""
        i = slot + self.n_slots  # 0-based index into the whole route
        for leg in self.legs:
            if i < leg.n_slots:
                return leg.goal(i - leg.n_slots)
            i -= leg.n_slots
        return self.legs[-1].goal(-1)

    def truncated(self, n_slots: int) -> Route:
        """Only the first ``n_slots`` slots of the route."""
        legs: list[Leg] = []
        for leg in self.legs:
            if n_slots <= 0:
                break
            legs.append(leg.truncated(n_slots))
            n_slots -= leg.n_slots
        return Route(tuple(legs))


class GoalCheck:
    """Checks each tick's goal against ``model`` (see the module docstring), starting from the pose ``q_start``
    (rad); ``clearance`` is the min clearance (metres) of the last segment written, or a lower bound of it (at
    first: of ``q_start``).  Most ticks need no query or one of a single pose: the segment's clearance is bounded
    from its ends' (:class:`~retarget.ik.bound.ClearanceBound`; after a query, a table contact by its ends' height
    slopes too: ``ClearanceBound.segment_low``); a goal whose own query is within the clearance is refused at
    once, as sampling would; only near a contact is the segment sampled (``CollisionModel.segment_clear``).  A move
    of a path planned ahead (``retarget.control.plan.solve_and_plan``) whose segment was bounded then
    (``ClearanceBound.proven``: the same bound, from the notes of the plan's IK pass) needs no more work when that
    bound keeps the clearance; any other move, or one whose bound falls short, is checked as above."""

    __slots__ = ("model", "clearance", "bound", "_segment_clear", "_limit", "_reach", "_at_cmd", "_cmd_state", "_memo")

    def __init__(self, model: CollisionModel, q_start: npt.NDArray[np.float64]):
        self.model = model
        q0 = np.asarray(q_start, dtype=np.float64)
        d = model.pair_bounds(q0, float(model.clearance) + HORIZON)  # exact near the clearance, bounds farther off
        self.clearance = float(d.min()) if d.size else math.inf
        self.bound = shared_bound(model)
        self.bound.note(q0.tolist(), d)
        #: a lower bound of every row's distance at the goal written (the bound's rows: pairs, pieces of long ones);
        #: None: that of :attr:`_cmd_state`
        self._at_cmd: np.ndarray | None = self.bound.rows_at_note()
        self._cmd_state = self.bound.state  #: the note the goal written was proven clear from (when _at_cmd is None)
        self._segment_clear = model.segment_clear
        self._limit = float(model.clearance)
        self._reach = self._limit + HORIZON
        #: the last goal accepted on the fast path, the note it was bounded from and its bound (the next move's start)
        self._memo: tuple[object, list[float], float] = (None, [], -math.inf)

    def allows(self, q_from: Sequence[float], q_to: Sequence[float]) -> bool:
        """Whether the segment ``q_from`` -> ``q_to`` (rad) keeps the clearance; sets :attr:`clearance` to its min
        clearance (or a lower bound of it, near the last segment checked: :class:`~retarget.ik.collide.
        ClearanceBound`) when it does (a blocked goal is not written: the clearance stays that of the pose held)."""
        bound, limit = self.bound, self._limit
        proven = bound.proven
        if proven is not None:  # a planned move, bounded ahead (ClearanceBound.prove)
            low = proven.find(q_from, q_to)
            if low is not None and low >= limit:
                self.clearance = low
                self._at_cmd, self._cmd_state = None, None
                self._memo = (None, [], -math.inf)
                return True
        # the fast path: both ends bounded from the last note alone (a bound from one reference is concave along a
        # straight segment, so its least over the segment is at an end)
        state, (memo_state, memo_q, memo_low) = bound.state, self._memo
        low = memo_low if memo_state is state and memo_q == list(q_from) else bound.quick(q_from)
        if low >= limit:
            low_to = bound.quick(q_to)
            if low_to >= limit:
                self.clearance = min(low, low_to)
                self._at_cmd, self._cmd_state = None, state
                self._memo = (state, list(q_to), low_to)
                return True
        low = min(bound.quick_previous(q_from), bound.quick_previous(q_to))  # the same from the note before
        if low >= limit:
            self.clearance = low
            self._at_cmd, self._cmd_state = None, bound.previous_state
            return True
        prior = self._at_cmd if self._at_cmd is not None else bound.pairs_at(q_from, self._cmd_state)
        at0 = np.maximum(prior, bound.pairs_at(q_from))
        at1 = bound.pairs_at(q_to)
        # no query near the last one: the two ends' bounds may come from different references (the goal written
        # last, the latest note), so the segment between them is bounded by their falls, not by the ends alone
        low = bound.segment_bound(q_from, q_to, at0, at1)
        if low < limit:
            end = np.array(q_to)
            d = self.model.pair_bounds(end, self._reach)  # one pose: cheap; exact near the clearance
            bound.note(q_to, d)
            if d.size and float(d.min()) < limit:  # the goal itself is not clear: no segment to sample
                return False
            at1 = bound.rows_at_note()  # (and the next goals near it need no query)
            low = bound.segment_bound(q_from, q_to, at0, at1)
            if low < limit:  # the new note alone, the table rows by their ends' height slopes
                low = max(low, bound.segment_low(q_from, q_to))
            if low < limit:  # near a contact: sample the segment
                check = self._segment_clear(np.array(q_from), end)
                if not check.clear:
                    return False
                low = float(check.min_clearance)
        self.clearance = low
        self._at_cmd = at1
        return True


def plan_route(
    model: RouteModel,
    q_from: npt.NDArray[np.float64],
    q_to: npt.NDArray[np.float64],
    *,
    waypoints: Sequence[npt.NDArray[np.float64]] = (),
) -> list[npt.NDArray[np.float64]] | None:
    """The poses a joint-space move from ``q_from`` to ``q_to`` goes through, ``q_to`` last: ``[q_to]`` when the
    straight segment is clear, ``[w, q_to]`` through the first of ``waypoints`` with both segments clear, else
    None (no safe route).  A ``q_to`` that is itself not clear has no route.

    >>> import retarget
    >>> from retarget.collision import CollisionModel, Sphere, World
    >>> arm = retarget.load_arm("wx250s")
    >>> model = CollisionModel.for_arm(arm)
    >>> len(plan_route(model, arm.rest, arm.home))
    1
    """
    if not model.is_clear(q_to):
        return None
    if model.segment_clear(q_from, q_to).clear:
        return [np.asarray(q_to, dtype=np.float64)]
    for w in waypoints:
        if model.segment_clear(q_from, w).clear and model.segment_clear(w, q_to).clear:
            return [np.asarray(w, dtype=np.float64), np.asarray(q_to, dtype=np.float64)]
    return None


def require_route(
    model: RouteModel,
    q_from: npt.NDArray[np.float64],
    q_to: npt.NDArray[np.float64],
    *,
    waypoints: Sequence[npt.NDArray[np.float64]],
    what: str,
) -> list[npt.NDArray[np.float64]]:
    """:func:`plan_route`, or a one-line ConfigError (key ``collision``) saying ``what`` move is blocked."""
    route = plan_route(model, q_from, q_to, waypoints=waypoints)
    if route is None:
        name, metres = model.worst_pair(q_to)
        if model.is_clear(q_to):
            detail = "its straight joint-space path collides and no safe waypoint (home, rest) avoids it"
        else:
            detail = f"that pose itself is within the clearance ({name} at {metres * 1e3:.1f} mm)"
        raise ConfigError(f"Expected a collision-free {what}, but {detail}", key="collision")
    return route
