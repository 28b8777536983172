"""Hands that move a limp arm during calibration: the user's own, or, on a simulated bus, the simulator's.

The flow asks the user to pose the arm, nudge a joint, sweep it through its range.  With :class:`SimHands` (``--yes``
on a ``sim://`` port) the simulated arm's body (:class:`sim.mount.ArmBody`) does it, on the bus clock, before the
prompt is answered: the whole flow then runs unattended.  Angles are the physical joints', radians.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Protocol

import numpy as np

from retarget.control.clock import Clock

if TYPE_CHECKING:
    from sim.mount import ArmBody

__all__ = ["Hands", "SimHands"]


class Hands(Protocol):
    """What moves the limp joints when nobody at the keyboard does."""

    def place(self, q: np.ndarray) -> None:
        """Turn every joint to ``q`` ``(n_joints,)`` rad and hold it there (returns once it is there)."""

    def nudge(self, joint: int, angle: float) -> None:
        """Turn joint ``joint`` alone to ``angle`` rad and hold it (returns once it is there)."""

    def sweep(self, joint: int, lower: float, upper: float) -> Callable[[], bool]:
        """Start turning joint ``joint`` to ``lower``, then ``upper``, then back; returns a step function that
        advances the gesture by one sample period and returns False once it is over."""

    def release(self) -> None:
        """Let go of every joint."""


class SimHands:
    """:class:`Hands` of a simulated arm: ``body`` (``SimBus.body``) turned on the bus ``clock``.

    ``duration``: seconds per turn; ``period``: seconds between two samples of a sweep; ``reach``: per joint index,
    the (lower, upper) rad the hand can turn it to (default the limits asked for): an arm that stops short.
    """

    def __init__(
        self,
        body: ArmBody,
        clock: Clock,
        *,
        duration: float = 0.5,
        period: float = 0.02,
        reach: dict[int, tuple[float, float]] | None = None,
    ):
        self.body = body
        self.clock = clock
        self.duration = duration
        self.period = period
        self.reach = dict(reach or {})

    def _turn(self, q: np.ndarray, joints: Sequence[int] | None = None) -> float:
        return self.body.turn(q.tolist(), duration=self.duration, joints=joints)

    def place(self, q: np.ndarray) -> None:
        self.clock.sleep_until(self._turn(np.asarray(q, dtype=np.float64)))

    def nudge(self, joint: int, angle: float) -> None:
        q = self.body.angles()
        q[joint] = angle
        self.clock.sleep_until(self._turn(q, [joint]))

    def sweep(self, joint: int, lower: float, upper: float) -> Callable[[], bool]:
        lo, hi = self.reach.get(joint, (lower, upper))
        start = float(self.body.angles()[joint])
        targets = [lo, hi, start]
        end = [self.clock.now()]

        def step() -> bool:
            if self.clock.now() >= end[0]:
                if not targets:
                    return False
                q = self.body.angles()
                q[joint] = targets.pop(0)
                end[0] = self._turn(q, [joint])
            self.clock.sleep_until(self.clock.now() + self.period)
            return True

        return step

    def release(self) -> None:
        self.body.release()
