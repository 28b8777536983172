"""A rig's planned path proven clear before it plays: every segment's bounds, each arm's own and the arms' against
each other, so that the tick loop's check of a planned move is a look-up.

A clip played with the look-ahead plan moves the rig along a path known before the first tick: tick ``k`` moves
from pose ``k`` to pose ``k + 1`` of it (pose 0 the start).  :class:`RigProof` holds, per segment,

- each arm's own bound (itself, its table and keep-outs): its collision bound's
  :meth:`~retarget.ik.bound.ClearanceBound.prove` of the arm's part of the path, from the notes of its IK pass;
- the arms' bound against each other (:func:`prove_apart`): poses measured in batches, coarse to fine, each pair's
  clearance bounded along a segment by the same first- and second-order travel bounds as the tick check's
  (:class:`~retarget.rig.check.RigGoalCheck`); a close pass those bounds cannot clear is sampled as the tick
  check would sample it (the same poses, and the same figure: the least of the pairs that may be the nearest), all
  such segments' samples in a few batches.

:meth:`RigProof.segment` finds a move's segment: the next one, else the one ending at the move's end (the path
rejoined after a blocked tick, or played again).  Every bound is a lower bound of the least clearance along its
segment (a sampled close pass: its least sample, the tick check's own figure for it), less the slack a move
matched to within :attr:`RigProof.EPS` may add; a segment whose bound falls short is checked at its tick as any
other move.

Arrays: poses ``(n + 1, n_joints)`` radians, the plant's vector (:class:`~retarget.rig.plant.RigPlant`); bounds
``(n,)`` metres.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np
import numpy.typing as npt

from retarget.ik.bound import ProvenPath, near_pose
from retarget.rig.clearance import RigClearance

__all__ = ["RigProof", "prove_apart", "sample_step"]

Array = npt.NDArray[np.float64]

#: the levels of :func:`prove_apart`: each measures the poses every ``K`` ticks around the segments the one before
#: left short (the last, 1: the segments' own ends); these measure the fewest poses of a few tried on the bundled
#: rigs' clips (about one pose in six when the arms move fast and near each other)
LEVELS = (24, 6, 2, 1)
_BATCH = 512  #: poses per batch of :meth:`~retarget.rig.clearance.RigClearance.measure` (bounded memory)


class RigProof:
    """The bounds of a rig's planned path, segment by segment (see the module docstring): ``poses``
    ``(n + 1, n_joints)`` rad, each arm's own ``arms[name]`` and the arms' ``apart`` ``(n,)`` metres (lower bounds
    of the least clearance along each segment; ``-inf``: none).

    >>> from retarget.rig import RigPlant, load_rig
    >>> rig = load_rig("wx250s-pair")
    >>> plant, between = RigPlant.of(rig), RigClearance(rig)
    >>> path = plant.home + np.linspace(0.0, 0.1, 11)[:, None]  # ten steps of 0.01 rad in every joint
    >>> proof = RigProof(path, {}, prove_apart(between, path), between)
    >>> k = proof.segment(path[3].tolist(), path[4].tolist())
    >>> k, between.clearance <= proof.apart[k] <= float(between.min_clearance(plant.split(path[4])))
    (3, True)
    >>> proof.segment(path[4].tolist(), path[3].tolist())  # not a segment of the path
    -1
    """

    EPS = ProvenPath.EPS  #: radians in all: how near a move's ends must be to its segment's (:func:`near_pose`)

    __slots__ = ("_poses", "_ends", "_next", "arms", "apart")

    def __init__(self, poses: npt.ArrayLike, arms: Mapping[str, Sequence[float]], apart: npt.ArrayLike,
                 between: RigClearance):  # fmt: skip
        self._poses: list[list[float]] = np.asarray(poses, dtype=np.float64).tolist()
        #: each end pose's first segment, for finding the path again
        self._ends: dict[tuple[float, ...], int] = {}
        for k, pose in enumerate(self._poses[1:]):
            self._ends.setdefault(tuple(pose), k)
        self._next = 0  #: the segment tried first
        #: each arm's own bounds, by arm name (:meth:`~retarget.ik.bound.ProvenPath.find`'s: its slack taken off)
        self.arms = {name: list(low) for name, low in arms.items()}
        # a move within EPS of a segment at both ends is within EPS of it all along: no point of a shape moves more
        # than its greatest motion per radian times that
        margin = 2.0 * self.EPS * float(between.motion.max(initial=0.0))
        self.apart: list[float] = (np.asarray(apart, dtype=np.float64) - margin).tolist()

    def __len__(self) -> int:
        return len(self._poses) - 1

    def segment(self, q_from: Sequence[float], q_to: Sequence[float]) -> int:
        """The segment the move ``q_from -> q_to`` (rad) is, to within :attr:`EPS` in all at each end: the next one
        after the last found, else the first that ends at ``q_to`` exactly; -1 when none."""
        poses, k = self._poses, self._next
        if k < len(poses) - 1 and near_pose(q_to, poses[k + 1]) and near_pose(q_from, poses[k]):
            self._next = k + 1
            return k
        k = self._ends.get(tuple(q_to), -1)  # (then its end is ``q_to``)
        if k >= 0 and near_pose(q_from, poses[k]):
            self._next = k + 1
            return k
        return -1

    @classmethod
    def prove(cls, between: RigClearance, path: npt.ArrayLike, arms: Mapping[str, Sequence[float]]) -> RigProof:
        """The proof of ``path`` ``(n + 1, n_joints)`` rad: the arms apart (:func:`prove_apart`) and each arm's own
        bounds ``arms[name]`` ``(n,)`` metres, of its part of these very segments (its collision bound's
        :meth:`~retarget.ik.bound.ClearanceBound.prove` of them: the :attr:`~retarget.ik.bound.ProvenPath.lows`)."""
        P = np.asarray(path, dtype=np.float64)
        apart, at = _prove_apart(between, P)
        short = np.flatnonzero(apart < between.clearance)
        if at is not None and short.size:  # close passes: sampled now as their ticks would sample them
            at.measure(np.concatenate([short, short + 1]))
            apart[short] = np.maximum(apart[short], sampled_along(between, travel_spread(between), at, short))
        return cls(P, arms, apart, between)


def prove_apart(between: RigClearance, path: npt.ArrayLike) -> Array:
    """Lower bounds of the arms' least clearance along every segment of ``path`` ``(n + 1, n_joints)`` rad
    (segment ``k``: pose ``k`` -> ``k + 1``): ``(n,)`` metres.

    Level by level (:data:`LEVELS`: ``K`` = 24, 6, 2, 1) each segment not yet proven is bounded from the poses at
    the multiples of ``K`` either side of it, measured (the least pair's clearance, from only the pairs that may be
    the nearest, and each shape's levers) a batch at a time: from a measured pose no pair closes by more than the
    whole rig's fall (every pair's at once, that pose's levers: :func:`~retarget.rig.check._fall`), a convex
    function of the move, so its bound along a segment is least at an end.  After the last level (the segment's own
    ends, now with every pair's clearance) each pair of a segment still short is bounded by ``(d0 + d1 - fall) / 2``
    (:func:`pair_falls` from either end's levers).  A segment still short keeps its best
    bound (:meth:`RigProof.prove` samples it then)."""
    return _prove_apart(between, path)[0]


def _prove_apart(between: RigClearance, path: npt.ArrayLike) -> tuple[Array, _Measured | None]:
    """:func:`prove_apart`, and the poses it measured (None: none)."""
    P = np.asarray(path, dtype=np.float64)
    n = len(P) - 1
    i, j = between.pair_shapes
    if n <= 0 or not i.size:
        return np.full(max(n, 0), math.inf), None
    spread = travel_spread(between)
    whole_spread = spread[i].max(axis=0) + spread[j].max(axis=0)
    at = _Measured(between, P)
    low = np.full(n, -math.inf)
    todo = np.arange(n)
    for step in LEVELS:
        r0 = todo // step * step
        for r in (r0, np.minimum(r0 + step, n)):
            at.measure(r, every_pair=False)
            w = at.whole[r]
            fall = np.maximum(
                whole_falls(w, whole_spread, P[todo] - P[r]), whole_falls(w, whole_spread, P[todo + 1] - P[r])
            )
            low[todo] = np.maximum(low[todo], at.least[r] - fall)
        todo = todo[low[todo] < between.clearance]
        if not todo.size:
            return low, at
    at.measure(np.concatenate([todo, todo + 1]))
    low[todo] = np.maximum(low[todo], pairs_along(between, spread, at, todo, P[todo + 1] - P[todo]).min(axis=1))
    return low, at


def sampled_along(between: RigClearance, spread: Array, at: _Measured, starts: npt.NDArray[np.intp]) -> Array:
    """Each segment ``starts[i] -> starts[i] + 1`` of the measured poses: its least arm-against-arm clearance over
    poses sampled along it (ends included) as the tick check samples a move near contact
    (:meth:`~retarget.rig.check.RigGoalCheck._segment_apart`, the same poses: so many that, by the end pose's levers,
    no pair closes by more than :func:`sample_step` between two samples); ``(k,)`` metres.  Not a bound: the tick
    check's own figure for such a move.  Only the pairs that :func:`pairs_along` leaves at or below the least of the
    segment's ends are sampled: no other can be the least of the samples, the first of which is the start.  All the
    segments' samples are measured in batches of :data:`_BATCH` poses."""
    P = at.poses
    dq = P[starts + 1] - P[starts]
    fall = pair_falls(between, spread, at.levers[starts + 1], dq).max(axis=1)
    counts = np.maximum(2, np.ceil(fall / sample_step(between.clearance)).astype(np.intp) + 1)
    segment = np.repeat(np.arange(starts.size), counts)
    s = np.concatenate([np.linspace(0.0, 1.0, int(c)) for c in counts])
    a = P[starts]
    poses = a[segment] + s[:, None] * dq[segment]
    ends_least = np.minimum(at.least[starts], at.least[starts + 1])
    kept = ~(pairs_along(between, spread, at, starts, dq) > ends_least[:, None])  # (k, n_pairs); a nan pair too
    segments = np.arange(starts.size)
    kept[segments, at.gaps[starts].argmin(axis=1)] = kept[segments, at.gaps[starts + 1].argmin(axis=1)] = True
    near = [np.flatnonzero(row) for row in kept]
    least = np.empty(len(poses))
    for k in range(0, len(poses), _BATCH):
        some = poses[k : k + _BATCH]
        arms = [some[:, part] for part in between.joint_slices]
        which = segment[k : k + _BATCH]
        sizes = np.array([near[i].size for i in which])
        rows = np.repeat(np.arange(len(some)), sizes)
        gaps = between.pair_gaps(between.ends(arms), rows, np.concatenate([near[i] for i in which]))
        least[k : k + _BATCH] = np.minimum.reduceat(gaps, np.concatenate(([0], np.cumsum(sizes)[:-1])))
    out: Array = np.minimum.reduceat(least, np.concatenate(([0], np.cumsum(counts)[:-1])))
    return out


def sample_step(clearance: float) -> float:
    """Metres: the most a pair may close between two samples of a move near contact (half the clearance)."""
    return 0.5 * max(clearance, 1e-3)


def pairs_along(between: RigClearance, spread: Array, at: _Measured, starts: npt.NDArray[np.intp], dq: Array) -> Array:
    """Each pair's least clearance along the moves ``dq`` ``(k, n_joints)`` rad from the measured poses ``starts``
    to the measured poses after them, or a lower bound of it ``(k, n_pairs)`` metres: ``(d0 + d1 - fall) / 2`` of
    its ends' clearances ``d0``, ``d1`` and how far it may close along the whole move, ``fall`` (:func:`pair_falls`
    from either end's levers, each a bound of the pair's whole closing along the move): at any point of the move,
    the closings since the start ``a`` and until the end ``b`` add up to at most ``fall``, so the pair keeps at
    least ``max(d0 - a, d1 - b) >= (d0 + d1 - a - b) / 2`` (and the bound is at most the lower end's too)."""
    d0, d1 = at.gaps[starts], at.gaps[starts + 1]
    fall = np.minimum(pair_falls(between, spread, at.levers[starts], dq),
                      pair_falls(between, spread, at.levers[starts + 1], dq))  # fmt: skip
    out: Array = 0.5 * (d0 + d1 - fall)
    return out


class _Measured:
    """The poses of a path measured so far: each one's least clearance ``least``, its shapes' ``levers``
    ``(n_poses, n_shapes, n_joints)`` and the whole rig's ``whole`` (per joint the greatest lever of either side of
    any pair, summed) ``(n_poses, n_joints)``, and of those measured with every pair (``full``) each pair's
    clearance ``gaps`` ``(n_poses, n_pairs)``; rows not measured are unset (``gaps``: nan)."""

    def __init__(self, between: RigClearance, poses: Array):
        self.between, self.poses = between, poses
        n = len(poses)
        self.done = np.zeros(n, dtype=bool)
        self.full = np.zeros(n, dtype=bool)
        self.gaps = np.full((n, between.pair_shapes[0].size), math.nan)
        self.least = np.empty(n)
        self.levers = np.empty((n, *between.motion.shape))
        self.whole = np.empty_like(poses)

    def measure(self, rows: npt.NDArray[np.intp], *, every_pair: bool = True) -> None:
        """Measure the poses ``rows`` not measured yet, :data:`_BATCH` at a time; ``every_pair``: each pair's
        clearance too (else only the least: the pairs that may be the nearest,
        :meth:`~retarget.rig.clearance.RigClearance.measure`), and for a pose measured before without them, those
        alone."""
        need = np.unique(rows)
        between = self.between
        if every_pair:
            again = need[self.done[need] & ~self.full[need]]
            for k in range(0, again.size, _BATCH):
                some = again[k : k + _BATCH]
                self.gaps[some] = between.distances(self._arms(some))
            self.full[again] = True
        need = need[~self.done[need]]
        i, j = (np.unique(side) for side in between.pair_shapes)  # the shapes either side of any pair
        for k in range(0, need.size, _BATCH):
            some = need[k : k + _BATCH]
            gaps, levers = between.measure(self._arms(some), every_pair=every_pair)
            if every_pair:
                self.gaps[some], gaps = gaps, gaps.min(axis=1)
            self.least[some], self.levers[some] = gaps, levers
            self.whole[some] = levers[:, i].max(axis=1) + levers[:, j].max(axis=1)
        self.done[need] = True
        self.full[need] |= every_pair

    def _arms(self, rows: npt.NDArray[np.intp]) -> dict[str, Array]:
        """Each arm's part of the poses ``rows``, by arm name (as :class:`RigClearance` takes them)."""
        poses, between = self.poses[rows], self.between
        return {a.name: poses[:, s] for a, s in zip(between.rig.arms, between.joint_slices, strict=True)}


def whole_falls(whole: Array, whole_spread: Array, dq: Array) -> Array:
    """How far any pair may close ``(k,)`` (metres) along ``k`` straight moves ``dq`` ``(k, n_joints)`` (rad), each
    from a pose whose whole-rig levers are ``whole`` ``(k, n_joints)`` (:class:`_Measured`): ``whole @ |dq| +
    whole_spread @ dq^2``, :func:`~retarget.rig.check._fall`'s bound."""
    out: Array = (whole * np.abs(dq) + whole_spread * dq * dq).sum(axis=1)
    return out


def pair_falls(between: RigClearance, spread: Array, levers: Array, dq: Array) -> Array:
    """How far each pair may close ``(k, n_pairs)`` (metres) along ``k`` straight moves ``dq`` ``(k, n_joints)``
    (rad), each from a pose whose shapes' levers are ``levers`` ``(k, n_shapes, n_joints)``: each shape's travel
    ``levers @ |dq| + spread @ dq^2`` (:meth:`~retarget.rig.check.RigGoalCheck._falls`), the pair's two summed."""
    travel = np.einsum("ksj,kj->ks", levers, np.abs(dq)) + (dq * dq) @ spread.T
    i, j = between.pair_shapes
    out: Array = travel[:, i] + travel[:, j]
    return out


def travel_spread(between: RigClearance) -> Array:
    """``(n_shapes, n_joints)`` per rad^2: ``spread[i, l] = (sum_{k>l} motion[i, k] + l motion[i, l]) / 4`` over the
    joints of shape ``i``'s arm (``l``, ``k`` counted within it), so that ``1/2 sum_{j<k} motion[i, k] |x_j| |x_k|
    <= spread[i] @ x^2`` (see :meth:`~retarget.rig.check.RigGoalCheck._falls`)."""
    out = np.zeros_like(between.motion)
    for joints in between.joint_slices:
        motion = between.motion[:, joints]
        after = np.cumsum(motion[:, ::-1], axis=1)[:, ::-1] - motion  # sum over k > l
        out[:, joints] = 0.25 * (after + np.arange(motion.shape[1])[None, :] * motion)
    return out
