"""The acceleration-limited step limiter: property tests over seeded random goal sequences, and the loop."""

from __future__ import annotations

import numpy as np
import pytest

from retarget.control.limits import StepLimiter
from retarget.control.profile import profile_step, stop_speed

EPS = 1e-9


def _goals(rng: np.random.Generator, kind: str, n: int, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """``(n, n_joints)`` goals of one kind: jumps, reversals, at the limits, or a random walk."""
    span = hi - lo
    if kind == "jumps":  # a new random pose every few ticks, anywhere (also outside the limits)
        idx = np.repeat(np.arange(n // 10 + 1), 10)[:n]
        return (lo - 0.2 * span + rng.random((n // 10 + 1, len(lo))) * 1.4 * span)[idx]
    if kind == "reversals":  # full-range sweeps that flip every 7 ticks
        return np.where((np.arange(n) // 7 % 2 == 0)[:, None], hi + 1.0, lo - 1.0)
    if kind == "limits":  # sit at a limit, overshoot it, jump to the other
        return np.where((rng.random((n, len(lo))) < 0.5), hi, lo) + rng.normal(0, 0.05, (n, len(lo)))
    return lo + span / 2 + np.cumsum(rng.normal(0, 0.05, (n, len(lo))), axis=0)  # a wandering goal


@pytest.mark.parametrize("kind", ["jumps", "reversals", "limits", "walk"])
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_never_exceeds_velocity_acceleration_or_joint_limits(kind: str, seed: int) -> None:
    rng = np.random.default_rng(seed)
    lo, hi = np.array([-1.0, -0.5, -3.0]), np.array([1.0, 0.3, 3.0])
    vmax, amax = np.array([0.05, 0.02, 0.1]), np.array([0.004, 0.001, 0.02])
    q0 = lo + rng.random(3) * (hi - lo)
    limiter = StepLimiter(lo, hi, vmax, q0, max_accel=amax)
    q, v = q0.copy(), np.zeros(3)
    goals = _goals(rng, kind, 400, lo, hi)
    for g in goals:
        elapsed = int(rng.choice([1, 1, 1, 2, 4]))  # overruns skip slots now and then
        if rng.random() < 0.05:
            limiter.brake(elapsed)  # a HOLD tick
        else:
            limiter.step(g.tolist(), elapsed)
        q1 = np.array(limiter.q)
        w = q1 - q  # this tick's step: one slot's travel
        assert np.all(q1 >= lo - EPS) and np.all(q1 <= hi + EPS), "left the joint limits"
        assert np.all(np.abs(w) <= vmax + EPS), "over the velocity limit"
        assert np.all(np.abs(w - v) <= amax * elapsed + EPS), "over the acceleration limit"
        q, v = q1, w


def test_brakes_before_the_limit_from_full_speed() -> None:
    """Running at full speed at the upper limit: it brakes at the limit's acceleration and stops on it."""
    limiter = StepLimiter(np.array([-10.0]), np.array([1.0]), np.array([0.1]), np.array([-5.0]),
                          max_accel=np.array([0.01]))  # fmt: skip
    qs = []
    for _ in range(200):
        limiter.step([50.0], elapsed=1)
        qs.append(limiter.q[0])
    assert max(qs) <= 1.0 and qs[-1] == pytest.approx(1.0, abs=1e-9)
    steps = np.diff(qs)
    assert steps.max() == pytest.approx(0.1) and np.abs(np.diff(steps)).max() <= 0.01 + EPS


def test_follows_a_moving_goal_without_lag() -> None:
    """A goal moving at constant speed (below the cap) is caught and then followed exactly."""
    limiter = StepLimiter(np.array([-10.0]), np.array([10.0]), np.array([0.1]), np.zeros(1),
                          max_accel=np.array([0.005]))  # fmt: skip
    for k in range(300):
        limiter.step([0.5 + 0.03 * k], elapsed=1)
    assert limiter.q[0] == pytest.approx(0.5 + 0.03 * 299, abs=1e-9)
    assert limiter.velocity[0] == pytest.approx(0.03)


def test_stops_on_a_still_goal_without_overshoot() -> None:
    limiter = StepLimiter(np.array([-10.0]), np.array([10.0]), np.array([0.2]), np.zeros(1),
                          max_accel=np.array([0.01]))  # fmt: skip
    qs = []
    for _ in range(200):
        limiter.step([3.0], elapsed=1)
        qs.append(limiter.q[0])
    assert max(qs) <= 3.0 + EPS and qs[-1] == pytest.approx(3.0)


def test_a_tighter_cap_brakes_at_the_acceleration_limit() -> None:
    limiter = StepLimiter(np.array([-10.0]), np.array([10.0]), np.array([0.2]), np.zeros(1),
                          max_accel=np.array([0.01]))  # fmt: skip
    for _ in range(40):
        limiter.step([9.0], elapsed=1)
    assert limiter.velocity[0] == pytest.approx(0.2)
    limiter.step([9.0], elapsed=1, max_step=[0.05])
    assert limiter.velocity[0] == pytest.approx(0.19)  # braking by a, not a jump to 0.05


@pytest.mark.parametrize(("d", "a"), [(0.0, 0.1), (0.05, 0.1), (0.1, 0.1), (0.37, 0.1), (12.3, 0.07)])
def test_stop_speed_is_the_largest_speed_that_stops_within_d(d: float, a: float) -> None:
    def run(w: float) -> float:
        total = 0.0
        while w > 0:
            total, w = total + w, w - a
        return total

    w = stop_speed(d, a)
    assert run(w) <= d + 1e-12 and run(w + 1e-6) > d


def test_profile_step_from_rest_accelerates_by_a() -> None:
    assert profile_step(0.0, 0.0, 5.0, 0.0, 1.0, 0.1, -9.0, 9.0) == pytest.approx(0.1)


@pytest.mark.parametrize("seed", range(3))
@pytest.mark.parametrize("kind", ["jumps", "smooth"])
def test_the_limiters_inlined_step_is_profile_step(seed: int, kind: str) -> None:
    """StepLimiter inlines profile_step (skipping the joint limits' bound a braking run away from them, and the
    square root where the goal is within half a slot's acceleration: stop_speed is then the distance itself): the
    same floats, tick for tick, near the limits and far from them, after jumps and along a goal it can follow."""
    rng = np.random.default_rng(seed)
    lo, hi, vmax, a = -1.0, 1.0, 0.08, 0.01
    limiter = StepLimiter(np.array([lo]), np.array([hi]), np.array([vmax]), np.array([0.0]), max_accel=np.array([a]))
    q, v, last = 0.0, 0.0, None
    t = np.arange(900)
    goals = (rng.uniform(-1.5, 1.5, 300).repeat(3) if kind == "jumps"
             else 0.9 * np.sin(t / rng.uniform(20, 60)) + rng.normal(0.0, 0.002, 900))  # fmt: skip
    for g in goals:
        u = 0.0 if last is None else float(np.clip(g - last, -vmax, vmax))
        w = profile_step(q, v, g, u, vmax, a, lo, hi)
        limiter.step([g], elapsed=1)
        assert limiter.q[0] == min(max(q + w, lo), hi)
        q, v, last = limiter.q[0], limiter.velocity[0], g
