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
N_TICKS = 1_000  #: ticks of the random teleop walk per arm
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
    """A random walk of targets, one queued per tick the follower asks for, with jumps and dips into the table
    and the base; closed after ``n`` ticks."""

    def __init__(self, gate, arm, n, seed):
        super().__init__(gate)
        rng = np.random.default_rng(seed)
        g = gate.bounds
        low, high = g.center - 0.8 * g.max_radius, g.center + 0.8 * g.max_radius
        low[2] = -0.05
        steps = rng.uniform(-1, 1, (n, 3)) * 0.02
        steps[rng.uniform(size=n) < 0.02] *= 15
        point, self.points = tool_point(arm, arm.rest), []
        for step in steps:
            point = np.clip(point + step, low, high)
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
    model = CollisionModel.for_arm(arm)
    clock = VirtualClock()
    gate = gate_for(arm, model, clock)
    source = Walk(gate, arm, N_TICKS, seed=3)
    follower = Follower(arm, source, clock=clock, rate=100.0, max_lag=0.05)
    records: list[TickRecord] = []
    result = run_teleop(arm, follower, config=LoopConfig(collision=model, max_ticks=N_TICKS), clock=clock,
                        on_tick=records.append)  # fmt: skip
    poses = np.array([r.q_cmd for r in records])
    assert len(poses) == N_TICKS
    assert np.all(brute_force_min_clearances(arm, poses) >= model.clearance - 1e-9)
    assert result.rejects[Reject.BLOCKED.value] > 0  # the walk went into blocked zones: rejected, never steered to
    assert result.summary.min_clearance_mm >= model.clearance * 1e3
