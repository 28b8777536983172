"""Teleoperation: steer the tool point to targets that arrive while the arm moves.

A :class:`Follower` turns a target source (:mod:`retarget.teleop.sources`: one shot, stdin, UDP, the interactive
keys) into the per-tick goal of the control loop (a :class:`~retarget.control.source.TargetSource`):

- accepted targets queue in arrival order; the follower steers toward the oldest one it has not passed,
  so a stream that comes faster than the arm moves is still visited *in order*;
- a **setpoint** walks from the tool point toward that target at most ``max_speed / rate`` metres per
  moving tick (the Cartesian speed limit; slots spent holding, or skipped by an overrun, give no extra
  step; the loop then limits each joint to its max velocity), and the IK solves for the setpoint each tick;
- a target is *passed* when the commanded tool point comes within ``pass_radius`` of it and a newer one
  waits, *reached* when it comes within ``tolerance`` and none waits, and given up as *unreachable* when
  the commanded tool point has stopped getting closer for ``stall_time`` seconds' worth of ticks that ran
  (slots skipped by an overrun do not count: a bus stall is no stalled arm; the arm is then at the
  nearest point it can reach);
- with nothing to steer toward (no target yet, the last one reached or given up, or a stale stream) the
  follower returns ``HOLD`` (``None``): the loop **holds** the commanded pose and runs no IK at all;
- **stale**: while the source is open and no target came for ``timeout`` seconds, the queue is dropped
  and the arm holds until a new target comes;
- **smoothing**: with a :class:`~retarget.mapping.filter.OneEuro` filter (``smoothing``; the CLI's default for
  streams), each target is smoothed as it arrives, causally, at its receive time, before it queues (its
  position as it came in stays in ``Target.raw``); the filter starts afresh after a stale stream, and takes
  targets that arrive less than a tick apart (a burst, a file on stdin) one tick apart.  When the stream ends
  (the source closes) its last target is queued once more as it came in, so the arm ends where the stream did.
  Its lag at steady speed is in :mod:`retarget.mapping.filter` (15 ms at 0.2 m/s for a 100 Hz stream, with the
  defaults);
- **superseded**: with ``max_lag``, a target received more than ``max_lag`` seconds before the newest
  one is skipped (counted), so a live stream faster than the arm cannot build an ever-growing lag.

Every outcome is recorded as a :class:`Visit`.  Frames: everything is the arm's base frame, metres;
:class:`~retarget.teleop.gate.BasePose` turns world-frame input into it at the gate.

:func:`run_teleop` runs the control loop (:func:`~retarget.control.loop.run_ticks`) on a follower until its
source is finished and the servos settled, with a :class:`PoseSolver` for IK.
"""

from __future__ import annotations

import collections
import dataclasses
import enum
import logging
import math
import threading
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from retarget.arm.model import Arm
from retarget.control.bus import Bus
from retarget.control.clock import Clock
from retarget.control.loop import LoopConfig, TickRecord, run_ticks
from retarget.control.source import HOLD, TargetSource, TickSolver, TickTarget
from retarget.control.stats import TickStats
from retarget.control.summary import RunSummary
from retarget.control.tracking import Following, Trajectory, following
from retarget.errors import BusError, ConfigError, require_positive
from retarget.ik.ccd import CCDSolver, IKResult
from retarget.mapping.config import MappingConfig
from retarget.mapping.filter import OneEuro
from retarget.mapping.workspace import ik_weights
from retarget.teleop.gate import Target, step_toward
from retarget.teleop.sources import Source

__all__ = ["Follower", "Phase", "PoseSolver", "TeleopResult", "Visit", "follower_result", "run_teleop", "tool_point"]

log = logging.getLogger(__name__)

DEFAULT_MAX_SPEED = 0.2  #: m/s, Cartesian speed limit of the tool point's setpoint
DEFAULT_TOLERANCE = 0.005  #: m, a one-shot target counts as reached within this (by FK of the present positions)
DEFAULT_PASS_RADIUS = 0.005  #: m, an intermediate stream point counts as passed within this
DEFAULT_ORIENTATION_TOLERANCE = math.radians(2.0)  #: rad, a target orientation counts as reached within this
ORIENTATION_SCALE = 0.1  #: m per rad: how orientation error counts against distance when judging progress


class Phase(enum.Enum):
    """What the follower is doing."""

    WAITING = "waiting"  #: no target yet: hold
    MOVING = "moving"  #: steering toward a target
    HOLDING = "holding"  #: the last target was reached or given up: hold
    STALE = "stale"  #: the stream went quiet for ``timeout`` seconds: hold


@dataclass(frozen=True)
class Visit:
    """The outcome of one target: reached/passed (``reached``) or given up at the nearest point."""

    seq: int  #: the target's number in its source
    target: npt.NDArray[np.float64]  #: ``(3,)`` metres, base frame
    reached: bool
    residual: float  #: metres, commanded tool point to target when it was left
    tick: int  #: the tick it was left at
    rotation: npt.NDArray[np.float64] | None = None  #: ``(3, 3)`` the target orientation, if it had one
    orientation_error: float = math.nan  #: radians, commanded tool frame to ``rotation`` when it was left


def _aim(goal: Target) -> npt.NDArray[np.float64]:
    """Where the follower steers for ``goal``: its nearest safe point when it is blocked, else itself."""
    return goal.position if goal.aim is None else goal.aim


def tool_point(arm: Arm, q: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """The tool point ``(3,)`` metres, base frame, of joint angles ``q`` ``(n_joints,)`` radians."""
    T, _ = arm.fk(q)
    return np.array(T[:3, 3], dtype=np.float64)


def rotation_angle(R: npt.NDArray[np.float64], target: npt.NDArray[np.float64]) -> float:
    """The angle, radians in ``[0, pi]``, of the rotation from ``R`` to ``target`` (both ``(3, 3)``)."""
    c = (float(np.trace(R.T @ target)) - 1.0) / 2.0
    return math.acos(min(1.0, max(-1.0, c)))


class Follower(TargetSource):
    """Follows the targets of ``source`` on ``arm``: a :class:`~retarget.control.source.TargetSource` that observes.

    ``clock`` is the loop's clock (targets are stamped on it).  Keyword-only knobs: ``rate`` (ticks per second
    of the loop), ``max_speed`` (m/s, ``inf``: no Cartesian limit), ``tolerance`` and ``pass_radius`` (m),
    ``timeout`` (s, None: never stale), ``max_lag`` (s, None: visit every target), ``stall_time`` (s) and
    ``stall_distance`` (m); ``orientation_tolerance`` (rad) for targets with a rotation, which count as reached
    only when the tool frame is within it too.  ``lockstep``: for a virtual clock (``--fast``), wait up to
    ``idle_wait`` *real* seconds for input whenever there is nothing to do, so virtual time does not race ahead
    of a reader thread.  ``queue_length``: targets kept waiting.  ``smoothing``: a One-Euro filter each target
    passes as it arrives (None: none).  A bad value raises ``ConfigError`` whose
    ``key`` is the parameter's name.  The loop calls :meth:`start` with the start pose before the first tick,
    then :meth:`target_at` and :meth:`observe` each tick; the outcomes are in :attr:`visits`.

    >>> import retarget
    >>> from retarget.control.clock import VirtualClock
    >>> from retarget.teleop.gate import TargetBounds, TargetGate
    >>> from retarget.teleop.sources import OneShotSource
    >>> arm = retarget.load_arm("wx250s")
    >>> clock = VirtualClock()
    >>> source = OneShotSource(TargetGate(TargetBounds.for_arm(arm), clock=clock), "0.3,0,0.2")
    >>> follower = Follower(arm, source, clock=clock, rate=100.0)
    >>> follower.start(arm.rest)
    0
    >>> goal = follower.target_at(0, 0.0)  # the setpoint's first step toward the target: 0.2 m/s at 100 Hz
    >>> round(float(np.linalg.norm(goal.position - follower.tool)) * 1e3, 3)
    2.0
    """

    observes = True  #: it watches the commanded pose to judge progress: not for the pipelined read-back

    def __init__(
        self,
        arm: Arm,
        source: Source,
        *,
        clock: Clock,
        rate: float,
        max_speed: float = DEFAULT_MAX_SPEED,
        tolerance: float = 1.5e-3,
        pass_radius: float = DEFAULT_PASS_RADIUS,
        timeout: float | None = None,
        max_lag: float | None = None,
        stall_time: float = 0.25,
        stall_distance: float = 1e-4,
        orientation_tolerance: float = DEFAULT_ORIENTATION_TOLERANCE,
        lockstep: bool = False,
        idle_wait: float = 0.1,
        queue_length: int = 4096,
        smoothing: OneEuro | None = None,
    ):
        self.arm = arm
        self.smoothing = smoothing
        self.source = source
        self.clock = clock
        self.rate = require_positive(rate, "rate")
        self.max_speed = require_positive(max_speed, "max_speed", inf=True)
        self.tolerance = require_tolerance(tolerance)
        self.pass_radius = max(require_positive(pass_radius, "pass_radius"), self.tolerance)
        self.timeout = None if timeout is None else require_positive(timeout, "timeout")
        self.max_lag = None if max_lag is None else require_positive(max_lag, "max_lag")
        self.stall_ticks = max(3, int(round(require_positive(stall_time, "stall_time") * self.rate)))
        self.stall_distance = float(stall_distance)
        self.orientation_tolerance = require_positive(orientation_tolerance, "orientation_tolerance")
        self.tool_rotation: npt.NDArray[np.float64] | None = (
            None  #: ``(3, 3)`` the commanded tool frame after the last tick
        )
        self.lockstep = lockstep
        self.idle_wait = float(idle_wait)
        self._step = self.max_speed / self.rate  # metres per tick
        self._queue: collections.deque[Target] = collections.deque(maxlen=queue_length)
        self.goal: Target | None = None  #: the target being steered toward
        self.setpoint: npt.NDArray[np.float64] | None = None  #: ``(3,)`` the rate-limited point the IK solves for
        self.tool: npt.NDArray[np.float64] | None = None  #: ``(3,)`` the commanded tool point after the last tick
        self.phase = Phase.WAITING
        self.visits: list[Visit] = []
        self.received = 0  #: targets taken from the source
        self.stale_events = 0  #: times the stream went stale
        self.skipped = 0  #: targets superseded (older than ``max_lag`` behind the newest) and not visited
        self._best = math.inf
        self._since_best = 0  # ticks observed at the goal since the cost last improved (not slots: see observe)
        self._last_tick = -1
        #: ``(3,)`` the target as it came in (before the filter) that the arm is steered toward or holds at; None
        #: before the first: what the tracking error is measured against
        self.reference: npt.NDArray[np.float64] | None = None
        self._smooth_time = -math.inf  # s, the time the last target was filtered at
        self._last_smoothed: Target | None = None  # the last target filtered, until the stream ends

    # ------------------------------------------------------------------ lifecycle

    def start(self, q_start: npt.NDArray[np.float64]) -> int:
        """Begin at joint angles ``q_start`` ``(n_joints,)`` radians: the setpoint starts at their tool point.
        Returns the first slot, 0 (no lead-in)."""
        T, _ = self.arm.fk(q_start)
        self.tool, self.tool_rotation = T[:3, 3].copy(), T[:3, :3].copy()
        self.setpoint = self.tool.copy()
        return 0

    def _commanded(self) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """The commanded tool point ``(3,)`` and frame ``(3, 3)`` after the last tick (since :meth:`start`)."""
        if self.tool is None or self.tool_rotation is None:
            raise RuntimeError("Follower.start(q_start) must be called before the first tick")
        return self.tool, self.tool_rotation

    @property
    def last_target(self) -> npt.NDArray[np.float64] | None:
        """``(3,)`` the target being steered toward, else the last one left; None before the first."""
        if self.goal is not None:
            return self.goal.position
        return self.visits[-1].target if self.visits else None

    @property
    def last_rotation(self) -> npt.NDArray[np.float64] | None:
        """``(3, 3)`` the orientation of :attr:`last_target`, if it has one."""
        if self.goal is not None:
            return self.goal.rotation
        return self.visits[-1].rotation if self.visits else None

    @property
    def pending(self) -> int:
        """Targets queued behind the current one."""
        return len(self._queue)

    def finished(self, tick: int = 0) -> bool:
        """True once the source is closed and every target it gave was reached, passed or given up."""
        return self.source.closed and self.goal is None and not self._queue and not self.source.queued

    # ------------------------------------------------------------------ the loop's side

    def _pull(self) -> None:
        new = self.source.drain()
        if self.smoothing is not None:
            new = [self._smoothed(target) for target in new]
            if self._last_smoothed is not None and self.source.closed and not self.source.queued:
                last, self._last_smoothed = self._last_smoothed, None  # the stream ended: end where it did
                if last.raw is not None and not np.array_equal(last.position, last.raw):
                    new.append(dataclasses.replace(last, position=last.raw))
        if not new:
            return
        self._queue.extend(new)
        self.received += len(new)
        if self.phase is Phase.STALE:
            log.info("target stream resumed")
        if self.max_lag is not None:
            newest = self._queue[-1].received
            while len(self._queue) > 1 and newest - self._queue[0].received > self.max_lag:
                self._queue.popleft()
                self.skipped += 1
            if self.goal is not None and newest - self.goal.received > self.max_lag:
                self.goal = None  # superseded: steer on from where the arm is to the next one
                self.setpoint = self._commanded()[0].copy()
                self.skipped += 1

    def _smoothed(self, target: Target) -> Target:
        """``target`` with its position through the One-Euro filter at its receive time (``raw``: as it came).

        Targets that arrive less than a tick apart (a burst, a file on stdin) are taken one tick apart: a filter
        needs their spacing, and a tick is the finest the arm can follow."""
        assert self.smoothing is not None
        self._smooth_time = max(target.received, self._smooth_time + 1.0 / self.rate)
        position = self.smoothing(target.position, self._smooth_time)
        self._last_smoothed = smoothed = dataclasses.replace(target, position=position, raw=target.position)
        return smoothed

    def target_at(self, tick: int, t: float) -> TickTarget | None:
        """The goal of tick ``tick``: the setpoint as a :class:`~retarget.control.source.TickTarget` (``(3,)``
        metres, the target's rotation ``(3, 3)`` or None), or ``HOLD`` (None) with nothing to steer toward."""
        if self.setpoint is None:
            raise RuntimeError("Follower.start(q_start) must be called before the first tick")
        self._pull()
        if self.timeout is not None and not self.source.closed and self.received:
            latest = self.source.latest()
            if latest is not None and self.clock.now() - latest.received > self.timeout:
                if self.phase is not Phase.STALE:
                    self.stale_events += 1
                    log.warning("no target for %.3g s: holding position", self.timeout)
                    if self.goal is not None:
                        self._leave(False, tick)
                self._queue.clear()
                if self.smoothing is not None:  # a resumed stream starts afresh, not from where it went quiet
                    self.smoothing.reset()
                    self._smooth_time = -math.inf
                self.phase = Phase.STALE
                return HOLD
        if self.goal is None:
            if not self._queue and self.lockstep and not self.source.closed:
                self.source.wait(self.idle_wait)
                self._pull()
            if not self._queue:
                if self.phase is not Phase.STALE:
                    self.phase = Phase.HOLDING if self.visits else Phase.WAITING
                return HOLD
            self.goal = self._queue.popleft()
            self.reference = self.goal.position if self.goal.raw is None else self.goal.raw
            self.setpoint = self._commanded()[0].copy()  # restart the walk where the arm is commanded to be
            self._best, self._since_best = math.inf, 0
        self.phase = Phase.MOVING
        self._last_tick = tick
        # one slot's step per moving tick, whatever slots passed since the last one: after a hold, a stale
        # stream or a wait, that gap is time spent standing, and after an overrun the loop's joint limit is one
        # slot too, so a longer step would only let the setpoint (and the IK) run ahead of the speed limit
        self.setpoint = step_toward(self.setpoint, _aim(self.goal), self._step)
        return TickTarget(self.setpoint, self.goal.rotation, False)

    def observe(
        self, tick: int, q_cmd: npt.NDArray[np.float64], q_present: npt.NDArray[np.float64] | None = None
    ) -> None:
        """After tick ``tick``: the commanded joint angles ``q_cmd`` ``(n_joints,)`` radians."""
        T, _ = self.arm.fk(q_cmd)
        self.tool, self.tool_rotation = tool, rotation = T[:3, 3].copy(), T[:3, :3].copy()
        goal, setpoint = self.goal, self.setpoint
        if goal is None or setpoint is None or not np.array_equal(setpoint, aim := _aim(goal)):
            return  # holding, or the setpoint is still on its way
        d = float(np.linalg.norm(tool - aim))
        angle = 0.0 if goal.rotation is None else rotation_angle(rotation, goal.rotation)
        radius = self.pass_radius if self._queue else self.tolerance
        cost = d + ORIENTATION_SCALE * angle
        if d <= radius and angle <= self.orientation_tolerance:
            if goal.aim is not None:  # at the nearest safe point of a blocked target: given up there
                log.info("target %d is blocked: holding at the nearest safe point", goal.seq)
                self._leave(False, tick)
            else:
                self._leave(True, tick, d)
        elif cost < self._best - self.stall_distance:
            self._best, self._since_best = cost, 0
        elif (since := self._since_best + 1) < self.stall_ticks:  # ticks, not slots: a bus stall is no stalled arm
            self._since_best = since
        else:
            log.info("target %d unreachable: holding %.1f mm, %.1f deg from it", goal.seq, d * 1e3, math.degrees(angle))
            self._leave(False, tick)

    def cancel(self) -> None:
        """Stop steering (the user quit): drop the queue and the current target; the loop holds from the next
        tick, and the run ends once the servos settle if the source is closed too.  Safe from a callback."""
        self._queue.clear()
        self.source.drain()
        if self.goal is not None:
            residual = float(np.linalg.norm(self._commanded()[0] - self.goal.position))
            self._leave(residual <= self.tolerance, self._last_tick, residual)

    def _leave(self, reached: bool, tick: int, residual: float | None = None) -> None:
        goal = self.goal
        assert goal is not None
        tool, rotation = self._commanded()
        if residual is None:
            residual = float(np.linalg.norm(tool - goal.position))
        angle = math.nan if goal.rotation is None else rotation_angle(rotation, goal.rotation)
        self.visits.append(Visit(goal.seq, goal.position, reached, residual, tick, goal.rotation, angle))
        self.goal = None
        self.setpoint = tool.copy()
        self.phase = Phase.HOLDING


# ------------------------------------------------------------------------------------------------ the session

TICK = 2 * math.pi / 4096  #: rad, one position tick of an X-series servo
#: the servos have arrived when the positions read back are within half a tick (plus rounding) of the goals, or
#: stopped changing within this of them (a real servo may hold a tick or two off under load)
SETTLE_TOLERANCE = 3 * TICK


@dataclass(frozen=True)
class TeleopResult:
    """The outcome of a teleop run.  Positions ``(3,)`` metres, base frame."""

    summary: RunSummary
    stats: TickStats
    visits: tuple[Visit, ...]
    target: npt.NDArray[np.float64] | None  #: the last target steered toward (None: no target came)
    reached: npt.NDArray[np.float64]  #: tool point of the final present positions (of the goals in a dry run)
    residual: float | None  #: metres, ``|reached - target|``
    tolerance: float
    received: int  #: targets accepted
    rejects: dict[str, int]  #: rejected messages by reason
    stale_events: int
    skipped: int  #: targets superseded by newer ones (``max_lag``) and not visited
    q_final: npt.NDArray[np.float64]  #: ``(n_joints,)`` rad, the final present positions (goals in a dry run)
    #: radians, the final tool frame to the last target's orientation (nan when it had none)
    orientation_error: float = math.nan
    orientation_tolerance: float = DEFAULT_ORIENTATION_TOLERANCE

    @property
    def reached_target(self) -> bool:
        """True when the last target was reached within ``tolerance`` (and ``orientation_tolerance`` when it
        had an orientation); False when none came."""
        if self.residual is None or self.residual > self.tolerance:
            return False
        return math.isnan(self.orientation_error) or self.orientation_error <= self.orientation_tolerance

    def to_dict(self) -> dict[str, object]:
        """JSON-ready: lengths in metres (``_m``) or millimetres (``_mm``), angles in degrees (``_deg``)."""

        def vec(v: npt.NDArray[np.float64] | None) -> list[float] | None:
            return None if v is None else [round(float(x), 6) for x in v]

        return {
            "target_m": vec(self.target),
            "reached_m": vec(self.reached),
            "residual_mm": None if self.residual is None else round(self.residual * 1e3, 3),
            "tolerance_mm": round(self.tolerance * 1e3, 3),
            "orientation_error_deg": None
            if math.isnan(self.orientation_error)
            else round(math.degrees(self.orientation_error), 3),
            "reached": self.reached_target,
            "joints_deg": [round(float(np.degrees(q)), 3) for q in self.q_final],
            "targets_received": self.received,
            "targets_reached": sum(v.reached for v in self.visits),
            "targets_unreachable": sum(not v.reached for v in self.visits),
            "rejected": self.rejects,
            "targets_skipped": self.skipped,
            "stale_events": self.stale_events,
            "hold_ticks": self.stats.holds,
        }

    def format(self) -> str:
        """Human lines for stderr."""
        rejected = sum(self.rejects.values())
        by_reason = ", ".join(f"{k} {v}" for k, v in self.rejects.items() if v)
        lines = [
            f"  targets: {self.received} received, {sum(v.reached for v in self.visits)} reached, "
            f"{sum(not v.reached for v in self.visits)} unreachable, {rejected} rejected"
            + (f" ({by_reason})" if by_reason else "")
            + f"; {self.skipped} skipped (lag); {self.stale_events} stale; {self.stats.holds} hold ticks"
        ]
        return "\n".join(lines)


class PoseSolver:
    """Two :class:`~retarget.ik.CCDSolver` s behind one ``solve`` (a :class:`~retarget.control.source.TickSolver`):
    targets without a rotation use the mapping's position-only per-joint weights (roll joints held), targets
    with one use every joint and an orientation weight.  Budget, tolerance and collision model from the loop
    config."""

    def __init__(self, arm: Arm, config: LoopConfig, *, orientation_weight: float = 0.1):
        mapping = MappingConfig.from_table(arm.mapping, path=arm.source)
        iterations, tolerance = config.ik_iterations, config.ik_tolerance
        weights = ik_weights(arm, mapping)
        collision = config.collision
        self.position = CCDSolver(
            arm, weights=weights, max_iterations=iterations, tolerance=tolerance, collision=collision
        )
        self.pose = CCDSolver(
            arm, orientation_weight=orientation_weight, max_iterations=iterations, tolerance=tolerance,
            collision=collision,
        )  # fmt: skip

    def solve(
        self,
        target: npt.NDArray[np.float64],
        q0: npt.NDArray[np.float64],
        rotation: npt.NDArray[np.float64] | None = None,
    ) -> IKResult:
        """IK for the tool point at ``target`` ``(3,)`` m (and frame ``rotation`` ``(3, 3)``) from ``q0`` rad."""
        if rotation is None:
            return self.position.solve(target, q0)
        return self.pose.solve(target, q0, rotation)


class Settle:
    """When a teleop run may end, after its source finished: once the servos' read-back settled on the last command
    (:meth:`settled`), or ``settle_time`` s (at ``rate`` ticks/s, at least one tick) after the source finished.
    :meth:`observe` every tick's command ``q_cmd`` and read-back ``q_present`` ``(n_joints,)`` rad; a dry run (no
    read-back) ends as soon as the source does."""

    def __init__(self, settle_time: float, rate: float):
        self.ticks = max(1, int(round(require_positive(settle_time, "settle_time") * rate)))
        self.present: npt.NDArray[np.float64] | None = None
        self.previous: npt.NDArray[np.float64] | None = None
        self.q_cmd: npt.NDArray[np.float64] | None = None
        self._done_tick: int | None = None

    def observe(self, q_cmd: npt.NDArray[np.float64], q_present: npt.NDArray[np.float64] | None) -> None:
        self.q_cmd, self.previous, self.present = q_cmd, self.present, q_present

    def finished(self, tick: int, source_finished: bool) -> bool:
        if not source_finished:
            self._done_tick = None
            return False
        if self.present is None or self.q_cmd is None:
            return True  # a dry run (or nothing ran): the goals are the result
        if self._done_tick is None:
            self._done_tick = tick
        return self.settled() or tick - self._done_tick >= self.ticks

    def settled(self) -> bool:
        """The read-back has settled on the command: within 0.6 of a position tick, or within ``SETTLE_TOLERANCE``
        and unchanged since the tick before (a servo that stopped short)."""
        if self.present is None or self.q_cmd is None:
            return False
        off = float(np.max(np.abs(self.present - self.q_cmd)))
        still = self.previous is not None and np.array_equal(self.present, self.previous)
        return off <= 0.6 * TICK or (still and off <= SETTLE_TOLERANCE)


class _Run(TargetSource):
    """The follower seen by the loop: adds the end condition (the source finished and the servos settled)."""

    observes = True

    def __init__(self, follower: Follower, settle: Settle):
        self.follower, self.settle = follower, settle

    def start(self, q_start: npt.NDArray[np.float64]) -> int:
        return self.follower.start(q_start)

    def target_at(self, tick: int, t: float) -> TickTarget | None:
        return self.follower.target_at(tick, t)

    def observe(self, tick: int, q_cmd: npt.NDArray[np.float64], q_present: npt.NDArray[np.float64] | None) -> None:
        self.follower.observe(tick, q_cmd, q_present)
        self.settle.observe(q_cmd, q_present)

    def finished(self, tick: int) -> bool:
        return self.settle.finished(tick, self.follower.finished(tick))


#: The largest ``tolerance`` (m) of a follower or a teleop run: past it "reached" says nothing (``1e300`` made
#: every target reached).
MAX_TOLERANCE = 0.1


def require_tolerance(value: object, key: str = "tolerance") -> float:
    """``value`` as a tolerance in metres, > 0 and at most :data:`MAX_TOLERANCE`, else a ConfigError naming ``key``."""
    tolerance = require_positive(value, key)
    if tolerance > MAX_TOLERANCE:
        raise ConfigError(f"Expected a tolerance > 0 and <= {MAX_TOLERANCE:g} m", key=key, value=value)
    return tolerance


def run_teleop(
    arm: Arm,
    follower: Follower,
    *,
    config: LoopConfig,
    clock: Clock,
    bus: Bus | None = None,
    solver: TickSolver | None = None,
    q_start: npt.NDArray[np.float64] | None = None,
    tolerance: float = DEFAULT_TOLERANCE,
    settle_time: float = 2.0,
    on_tick: Callable[[TickRecord], None] | None = None,
    on_progress: Callable[[TickRecord], None] | None = None,
    stop: threading.Event | None = None,
    name: str = "teleop",
) -> TeleopResult:
    """Run the control loop (:func:`~retarget.control.loop.run_ticks`) on ``follower`` until its source is
    finished and the servos settled (at most ``settle_time`` s more), ``config.max_ticks``, ``stop`` or Ctrl-C.

    ``bus`` must be connected (None: a dry run); ``clock`` is the loop's (and the follower's).  The start pose
    ``(n_joints,)`` rad is the bus's present positions, else ``q_start``, else the arm's rest pose.  ``solver``
    defaults to a :class:`PoseSolver` with the config's budget.  ``on_tick``/``on_progress`` get
    :class:`~retarget.control.loop.TickRecord` s as in ``run_ticks``; ``name`` labels the summary.  Returns a
    :class:`TeleopResult`: the reached point ``(3,)`` m is the FK of the positions read back at the end (of the
    goals in a dry run), reached when within ``tolerance`` metres of the last target.

    >>> import retarget
    >>> from retarget.control.clock import VirtualClock
    >>> from retarget.teleop.gate import TargetBounds, TargetGate
    >>> from retarget.teleop.sources import OneShotSource
    >>> arm = retarget.load_arm("wx250s")
    >>> clock = VirtualClock()
    >>> source = OneShotSource(TargetGate(TargetBounds.for_arm(arm), clock=clock), "0.3,0,0.2")
    >>> result = run_teleop(arm, Follower(arm, source, clock=clock, rate=100.0), config=LoopConfig(), clock=clock)
    >>> result.reached_target, result.residual is not None and result.residual <= 0.005
    (True, True)
    """
    tolerance = require_tolerance(tolerance)
    trajectory = Trajectory(reference=lambda _record: follower.reference)  # for the tracking error
    run = _Run(follower, Settle(settle_time, config.rate))
    try:
        stats = run_ticks(
            arm,
            run,
            solver if solver is not None else PoseSolver(arm, config),
            config=config,
            clock=clock,
            bus=bus,
            q_start=q_start,
            on_tick=trajectory.chain(on_tick),
            on_progress=on_progress,
            stop=stop,
        )
    except BusError as exc:  # the summary of the ticks that ran goes with the error
        if isinstance(exc.stats, TickStats):
            exc.summary = exc.stats.summary(
                arm=arm.name, clip=name, frames=follower.received, duration_s=exc.stats.run_time,
                following=following(arm, trajectory, rate=config.rate),
            )  # fmt: skip
        raise
    measured = following(arm, trajectory, rate=config.rate)
    return _result(arm, follower, stats, tolerance=tolerance, name=name, measured=measured)


def _result(
    arm: Arm, follower: Follower, stats: TickStats, *, tolerance: float, name: str, measured: Following | None = None
) -> TeleopResult:
    """The :class:`TeleopResult` of a run that ended with ``stats``."""
    q_final = stats.q_present if stats.q_present is not None else stats.q_cmd
    if q_final is None:
        raise RuntimeError("Expected the run's last goals in its stats")
    summary = stats.summary(
        arm=arm.name, clip=name, frames=follower.received, duration_s=stats.run_time, following=measured
    )
    return follower_result(follower, q_final, summary, stats, tolerance=tolerance)


def follower_result(
    follower: Follower, q_final: npt.NDArray[np.float64], summary: RunSummary, stats: TickStats, *, tolerance: float
) -> TeleopResult:
    """The :class:`TeleopResult` of ``follower``'s run (one arm's part of a rig's too): its visits and last target,
    and the FK of its final pose ``q_final`` ``(n_joints,)`` rad (present positions, else the goals)."""
    T, _ = follower.arm.fk(q_final)
    reached = np.array(T[:3, 3], dtype=np.float64)
    rotation = follower.last_rotation
    target = follower.last_target
    return TeleopResult(
        summary=summary,
        stats=stats,
        visits=tuple(follower.visits),
        target=target,
        reached=reached,
        residual=None if target is None else float(np.linalg.norm(reached - target)),
        tolerance=float(tolerance),
        received=follower.received,
        rejects=follower.source.rejects,
        stale_events=follower.stale_events,
        skipped=follower.skipped,
        q_final=np.array(q_final, dtype=np.float64),
        orientation_error=math.nan if rotation is None else rotation_angle(T[:3, :3], rotation),
        orientation_tolerance=follower.orientation_tolerance,
    )
