"""Collision safety in teleop: blocked targets rejected at the gate, a one-shot into a blocked zone stops at the
nearest safe point, and a random walk of targets never commands a pose within the clearance."""

from __future__ import annotations

import numpy as np
import pytest

from retarget import load_arm
from retarget.collision import CollisionModel, Sphere, World
from retarget.control import LoopConfig, TickRecord
from retarget.control.clock import VirtualClock
from retarget.teleop import Follower, run_teleop, tool_point
from retarget.teleop.gate import Reject, TargetBounds, TargetGate, TargetRejected
from retarget.teleop.sources import OneShotSource, Source
from tests.helpers import brute_force_min_clearances

ARMS = ["wx250s", "vx300s", "px100", "omx", "koch"]
N_TICKS = 10_000  #: ticks of the random teleop walk per arm
BALL = Sphere((0.3, 0.0, 0.2), 0.05)


def gate_for(arm, model, clock=None):
    return TargetGate(TargetBounds.for_arm(arm, collision=model), clock=clock or VirtualClock())


@pytest.mark.parametrize(
    ("message", "reason"),
    [("0.3 0 0.2", "keep-out"), ("0.31,0.02,0.24", "keep-out"), ("0 0 0.03", "base"), ("0.3 0 0.005", "table")],
    ids=["ball-centre", "ball-edge", "base", "table"],
)
def test_a_stream_target_in_a_blocked_zone_is_rejected_and_counted(arm, message, reason):
    model = CollisionModel.for_arm(arm, world=World(keep_out=(BALL,)))
    gate = gate_for(arm, model)
    assert gate.accept(message, source="stdin") is None
    assert gate.rejects.counts()[Reject.BLOCKED.value] == 1 and gate.accepted == 0
    with pytest.raises(TargetRejected, match=r"^target: Expected a point 10 mm clear of the table"):
        gate.bounds.check(np.array([float(v) for v in message.replace(",", " ").split()]))
    assert gate.accept("0.3 0.2 0.2") is not None  # clear of the ball: accepted


def test_without_a_model_nothing_is_blocked(arm):
    gate = TargetGate(TargetBounds.for_arm(arm), clock=VirtualClock())
    assert gate.accept("0.3 0 0.2") is not None and gate.rejects.total == 0


def test_a_one_shot_into_a_keep_out_stops_at_the_nearest_safe_point(arm):
    model = CollisionModel.for_arm(arm, world=World(keep_out=(BALL,)))
    clock = VirtualClock()
    gate = gate_for(arm, model, clock)
    source = OneShotSource(gate, "0.3,0,0.2")
    records: list[TickRecord] = []
    result = run_teleop(arm, Follower(arm, source, clock=clock, rate=100.0), config=LoopConfig(collision=model),
                        clock=clock, on_tick=records.append)  # fmt: skip
    assert not result.reached_target and result.residual is not None and result.residual > 0.05
    assert result.rejects[Reject.BLOCKED.value] == 1 and [v.reached for v in result.visits] == [False]
    assert model.is_clear(result.q_final)
    assert np.linalg.norm(result.reached - tool_point(arm, arm.rest)) > 0.05  # it moved toward the ball
    assert np.all(brute_force_min_clearances(arm, [r.q_cmd for r in records], world=model.world) >= model.clearance)


class Walk(Source):
    """A random walk of targets, one queued per tick the follower asks for; closed after ``n`` ticks.  It is drawn
    back toward a point in front of the arm (a discrete Ornstein-Uhlenbeck process, folded at 5 cm below the
    table) and now and then dips below the table, into the base or into ``zone`` (a keep-out ball), or jumps
    anywhere in the box around the reach, and walks back from there."""

    def __init__(self, gate, arm, n, seed, zone):
        super().__init__(gate)
        rng = np.random.default_rng(seed)
        g = gate.bounds
        pivot, reach = g.center, g.max_radius
        home = tool_point(arm, arm.home)
        front = (home - pivot) * [1.0, 1.0, 0.0]
        centre = pivot + reach * (0.45 * front / np.linalg.norm(front) + [0.0, 0.0, 0.3])
        noise = rng.normal(0.0, 0.03 * reach, (n, 3))
        kind = rng.choice(5, n, p=[0.975, 0.003, 0.01, 0.002, 0.01])  # on, jump, table, base, keep-out
        dips = (
            pivot + rng.uniform(-1.0, 1.0, (n, 3)) * reach,
            np.c_[pivot[:2] + rng.uniform(-0.8, 0.8, (n, 2)) * reach, rng.uniform(-0.05, 0.005, n)],
            np.c_[pivot[:2] + rng.uniform(-0.03, 0.03, (n, 2)), rng.uniform(0.0, pivot[2] + 0.01, n)],
            zone.center + rng.uniform(-0.5, 0.5, (n, 3)) * zone.radius,
        )
        point, self.points = tool_point(arm, arm.rest), []
        for k in range(n):
            point = point + 0.05 * (centre - point) + noise[k] if kind[k] == 0 else dips[kind[k] - 1][k]
            point[2] = abs(point[2] + 0.05) - 0.05
            self.points.append(point)
        self.n, self.k = n, 0

    def drain(self):
        if self.k < self.n:
            self.feed(" ".join(f"{v:.5f}" for v in self.points[self.k]))
            self.k += 1
            if self.k == self.n:
                self._finish()
        return super().drain()


@pytest.mark.parametrize("name", ARMS)
def test_a_random_teleop_walk_never_commands_a_pose_within_the_clearance(name):
    arm = load_arm(name)
    pivot, reach = TargetBounds.for_arm(arm).center, TargetBounds.for_arm(arm).max_radius
    home = tool_point(arm, arm.home)
    side = np.cross([0.0, 0.0, 1.0], home - pivot)
    zone = Sphere(tuple(pivot + 0.5 * (home - pivot) + 0.3 * reach * side / np.linalg.norm(side)), 0.08 * reach)
    model = CollisionModel.for_arm(arm, world=World(keep_out=(zone,)))
    clock = VirtualClock()
    gate = gate_for(arm, model, clock)
    source = Walk(gate, arm, N_TICKS, seed=3, zone=zone)
    follower = Follower(arm, source, clock=clock, rate=100.0, max_lag=0.05)
    records: list[TickRecord] = []
    result = run_teleop(arm, follower, config=LoopConfig(collision=model, max_ticks=N_TICKS), clock=clock,
                        on_tick=records.append)  # fmt: skip
    poses = np.array([r.q_cmd for r in records])
    assert len(poses) == N_TICKS
    worst = brute_force_min_clearances(arm, np.unique(poses, axis=0), world=model.world)  # every distinct pose
    assert np.all(worst >= model.clearance - 1e-9)
    blocked = result.rejects[Reject.BLOCKED.value]  # targets in blocked zones: rejected, never steered to
    assert 0.02 * N_TICKS < blocked < N_TICKS
    assert result.summary.min_clearance_mm >= model.clearance * 1e3
