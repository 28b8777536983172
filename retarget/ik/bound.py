"""A cheap lower bound of the clearance near a checked pose: most collision checks of a tick need no query.

See :class:`ClearanceBound`.  The IK's :class:`~retarget.ik.collide.CollisionGuard` and the control loop's goal
check share one per model (:func:`shared_bound`).

Arrays: ``q`` ``(n_joints,)`` float64 radians; pair distances ``(n_pairs,)`` metres, as the model's ``pair_names``.
"""

from __future__ import annotations

import math
import operator
import weakref
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from retarget.collision import CollisionModel

__all__ = ["HORIZON", "ClearanceBound", "shared_bound"]

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
