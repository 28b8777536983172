"""A hand turning a limp servo's horn: paths from the servo's clock time to the shaft's Present Position.

A :data:`HandPath` maps clock time (s, the servo's clock) to the Present Position (pulses, in the servo's reporting
frame: Homing Offset and Drive Mode applied) the hand holds the horn at.  :meth:`sim.servo.SimServo.move_by_hand`
takes one; :func:`smoothstep_path` is the usual "turn it from here to there in so many seconds" gesture.

>>> path = smoothstep_path(t0=1.0, start=2048.0, end=3072.0, duration=2.0)
>>> path(0.0), path(2.0), path(3.0), path(9.0)  # before, half-way, at the end, and held there
(2048.0, 2560.0, 3072.0, 3072.0)
>>> round(rate(path, 2.0), 1)  # pulses/s half-way: 1.5 x the mean speed of 512 pulses/s
768.0
"""

from __future__ import annotations

from collections.abc import Callable

HandPath = Callable[[float], float]  #: clock time (s) -> Present Position (pulses)
_H = 1e-4  #: s, the step of the numerical derivative


def smoothstep_path(*, t0: float, start: float, end: float, duration: float) -> HandPath:
    """From ``start`` at ``t0`` to ``end`` at ``t0 + duration`` (pulses, s), easing in and out; held before and after.

    The smoothstep ``3u^2 - 2u^3`` starts and ends at rest, as a hand does.  ``duration <= 0`` jumps at ``t0``.
    """
    if duration < 0:
        raise ValueError(f"Expected a duration >= 0 s, got {duration}")

    def path(t: float) -> float:
        if duration == 0:
            return float(end) if t >= t0 else float(start)
        u = min(max((t - t0) / duration, 0.0), 1.0)
        return float(start) + (float(end) - float(start)) * u * u * (3.0 - 2.0 * u)

    return path


def rate(path: HandPath, t: float) -> float:
    """d(path)/dt at ``t`` (pulses/s), by a central difference."""
    return (path(t + _H) - path(t - _H)) / (2.0 * _H)
