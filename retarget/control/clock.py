"""Clocks for the control loop and the simulator.

A real run paces itself on :class:`MonotonicClock`.  ``--fast`` runs and tests
share one :class:`VirtualClock` between the control loop and the simulated
servos, so a minute of motion runs in milliseconds while the servos still see
time pass at the tick rate.
"""

from __future__ import annotations

import time
from typing import Protocol


class Clock(Protocol):
    def now(self) -> float:
        """Seconds since an arbitrary origin, monotonic."""

    def sleep_until(self, t: float) -> None:
        """Return once ``now() >= t`` (immediately when it already is)."""


class MonotonicClock:
    """Wall time from ``time.perf_counter``; sleeps, then spins the last half millisecond for accuracy."""

    spin: float = 0.0005

    def now(self) -> float:
        return time.perf_counter()

    def sleep_until(self, t: float) -> None:
        remaining = t - time.perf_counter()
        if remaining > self.spin:
            time.sleep(remaining - self.spin)
        while time.perf_counter() < t:
            pass


class VirtualClock:
    """Time that moves only when told to: ``sleep_until`` and ``advance`` jump it forward."""

    def __init__(self, start: float = 0.0):
        self._t = float(start)

    def now(self) -> float:
        return self._t

    def sleep_until(self, t: float) -> None:
        if t > self._t:
            self._t = float(t)

    def advance(self, dt: float) -> None:
        if dt < 0:
            raise ValueError(f"Expected dt >= 0, got {dt}")
        self._t += float(dt)
