"""The tick loop's schedule: slot ``k`` starts at ``t0 + k / rate`` on the loop's clock.

A tick waits for its slot, runs, then :meth:`Schedule.advance` reads the clock once: a tick that ended after
the next slot began is an **overrun**, and the next tick runs in the slot the clock is in, skipping the
missed ones, instead of running late for ever after, so delays never accumulate as drift.
"""

from __future__ import annotations

import math

from retarget.control.clock import Clock

__all__ = ["Schedule"]


class Schedule:
    """The slots of one run on ``clock`` at ``rate`` ticks per second; ``first`` (<= 0) is the current slot now.

    ``slot`` is the slot of the tick to run, ``time`` its start in seconds since the run's start (slot 0;
    negative in a lead-in).

    >>> from retarget.control.clock import VirtualClock
    >>> clock = VirtualClock()
    >>> schedule = Schedule(clock, rate=100.0, first=0)
    >>> schedule.wait(), schedule.advance(), schedule.slot  # on time: the next slot
    (0.0, False, 1)
    >>> schedule.wait()
    0.01
    >>> clock.advance(0.035)  # 3.5 slots of work: an overrun, on to the slot the clock is in
    >>> schedule.advance(), schedule.slot
    (True, 4)
    """

    __slots__ = ("_clock", "dt", "t0", "slot", "time")

    def __init__(self, clock: Clock, *, rate: float, first: int = 0):
        self._clock = clock
        self.dt = 1.0 / rate  #: seconds per slot
        self.t0 = clock.now() - first * self.dt  #: clock time of slot 0
        self.slot = first
        self.time = first * self.dt

    def wait(self) -> float:
        """Sleep until the current slot starts; returns its time since the run's start (``slot / rate``)."""
        self.time = slot_time = self.slot * self.dt
        self._clock.sleep_until(self.t0 + slot_time)
        return slot_time

    def advance(self) -> bool:
        """End the current slot's tick: move to the next slot, or after an overrun (the tick ended after the
        next slot began) to the slot the clock is in.  Returns True on an overrun."""
        k, dt = self.slot, self.dt
        now = self._clock.now() - self.t0
        if now > self.time + dt:
            self.slot = max(k + 1, math.floor(now / dt))
            return True
        self.slot = k + 1
        return False
