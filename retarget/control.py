"""The fixed-rate control loop that plays retargeted motion, or live targets, on a bus.

One tick loop, :func:`run_ticks`, serves both uses: it asks a
:class:`TargetSource` for each tick's target.  :class:`ControlLoop` plays a
clip through a :class:`ClipSource`; ``retarget.teleop`` follows targets that
arrive while the arm moves.  Each tick ``k`` has a slot on the loop's clock,
``t0 + k / rate`` (for a clip, also a clip time ``start + k * speed / rate``,
wrapped into ``[start, end)`` with ``loop``).  In its slot a tick:

1. takes the source's target (a clip's frames are resampled to ticks by linear
   interpolation, then pulled into the workspace, a block of slots at a time).
   A source with nothing to steer toward returns ``None``: the tick **holds**,
   keeps the commanded pose and runs no IK (0 sweeps), then goes on to 4;
2. solves IK with the arm's :class:`~retarget.ik.CCDSolver`, warm-started from
   the last commanded solution moved on by half its last step (a damped
   constant-velocity prediction: about 25 % fewer sweeps than the plain last
   solution; seeding from the commanded pose rather than the raw IK solution
   keeps a velocity-limited tick from letting IK wander off), within
   ``ik_iterations`` sweeps (the per-tick budget), with the mapping's per-joint
   weights;
3. limits each joint's step to ``velocity_scale x max_velocity / rate`` (one
   slot's worth, also after an overrun skipped slots: the arm then lags its
   targets and catches up within the limit, it never jumps);
4. sends the goals in one ``bus.write_goals``;
5. reads the present positions back with ``bus.read_positions``.

**Pipelined read-back** (``run_ticks(pipeline=True)``; :class:`ControlLoop`'s default): step 5 is split in
two.  ``bus.request_positions()`` sends the read right after the write, and the next tick collects it with
``bus.collect_positions()`` after its own steps 1-3, just before its write.  The host computes while the
status packets are on the wire instead of leaving the wire idle while it computes: on a bus-bound loop
(1 Mbps, six servos: about 1.06 ms of wire time per tick) that is the difference between the wire rate and
about 88 % of it.  The wire carries the same packets in the same order (write k, read k, write k+1, ...) and
nothing depends on the read-back: IK starts from the commanded pose.  A tick's record (``on_tick``,
``on_progress``) then comes a tick later, once its read-back is in; the last one after the loop.

A source may also give a tick a :class:`JointGoal` (a pose in joint space): the
tick then runs no IK (0 sweeps) and steps 3-5 move toward that pose.

**Lead-in.**  On a bus, :meth:`ControlLoop.run` first moves the arm from its
present pose to the clip's first pose (:meth:`ControlLoop.initial_pose`, the IK
solution of the first target) along a straight line in joint space with a
raised-cosine time profile (at rest at both ends, synchronised so all joints
arrive together), at a peak speed of ``lead_in_speed`` rad/s per joint (capped
by ``velocity_scale x max_velocity``); after an overrun too, each lead-in tick
steps at most that speed's one slot (:attr:`JointGoal.max_step`): the arm lags
the plan and catches up as it slows down, never faster.  Its ticks are slots ``-n .. -1`` of the
same tick loop, before the clip's clock starts (their ``time`` is negative,
``TickRecord.lead_in`` is set, ``clip_time`` is the clip's start), so the clip
still starts at slot 0 with the same bus calls, limits and velocity limiting.
Its ticks are counted apart: the summary's ticks, IK stats, tick times,
overruns and real-time factor are the clip's; ``lead_in_ticks`` and
``lead_in_s`` report the lead-in; ``max_ticks`` counts clip ticks.  A dry run
has no lead-in (no arm to move): start it from ``initial_pose()`` to get the
trajectory the clip part of a bus run commands.

It is deadline-aware: a tick that ends after the next slot's deadline counts
as an overrun, and the loop resumes at the slot the clock is in (skipping the
missed ones) instead of running late for ever after, so delays never
accumulate as drift.  The clock is injected: :class:`~retarget.clock.MonotonicClock`
for real time, one :class:`~retarget.clock.VirtualClock` shared with the
simulator for ``--fast`` runs.  ``bus=None`` is a dry run: everything but the
bus.

Ctrl-C: :meth:`ControlLoop.stop` (signal-safe) ends the run at the next tick
boundary, and a ``KeyboardInterrupt`` raised inside a tick (e.g. by a
telemetry callback) ends it too; either way the summary says ``interrupted``.
:func:`run_on_bus` connects the bus and always closes it, so the bus's own
shutdown sequence (hold, rest or torque off) runs.

Arrays: joint angles ``(n_joints,)`` float64 radians in ``Arm.joint_names``
order; targets ``(3,)`` metres in the arm's base frame.
"""

from __future__ import annotations

import logging
import math
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, NamedTuple, Protocol

import numpy as np

from retarget.bus import connected
from retarget.clock import Clock, MonotonicClock
from retarget.errors import ConfigError, RetargetError
from retarget.summary import RunSummary, summarize

if TYPE_CHECKING:
    from retarget.arm import Arm
    from retarget.bus import Bus
    from retarget.ik import CCDSolver
    from retarget.mapping import Targets

__all__ = [
    "ClipSource",
    "ControlLoop",
    "JointGoal",
    "LeadIn",
    "LoopConfig",
    "TargetSource",
    "TickRecord",
    "TickStats",
    "run_on_bus",
    "run_ticks",
]

log = logging.getLogger(__name__)

_BLOCK = 256  #: targets are resampled this many slots at a time
_LEAD = 0.5  #: the IK seed leads the commanded pose by this fraction of its last step


@dataclass(frozen=True, kw_only=True)
class LoopConfig:
    """Timing and safety knobs of a run.  Errors name the CLI option (``key="--rate"``)."""

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

    def __post_init__(self) -> None:
        def bad(key: str, message: str, value: object) -> None:
            raise ConfigError(message, key=key, value=value)

        if not (math.isfinite(self.rate) and self.rate > 0):
            bad("--rate", "Expected a tick rate > 0 Hz", self.rate)
        if not (math.isfinite(self.speed) and self.speed > 0):
            bad("--speed", "Expected a speed > 0", self.speed)
        if not (math.isfinite(self.start) and self.start >= 0):
            bad("--start", "Expected a start time >= 0 s", self.start)
        if self.end is not None and not (math.isfinite(self.end) and self.end > self.start):
            bad("--end", f"Expected an end time after --start ({self.start:g} s)", self.end)
        if self.max_ticks is not None and self.max_ticks < 1:
            bad("--max-ticks", "Expected at least 1 tick", self.max_ticks)
        if not (math.isfinite(self.velocity_scale) and 0 < self.velocity_scale <= 1):
            bad("--velocity-scale", "Expected a fraction in (0, 1]", self.velocity_scale)
        if self.ik_iterations < 1:
            bad("--ik-iterations", "Expected at least 1 sweep", self.ik_iterations)
        if not (math.isfinite(self.ik_tolerance) and self.ik_tolerance > 0):
            bad("--ik-tolerance", "Expected a tolerance > 0 m", self.ik_tolerance)
        if not (math.isfinite(self.lead_in_speed) and self.lead_in_speed >= 0):
            bad("--lead-in", "Expected a joint speed >= 0 rad/s (0: no lead-in)", self.lead_in_speed)


@dataclass(frozen=True, slots=True)
class TickRecord:
    """What one tick did.  Angles radians, target metres (base frame), times seconds."""

    tick: int  #: slot index since the start (skipped slots leave gaps)
    time: float  #: the slot's time since the run's start, loop clock
    clip_time: float  #: seconds into the clip
    target: np.ndarray  #: ``(3,)``
    q_cmd: np.ndarray  #: ``(n_joints,)`` goals sent
    q_present: np.ndarray | None  #: ``(n_joints,)`` read back; None in a dry run
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


class ControlLoop:
    """Plays :class:`~retarget.mapping.Targets` on an arm at a fixed rate.  See the module docstring.

    ``solver`` defaults to a :class:`~retarget.ik.CCDSolver` with the config's
    budget (and the mapping's orientation weight when the targets carry
    rotations).  ``on_tick(record)`` is called after every tick;
    ``on_progress(record)`` on the first tick, then about once per
    ``progress_every`` real seconds (so ``--fast`` runs do not flood the terminal), as read from
    ``progress_time()`` (default ``time.perf_counter``; a test passes a fake one to check the pacing).
    ``pipeline``: overlap each tick's read-back with the next tick's compute on a bus (see the module
    docstring); False reads back within the tick.
    """

    def __init__(
        self,
        arm: Arm,
        targets: Targets,
        *,
        config: LoopConfig | None = None,
        clock: Clock | None = None,
        solver: CCDSolver | None = None,
        on_tick: Callable[[TickRecord], None] | None = None,
        on_progress: Callable[[TickRecord], None] | None = None,
        clip_name: str = "",
        progress_time: Callable[[], float] | None = None,
        pipeline: bool = True,
    ):
        self.arm = arm
        self.pipeline = pipeline
        self.targets = targets
        self.config = config = config or LoopConfig()
        self.clock: Clock = clock if clock is not None else MonotonicClock()
        from retarget.ik import CCDSolver
        from retarget.mapping import ik_weights

        self._solver_kwargs = {"tolerance": config.ik_tolerance, "weights": ik_weights(arm, targets.config)}
        if targets.rotations is not None:
            self._solver_kwargs["orientation_weight"] = targets.config.orientation_weight
        if solver is None:
            solver = CCDSolver(arm, max_iterations=config.ik_iterations, **self._solver_kwargs)
        self.solver = solver
        self.on_tick = on_tick
        self.on_progress = on_progress
        self.progress_time = progress_time
        self.clip_name = clip_name
        self._stop = threading.Event()

        clip_duration = (targets.n_frames - 1) * targets.frame_time
        end = clip_duration if config.end is None else min(config.end, clip_duration)
        if config.start >= end and targets.n_frames > 1:
            raise ConfigError(
                f"Expected a start time before the clip's end ({end:g} s)", key="--start", value=config.start
            )
        self.window = (float(config.start), float(end))
        self.step = step = config.speed / config.rate  #: clip seconds per tick
        span = end - config.start
        if config.loop:
            n = max(1, round(span / step))
        else:
            n = int(math.floor(span / step + 1e-9)) + 1
        #: slots of one pass over the window (a looping run wraps slot ``k`` to ``k % n_slots``)
        self.n_slots = n
        self.frames = int(round(span / targets.frame_time)) + 1

    def clip_time(self, i: int) -> float:
        """Clip seconds of slot ``i`` of a pass (``0 <= i < n_slots``)."""
        return self.config.start + i * self.step

    def sample(self, first: int, stop: int) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
        """Targets of slots ``first..stop-1`` of a pass: positions ``(n, 3)`` m, rotations or None, clamped ``(n,)``."""
        return self.targets.sample(self.config.start + np.arange(first, stop) * self.step)

    @property
    def n_ticks(self) -> int | None:
        """The most ticks the run will take (None: a loop without ``max_ticks`` runs until stopped)."""
        n = None if self.config.loop else self.n_slots
        if self.config.max_ticks is not None:
            n = self.config.max_ticks if n is None else min(n, self.config.max_ticks)
        return n

    def stop(self) -> None:
        """Ask the run to end at the next tick boundary (safe from a signal handler or another thread)."""
        self._stop.set()

    def initial_pose(self, *, iterations: int = 200) -> np.ndarray:
        """The IK solution of the first target, solved cold from home with a large budget: ``(n_joints,)`` rad."""
        from retarget.ik import CCDSolver

        solver = CCDSolver(self.arm, max_iterations=iterations, **self._solver_kwargs)
        positions, rotations, _ = self.sample(0, 1)
        rotation = None if rotations is None else rotations[0]
        return np.array(solver.solve(positions[0], self.arm.home, rotation).q, dtype=np.float64)

    def run(
        self, bus: Bus | None = None, *, q_start: np.ndarray | None = None, lead_in: bool | None = None
    ) -> RunSummary:
        """Run the loop on a connected ``bus`` (``None``: dry run) and return the summary.

        The start pose is the bus's present positions, else ``q_start``, else the
        arm's rest pose.  ``lead_in``: first move from the start pose to
        :meth:`initial_pose` (see the module docstring; nothing when
        ``config.lead_in_speed`` is 0); default on a bus only, True previews it in
        a dry run.  ``BusError`` propagates (the caller closes the bus).
        """
        if lead_in is None:
            lead_in = bus is not None
        lead_to = self.initial_pose() if lead_in and self.config.lead_in_speed > 0 else None
        source = ClipSource(self, lead_in_to=lead_to)
        ticks = run_ticks(
            self.arm,
            source,
            self.solver,
            config=self.config,
            clock=self.clock,
            bus=bus,
            q_start=q_start,
            on_tick=self.on_tick,
            on_progress=self.on_progress,
            progress_time=self.progress_time,
            stop=self._stop,
            pipeline=self.pipeline,
        )
        played = (ticks.last_slot + 1) * self.config.speed / self.config.rate if ticks.last_slot >= 0 else 0.0
        return ticks.summary(arm=self.arm.name, clip=self.clip_name, frames=self.frames, duration_s=played)


class TargetSource(Protocol):
    """Where each tick's target comes from: a clip (:class:`ClipSource`) or a live stream (``retarget.teleop``).

    ``target_at(tick, t)`` gets the slot index and its time since the run's start (loop clock) and returns
    ``(position (3,) metres, rotation (3, 3) | None, clamped)``, or ``None`` to **hold**: the tick then
    keeps the commanded pose and runs no IK (0 sweeps); or a :class:`JointGoal` to move toward a pose in
    joint space without IK.  ``finished(tick)`` ends the run before slot ``tick``.  Optional:
    ``start(q_start)`` is called once with the start pose before the first tick and may return the first
    slot: ``-n`` runs ``n`` lead-in slots ``-n .. -1`` before the run's clock starts (counted apart, see
    :class:`TickStats`); ``None`` or 0 starts at slot 0.  ``observe(tick, q_cmd, q_present)`` is called
    after each tick (the goals sent and the positions read back, ``None`` in a dry run), and
    ``clip_time(tick)`` names the tick's clip seconds (default: the slot's time).
    """

    def target_at(self, tick: int, t: float) -> tuple[np.ndarray, np.ndarray | None, bool] | None: ...

    def finished(self, tick: int) -> bool: ...


class JointGoal(NamedTuple):
    """A tick's goal as a pose in joint space (a :class:`TargetSource` may return it): the tick runs no IK."""

    q: np.ndarray  #: ``(n_joints,)`` rad, the pose to move toward (velocity-limited and clamped like a solution)
    target: np.ndarray  #: ``(3,)`` metres, base frame: what the tick reports as its target
    #: ``(n_joints,)`` rad, a tighter per-tick step limit than ``velocity_scale x max_velocity / rate`` for this
    #: tick (a lead-in's own speed, kept after an overrun too); None: the loop's
    max_step: tuple[float, ...] | None = None


@dataclass(frozen=True)
class LeadIn:
    """A joint-space move from ``q_from`` to ``q_to`` ``(n_joints,)`` rad over slots ``-n_slots .. -1``.

    Straight in joint space with a raised-cosine time profile: at slot ``-n_slots - 1 + i`` the pose is
    ``q_from + s_i (q_to - q_from)``, ``s_i = (1 - cos(pi i / n)) / 2``, so it starts and ends at rest, every
    joint arrives together at slot -1, and joint ``j``'s largest step, ``|dq_j| sin(pi / 2n)``, stays within
    ``speed_j / rate``.  No slots when a single step is already within that speed.
    """

    q_from: np.ndarray
    q_to: np.ndarray
    target: np.ndarray  #: ``(3,)`` metres: the target whose solution ``q_to`` is, reported by the lead-in ticks
    n_slots: int
    #: rad per joint, ``speed / rate``: each goal's step limit in the loop, so a tick after an overrun moves on at
    #: the lead-in's speed (and the lead-in catches up on its slower end) instead of jumping to the planned pose
    max_step: tuple[float, ...] | None = None

    @classmethod
    def plan(
        cls, q_from: np.ndarray, q_to: np.ndarray, *, speed: np.ndarray, rate: float, target: np.ndarray
    ) -> LeadIn:
        """The lead-in at peak joint speeds ``speed`` ``(n_joints,)`` rad/s (> 0) and ``rate`` ticks per second."""
        q_from = np.asarray(q_from, dtype=np.float64)
        q_to = np.asarray(q_to, dtype=np.float64)
        ratio = float(np.max(np.abs(q_to - q_from) / speed)) * rate  # slots the move takes at constant speed
        n = 0 if ratio <= 1.0 else math.ceil(math.pi / (2.0 * math.asin(1.0 / ratio)))
        # a hair above speed / rate: the plan's own steps (<= speed / rate up to rounding) pass unchanged
        max_step = tuple((np.broadcast_to(speed, q_from.shape) / rate * (1.0 + 1e-9)).tolist())
        return cls(q_from=q_from, q_to=q_to, target=np.asarray(target, dtype=np.float64), n_slots=n, max_step=max_step)

    def goal(self, slot: int) -> JointGoal:
        """The goal of lead-in slot ``slot`` (``-n_slots <= slot < 0``)."""
        i = slot + self.n_slots + 1
        if i >= self.n_slots:
            return JointGoal(self.q_to, self.target, self.max_step)
        s = 0.5 - 0.5 * math.cos(math.pi * i / self.n_slots)
        return JointGoal(self.q_from + s * (self.q_to - self.q_from), self.target, self.max_step)


class ClipSource:
    """The :class:`TargetSource` of a :class:`ControlLoop`: its clip window, sampled a block of slots at a time.

    With ``lead_in_to`` (a pose ``(n_joints,)`` rad, normally :meth:`ControlLoop.initial_pose`), ``start``
    plans a :class:`LeadIn` from the start pose to it at the config's ``lead_in_speed`` and the clip starts
    after it, at slot 0.
    """

    def __init__(self, loop: ControlLoop, *, lead_in_to: np.ndarray | None = None):
        self.loop = loop
        self.n_slots = loop.n_slots
        self.looping = loop.config.loop
        self.lead_in_to = lead_in_to
        self.lead_in: LeadIn | None = None  #: planned by ``start``
        self._block0 = self._block1 = 0  # the slots [block0, block1) of a pass whose targets are sampled
        self._positions = self._clamped = np.empty(0)
        self._rotations: np.ndarray | None = None

    def start(self, q_start: np.ndarray) -> int:
        """Plan the lead-in from ``q_start`` (if any); returns the first slot, ``-n`` for ``n`` lead-in slots."""
        if self.lead_in_to is None:
            return 0
        loop, cfg = self.loop, self.loop.config
        speed = np.minimum(cfg.lead_in_speed, cfg.velocity_scale * loop.arm.max_velocity)
        positions, _, _ = loop.sample(0, 1)
        self.lead_in = LeadIn.plan(q_start, self.lead_in_to, speed=speed, rate=cfg.rate, target=positions[0])
        if self.lead_in.n_slots:
            log.info(
                "lead-in: %d ticks (%.2f s) to the clip's first pose at <= %.3g rad/s",
                self.lead_in.n_slots,
                self.lead_in.n_slots / cfg.rate,
                cfg.lead_in_speed,
            )
        return -self.lead_in.n_slots

    def finished(self, tick: int) -> bool:
        return not self.looping and tick >= self.n_slots

    def clip_time(self, tick: int) -> float:
        if tick < 0:  # the lead-in: the clip waits at its start
            return self.loop.config.start
        return self.loop.clip_time(tick % self.n_slots if self.looping else tick)

    def target_at(self, tick: int, t: float) -> tuple[np.ndarray, np.ndarray | None, bool] | JointGoal:
        if tick < 0:
            return self.lead_in.goal(tick)  # type: ignore[union-attr]
        i = tick % self.n_slots if self.looping else tick
        if not self._block0 <= i < self._block1:  # sample the targets of the next slots, a block at a time
            if i == self._block1 or self._rotations is not None:
                self._block0, self._block1 = i, min(i + _BLOCK, self.n_slots)
                self._positions, self._rotations, self._clamped = self.loop.sample(self._block0, self._block1)
            else:  # after a skip only this slot (an overrunning loop skips every tick)
                one, moved = self.loop.targets.at(self.loop.clip_time(i))
                self._block0, self._block1 = i, i + 1
                self._positions, self._clamped = one[None], (moved,)
                return one, None, moved
        j = i - self._block0
        rotations = self._rotations
        return self._positions[j], None if rotations is None else rotations[j], bool(self._clamped[j])


@dataclass
class TickStats:
    """Per-tick series and counters of one :func:`run_ticks` run (times seconds, errors metres).

    The series, counters, ``wall_time`` and ``run_time`` cover the ticks of slots >= 0 (a clip's ticks);
    the lead-in's ticks (slots < 0) are counted apart in ``lead_in_*``.  ``bus_errors``/``bus_retries``
    cover the whole run.
    """

    rate: float
    dry_run: bool
    errors: list[float] = field(default_factory=list)
    sweeps: list[int] = field(default_factory=list)
    converged: list[bool] = field(default_factory=list)
    clamped: list[bool] = field(default_factory=list)
    velocity_limited: list[bool] = field(default_factory=list)
    compute: list[float] = field(default_factory=list)
    bus: list[float] = field(default_factory=list)
    holds: int = 0  #: ticks that held the pose (the source had no target; no IK ran)
    overruns: int = 0
    skipped: int = 0
    interrupted: bool = False
    last_slot: int = -1
    wall_time: float = 0.0
    bus_errors: int = 0
    bus_retries: int = 0
    q_cmd: np.ndarray | None = None  #: the last goals sent ``(n_joints,)`` rad
    q_present: np.ndarray | None = None  #: the last positions read ``(n_joints,)`` rad
    lead_in_slots: int = 0  #: slots the source's lead-in planned (``-first slot``)
    lead_in_ticks: int = 0  #: lead-in ticks that ran
    lead_in_time: float = 0.0  #: loop-clock seconds of the lead-in slots that ran (at most ``lead_in_slots / rate``)
    lead_in_wall_time: float = 0.0  #: real seconds the lead-in took

    @property
    def ticks(self) -> int:
        return len(self.errors)

    @property
    def run_time(self) -> float:
        """Loop-clock seconds from the first slot to the end of the last one."""
        return (self.last_slot + 1) / self.rate if self.last_slot >= 0 else 0.0

    def summary(self, *, arm: str, clip: str, frames: int, duration_s: float) -> RunSummary:
        return summarize(
            arm=arm,
            clip=clip,
            dry_run=self.dry_run,
            interrupted=self.interrupted,
            frames=frames,
            rate=self.rate,
            duration_s=duration_s,
            run_time_s=self.run_time,
            wall_time_s=self.wall_time,
            ik_error_m=np.asarray(self.errors),
            ik_sweeps=np.asarray(self.sweeps),
            ik_converged=np.asarray(self.converged, dtype=bool),
            clamped=np.asarray(self.clamped, dtype=bool),
            velocity_limited=np.asarray(self.velocity_limited, dtype=bool),
            compute_s=np.asarray(self.compute),
            bus_s=np.asarray(self.bus),
            overruns=self.overruns,
            skipped_ticks=self.skipped,
            bus_errors=self.bus_errors,
            bus_retries=self.bus_retries,
            lead_in_ticks=self.lead_in_ticks,
            lead_in_s=self.lead_in_time,
        )


def run_ticks(
    arm: Arm,
    source: TargetSource,
    solver: CCDSolver,
    *,
    config: LoopConfig,
    clock: Clock,
    bus: Bus | None = None,
    q_start: np.ndarray | None = None,
    on_tick: Callable[[TickRecord], None] | None = None,
    on_progress: Callable[[TickRecord], None] | None = None,
    progress_time: Callable[[], float] | None = None,
    stop: threading.Event | None = None,
    pipeline: bool = False,
) -> TickStats:
    """The fixed-rate tick loop shared by replay and teleop; see the module docstring for one tick.

    Runs slots ``first, first + 1, ...`` (``first`` from ``source.start``, default 0; slots < 0 are a
    lead-in before the run's clock starts) until ``source.finished(k)``, ``config.max_ticks`` ticks of
    slots >= 0, ``stop`` or Ctrl-C.  ``on_progress`` gets the first tick's record, then one whenever
    ``progress_time()`` (seconds; default the tick's own ``time.perf_counter`` reading) has passed the last
    report by ``config.progress_every``.  The start pose is the bus's present positions, else ``q_start``, else
    the arm's rest pose.  ``BusError`` propagates (the caller closes the bus).

    ``pipeline`` (on a bus): each tick's read-back is requested right after its write and collected by the
    next tick after its target, IK and velocity limit, so the host computes while the status packets are on
    the wire (see the module docstring).  The bus sees the same instructions in the same order; a tick's
    record (``on_tick``, ``on_progress``) then comes once its read-back is in, during the next tick.  Not for
    a source with ``observe``: it would see tick ``k`` only after choosing the target of tick ``k + 1``.
    """
    cfg = config
    dt = 1.0 / cfg.rate
    lower, upper = arm.lower, arm.upper
    vstep = arm.max_velocity * cfg.velocity_scale * dt  # rad per slot
    solve = solver.solve
    target_at = source.target_at
    finished = source.finished
    observe = getattr(source, "observe", None)
    clip_time = getattr(source, "clip_time", None)
    pipeline = pipeline and bus is not None
    if pipeline and observe is not None:
        raise ValueError("Expected a source without observe() with pipeline=True: it would see each tick one late")
    stop = stop if stop is not None else threading.Event()
    perf = time.perf_counter
    array = np.array
    st = TickStats(rate=cfg.rate, dry_run=bus is None)

    status0 = bus.status() if bus is not None else None
    retries_before = status0.retries if status0 is not None else 0
    if bus is not None:
        q_cmd = np.asarray(bus.read_positions(), dtype=np.float64)
    elif q_start is not None:
        q_cmd = np.asarray(q_start, dtype=np.float64)
    else:
        q_cmd = arm.rest
    if q_cmd.shape != (arm.n_joints,):
        raise ValueError(f"Expected a start pose of shape ({arm.n_joints},), got {q_cmd.shape}")
    q_cmd = np.clip(q_cmd, lower, upper)
    # the tick's arithmetic runs on plain floats: on a handful of joints numpy's per-call overhead costs more
    # than the math, and on a bus that time sits between the last reply and the next write
    bounds = tuple(zip(lower.tolist(), upper.tolist(), strict=True))  # per joint (lo, hi) rad
    vsteps = vstep.tolist()
    q = q_cmd.tolist()  # the commanded pose as floats; q_cmd is its array, a new one every tick
    zero = [0.0] * arm.n_joints
    velocity = zero  # of the commanded pose, rad per slot
    first = (source.start(q_cmd) or 0) if hasattr(source, "start") else 0
    if first > 0:
        raise ValueError(f"Expected the source's first slot <= 0, got {first}")
    # the lead-in (slots < 0) is counted apart: until slot 0, max_ticks is off and nothing is split
    boundary = 0 if first < 0 else sys.maxsize  # the slot where the lead-in ends
    max_ticks = None if first < 0 else cfg.max_ticks
    lead: tuple[int, int, int, int, float] | None = None  # ticks, overruns, skipped, holds, wall at slot 0

    err_l, sweeps_l, conv_l, clamp_l = st.errors, st.sweeps, st.converged, st.clamped
    vlim_l, comp_l, bus_l = st.velocity_limited, st.compute, st.bus
    overruns = skipped = holds = 0
    last_slot = first - 1
    next_progress = -math.inf  # progress_time of the next progress report: the first tick reports
    retries_seen = retries_before
    target = np.full(3, np.nan)  # held ticks report the last target
    present = None

    def finish(done: _Tick, present: np.ndarray | None, bus_time: float) -> None:
        """What needs the read-back of tick ``done``: its bus time and retries, observe, progress and record."""
        nonlocal retries_seen, next_progress
        bus_l.append(bus_time)
        retries = 0
        if bus is not None:
            retries_now = bus.status().retries
            retries, retries_seen = retries_now - retries_seen, retries_now
        if observe is not None:
            observe(done.slot, done.q_cmd, present)
        report = False
        if on_progress is not None:
            progress_now = done.ended if progress_time is None else progress_time()
            report = progress_now >= next_progress
        if on_tick is not None or report:
            slot = done.slot
            record = TickRecord(
                tick=slot,
                time=done.time,
                clip_time=clip_time(slot) if clip_time is not None else done.time,
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
            )
            if on_tick is not None:
                on_tick(record)
            if report:
                next_progress = progress_now + cfg.progress_every
                on_progress(record)  # type: ignore[misc]

    pending: _Tick | None = None  # pipeline: the tick whose read-back is on the wire
    pending_present: np.ndarray | None = None  # pipeline: that read-back, once collected
    in_flight = False  # pipeline: request_positions returned and collect_positions was not called since
    wall0 = wall_clip = perf()
    t0 = clock.now() - first * dt  # slot k starts at t0 + k * dt: slot `first` now
    k = first
    ticks = 0
    try:
        while (max_ticks is None or ticks < max_ticks) and not stop.is_set() and not finished(k):
            slot_time = k * dt
            clock.sleep_until(t0 + slot_time)
            c0 = perf()
            if k >= boundary:  # the first tick after the lead-in: from here on the counts are the clip's
                boundary = sys.maxsize
                lead = (ticks, overruns, skipped, holds, c0)
                wall_clip = c0
                max_ticks = None if cfg.max_ticks is None else cfg.max_ticks + ticks
            sample = target_at(k, slot_time)
            elapsed = k - last_slot
            limits = vsteps
            if sample is None:  # hold: no IK, the goals stay
                holds += 1
                velocity = zero
                error, sweeps, converged, vlimited, clamped = 0.0, 0, True, False, False
            else:
                if sample.__class__ is JointGoal:  # a pose in joint space: no IK
                    target = sample.target
                    goal = sample.q.tolist()
                    error, sweeps, converged, clamped = 0.0, 0, True, False
                    if sample.max_step is not None:
                        limits = [a if a < b else b for a, b in zip(vsteps, sample.max_step, strict=True)]
                else:
                    target, rotation, clamped = sample
                    # seed: where the commanded pose is heading at half its current speed (a full-speed
                    # prediction saves a few more sweeps but overshoots into joint-limit traps now and then)
                    lead_by = _LEAD * elapsed
                    seed = [
                        lo if (x := a + lead_by * v) < lo else hi if x > hi else x
                        for a, v, (lo, hi) in zip(q, velocity, bounds, strict=True)
                    ]
                    result = solve(target, array(seed), rotation)
                    goal = result.q.tolist()
                    error, sweeps, converged = result.error, result.iterations, result.converged
                # each joint's step limited to one slot's vstep, then the pose clamped to the limits; never
                # vstep * elapsed: after a stall (skipped slots) that would be one jump of the whole stall's
                # travel, which the servos then run at full speed.  The arm lags and catches up instead.
                vlimited = False
                q_next = []
                for x, x0, m, (lo, hi) in zip(goal, q, limits, bounds, strict=True):
                    d = x - x0
                    if d > m:
                        d, vlimited = m, True
                    elif d < -m:
                        d, vlimited = -m, True
                    y = x0 + d
                    q_next.append(lo if y < lo else hi if y > hi else y)
                velocity = [(x - x0) / elapsed for x, x0 in zip(q_next, q, strict=True)]  # rad per slot
                q = q_next
                q_cmd = array(q)
            c1 = perf()
            collect_time = 0.0
            if pipeline:  # the last tick's read-back (on the wire while this tick computed), then this tick's
                if in_flight:
                    in_flight = False
                    present = pending_present = bus.collect_positions()  # type: ignore[union-attr]
                    collect_time = perf() - c1
                bus.write_goals(q_cmd)  # type: ignore[union-attr]
                bus.request_positions()  # type: ignore[union-attr]
                in_flight = True
            elif bus is not None:
                bus.write_goals(q_cmd)
                present = bus.read_positions()
            c2 = perf() if bus is not None else c1
            last_slot = k
            # deadline: did this tick end after the next slot began?
            now = clock.now() - t0
            overrun = now > slot_time + dt
            next_k = k + 1
            if overrun:
                overruns += 1
                next_k = max(k + 1, math.floor(now / dt))
                skipped += next_k - k - 1
            err_l.append(error)
            sweeps_l.append(sweeps)
            conv_l.append(converged)
            clamp_l.append(clamped)
            vlim_l.append(vlimited)
            comp_l.append(c1 - c0)
            tick = _Tick(k, slot_time, target, q_cmd, error, sweeps, converged, clamped, vlimited, overrun, c1 - c0, c2)
            if pipeline:
                done, pending = pending, tick._replace(bus_time=c2 - c1 - collect_time)
                done_present, pending_present = pending_present, None
                if done is not None:
                    finish(done, done_present, done.bus_time + collect_time)
            else:
                finish(tick, present, c2 - c1)
            k = next_k
            ticks += 1
        if pending is not None:  # the last tick's read-back
            in_flight = False
            c1 = perf()
            present = bus.collect_positions()  # type: ignore[union-attr]
            done, pending = pending, None
            finish(done, present, done.bus_time + perf() - c1)
        st.interrupted = stop.is_set()
    except KeyboardInterrupt:
        st.interrupted = True
        log.info("interrupted at tick %d", k)
        if pending is not None:  # its goals went out: record it, with its read-back if that is still to collect
            try:
                present = pending_present
                if in_flight:
                    in_flight = False
                    present = bus.collect_positions()  # type: ignore[union-attr]
                finish(pending, present, pending.bus_time)
            except (KeyboardInterrupt, RetargetError) as exc:
                log.info("the last tick's record is lost: %r", exc)
    wall1 = perf()
    st.last_slot = last_slot
    if first < 0:  # split the lead-in's ticks off the series and counters
        if lead is None:  # it never reached slot 0 (a tick interrupted in its callbacks is in the series)
            lead = (len(err_l), overruns, skipped, holds, wall1)
        n_lead, lead_overruns, lead_skipped, lead_holds, wall_clip = lead
        for series in (err_l, sweeps_l, conv_l, clamp_l, vlim_l, comp_l, bus_l):
            del series[:n_lead]
        overruns, skipped, holds = overruns - lead_overruns, skipped - lead_skipped, holds - lead_holds
        st.lead_in_slots, st.lead_in_ticks = -first, n_lead
        st.lead_in_time = (min(last_slot, -1) - first + 1) / cfg.rate
        st.lead_in_wall_time = wall_clip - wall0
    st.wall_time = wall1 - wall_clip
    st.overruns, st.skipped, st.holds = overruns, skipped, holds
    st.q_cmd, st.q_present = q_cmd, present
    if bus is not None:
        status1 = bus.status()
        st.bus_errors = status1.errors - status0.errors
        st.bus_retries = status1.retries - retries_before
    return st


class _Tick(NamedTuple):
    """What :func:`run_ticks` keeps of a tick until its read-back is in (see ``finish``)."""

    slot: int
    time: float
    target: np.ndarray
    q_cmd: np.ndarray
    error: float
    sweeps: int
    converged: bool
    clamped: bool
    velocity_limited: bool
    overrun: bool
    compute_time: float
    ended: float  #: perf_counter when its bus calls returned
    bus_time: float = 0.0  #: pipeline: seconds of its write and request


def run_on_bus(loop: ControlLoop, bus: Bus) -> RunSummary:
    """Connect ``bus``, run ``loop`` on it and always close it (its shutdown sequence runs even on Ctrl-C)."""
    with connected(bus):
        return loop.run(bus)
