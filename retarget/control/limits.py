"""The step limiter: the commanded pose, moved toward each tick's goal within one slot of speed and the limits.

Each tick, each joint's step toward the goal is cut to ``velocity_scale x max_velocity / rate`` (one slot's
worth; a :class:`~retarget.control.source.JointGoal` may ask for less with its ``max_step``), then the pose is
clamped to the joint limits.  One slot's worth also after an overrun skipped slots: a stall's whole travel in
one step would be a jump the servos then run at full speed; the arm lags its targets and catches up instead.

It also predicts the IK seed: the commanded pose moved on by half its last step (a damped constant-velocity
prediction: about 25 % fewer sweeps than the plain last pose; seeding from the commanded pose rather than the
raw IK solution keeps a velocity-limited tick from letting IK wander off).

The arithmetic runs on plain Python floats on purpose: on a handful of joints numpy's per-call overhead costs
more than the math, and on a bus that time sits between the last reply and the next write.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

__all__ = ["StepLimiter"]

_LEAD = 0.5  #: the IK seed leads the commanded pose by this fraction of its last step


class StepLimiter:
    """The commanded pose ``q`` (floats, rad) and its velocity (rad per slot), stepped within the limits.

    ``lower``/``upper``/``max_step`` are ``(n_joints,)``: the joint limits (rad) and the largest step per slot
    (rad); ``q_start`` ``(n_joints,)`` rad is the pose to start from (inside the limits).

    >>> limiter = StepLimiter(np.array([-1.0, -1.0]), np.array([1.0, 0.5]), np.array([0.1, 0.1]), np.zeros(2))
    >>> limiter.step([0.05, 2.0], elapsed=1), limiter.q
    (True, [0.05, 0.1])
    >>> limiter.seed(elapsed=1).round(3).tolist()
    [0.075, 0.15]
    """

    __slots__ = ("bounds", "max_step", "q", "velocity", "_zero")

    def __init__(
        self,
        lower: npt.NDArray[np.float64],
        upper: npt.NDArray[np.float64],
        max_step: npt.NDArray[np.float64],
        q_start: npt.NDArray[np.float64],
    ):
        self.bounds: tuple[tuple[float, float], ...] = tuple(zip(lower.tolist(), upper.tolist(), strict=True))
        self.max_step: list[float] = max_step.tolist()  #: rad per slot, per joint
        self.q: list[float] = q_start.tolist()  #: the commanded pose, rad
        self._zero = [0.0] * len(self.q)
        self.velocity: list[float] = self._zero  #: of the commanded pose, rad per slot

    def hold(self) -> None:
        """A tick that keeps the commanded pose: it stands still."""
        self.velocity = self._zero

    def seed(self, elapsed: int) -> npt.NDArray[np.float64]:
        """The IK seed of a tick ``elapsed`` slots after the last: where the commanded pose is heading at half its
        current speed, clamped to the limits (a full-speed prediction saves a few more sweeps but overshoots
        into joint-limit traps now and then)."""
        lead_by = _LEAD * elapsed
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
