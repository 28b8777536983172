"""A cheap lower bound of the clearance near a checked pose: most collision checks of a tick need no query.

See :class:`ClearanceBound`.  The IK's :class:`~retarget.ik.collide.CollisionGuard` and the control loop's goal
check share one per model (:func:`shared_bound`).  It keeps its last notes (:meth:`ClearanceBound.recall`: a pose
near an earlier one needs no query), and bounds the moves of a path planned ahead from the notes its IK pass made,
all at once (:meth:`ClearanceBound.prove`, :class:`ProvenPath`: the loop's goal check takes those bounds).

Arrays: ``q`` ``(n_joints,)`` float64 radians; pair distances ``(n_pairs,)`` metres, as the model's ``pair_names``;
row distances ``(n_rows,)`` metres, the bound's rows (:class:`~retarget.collision.pieces.Pieces`: the pairs, with
the long moving capsules cut into pieces).
"""

from __future__ import annotations

import math
import weakref
from collections.abc import Sequence
from operator import mul, sub
from typing import TYPE_CHECKING

import numpy as np

from retarget.arm.kinematics import rpy_matrix

if TYPE_CHECKING:
    from retarget.collision import CollisionModel
    from retarget.collision.pieces import Pieces

__all__ = ["HORIZON", "ClearanceBound", "ProvenPath", "TableSlopes", "shared_bound"]

#: metres beyond the clearance within which a query measures a pair exactly (farther ones keep a cheap lower bound
#: of at least this: ``CollisionModel.pair_bounds``)
HORIZON = 0.01

State = tuple[np.ndarray, np.ndarray]  #: a note: its pose ``(n_joints,)`` rad and row distances ``(n_rows,)`` m
#: a note's plain-float screen: its pose and its groups of rows (least distance, greatest levers)
Screen = tuple[list[float], list[tuple[float, ...]]]
_BLOCK = 256  #: segments per product in ClearanceBound.prove
KEPT = 64  #: notes kept for :meth:`ClearanceBound.recall`
_NEAR = 6  #: rows the screen bounds one by one (the rest in groups: see ClearanceBound._screen_for)
_BANDS = (0.0, 0.01, 0.03, 0.1)  #: where the screen's bands of rows start, metres beyond the least of them


class ClearanceBound:
    """A lower bound of the clearance of poses near one that was checked, so most checks can be skipped.

    A pair of shapes on frames ``a < b`` (a zone of the world is on the base frame, 0) keeps a distance that
    depends only on joints ``a .. b-1``; a turn of joint ``j`` alone changes it by at most ``L_j`` per radian
    (:func:`~retarget.collision.levers.pair_levers`: the greatest distance from the joint's axis of the points of
    either shape, bounded whatever the other joints do).  So from a checked pose ``q_ref`` to ``q`` the pair's
    distance falls by at most ``sum_j |q_j - q_ref_j| L_j``.  Long moving capsules are cut into pieces, each with
    its own distance and smaller levers (:class:`~retarget.collision.pieces.Pieces`): the rows of the bound.
    After :meth:`note` of ``q_ref`` with its pair distances, :meth:`lower_bound` of ``q`` is the smallest row
    distance minus its fall: when it is still at least the clearance, ``q`` is clear without a query; and so is
    every pose of a straight joint-space segment whose two ends are (the bound is concave along the segment).
    Five small numpy operations on preallocated buffers; the last pose's value is kept (a second call with the
    same pose costs a comparison).

    >>> import retarget
    >>> from retarget.collision import CollisionModel
    >>> arm = retarget.load_arm("wx250s")
    >>> model = CollisionModel.for_arm(arm)
    >>> bound = ClearanceBound(model)
    >>> bound.note(arm.home.tolist(), model.distances(arm.home))
    >>> abs(bound.lower_bound(arm.home.tolist()) - model.min_clearance(arm.home)) < 1e-12
    True
    >>> bound.lower_bound((arm.home + 0.01).tolist()) < model.min_clearance(arm.home + 0.01)
    True
    """

    __slots__ = ("_pieces", "_levers", "_state", "_previous", "_last", "_move", "_fall", "_clearance", "_scale",
                 "_inv_sigma", "_rows", "_screen", "_screen_previous", "_slopes", "_log", "proven", "_kept", "_kept_q",
                 "_kept_d", "_kept_move", "_kept_fall", "_kept_at")  # fmt: skip

    def __init__(self, model: CollisionModel):
        from retarget.collision.pieces import Pieces  # (the collision package never imports this one)

        self._pieces = Pieces(model)  #: the rows: the pairs, long movers cut into pieces
        self._levers = np.ascontiguousarray(self._pieces.levers)  #: ``(n_rows, n_joints)`` metres per radian
        self._state: State | None = None  #: the last note; one tuple, replaced whole
        self._previous: State | None = None  #: the note before it: a motion that swings back may be near it
        #: the last pose :meth:`quick` bounded (a copy), the note it was bounded from and the value
        self._last: tuple[State | None, list[float], float] = (None, [], -math.inf)
        self._move = np.empty(model.arm.n_joints)  # buffers of _low
        self._fall = np.empty(len(self._levers))
        # the screen (see _screen_for): each joint's greatest lever, and each row's levers in units of them
        self._clearance = float(model.clearance)
        scale = self._levers.max(axis=0, initial=0.0)
        self._scale: list[float] = scale.tolist()
        sigma = (self._levers / np.where(scale > 0, scale, 1.0)).sum(axis=1)  # (n_rows,), 0 .. n_joints
        self._inv_sigma = np.where(sigma > 0, 1.0 / np.where(sigma > 0, sigma, 1.0), 0.0)

        self._rows: list[list[float]] = self._levers.tolist()
        self._screen: Screen | None = None
        self._screen_previous: Screen | None = None
        self._slopes = TableSlopes(model, self._pieces, self._levers)  #: the table rows' second bound
        self._log: list[State] | None = None  #: the notes since :meth:`record` (None: not recording)
        # the last KEPT notes, for :meth:`recall`: each note's state and screen, and its pose and rows stacked (a
        # ring; rows of -inf until filled, so an empty slot never bounds anything)
        n, n_rows = model.arm.n_joints, len(self._levers)
        self._kept: list[tuple[State, Screen | None] | None] = [None] * KEPT
        self._kept_q = np.zeros((KEPT, n))
        self._kept_d = np.full((KEPT, n_rows), -math.inf)
        self._kept_move = np.empty((KEPT, n))
        self._kept_fall = np.empty((KEPT, n_rows))
        self._kept_at = 0  #: the slot the next note goes to
        #: the segments of the last path proven clear (:meth:`prove`), for the loop's goal check; None: none
        self.proven: ProvenPath | None = None

    @property
    def previous_state(self) -> State | None:
        """The note before the last (as :attr:`state`; None: fewer than two notes)."""
        return self._previous

    @property
    def state(self) -> State | None:
        """The last note: its pose ``(n_joints,)`` rad and row distances ``(n_rows,)`` metres (None: no note)."""
        return self._state

    def note(self, q: Sequence[float] | np.ndarray, distances: np.ndarray) -> None:
        """Pose ``q`` (rad) was checked: ``distances`` ``(n_pairs,)`` metres, every pair's (lower bounds will do;
        exact ones near the clearance let the pieces of a long link be measured)."""
        ref = np.array(q, dtype=np.float64)
        self._previous, self._state = self._state, (ref, self._pieces.rows(ref, distances))
        self._screen_previous, self._screen = self._screen, self._screen_for(self._state)
        if self._log is not None:
            self._log.append(self._state)
        at = self._kept_at
        self._kept[at] = (self._state, self._screen)
        self._kept_q[at] = ref
        self._kept_d[at] = self._state[1]
        self._kept_at = (at + 1) % KEPT

    def recall(self, q: Sequence[float] | np.ndarray) -> float:
        """A lower bound of the min clearance (metres) of pose ``q`` (rad) from the best of the last :data:`KEPT`
        notes (each bounds it by itself, as the last one does in :meth:`quick`; a motion that comes back near
        where it was, or an IK pass over poses the loop has noted, needs no query).  When that keeps the clearance
        the note it came from becomes the last (the one :meth:`quick` bounds from; the last one the one before).
        A few numpy calls on preallocated buffers; ``-inf`` before the first note, ``inf`` without pairs."""
        fall = self._kept_fall
        if not fall.shape[1]:
            return math.inf
        move = self._kept_move
        np.subtract(q, self._kept_q, out=move)
        np.abs(move, out=move)
        np.matmul(move, self._levers.T, out=fall)
        np.subtract(self._kept_d, fall, out=fall)
        lows = fall.min(axis=1)
        k = int(lows.argmax())
        low = float(lows[k])
        kept = self._kept[k]
        if kept is None:
            return -math.inf
        if low >= self._clearance and kept[0] is not self._state:
            self._previous, self._state = self._state, kept[0]
            self._screen_previous, self._screen = self._screen, kept[1]
            if self._log is not None:
                self._log.append(kept[0])
        return low

    def record(self, on: bool = True) -> list[State]:
        """Start keeping every note (the last one first, when there is one; a note :meth:`recall` makes the last again
        too): the list they are appended to, until :meth:`prove` or ``record(False)`` (which stops it and returns
        an empty list)."""
        self._log = ([] if self._state is None else [self._state]) if on else None
        return [] if self._log is None else self._log

    def prove(
        self, starts: np.ndarray, ends: np.ndarray, notes: Sequence[State], index: Sequence[int] | np.ndarray
    ) -> ProvenPath:
        """Lower bounds of the min clearance over each straight joint-space segment ``starts[i] -> ends[i]``
        ``(n, n_joints)`` rad, from the notes ``notes`` (:meth:`record`'s): each segment from its note ``index[i]``
        and the notes either side of it (the best of the three; each a lower bound by itself: a bound from one
        note is concave along a straight segment, so its least is at an end).  Kept as :attr:`proven` for the
        loop's goal check, which takes a segment's bound when its move is that segment (:class:`ProvenPath`);
        stops recording."""
        self._log = None
        starts = np.asarray(starts, dtype=np.float64).reshape(-1, len(self._scale))
        ends = np.asarray(ends, dtype=np.float64).reshape(starts.shape)
        self.proven = ProvenPath(starts, ends, self._lows(starts, ends, notes, index, 0.0), self._scale)
        return self.proven

    def pose_lows(
        self, poses: np.ndarray, notes: Sequence[State], index: Sequence[int] | np.ndarray, reach: float = 0.0
    ) -> np.ndarray:
        """Lower bounds ``(n,)`` metres of the min clearance of each pose ``poses[i]`` ``(n, n_joints)`` rad, from
        the notes as :meth:`prove` bounds a segment (each pose a segment of no length), the neighbours' notes tried
        where a pose's own leaves it below the clearance plus ``reach`` metres.  Changes nothing."""
        poses = np.asarray(poses, dtype=np.float64).reshape(-1, len(self._scale))
        return self._lows(poses, poses, notes, index, reach)

    def _lows(
        self, starts: np.ndarray, ends: np.ndarray, notes: Sequence[State], index: Sequence[int] | np.ndarray,
        reach: float
    ) -> np.ndarray:  # fmt: skip
        """:meth:`prove`'s bounds (the neighbours' notes tried below the clearance plus ``reach``)."""
        low = np.full(len(starts), -math.inf)
        if notes and len(starts):
            refs = np.array([s[0] for s in notes])
            rows = np.array([s[1] for s in notes])
            index = np.asarray(index, dtype=np.intp)
            todo = np.arange(len(starts))
            for shift in (0, 1, -1):  # the neighbours only for the segments their own note leaves short
                k = np.clip(index[todo] + shift, 0, len(notes) - 1)
                low[todo] = np.maximum(low[todo], self._segments_low(starts[todo], ends[todo], refs[k], rows[k]))
                todo = todo[low[todo] < self._clearance + reach]
                if not todo.size:
                    break
        return low

    def _segments_low(self, starts: np.ndarray, ends: np.ndarray, refs: np.ndarray, rows: np.ndarray) -> np.ndarray:
        """Per segment ``starts[i] -> ends[i]`` ``(m, n_joints)`` rad, the lower bound from the note of pose
        ``refs[i]`` and row distances ``rows[i]`` ``(m, n_rows)`` metres: each row's distance less its greatest fall
        at either end (``(m,)`` metres).  In blocks of :data:`_BLOCK` segments (a small product stays on one thread:
        waking a BLAS pool costs more than the product)."""
        out = np.empty(len(starts))
        levers_t = self._levers.T
        for i in range(0, len(starts), _BLOCK):
            block = slice(i, i + _BLOCK)
            ref = refs[block]
            fall = np.maximum(np.abs(starts[block] - ref) @ levers_t, np.abs(ends[block] - ref) @ levers_t)
            out[block] = (rows[block] - fall).min(axis=1, initial=math.inf)
        return out

    def _screen_for(self, state: State) -> Screen | None:
        """The plain-float screen of a note: the :data:`_NEAR` rows that the least motion brings to the clearance
        (their slack over their levers, summed in units of each joint's greatest lever), one by one, and the rest
        in bands of distance (:data:`_BANDS`), each its least distance and its greatest lever per joint."""
        ref, d = state
        if len(d) <= _NEAR:
            return None
        room = (d - self._clearance) * self._inv_sigma  # (rows no joint moves: 0, so first; they have no levers)
        order = np.argpartition(room, _NEAR)
        near = order[:_NEAR].tolist()
        far = order[_NEAR:]
        far = far[np.argsort(d[far], kind="stable")]
        df = d[far].tolist()
        starts: list[int] = []
        i = 0
        for band in _BANDS:  # where each band starts in the far rows (sorted by distance)
            edge = df[0] + band
            while i < len(df) and df[i] < edge:
                i += 1
            if i < len(df) and (not starts or i > starts[-1]):
                starts.append(i)
        starts[0] = 0
        levers = np.maximum.reduceat(self._levers[far], starts, axis=0).tolist()
        rows, d_list = self._rows, d.tolist()
        groups = [(d_list[r], *rows[r]) for r in near] + [(df[i], *row) for i, row in zip(starts, levers, strict=True)]
        return ref.tolist(), groups

    @staticmethod
    def _screened(screen: Screen, q: list[float]) -> float:
        """The screen's lower bound of the min clearance of ``q`` (rad): each group's distance less its fall
        (``(distance, lever_0, lever_1, ...)`` each; unrolled for the usual five and six joints)."""
        ref, groups = screen
        low = math.inf
        if len(ref) == 6:
            m0, m1, m2 = abs(q[0] - ref[0]), abs(q[1] - ref[1]), abs(q[2] - ref[2])
            m3, m4, m5 = abs(q[3] - ref[3]), abs(q[4] - ref[4]), abs(q[5] - ref[5])
            for d, a, b, c, e, f, g in groups:
                v = d - (a * m0 + b * m1 + c * m2 + e * m3 + f * m4 + g * m5)
                if v < low:
                    low = v
            return low
        if len(ref) == 5:
            m0, m1, m2 = abs(q[0] - ref[0]), abs(q[1] - ref[1]), abs(q[2] - ref[2])
            m3, m4 = abs(q[3] - ref[3]), abs(q[4] - ref[4])
            for d, a, b, c, e, f in groups:
                v = d - (a * m0 + b * m1 + c * m2 + e * m3 + f * m4)
                if v < low:
                    low = v
            return low
        moves = list(map(abs, map(sub, q, ref)))
        for d, *levers in groups:
            v = d - sum(map(mul, levers, moves))
            if v < low:
                low = v
        return low

    def rows_at_note(self) -> np.ndarray:
        """The last note's row distances (a copy; metres), as :meth:`pairs_at` gives them."""
        if self._state is None:
            raise ValueError("Expected a note before rows_at_note")
        return self._state[1].copy()

    def quick(self, q: Sequence[float] | np.ndarray) -> float:
        """A lower bound of the min clearance (metres) of pose ``q`` (rad) from the last note, the same as
        :meth:`lower_bound`: first in plain floats (a few microseconds: the nearest rows one by one, the rest in
        bands of distance, each its least distance less its greatest levers' fall), then, when that is below the
        clearance, every row's own (a few numpy calls); the last pose's value is kept (a second call costs a
        comparison).  ``-inf`` before the first :meth:`note`, ``inf`` without pairs."""
        qs = q.tolist() if isinstance(q, np.ndarray) else list(q)
        state, (last_state, last_q, value) = self._state, self._last
        if last_state is state and qs == last_q:
            return value
        screen = self._screen
        value = math.nan if screen is None or len(qs) != len(screen[0]) else self._screened(screen, qs)
        if not value >= self._clearance:  # (or nan: no screen) the screen is not enough: every row
            value = self._low(state, qs)
        self._last = (state, qs, value)
        return value

    def quick_previous(self, q: Sequence[float] | np.ndarray) -> float:
        """A lower bound of the min clearance of ``q`` from the note before the last (``-inf`` before the second
        note): its plain-float screen only (a last resort before a query: no numpy)."""
        qs = q.tolist() if isinstance(q, np.ndarray) else list(q)
        screen = self._screen_previous
        if screen is None or len(qs) != len(screen[0]):
            return self._low(self._previous, qs)
        return self._screened(screen, qs)

    def lower_bound(self, q: Sequence[float] | np.ndarray) -> float:
        """A lower bound of the min clearance (metres) of pose ``q`` (rad); ``-inf`` before the first :meth:`note`."""
        return self.quick(q)

    def _low(self, state: State | None, q: Sequence[float] | np.ndarray) -> float:
        fall = self._fall
        if not fall.size:
            return math.inf
        if state is None:
            return -math.inf
        ref, d = state
        if len(q) != len(ref):
            raise ValueError(f"Expected {len(ref)} joint angles, got {len(q)}")
        move = self._move
        np.subtract(q, ref, out=move)
        np.abs(move, out=move)
        np.dot(self._levers, move, out=fall)
        np.subtract(d, fall, out=fall)
        return float(fall.min())

    def pairs_at(self, q: Sequence[float] | np.ndarray, state: State | None | bool = True) -> np.ndarray:
        """A lower bound of every row's distance in pose ``q`` ``(n_rows,)`` metres (``-inf`` before a note), from
        the last note, or from ``state`` (an earlier :attr:`state`) when given."""
        if state is True:
            state = self._state
        if state is None:
            return np.full(len(self._levers), -math.inf)
        assert state is not False  # noqa: S101 - only True or a state
        ref, d = state
        fall: np.ndarray = d - self._levers @ np.abs(np.asarray(q, dtype=np.float64) - ref)
        return fall

    def segment_low(self, q0: Sequence[float] | np.ndarray, q1: Sequence[float] | np.ndarray) -> float:
        """A lower bound of the min clearance (metres) over the straight joint-space segment ``q0`` -> ``q1`` (rad;
        ``q0 == q1``: one pose) from the last note alone, sharper than :meth:`quick` where a moving capsule's
        table distance decides: each row its distance less its greatest fall at either end (a row's bound is
        concave along the segment), and when only table rows fall below the clearance, each of those at least
        the :class:`TableSlopes` bound (its ends' heights follow their slopes: shoulder and elbow turns that keep
        the tool's height cancel out).  A few numpy calls; ``-inf`` before the first note, ``inf`` without pairs."""
        state = self._state
        if not self._fall.size:
            return math.inf
        if state is None:
            return -math.inf
        return self._slopes.segment_low(state, q0, q1, self._clearance)

    def segment_bound(self, q0: Sequence[float], q1: Sequence[float], at0: np.ndarray, at1: np.ndarray) -> float:
        """A lower bound of the min clearance over the straight joint-space segment ``q0`` -> ``q1``, from lower
        bounds ``at0``, ``at1`` ``(n_rows,)`` of the row distances at its ends: each row's distance is within
        its fall ``L`` of both ends' along the way, so it is at least ``min(a, b)`` and ``(a + b - L) / 2``."""
        fall = self._levers @ np.abs(np.asarray(q1, dtype=np.float64) - np.asarray(q0, dtype=np.float64))
        low = np.minimum(np.minimum(at0, at1), 0.5 * (at0 + at1 - fall))
        return float(low.min()) if low.size else math.inf


class ProvenPath:
    """Segments of a joint path, each with a lower bound of its min clearance (:meth:`ClearanceBound.prove`): the
    moves a planned clip makes, tick by tick, so that its goal check takes each tick's bound instead of working it
    out again.

    :meth:`find` gives a segment's bound for a move ``q_from -> q_to`` that is that segment to within ``EPS`` rad
    in all at each end (the loop's limiter, fed the plan, reproduces it to rounding), less ``EPS`` times the
    sum of the greatest levers: every pose of the move is within ``EPS`` per joint of the segment's pose at the same
    fraction, and no row's distance falls by more than its levers times that.  It tries only the segment after
    the last one found (the loop plays the path in order) and the first (the path played again), so a miss costs
    two comparisons.

    >>> import retarget
    >>> from retarget.collision import CollisionModel
    >>> model = CollisionModel.for_arm(retarget.load_arm("wx250s"))
    >>> bound, home = ClearanceBound(model), model.arm.home
    >>> notes = bound.record()
    >>> bound.note(home, model.distances(home))
    >>> path = bound.prove(home[None], (home + 0.01)[None], notes, [0])
    >>> low = path.find(home.tolist(), (home + 0.01).tolist())
    >>> model.clearance <= low <= model.min_clearance(home + 0.01)
    True
    >>> path.find(home.tolist(), (home + 0.02).tolist()) is None  # not that segment
    True
    """

    EPS = 1e-9  #: radians per joint: how near a move's ends must be to the segment's

    __slots__ = ("_starts", "_ends", "_low", "_next")

    def __init__(self, starts: np.ndarray, ends: np.ndarray, low: np.ndarray, scale: Sequence[float]):
        margin = self.EPS * float(sum(scale))
        self._starts: list[list[float]] = starts.tolist()
        self._ends: list[list[float]] = ends.tolist()
        self._low: list[float] = (low - margin).tolist()
        self._next = 0  #: the segment tried next

    def __len__(self) -> int:
        return len(self._low)

    @property
    def lows(self) -> list[float]:
        """Every segment's bound in order (metres, the slack's margin taken off): what :meth:`find` gives for each
        segment, found in order (a copy)."""
        return list(self._low)

    def matches(self, starts: np.ndarray, ends: np.ndarray) -> bool:
        """Whether ``starts -> ends`` ``(n, n_joints)`` rad are its segments exactly (the same poses, in order)."""
        return bool(starts.tolist() == self._starts and ends.tolist() == self._ends)

    def find(self, q_from: Sequence[float], q_to: Sequence[float]) -> float | None:
        """A lower bound of the min clearance (metres) of the move ``q_from -> q_to`` (rad) when it is the next
        segment (see the class docstring), else None."""
        if isinstance(q_from, np.ndarray):
            q_from = q_from.tolist()
        if isinstance(q_to, np.ndarray):
            q_to = q_to.tolist()
        for i in (self._next, 0):  # the next segment, or the first again (the path played once more)
            if i < len(self._low) and near_pose(q_to, self._ends[i]) and near_pose(q_from, self._starts[i]):
                self._next = i + 1
                return self._low[i]
        return None


def near_pose(a: Sequence[float], b: list[float]) -> bool:
    """Whether pose ``a`` is ``b``, or within :attr:`ProvenPath.EPS` of it in all (so per element; False for a NaN or a
    length mismatch: a NaN fails the sum's comparison)."""
    return a == b or len(a) == len(b) and sum(map(abs, map(sub, a, b))) <= ProvenPath.EPS


class TableSlopes:
    """A second lower bound of each moving capsule's table distance near a note: from its ends' heights and
    slopes, not the sum of its levers' falls.

    A point ``p`` on frame ``f`` has height ``z(q)``; its slope along joint ``j < f`` is ``(a_j x (p - o_j))_z``
    (axis ``a_j`` through ``o_j``), and its second derivatives are ``(a_i x (a_j x (p - o_j)))_z`` (``i <= j``), at
    most ``t_i rho_j``: ``rho_j`` the point's distance from axis ``j`` (at most the row's lever ``L_j``, bounded
    whatever the pose) and ``t_i`` the horizontal part of ``a_i`` (1 but for the first joint, whose axis is fixed
    in the base frame: 0 for a turntable).  So along the straight segment from the note's pose ``q_ref`` to ``q``,
    ``z(q) >= z(q_ref) + g . dq - Q(|dq|) / 2`` with ``Q(m) = sum_j L_j m_j (m_j + 2 sum_{i<j} t_i m_i)`` (Taylor
    with the integral remainder).  Over a segment ``q0 -> q1`` the linear term is least at an end and ``Q`` is at
    most ``Q(max(|dq0|, |dq1|))``; the capsule's table distance is its lower end's height less its radius.  Where
    shoulder and elbow turn together and keep the ends' heights, the levers' sum ``L . |dq|`` counts both turns
    in full; this bound counts what is left of them, plus a second-order term.

    The slopes are computed once per note, when first needed, from the model's one-pose buffers (each joint's
    origin and axis ride along with the geometry's points: no forward pass when they hold the note's pose).
    """

    def __init__(self, model: CollisionModel, pieces: Pieces, levers: np.ndarray):
        self.model = model
        rows: list[int] = []
        caps: list[int] = []
        if model.world.table:
            first = len(model._cc) + len(model._cb)
            whole = pieces._whole.tolist()
            for i, cap in enumerate(model._mcap.tolist()):
                k = first + i
                if k in whole and model.pair_names[k].endswith("/table"):
                    rows.append(whole.index(k))
                    caps.append(cap)
        self.rows = np.array(rows, dtype=np.intp)  #: ``(m,)`` the bound's rows of capsules against the table
        self._caps = np.array(caps, dtype=np.intp)
        self._frame = model._cap_frame[self._caps]  # (m,)
        self._radius = model._cap_r[self._caps]  # (m,)
        self._levers = levers[self.rows]  # (m, n)
        self._all = levers  # (n_rows, n)
        self._other = np.setdiff1d(np.arange(len(levers)), self.rows)  #: the rows that are not table rows
        arm = model.arm
        axis0 = rpy_matrix(arm.joints[0].origin_rpy) @ np.asarray(arm.joints[0].axis, dtype=np.float64)
        tilt = np.ones(arm.n_joints)
        tilt[0] = min(1.0, math.hypot(float(axis0[0]), float(axis0[1])) / float(np.linalg.norm(axis0)))
        self._tilt = tilt  #: ``t_i``: the horizontal part of each joint's axis (1 but for the first)
        n = arm.n_joints
        #: per end, which joints move it (``j < frame``): ``(2m, n)``
        self._moves = (np.arange(n)[None, :] < np.repeat(self._frame, 2)[:, None]).astype(np.float64)
        self._state: object = None
        self._slope = np.zeros((2 * len(rows), n))  #: ``(2m, n)`` each end's height slope per joint, m/rad
        self._height = np.zeros(2 * len(rows))  #: ``(2m,)`` each end's height at the note, metres

    def _at(self, state: object, ref: np.ndarray) -> None:
        """The ends' heights and slopes at the note's pose ``ref`` (once per note)."""
        if self._state is state:
            return
        origin, axis, caps = self.model._one.joint_points(ref)  # (3, n), (3, n), (3, n_caps, 2)
        p = caps[:, self._caps].reshape(3, -1)  # (3, 2m): each table capsule's two ends
        dx = p[0][:, None] - origin[0][None, :]  # (2m, n)
        dy = p[1][:, None] - origin[1][None, :]
        self._slope = (axis[0][None, :] * dy - axis[1][None, :] * dx) * self._moves
        self._height = p[2].copy()
        self._state = state

    def segment_low(
        self, state: State, q0: Sequence[float] | np.ndarray, q1: Sequence[float] | np.ndarray, clearance: float
    ) -> float:
        """:meth:`ClearanceBound.segment_low` from the note ``state = (ref, rows)``: the rows' linear bound over the
        segment ``q0 -> q1`` (rad), and when the other rows keep ``clearance`` but the table rows do not, the table
        rows raised to this bound where it is higher (metres)."""
        ref, d = state
        da = np.subtract(q0, ref)
        db = np.subtract(q1, ref)
        ma, mb = np.abs(da), np.abs(db)
        low: np.ndarray = d - np.maximum(self._all @ ma, self._all @ mb)
        rows = self.rows
        if not rows.size:
            return float(low.min())
        other = float(low[self._other].min(initial=math.inf))
        table = float(low[rows].min())
        if other < clearance or table >= clearance:
            return min(other, table)
        raised = np.maximum(low[rows], self.heights(state, da, db))
        return min(other, float(raised.min()))

    def heights(self, state: State, d0: np.ndarray, d1: np.ndarray) -> np.ndarray:
        """This bound of each table row ``(m,)`` metres (as :attr:`rows`) over the segment from ``ref + d0`` to
        ``ref + d1`` (rad) about the note ``state = (ref, rows)``."""
        self._at(state, state[0])
        m = np.maximum(np.abs(d0), np.abs(d1))
        before = np.cumsum(self._tilt * m)
        before[1:] = before[:-1].copy()
        before[0] = 0.0  # sum_{i<j} t_i m_i
        quad = 0.5 * (self._levers @ (m * (m + 2.0 * before)))  # (m,)
        ends = self._height + np.minimum(self._slope @ d0, self._slope @ d1)  # (2m,) each end's least height
        out: np.ndarray = np.minimum(ends[0::2], ends[1::2]) - self._radius - quad
        return out


_SHARED: weakref.WeakKeyDictionary[CollisionModel, ClearanceBound] = weakref.WeakKeyDictionary()


def shared_bound(model: CollisionModel) -> ClearanceBound:
    """The :class:`ClearanceBound` of ``model`` that its IK solvers and the control loop's goal check share: a pose
    one of them queried (say the IK's solution) spares the other a query of the same or a nearby pose.  Every
    note is a true measurement, so sharing is sound; not for threads that solve at the same time."""
    bound = _SHARED.get(model)
    if bound is None:
        bound = _SHARED[model] = ClearanceBound(model)
    return bound
