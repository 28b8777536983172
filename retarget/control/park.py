"""The move to rest at shutdown, made collision-safe: :func:`park` and :func:`check_moves`.

The bus's shutdown (``ShutdownMode.REST``) sends one goal at the rest pose and lets the servos' profile take
the arm there, a straight line in joint space at best.  When that line collides (checked with
``CollisionModel.segment_clear``), :func:`park` first drives the arm through the tick loop to a safe waypoint
(home) from which the straight move to rest is clear, so the bus's own rest move then starts there; when no
waypoint helps, it turns the bus's rest move off (the arm holds where it is, torque on) with an error line.

:func:`check_moves` runs before the bus connects, so before torque is enabled: the clip's first pose and the
rest pose must be clear and reachable from home along safe routes, else a one-line ConfigError.

Joint angles ``(n_joints,)`` float64 radians.
"""

from __future__ import annotations

import logging
import threading
from dataclasses import replace

import numpy as np
import numpy.typing as npt

from retarget.arm.model import Arm
from retarget.control.bus import Bus, ShutdownMode
from retarget.control.clock import Clock
from retarget.control.loop import LoopConfig, run_ticks
from retarget.control.replay import LeadIn
from retarget.control.safety import Route, plan_route, require_route
from retarget.control.source import JointGoal, TargetSource, TickGoal
from retarget.ik.ccd import CCDSolver

__all__ = ["RouteMoves", "check_moves", "park"]

log = logging.getLogger(__name__)


def check_moves(arm: Arm, config: LoopConfig, *, first: npt.NDArray[np.float64] | None, rest: bool) -> None:
    """Before connecting: a safe route from home to the clip's ``first`` pose (None: no clip) and, with ``rest``
    (``--shutdown rest``), from home to rest; a one-line ConfigError (key ``collision``) when one has none."""
    model = config.collision
    if model is None:
        return
    if first is not None:
        require_route(model, arm.home, first, waypoints=(arm.rest,), what="lead-in to the clip's first pose")
    if rest:
        require_route(model, arm.home, arm.rest, waypoints=(), what="move to the rest pose")


class RouteMoves(TargetSource):
    """The ticks of a route (slots ``-n .. -1``), then the end: a move played on its own through the tick loop."""

    def __init__(self, route: LeadIn | Route):
        self.route = route

    def start(self, q_start: npt.NDArray[np.float64]) -> int:
        return -self.route.n_slots

    def target_at(self, tick: int, t: float) -> TickGoal:
        goal: JointGoal = self.route.goal(tick)
        return goal

    def finished(self, tick: int) -> bool:
        return tick >= 0


def park(arm: Arm, bus: Bus, *, config: LoopConfig, clock: Clock, stop: threading.Event | None = None) -> bool:
    """Before a REST shutdown: when the straight move from the present pose to rest collides, drive the arm to a
    safe waypoint (home) first; when none helps, turn the bus's rest move off (it holds).  Returns True when the
    bus's rest move is safe to run.  Nothing without ``config.collision``."""
    model = config.collision
    if model is None:
        return True
    q = np.clip(np.asarray(bus.read_positions(), dtype=np.float64), arm.lower, arm.upper)
    if model.segment_clear(q, arm.rest).clear:
        return True
    route = plan_route(model, q, arm.rest, waypoints=(arm.home,))
    if route is None or len(route) < 2:
        log.error("the move to rest collides and no safe waypoint avoids it: holding here (torque stays on)")
        if hasattr(bus, "shutdown_mode"):
            bus.shutdown_mode = ShutdownMode.HOLD
        return False
    log.warning("the straight move to rest collides: going through home first")
    speed = np.minimum(config.lead_in_speed or 0.5, config.velocity_scale * arm.max_velocity)
    target = np.asarray(arm.fk(route[0])[0][:3, 3], dtype=np.float64)
    leg = LeadIn.plan(q, route[0], speed=speed, rate=config.rate, target=target, accel=arm.max_acceleration)
    run_ticks(arm, RouteMoves(leg), CCDSolver(arm), config=replace(config, max_ticks=None), clock=clock, bus=bus,
              stop=stop)  # fmt: skip
    return True
