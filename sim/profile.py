"""Motion profiles of a simulated servo: piecewise constant-acceleration segments, evaluated in closed form.

The servo's profile (velocity- or time-based, ``drivers.servo_plan.Profile``) shapes each move; what it
plans for one goal is a :class:`Trajectory` (the e-Manual's Position/Velocity Trajectory items report it).

Units are the servo's own: position in pulses, velocity in pulses/s, acceleration in pulses/s^2, time in
seconds on the servo's clock.  A profile is planned once, when a goal is written, and then evaluated at any
later time, so a read after a minute of virtual time costs the same as a read after a millisecond.

* :func:`velocity_profile`: the X-series velocity-based profile (Drive Mode bit 2 = 0): accelerate at
  ``accel`` to at most ``vmax``, cruise, decelerate to stop on the goal -- a trapezoid, or a triangle when
  the move is short.  It starts from the present velocity, so a goal changed in mid-move blends.
  ``accel = inf`` (Profile Acceleration 0) jumps to speed.
* :func:`time_profile`: the time-based profile (Drive Mode bit 2 = 1): reach the goal ``t_total`` after the
  write with ``t_accel`` ramps (clipped to half of ``t_total``), started from rest.
* :func:`ramp_profile`: velocity mode, ramp to a goal velocity and keep it.
"""

from __future__ import annotations

import math
from typing import NamedTuple


class Segment(NamedTuple):
    """One constant-acceleration piece of a :class:`Trajectory` (a tuple: built on every goal a servo takes)."""

    t0: float  #: start time, s
    p0: float  #: position at t0, pulses
    v0: float  #: velocity at t0, pulses/s
    a: float  #: constant acceleration, pulses/s^2
    duration: float  #: s; math.inf for the last segment of a velocity-mode ramp


class Trajectory(NamedTuple):
    """A planned motion: segments back to back, then rest at ``end_position`` (unless the last never ends).

    Immutable (a NamedTuple: every goal a servo takes plans one).

    >>> move = velocity_profile(0.0, 0.0, 0.0, goal=100.0, vmax=1000.0, accel=10_000.0)
    >>> move.shape, round(move.t_end, 3)  # a triangle (Moving Status bits 4-5 = 2), 0.2 s long
    (2, 0.2)
    >>> move.state(0.05), move.state(1.0)  # (pulses, pulses/s, pulses/s^2): speeding up, then at rest
    ((12.5, 500.0, 10000.0), (100.0, 0.0, 0.0))
    """

    segments: tuple[Segment, ...]
    end_position: float
    shape: int = 0  #: Moving Status bits 4-5: 0 step, 1 rectangle, 2 triangle, 3 trapezoid

    @property
    def t_end(self) -> float:
        if not self.segments:
            return -math.inf
        last = self.segments[-1]
        return last.t0 + last.duration

    def state(self, t: float) -> tuple[float, float, float]:
        """``(position, velocity, acceleration)`` at time ``t``."""
        for t0, p0, v0, a, duration in self.segments:
            if t < t0:
                return p0, v0, 0.0
            dt = t - t0
            if dt <= duration:
                return p0 + v0 * dt + 0.5 * a * dt * dt, v0 + a * dt, a
        return self.end_position, 0.0, 0.0

    def done(self, t: float) -> bool:
        return t >= self.t_end


def rest(position: float) -> Trajectory:
    return Trajectory((), float(position))


def _segment(values: tuple[float, float, float, float, float]) -> Segment:
    """``Segment(*values)`` without the NamedTuple's Python-level ``__new__`` (a move plans two or three)."""
    return tuple.__new__(Segment, values)


def _append(segs: list[Segment], t: float, p: float, v: float, a: float, d: float) -> tuple[float, float, float]:
    """Add a segment; return the (t, p, v) at its end."""
    if d > 0:
        segs.append(_segment((t, p, v, a, d)))
    return t + d, p + v * d + 0.5 * a * d * d, v + a * d


def velocity_profile(t0: float, p0: float, v0: float, goal: float, vmax: float, accel: float) -> Trajectory:
    """Time-optimal move from ``(p0, v0)`` at ``t0`` to rest at ``goal`` within ``|v| <= vmax``, ``|a| <= accel``."""
    if vmax <= 0:
        raise ValueError(f"Expected vmax > 0, got {vmax}")
    if accel <= 0:
        raise ValueError(f"Expected accel > 0, got {accel}")
    segs: list[Segment] = []
    t, p, v = t0, float(p0), float(v0)
    if math.isinf(accel):  # Profile Acceleration 0: velocity steps, a rectangle
        d = goal - p
        if d:
            t, p, v = _append(segs, t, p, math.copysign(vmax, d), 0.0, abs(d) / vmax)
        return Trajectory(tuple(segs), float(goal), 1 if segs else 0)
    for _ in range(3):  # at most: stop an overshoot or overspeed, then plan from rest
        d = goal - p
        s = 1.0 if d > 0 or (d == 0 and v < 0) else -1.0
        x, u = s * d, s * v  # distance and speed toward the goal
        stopping = u * u / (2 * accel) if u > 0 else 0.0
        if u < 0 or u > vmax or stopping > x + 1e-9:
            # moving away, too fast, or cannot stop in time: brake to rest first, then replan
            t, p, v = _append(segs, t, p, v, -math.copysign(accel, v), abs(v) / accel)
            v = 0.0
            continue
        peak = math.sqrt(accel * x + 0.5 * u * u)
        if peak > vmax:
            t1 = (vmax - u) / accel
            t3 = vmax / accel
            cruise = x - (vmax * vmax - u * u) / (2 * accel) - vmax * vmax / (2 * accel)
            t, p, v = _append(segs, t, p, v, s * accel, t1)
            t, p, v = _append(segs, t, p, s * vmax, 0.0, max(cruise, 0.0) / vmax)
            _append(segs, t, p, s * vmax, -s * accel, t3)
            shape = 3
        else:  # a triangle (every tick's small step)
            t, p, v = _append(segs, t, p, v, s * accel, (peak - u) / accel)
            _append(segs, t, p, s * peak, -s * accel, peak / accel)
            shape = 2
        return tuple.__new__(Trajectory, (tuple(segs), float(goal), shape if segs else 0))  # Trajectory(...), faster
    raise AssertionError("velocity_profile did not converge")  # pragma: no cover


def time_profile(t0: float, p0: float, goal: float, t_total: float, t_accel: float, vmax: float) -> Trajectory:
    """Move from rest at ``p0`` to ``goal`` in ``t_total`` s with ``t_accel`` s ramps, slowed to respect ``vmax``."""
    d = goal - p0
    if d == 0:
        return rest(goal)
    t_accel = min(max(t_accel, 0.0), t_total / 2)
    if t_total <= 0:  # Profile Velocity 0: as fast as possible
        return velocity_profile(t0, p0, 0.0, goal, vmax, math.inf)
    peak = abs(d) / (t_total - t_accel)
    if peak > vmax:  # the motor cannot: stretch the profile, keeping the ramp fraction
        scale = peak / vmax
        t_total, t_accel, peak = t_total * scale, t_accel * scale, vmax
    s = math.copysign(1.0, d)
    segs: list[Segment] = []
    t, p, v = t0, float(p0), 0.0
    if t_accel == 0:
        _append(segs, t, p, s * peak, 0.0, t_total)
        return Trajectory(tuple(segs), float(goal), 1)
    a = peak / t_accel
    t, p, v = _append(segs, t, p, v, s * a, t_accel)
    t, p, v = _append(segs, t, p, s * peak, 0.0, t_total - 2 * t_accel)
    _append(segs, t, p, s * peak, -s * a, t_accel)
    return Trajectory(tuple(segs), float(goal), 2 if t_total == 2 * t_accel else 3)


def ramp_profile(t0: float, p0: float, v0: float, v_goal: float, accel: float) -> Trajectory:
    """Velocity mode: ramp from ``v0`` to ``v_goal`` at ``accel`` (inf: at once) and keep it forever."""
    segs: list[Segment] = []
    t, p, v = t0, float(p0), float(v0)
    if not math.isinf(accel) and v != v_goal:
        t, p, v = _append(segs, t, p, v, math.copysign(accel, v_goal - v), abs(v_goal - v) / accel)
    segs.append(Segment(t, p, float(v_goal), 0.0, math.inf))
    return Trajectory(tuple(segs), math.nan, 3 if len(segs) > 1 else 1)
