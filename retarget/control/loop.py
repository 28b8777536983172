"""The fixed-rate tick loop shared by clip replay and teleop: :func:`run_ticks`.

It asks a :class:`~retarget.control.source.TargetSource` for each tick's goal: ``retarget.control.ControlLoop``
plays a clip through a ``ClipSource``; ``retarget.teleop.Follower`` follows targets that arrive while the arm
moves.  Each tick ``k`` has a slot on the loop's clock, ``t0 + k / rate``.  In its slot a tick:

1. takes the source's goal: a :class:`~retarget.control.source.TickTarget` (a point), a
   :class:`~retarget.control.source.JointGoal` (a pose in joint space: no IK, 0 sweeps) or ``HOLD``
   (``None``: no IK; the commanded pose brakes to rest at the acceleration limit, on to 4);
2. solves IK for a point with the :class:`~retarget.control.source.TickSolver` (the arm's
   :class:`~retarget.ik.CCDSolver`), warm-started from the commanded pose moved on by half its last step,
   within ``ik_iterations`` sweeps (the per-tick budget);
3. limits each joint's step to one slot of ``velocity_scale x max_velocity`` (or the JointGoal's tighter
   ``max_step``) and its change of step to one slot's ``max_acceleration`` (a trapezoidal profile that follows
   the moving goal and brakes before the joint limits, :mod:`~retarget.control.profile`), then clamps the pose
   to the joint limits; a goal the collision check blocks is not written: the pose brakes at the acceleration
   limit when that step is clear, else stops at once (``TickRecord.blocked``);
4. sends the goals in one ``bus.write_goals``;
5. reads the present positions back, within the tick or pipelined with the next tick's steps 1-3.

The parts, one module each:

- :mod:`~retarget.control.schedule`: the slots, deadlines and overruns (an overrun resumes at the slot the
  clock is in, skipping the missed ones, so delays never accumulate as drift);
- :mod:`~retarget.control.source`: what a source answers, and the solver the loop calls;
- :mod:`~retarget.control.limits`: the step limiter and the IK seed (steps 2-3, on plain floats);
- :mod:`~retarget.control.readback`: steps 4-5, inline or pipelined, and when a tick's record goes out;
- :mod:`~retarget.control.stats`: the per-tick series, with a lead-in's ticks (slots < 0) kept apart.

The clock is injected: :class:`~retarget.control.clock.MonotonicClock` for real time, one
:class:`~retarget.control.clock.VirtualClock` shared with the simulator for ``--fast`` runs.  ``bus=None`` is
a dry run: everything but the bus.  A ``stop`` event ends the run at the next tick boundary, and a
``KeyboardInterrupt`` raised inside a tick (e.g. by a telemetry callback) ends it too; either way the stats
say ``interrupted``.

Arrays: joint angles ``(n_joints,)`` float64 radians in ``Arm.joint_names`` order; targets ``(3,)`` metres
in the arm's base frame.
"""

from __future__ import annotations

import contextlib
import logging
import math
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Protocol

import numpy as np
import numpy.typing as npt

from retarget.control.bus import Bus, BusStatus
from retarget.control.clock import Clock
from retarget.control.limits import StepLimiter
from retarget.control.plan import JERK_COST
from retarget.control.readback import ReadBack, SentTick, read_back_for
from retarget.control.safety import GoalCheck
from retarget.control.schedule import Schedule
from retarget.control.source import JointGoal, TargetSource, TickSolver, TickTarget, as_target_source
from retarget.control.stats import StatsRecorder, TickStats
from retarget.errors import BusError, ConfigError

if TYPE_CHECKING:
    from retarget.collision import CollisionModel

__all__ = [
    "Checker",
    "JointGoal",
    "LoopConfig",
    "Plant",
    "TargetSource",
    "TickRecord",
    "TickStats",
    "TickTarget",
    "run_ticks",
    "tee",
]

log = logging.getLogger(__name__)


class Plant(Protocol):
    """What the loop needs of the joints it steps: an :class:`~retarget.arm.model.Arm`, or several arms as one
    vector (``retarget.rig.RigPlant``).  Arrays ``(n_joints,)`` float64: rad, rad/s, rad/s^2."""

    @property
    def n_joints(self) -> int: ...

    @property
    def lower(self) -> npt.NDArray[np.float64]: ...

    @property
    def upper(self) -> npt.NDArray[np.float64]: ...

    @property
    def max_velocity(self) -> npt.NDArray[np.float64]: ...

    @property
    def max_acceleration(self) -> npt.NDArray[np.float64]: ...

    @property
    def rest(self) -> npt.NDArray[np.float64]: ...

    @property
    def home(self) -> npt.NDArray[np.float64]: ...


class Checker(Protocol):
    """The last check of each goal before it is written (:class:`~retarget.control.safety.GoalCheck` is one):
    whether the move ``q_from`` -> ``q_to`` (rad) keeps the clearance, and the least clearance (metres) of the
    last move it allowed."""

    clearance: float

    def allows(self, q_from: Sequence[float], q_to: Sequence[float]) -> bool: ...


@dataclass(frozen=True, kw_only=True)
class LoopConfig:
    """Timing and safety knobs of a run.  A bad value raises ``ConfigError`` whose ``key`` is the field's name.

    >>> LoopConfig(rate=50.0).velocity_scale
    1.0
    >>> LoopConfig(rate=0.0)
    Traceback (most recent call last):
    ...
    retarget.errors.ConfigError: rate: Expected a tick rate > 0 Hz (got 0.0)
    """

    rate: float = 100.0  #: ticks per second
    speed: float = 1.0  #: clip seconds per second of run time
    start: float = 0.0  #: clip seconds
    end: float | None = None  #: clip seconds, exclusive with ``loop``; None = the clip's end
    loop: bool = False  #: wrap back to ``start`` after ``end``
    max_ticks: int | None = None  #: stop after this many ticks (needed to bound a ``loop`` run in tests)
    velocity_scale: float = 1.0  #: fraction of each joint's max velocity allowed per tick
    ik_iterations: int = 30  #: IK sweeps per tick (the per-tick budget; a warm tick needs 1-5)
    ik_tolerance: float = 1e-3  #: metres
    progress_every: float = 1.0  #: real seconds between progress callbacks (the first tick always reports)
    #: peak joint speed, rad/s, of the lead-in to the clip's first pose on a bus (capped by each joint's
    #: ``velocity_scale x max_velocity``); 0 = no lead-in (the first ticks go there at full speed)
    lead_in_speed: float = 0.5
    #: the look-ahead plan's soft cost on the change of acceleration (:func:`~retarget.control.plan.plan_path`'s
    #: ``jerk_cost``; 0: follow the clip as closely as the limits allow, however the acceleration flips)
    jerk_cost: float = JERK_COST
    #: the collision model every goal is checked against before it is written (the pose and the joint-space
    #: segment from the last goal, :mod:`~retarget.control.safety`); None: no check
    collision: CollisionModel | None = field(default=None, compare=False)

    #: the documented ranges (a run's length and every check stay bounded): ticks per second, clip speed,
    #: velocity fraction, lead-in rad/s (or 0), IK sweeps per tick, IK tolerance metres, the plan's jerk cost
    RATE_RANGE = (1.0, 1000.0)
    SPEED_RANGE = (0.01, 100.0)
    VELOCITY_SCALE_RANGE = (0.01, 1.0)
    LEAD_IN_SPEED_RANGE = (0.01, 20.0)
    IK_ITERATIONS_RANGE = (1.0, 1000.0)
    IK_TOLERANCE_RANGE = (0.0, 0.1)  # (> 0, checked first)
    JERK_COST_RANGE = (0.0, 1.0)

    def __post_init__(self) -> None:
        _require(_finite(self.rate) and self.rate > 0, "rate", "Expected a tick rate > 0 Hz", self.rate)
        _within(self.rate, self.RATE_RANGE, "rate", "Expected a tick rate from {lo:g} to {hi:g} Hz")
        _require(_finite(self.speed) and self.speed > 0, "speed", "Expected a speed > 0", self.speed)
        _within(self.speed, self.SPEED_RANGE, "speed", "Expected a speed from {lo:g} to {hi:g}")
        _require(_finite(self.start) and self.start >= 0, "start", "Expected a start time >= 0 s", self.start)
        if self.end is not None:
            message = f"Expected an end time after start ({self.start:g} s)"
            _require(_finite(self.end) and self.end > self.start, "end", message, self.end)
        if self.max_ticks is not None:
            _require(self.max_ticks >= 1, "max_ticks", "Expected at least 1 tick", self.max_ticks)
        scale = self.velocity_scale
        _require(_finite(scale) and 0 < scale <= 1, "velocity_scale", "Expected a fraction in (0, 1]", scale)
        _within(scale, self.VELOCITY_SCALE_RANGE, "velocity_scale", "Expected a fraction from {lo:g} to {hi:g}")
        _require(self.ik_iterations >= 1, "ik_iterations", "Expected at least 1 sweep", self.ik_iterations)
        _within(self.ik_iterations, self.IK_ITERATIONS_RANGE, "ik_iterations", "Expected {lo:g} to {hi:g} sweeps")
        tolerance = self.ik_tolerance
        _require(_finite(tolerance) and tolerance > 0, "ik_tolerance", "Expected a tolerance > 0 m", tolerance)
        _within(tolerance, self.IK_TOLERANCE_RANGE, "ik_tolerance", "Expected a tolerance <= {hi:g} m")
        speed, message = self.lead_in_speed, "Expected a joint speed >= 0 rad/s (0: no lead-in)"
        _require(_finite(speed) and speed >= 0, "lead_in_speed", message, speed)
        if speed != 0:
            message = "Expected a joint speed from {lo:g} to {hi:g} rad/s, or 0 (no lead-in)"
            _within(speed, self.LEAD_IN_SPEED_RANGE, "lead_in_speed", message)
        every = self.progress_every
        _require(_finite(every) and every > 0, "progress_every", "Expected a period > 0 s", every)
        message = "Expected a jerk cost from {lo:g} to {hi:g} (0: none)"  # (nan fails the range too)
        _within(self.jerk_cost, self.JERK_COST_RANGE, "jerk_cost", message)


def _within(value: float, bounds: tuple[float, float], key: str, message: str) -> None:
    """``value`` within ``bounds`` (inclusive), else a ConfigError with ``message`` formatted with ``lo``, ``hi``."""
    lo, hi = bounds
    _require(lo <= value <= hi, key, message.format(lo=lo, hi=hi), value)


def _finite(x: float) -> bool:
    return math.isfinite(x)


def _require(ok: bool, key: str, message: str, value: object) -> None:
    if not ok:
        raise ConfigError(message, key=key, value=value)


@dataclass(slots=True)
class TickRecord:
    """What one tick did.  Angles radians, target metres (base frame), times seconds.

    A record to read, not to change (every ``on_tick`` gets the same one).  It is not frozen because one is built
    every tick, and a frozen dataclass of this many fields takes ~7x as long to build (~5 us against ~0.7 us: a
    sixth of the loop's own time per tick of an offline export)."""

    tick: int  #: slot index since the start (skipped slots leave gaps)
    time: float  #: the slot's time since the run's start, loop clock
    clip_time: float  #: seconds into the clip
    target: npt.NDArray[np.float64]  #: ``(3,)``
    q_cmd: npt.NDArray[np.float64]  #: ``(n_joints,)`` goals sent
    q_present: npt.NDArray[np.float64] | None  #: ``(n_joints,)`` read back; None in a dry run
    ik_error: float  #: metres, IK solution to target
    ik_sweeps: int
    ik_converged: bool
    compute_time: float  #: real seconds: target + IK + velocity limit
    bus_time: float  #: real seconds: write + read
    clamped: bool
    velocity_limited: bool
    overrun: bool
    bus_retries: int  #: retries the bus made during this tick
    lead_in: bool = False  #: a tick of the lead-in (slot < 0, before the clip's clock starts)
    #: servos whose read-back missed this tick (their last position stands in ``q_present``); 0 = all fresh
    stale: int = 0
    #: the tick's goal collided (pose or path within the clearance): it was not written, the arm held
    blocked: bool = False
    #: metres, the min clearance of the motion written this tick (nan without a collision model)
    min_clearance: float = math.nan
    #: the gripper (retarget.control.gripper): closure commanded 0 (open) .. 1 (closed), the last reading's shaft
    #: angle (rad) and current (A, or load fraction on XL430); nan without a gripper command
    gripper_cmd: float = math.nan
    gripper_present: float = math.nan
    gripper_current: float = math.nan


def tee(*callbacks: Callable[[TickRecord], None] | None) -> Callable[[TickRecord], None] | None:
    """One ``on_tick`` calling each of ``callbacks`` that is not None in order (None when there are none).

    >>> seen = []
    >>> tee(None, seen.append, lambda r: seen.append(-r))(1)
    >>> seen, tee(None, None)
    ([1, -1], None)
    """
    given = [c for c in callbacks if c is not None]
    if len(given) <= 1:
        return given[0] if given else None

    def both(record: TickRecord) -> None:
        for callback in given:
            callback(record)

    return both


def run_ticks(
    arm: Plant,
    source: TargetSource,
    solver: TickSolver,
    *,
    config: LoopConfig,
    clock: Clock,
    bus: Bus | None = None,
    q_start: npt.NDArray[np.float64] | None = None,
    on_tick: Callable[[TickRecord], None] | None = None,
    on_progress: Callable[[TickRecord], None] | None = None,
    progress_time: Callable[[], float] | None = None,
    stop: threading.Event | None = None,
    pipeline: bool = False,
    goal_check: Callable[[npt.NDArray[np.float64]], Checker] | None = None,
) -> TickStats:
    """Run ``source``'s goals on ``arm`` at ``config.rate`` ticks per second; see the module docstring.

        Runs slots ``first, first + 1, ...`` (``first = source.start(q_start)``, <= 0; slots < 0 are a lead-in
        before the run's clock starts) until ``source.finished(k)``, ``config.max_ticks`` ticks of slots >= 0,
        ``stop`` or Ctrl-C.  ``solver`` solves IK for the source's points.  ``bus``: a connected bus (None: a dry
        run).  The start pose ``(n_joints,)`` rad is the bus's present positions, else ``q_start``, else the arm's
        rest pose, clamped to the limits.  ``on_tick(record)`` gets every tick's :class:`TickRecord`;
        ``on_progress(record)`` the first, then one whenever ``progress_time()`` (seconds; default the tick's own
        ``time.perf_counter`` reading) has passed the last report by ``config.progress_every``.  ``pipeline`` (on a
        bus): collect each tick's read-back during the next tick (see :mod:`~retarget.control.readback`); a tick's
        record then comes once its read-back is in.  Not for a source that ``observes`` (ValueError).  ``arm``: an
    :class:`~retarget.arm.model.Arm`, or any :class:`Plant` (a rig's arms as one vector).  ``goal_check(q_start)``:
    the :class:`Checker` of every goal, instead of a :class:`~retarget.control.safety.GoalCheck` of
    ``config.collision`` (a rig checks its arms against each other too).  Returns
        the run's :class:`~retarget.control.stats.TickStats`.  ``BusError`` propagates (the caller closes the bus).

        >>> import retarget
        >>> from retarget.control.clock import VirtualClock
        >>> from retarget.ik import CCDSolver
        >>> arm = retarget.load_arm("wx250s")
        >>> class Point(TargetSource):
        ...     def target_at(self, tick: int, t: float) -> TickTarget:
        ...         return TickTarget(np.array([0.3, 0.0, 0.2]))
        ...     def finished(self, tick: int) -> bool:
        ...         return tick >= 100  # 1 s at 100 Hz
        >>> stats = run_ticks(arm, Point(), CCDSolver(arm), config=LoopConfig(), clock=VirtualClock())
        >>> stats.ticks, stats.run_time, stats.converged[-1], stats.velocity_limited[-1]
        (100, 1.0, True, False)
    """
    source = as_target_source(source)
    pipeline = pipeline and bus is not None
    if pipeline and source.observes:
        raise ValueError("Expected a source without observe() with pipeline=True: it would see each tick one late")
    status = bus.status() if bus is not None else None
    q_cmd = _start_pose(arm, bus, q_start)
    first = source.start(q_cmd)
    if first > 0:
        raise ValueError(f"Expected the source's first slot <= 0, got {first}")
    recorder = StatsRecorder(rate=config.rate, dry_run=bus is None, first=first, wall0=time.perf_counter())
    recorder.stats.collision_checked = config.collision is not None or goal_check is not None
    retries = status.retries if status is not None else 0
    stale = status.stale_reads if status is not None else 0
    reporter = _Reporter(source, recorder, bus, config, on_tick, on_progress, progress_time, retries, stale)
    check: Checker | None = None
    if goal_check is not None:
        check = goal_check(q_cmd)
    elif config.collision is not None:
        check = GoalCheck(config.collision, q_cmd)
    run = _Run(arm, source, solver, config, q_cmd, first, recorder, check)
    read_back = read_back_for(bus, reporter, pipeline=pipeline)
    schedule = Schedule(clock, rate=config.rate, first=first)  # slot `first` starts now
    try:
        stats = run.run(schedule, read_back, stop if stop is not None else threading.Event())
    except BusError as exc:  # the ticks so far go with the error, for the caller's summary of a failed run
        exc.stats = stats = recorder.finish(wall1=time.perf_counter(), last_slot=run.last_slot)
        stats.q_cmd, stats.q_present = run.q_cmd, read_back.present
        with contextlib.suppress(Exception):  # the counts of a failed bus are a bonus, never a second error
            _add_bus_counts(stats, bus, status)
        raise
    _add_bus_counts(stats, bus, status)
    return stats


def _add_bus_counts(stats: TickStats, bus: Bus | None, status: BusStatus | None) -> None:
    """The run's share of the bus's counters: errors, retries, stale reads, reboots, late packets."""
    if bus is not None and status is not None:
        end = bus.status()
        stats.bus_errors, stats.bus_retries = end.errors - status.errors, end.retries - status.retries
        stats.stale_reads = end.stale_reads - status.stale_reads
        stats.stale_ticks = end.stale_ticks - status.stale_ticks
        stats.worst_stale = end.worst_stale
        stats.bus_reboots = end.reboots - status.reboots
        stats.late_packets = end.late_packets - status.late_packets


def _start_pose(arm: Plant, bus: Bus | None, q_start: npt.NDArray[np.float64] | None) -> npt.NDArray[np.float64]:
    """The bus's present positions, else ``q_start``, else the arm's rest pose; clamped to the limits."""
    if bus is not None:
        q = np.asarray(bus.read_positions(), dtype=np.float64)
    elif q_start is not None:
        q = np.asarray(q_start, dtype=np.float64)
    else:
        q = arm.rest
    if q.shape != (arm.n_joints,):
        raise ValueError(f"Expected a start pose of shape ({arm.n_joints},), got {q.shape}")
    return np.clip(q, arm.lower, arm.upper)


class _Run:
    """One run of :func:`run_ticks`: the commanded pose, and the ticks from the first slot to the end."""

    def __init__(
        self,
        arm: Plant,
        source: TargetSource,
        solver: TickSolver,
        config: LoopConfig,
        q_cmd: npt.NDArray[np.float64],
        first: int,
        recorder: StatsRecorder,
        check: Checker | None,
    ):
        self.source, self.target_at, self.solve = source, source.target_at, solver.solve
        self.max_ticks, self.recorder = config.max_ticks, recorder
        max_step = arm.max_velocity * config.velocity_scale * (1.0 / config.rate)  # rad per slot
        max_accel = arm.max_acceleration * (1.0 / config.rate) ** 2  # rad per slot^2: the trapezoidal profile
        self.limiter = StepLimiter(arm.lower, arm.upper, max_step, q_cmd, max_accel=max_accel)
        self.q_cmd = q_cmd  #: the commanded pose as an array: a new one each tick that moves
        self.target = np.full(3, np.nan)  #: the last target (held ticks report it)
        self.slot = first  #: the running tick's slot
        self.check = check
        self.blocked = False  #: the running tick's goal was blocked
        self.last_slot = first - 1  #: the slot of the last tick that sent its goals

    def run(self, schedule: Schedule, read_back: ReadBack, stop: threading.Event) -> TickStats:
        """The ticks until the end (see :func:`run_ticks`), then the last read-back; the stats."""
        try:
            self.ticks(schedule, read_back, stop)
            read_back.finish()
            interrupted = stop.is_set()
        except KeyboardInterrupt:
            interrupted = True
            log.info("interrupted at tick %d", self.slot)
            read_back.interrupt()
        stats = self.recorder.finish(wall1=time.perf_counter(), last_slot=self.last_slot)
        stats.interrupted = interrupted
        stats.q_cmd, stats.q_present = self.q_cmd, read_back.present
        return stats

    def ticks(self, schedule: Schedule, read_back: ReadBack, stop: threading.Event) -> None:
        """One tick per slot until the source is finished, ``max_ticks`` clip ticks ran or ``stop`` is set."""
        finished, recorder, max_ticks, perf = self.source.finished, self.recorder, self.max_ticks, time.perf_counter
        while True:
            k = self.slot = schedule.slot
            if (max_ticks is not None and recorder.clip_ticks >= max_ticks) or stop.is_set() or finished(k):
                return
            slot_time = schedule.wait()
            c0 = perf()
            recorder.begin(k, c0)
            error, sweeps, converged, clamped, limited = self.steer(k, slot_time)
            c1 = perf()
            compute = c1 - c0
            bus = read_back.send(self.q_cmd, c1)
            self.last_slot = k
            overrun = schedule.advance()
            skipped = schedule.slot - k - 1
            row = recorder.series.add(error, sweeps, converged, clamped, limited, compute, bus, overrun, skipped)
            target, q_cmd, ended = self.target, self.q_cmd, read_back.ended
            clearance = math.nan
            if self.check is not None:
                clearance = self.check.clearance
                recorder.series.note_clearance(clearance)
            sent = SentTick(row, k, slot_time, target, q_cmd, error, sweeps, converged, clamped, limited, overrun,
                            compute, bus, ended, self.blocked, clearance)  # fmt: skip
            read_back.record(sent)  # reported now, or once its read-back is in

    def steer(self, k: int, slot_time: float) -> tuple[float, int, bool, bool, bool]:
        """Steps 1-3 of slot ``k``: the source's goal, IK toward a point, the step limit.  Sets ``q_cmd`` and
        ``target``; returns (IK error m, IK sweeps, converged, clamped, velocity-limited)."""
        goal = self.target_at(k, slot_time)
        limiter = self.limiter
        self.blocked = False
        elapsed = k - self.last_slot
        before = limiter.state()
        if goal is None:  # hold: no IK; brake to rest at the acceleration limit (nothing when already still)
            self.recorder.series.holds += 1
            if limiter.brake(elapsed):
                if not self._allowed():  # the braking step collides: stop at once (counted as blocked)
                    self.recorder.series.blocked += 1
                    self._stop_here()
                self.q_cmd = np.array(limiter.q)
            return 0.0, 0, True, False, False
        if isinstance(goal, JointGoal):  # a pose in joint space: no IK
            self.target = goal.target
            limited = limiter.step(goal.q.tolist(), elapsed, goal.max_step)
            error, sweeps, converged, clamped = 0.0, 0, True, goal.clamped
            if goal.ik is not None:  # planned ahead from this IK solution: its figures are the tick's
                error, sweeps, converged = goal.ik.error, goal.ik.iterations, goal.ik.converged
                if goal.ik.blocked:
                    self.recorder.series.ik_blocked += 1
        else:
            self.target, rotation, clamped = goal
            result = self.solve(self.target, limiter.seed(elapsed), rotation)
            limited = limiter.step(result.q.tolist(), elapsed)
            error, sweeps, converged = result.error, result.iterations, result.converged
            if result.blocked:  # IK ended at the nearest clear pose: the target needs a colliding one
                self.recorder.series.ik_blocked += 1
        if not self._allowed():  # not written: brake at the limit instead when that step is clear, else stop here
            self.blocked = True
            self.recorder.series.blocked += 1
            limiter.restore(before)
            if limiter.brake(elapsed) and not self._allowed():
                self._stop_here()
        self.q_cmd = np.array(limiter.q)
        return error, sweeps, converged, clamped, limited

    def _allowed(self) -> bool:
        """Whether the step from the commanded pose to the limiter's keeps the clearance (no model: always)."""
        return self.check is None or self.check.allows(self.q_cmd.tolist(), self.limiter.q)

    def _stop_here(self) -> None:
        """The collision check's instant stop: the limiter back at the commanded pose, at rest (the one step that
        may exceed the acceleration limit; ``TickRecord.blocked`` marks it)."""
        self.blocked = True
        self.limiter.q = self.q_cmd.tolist()
        self.limiter.hold()


class _Reporter:
    """Reports a tick once its read-back is in: its bus time and retries, ``observe``, ``on_tick``, ``on_progress``."""

    def __init__(
        self,
        source: TargetSource,
        recorder: StatsRecorder,
        bus: Bus | None,
        config: LoopConfig,
        on_tick: Callable[[TickRecord], None] | None,
        on_progress: Callable[[TickRecord], None] | None,
        progress_time: Callable[[], float] | None,
        retries: int,
        stale: int = 0,
    ):
        self.source, self.observes, self.recorder, self.bus = source, source.observes, recorder, bus
        self.on_tick, self.on_progress, self.progress_time = on_tick, on_progress, progress_time
        self.progress_every = config.progress_every
        self.next_progress = -math.inf  # progress time of the next progress report: the first tick reports
        self.retries = retries  # the bus's retries when the last tick was reported
        self.stale = stale  # the bus's stale reads then

    def __call__(self, done: SentTick, present: npt.NDArray[np.float64] | None, collect_time: float) -> None:
        """Report ``done`` with its read-back ``present`` (None: none) that took ``collect_time`` s to collect."""
        bus_time = done.bus_time
        if collect_time:  # pipelined: collecting its read-back during the next tick was bus time of this one
            bus_time = self.recorder.add_bus_time(done.slot, done.row, collect_time)
        retries = stale = 0
        if self.bus is not None:
            status = self.bus.status()
            retries, self.retries = status.retries - self.retries, status.retries
            stale, self.stale = status.stale_reads - self.stale, status.stale_reads
        if self.observes:
            self.source.observe(done.slot, done.q_cmd, present)
        report, progress_now = False, 0.0
        if self.on_progress is not None:
            progress_now = done.ended if self.progress_time is None else self.progress_time()
            report = progress_now >= self.next_progress
        if self.on_tick is not None or report:
            record = self.record(done, present, bus_time, retries, stale)
            if self.on_tick is not None:
                self.on_tick(record)
            if report and self.on_progress is not None:
                self.next_progress = progress_now + self.progress_every
                self.on_progress(record)

    def record(
        self, done: SentTick, present: npt.NDArray[np.float64] | None, bus_time: float, retries: int, stale: int = 0
    ) -> TickRecord:
        slot = done.slot
        return TickRecord(
            tick=slot,
            time=done.time,
            clip_time=self.source.clip_time(slot, done.time),
            target=done.target,
            q_cmd=done.q_cmd,
            q_present=present,
            ik_error=float(done.error),
            ik_sweeps=int(done.sweeps),
            ik_converged=bool(done.converged),
            compute_time=done.compute_time,
            bus_time=bus_time,
            clamped=done.clamped,
            velocity_limited=done.velocity_limited,
            overrun=done.overrun,
            bus_retries=retries,
            lead_in=slot < 0,
            stale=stale,
            blocked=done.blocked,
            min_clearance=done.min_clearance,
        )
