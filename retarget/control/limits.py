"""The step limiter: the commanded pose, moved toward each tick's goal within one slot of speed and the limits.

Each tick, each joint's step toward the goal is cut to ``velocity_scale x max_velocity / rate`` (one slot's
worth; a :class:`~retarget.control.source.JointGoal` may ask for less with its ``max_step``), then the pose is
clamped to the joint limits.  One slot's worth also after an overrun skipped slots: a stall's whole travel in
one step would be a jump the servos then run at full speed; the arm lags its targets and catches up instead.

It also predicts the IK seed: the commanded pose moved on by half its last step (a damped constant-velocity
prediction: about 25 % fewer sweeps than the plain last pose; seeding from the commanded pose rather than the
raw IK solution keeps a velocity-limited tick from letting IK wander off).

With ``max_accel`` (rad per slot^2, per joint) the step is also acceleration-limited: a discrete trapezoidal
profile (:mod:`~retarget.control.profile`) that follows the moving goal (its step since the last tick is
fed forward), changes each joint's step by at most ``max_accel`` per slot and brakes in time for the joint
limits, so the commanded pose never leaves them.  It works from the last commanded pose and step: after an
overrun of ``elapsed`` slots the step decays toward rest by ``max_accel`` per missed slot (the servos braked
onto the held goal), then one slot's step follows; a :data:`~retarget.control.source.HOLD` tick
(:meth:`StepLimiter.brake`) brakes to rest at ``max_accel``.  Without ``max_accel`` each tick's step is cut to
one slot's worth only (the goal is reached in one step if it can be).

The arithmetic runs on plain Python floats on purpose: on a handful of joints numpy's per-call overhead costs
more than the math, and on a bus that time sits between the last reply and the next write.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from retarget.control.profile import braking_run, stop_speed

__all__ = ["StepLimiter"]

SEED_LEAD = 0.5  #: the IK seed leads the commanded pose by this fraction of its last step (:meth:`StepLimiter.seed`)


class StepLimiter:
    """The commanded pose ``q`` (floats, rad) and its velocity (rad per slot), stepped within the limits.

    ``lower``/``upper``/``max_step`` are ``(n_joints,)``: the joint limits (rad) and the largest step per slot
    (rad); ``q_start`` ``(n_joints,)`` rad is the pose to start from (inside the limits).

    >>> limiter = StepLimiter(np.array([-1.0, -1.0]), np.array([1.0, 0.5]), np.array([0.1, 0.1]), np.zeros(2))
    >>> limiter.step([0.05, 2.0], elapsed=1), limiter.q
    (True, [0.05, 0.1])
    >>> limiter.seed(elapsed=1).round(3).tolist()
    [0.075, 0.15]

    ``max_accel`` ``(n_joints,)`` rad per slot^2 limits the acceleration too (a trapezoidal profile):

    >>> limiter = StepLimiter(np.array([-1.0]), np.array([1.0]), np.array([0.1]), np.zeros(1),
    ...                       max_accel=np.array([0.02]))
    >>> for _ in range(3):
    ...     _ = limiter.step([1.0], elapsed=1)
    >>> round(limiter.q[0], 3), round(limiter.velocity[0], 3)  # 0.02 + 0.04 + 0.06: speeding up by 0.02
    (0.12, 0.06)
    """

    __slots__ = ("bounds", "max_step", "max_accel", "q", "velocity", "goal", "_zero", "_far")

    def __init__(
        self,
        lower: npt.NDArray[np.float64],
        upper: npt.NDArray[np.float64],
        max_step: npt.NDArray[np.float64],
        q_start: npt.NDArray[np.float64],
        *,
        max_accel: npt.NDArray[np.float64] | None = None,
    ):
        self.bounds: tuple[tuple[float, float], ...] = tuple(zip(lower.tolist(), upper.tolist(), strict=True))
        self.max_step: list[float] = max_step.tolist()  #: rad per slot, per joint
        self.q: list[float] = q_start.tolist()  #: the commanded pose, rad
        self._zero = [0.0] * len(self.q)
        self.velocity: list[float] = self._zero  #: of the commanded pose, rad per slot
        #: rad per slot^2, per joint; None: no acceleration limit
        self.max_accel: list[float] | None = None if max_accel is None else max_accel.tolist()
        #: rad per joint: from this far from a joint limit, its braking bound allows a full step
        accel = self.max_accel or []
        self._far = [braking_run(m, a) for m, a in zip(self.max_step, accel, strict=False)]
        self.goal: list[float] | None = None  #: the last tick's goal (rad), for its step; None after a stop

    def state(self) -> tuple[list[float], list[float], list[float] | None]:
        """The pose, velocity and last goal, for :meth:`restore` (the lists are replaced, never changed in place)."""
        return self.q, self.velocity, self.goal

    def restore(self, state: tuple[list[float], list[float], list[float] | None]) -> None:
        """Back to a :meth:`state` (a tick whose step was not written)."""
        self.q, self.velocity, self.goal = state

    def hold(self) -> None:
        """A tick that keeps the commanded pose: it stands still at once, also with ``max_accel`` (the loop does
        this only for the collision check's instant stop; a tick without a goal brakes, :meth:`brake`)."""
        self.velocity = self._zero
        self.goal = None

    def brake(self, elapsed: int = 1) -> bool:
        """A tick without a goal: stand still, or with ``max_accel`` brake one slot toward rest (``elapsed - 1``
        missed slots braked before it).  Returns True when the commanded pose moved."""
        accel = self.max_accel
        self.goal = None
        if accel is None or not any(self.velocity):
            self.velocity = self._zero
            return False
        v = [_toward_zero(x, a * elapsed) for x, a in zip(self.velocity, accel, strict=True)]
        bounds = zip(self.q, v, self.bounds, strict=True)
        self.q = [lo if (y := x + w) < lo else hi if y > hi else y for x, w, (lo, hi) in bounds]
        self.velocity = v
        return True

    def seed(self, elapsed: int) -> npt.NDArray[np.float64]:
        """The IK seed of a tick ``elapsed`` slots after the last: where the commanded pose is heading at half its
        current speed, clamped to the limits (a full-speed prediction saves a few more sweeps but overshoots
        into joint-limit traps now and then)."""
        lead_by = SEED_LEAD * elapsed
        seed = [
            lo if (x := a + lead_by * v) < lo else hi if x > hi else x
            for a, v, (lo, hi) in zip(self.q, self.velocity, self.bounds, strict=True)
        ]
        return np.array(seed)

    def step(self, goal: Sequence[float], elapsed: int, max_step: Sequence[float] | None = None) -> bool:
        """Move the commanded pose toward ``goal`` (rad) by at most one slot's step per joint (or ``max_step``
        where that is tighter), then clamp it to the limits; ``elapsed`` slots since the last tick set the
        velocity.  Returns True when a joint's step was cut (velocity-limited)."""
        limits = self.max_step
        if max_step is not None:
            limits = [a if a < b else b for a, b in zip(limits, max_step, strict=True)]
        if self.max_accel is not None:
            return self._profile(goal, elapsed, limits)
        limited = False
        q = self.q
        q_next = []
        for x, x0, m, (lo, hi) in zip(goal, q, limits, self.bounds, strict=True):
            d = x - x0
            if d > m:
                d, limited = m, True
            elif d < -m:
                d, limited = -m, True
            y = x0 + d
            q_next.append(lo if y < lo else hi if y > hi else y)
        self.velocity = [(x - x0) / elapsed for x, x0 in zip(q_next, q, strict=True)]
        self.q = q_next
        return limited

    def _profile(self, goal: Sequence[float], elapsed: int, limits: list[float]) -> bool:
        """:meth:`step` with the acceleration limit: one slot's step of the trapezoidal profile per joint."""
        accel = self.max_accel
        assert accel is not None
        last = self.goal
        goal = list(goal)
        self.goal = goal
        v0 = self.velocity
        if elapsed > 1:  # the missed slots held the last goal: the servos braked onto it
            v0 = [_toward_zero(x, a * (elapsed - 1)) for x, a in zip(v0, accel, strict=True)]
        limited = False
        q_next, v_next = [], []
        far = self._far
        sqrt, floor = math.sqrt, math.floor
        # profile_step inlined (it is the reference, tested against this), except that a joint limit's braking
        # bound is computed only within a braking run of it (farther off it allows a full step anyway)
        for i, (x0, v, g, m, a, (lo, hi)) in enumerate(zip(self.q, v0, goal, limits, accel, self.bounds, strict=True)):
            u = 0.0 if last is None else (g - last[i]) / elapsed
            u = m if u > m else -m if u < -m else u
            d = g - x0 - u
            if -0.5 * a < d < 0.5 * a:  # stop_speed's n is 0 (|d| < a): it gives d itself, the same float
                w = u + d
            elif d > 0.0:  # u + stop_speed(d, a), inlined (the same expressions, so the same floats)
                n = floor((sqrt(1.0 + 8.0 * d / a) - 1.0) * 0.5)
                w = u + (d + a * n * (n + 1) * 0.5) / (n + 1)
            else:  # u - stop_speed(-d, a)
                d = -d
                n = floor((sqrt(1.0 + 8.0 * d / a) - 1.0) * 0.5)
                w = u - (d + a * n * (n + 1) * 0.5) / (n + 1)
            low, high = v - a, v + a
            if low < -m:
                low = -m
            if high > m:
                high = m
            if x0 - lo < far[i]:
                low = max(low, -stop_speed(x0 - lo, a))
            if hi - x0 < far[i]:
                high = min(high, stop_speed(hi - x0, a))
            if low > high:  # the cap fell below the speed (a tighter max_step): brake at the acceleration limit
                w = v - a if v > 0.0 else v + a
            else:
                w = low if w < low else high if w > high else w
            if (w >= m or w <= -m) and abs(g - x0) > m:
                limited = True
            y = x0 + w
            q_next.append(lo if y < lo else hi if y > hi else y)
            v_next.append(w)
        self.q, self.velocity = q_next, v_next
        return limited


def _toward_zero(x: float, by: float) -> float:
    """``x`` moved toward 0 by ``by`` (>= 0), stopping at 0."""
    return x - by if x > by else x + by if x < -by else 0.0
