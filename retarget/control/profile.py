"""The acceleration-limited step of one joint: a discrete trapezoidal profile that follows a moving goal.

Units are slots: a position in rad, a velocity ``v`` in rad per slot (the step the joint takes in one slot),
an acceleration ``a`` in rad per slot^2 (the most a step may differ from the last).  The rule, per joint and
tick, with ``q``/``v`` the commanded pose and its last step, ``g`` the tick's goal and ``u`` the goal's own
step since the last tick (clamped to the velocity cap ``vmax``):

1. aim: ``w = u + sign(d) * stop_speed(|d|, a)`` with ``d = g - q - u``: move with the goal, plus the
   fastest relative step from which the joint can still brake to the goal's speed exactly on it (no
   overshoot of a goal that moves on as it did; a small ``|d| <= a`` is closed in one step);
2. the feasible steps: ``|w - v| <= a`` (the acceleration limit), ``|w| <= vmax`` (the velocity limit) and
   ``-stop_speed(q - lower) <= w <= stop_speed(upper - q)``: the discrete form of ``v <= sqrt(2 a d)``, so the
   joint can always brake before a joint limit; the aim is clamped into them.

``stop_speed(d, a)`` is exact for the discrete profile: the largest step ``w`` whose braking run
``w + (w - a) + (w - 2a) + ...`` (positive terms) is at most ``d``.  Because braking by ``a`` each slot from a
feasible state stays feasible, the three constraints never contradict each other once the first state is
feasible (a pose inside the limits at rest); if the velocity cap drops below the current speed (a tighter
``max_step``), the joint brakes at ``a`` instead of jumping down.

Goal feedforward from IK goals is stable on redundant joints: their IK goal is the seed ``q + v / 2``, so
``d = -v/2 - (v - v_prev)/2`` points against the motion and the joint comes to rest.
"""

from __future__ import annotations

import math

__all__ = ["braking_run", "profile_step", "stop_speed"]


def stop_speed(d: float, a: float) -> float:
    """The largest step (rad/slot, >= 0) from which the joint brakes at ``a`` (rad/slot^2) within ``d`` rad,
    counting this step's own travel.  ``d <= 0`` gives 0.

    >>> stop_speed(0.0, 0.1), stop_speed(0.1, 0.1), round(stop_speed(0.3, 0.1), 12), stop_speed(0.05, 0.1)
    (0.0, 0.1, 0.2, 0.05)
    """
    if d <= 0.0:
        return 0.0
    n = math.floor((math.sqrt(1.0 + 8.0 * d / a) - 1.0) * 0.5)  # the most whole steps a, 2a, .. na within d
    return (d + a * n * (n + 1) * 0.5) / (n + 1)


def braking_run(v: float, a: float) -> float:
    """An upper bound (rad) of the travel of a joint braking at ``a`` from the step ``v`` (>= 0): from at least this
    far from a joint limit, :func:`stop_speed` allows ``v`` or more (so the limit's bound need not be computed).

    >>> braking_run(0.1, 0.01) >= 0.1 + 0.09 + 0.08 + 0.07 + 0.06 + 0.05 + 0.04 + 0.03 + 0.02 + 0.01
    True
    """
    return v * v / (2.0 * a) + v + a


def profile_step(q: float, v: float, g: float, u: float, vmax: float, a: float, lo: float, hi: float) -> float:
    """The next step (rad/slot) of a joint at ``q`` (rad) whose last step was ``v``, toward goal ``g`` moving by
    ``u`` per slot, within the velocity cap ``vmax``, the acceleration ``a`` and the joint limits ``lo..hi``;
    see the module docstring.

    >>> profile_step(0.0, 0.0, 1.0, 0.0, 0.5, 0.1, -2.0, 2.0)  # from rest: one slot's acceleration
    0.1
    >>> round(profile_step(0.0, 0.3, 0.3, 0.0, 0.5, 0.1, -2.0, 2.0), 12)  # fast and near the goal: brake
    0.2
    >>> round(profile_step(1.9, 0.1, 5.0, 0.0, 0.5, 0.1, -2.0, 2.0), 12)  # 0.1 rad from the upper limit: last step
    0.1
    """
    d = g - q - u
    w = u + (stop_speed(d, a) if d >= 0.0 else -stop_speed(-d, a))
    low = max(v - a, -vmax, -stop_speed(q - lo, a))
    high = min(v + a, vmax, stop_speed(hi - q, a))
    if low > high:  # the cap fell below the speed (a tighter max_step): brake at the acceleration limit
        return v - a if v > 0.0 else v + a
    return low if w < low else high if w > high else w
