"""The fixed-rate tick loop shared by clip replay and teleop: :func:`run_ticks`.

It asks a :class:`TargetSource` for each tick's target: ``retarget.control.ControlLoop`` plays a clip
through a ``ClipSource``; ``retarget.teleop.follower`` follows targets that arrive while the arm moves.  Each tick
``k`` has a slot on the loop's clock, ``t0 + k / rate``.  In its slot a tick:

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

A source may also give a tick a :class:`JointGoal` (a pose in joint space): the
tick then runs no IK (0 sweeps) and steps 3-5 move toward that pose.

**Pipelined read-back** (``run_ticks(pipeline=True)``; ``ControlLoop``'s default): step 5 is split in
two.  ``bus.request_positions()`` sends the read right after the write, and the next tick collects it with
``bus.collect_positions()`` after its own steps 1-3, just before its write.  The host computes while the
status packets are on the wire instead of leaving the wire idle while it computes: on a bus-bound loop
(1 Mbps, six servos: 1.06 ms of wire time per tick) that takes the loop from 88-91 % of the wire rate
to 93-96 % (``bench/bench_replay.py``).  The wire carries the same packets in the same order (write k,
read k, write k+1, ...) and nothing depends on the read-back: IK starts from the commanded pose.  A tick's
record (``on_tick``, ``on_progress``) then comes a tick later, once its read-back is in; the last one
after the loop.  Not for a source with ``observe`` (it must see tick ``k`` before choosing tick ``k + 1``).

It is deadline-aware: a tick that ends after the next slot's deadline counts
as an overrun, and the loop resumes at the slot the clock is in (skipping the
missed ones) instead of running late for ever after, so delays never
accumulate as drift.  The clock is injected: :class:`~retarget.clock.MonotonicClock`
for real time, one :class:`~retarget.clock.VirtualClock` shared with the
simulator for ``--fast`` runs.  ``bus=None`` is a dry run: everything but the
bus.  A ``stop`` event ends the run at the next tick boundary, and a
``KeyboardInterrupt`` raised inside a tick (e.g. by a telemetry callback) ends
it too; either way the stats say ``interrupted``.

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

from retarget.control.summary import RunSummary, summarize
from retarget.errors import ConfigError

if TYPE_CHECKING:
    from retarget.arm.model import Arm
    from retarget.control.bus import Bus
    from retarget.control.clock import Clock
    from retarget.ik.ccd import CCDSolver

__all__ = ["JointGoal", "LoopConfig", "TargetSource", "TickRecord", "TickStats", "run_ticks"]

log = logging.getLogger(__name__)

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

    def finish(done: _Tick, present: np.ndarray | None, collect_time: float) -> None:
        """What needs the read-back of tick ``done``: the time it took to collect (pipelined; added to the
        tick's bus time), its retries, observe, progress and record."""
        nonlocal retries_seen, next_progress
        bus_l[done.index] += collect_time
        bus_time = bus_l[done.index]
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
            bus_l.append(c2 - c1 - collect_time)  # pipelined: its write and request; the collect is added later
            tick = _Tick(
                len(bus_l) - 1,
                k,
                slot_time,
                target,
                q_cmd,
                error,
                sweeps,
                converged,
                clamped,
                vlimited,
                overrun,
                c1 - c0,
                c2,
            )
            if pipeline:
                done, pending = pending, tick
                done_present, pending_present = pending_present, None
                if done is not None:
                    finish(done, done_present, collect_time)
            else:
                finish(tick, present, 0.0)
            k = next_k
            ticks += 1
        if pending is not None:  # the last tick's read-back
            in_flight = False
            c1 = perf()
            present = bus.collect_positions()  # type: ignore[union-attr]
            done, pending = pending, None
            finish(done, present, perf() - c1)
        st.interrupted = stop.is_set()
    except KeyboardInterrupt:
        st.interrupted = True
        log.info("interrupted at tick %d", k)
        if pending is not None:  # its goals went out: record it, with its read-back if that is still to collect
            present = pending_present
            # in flight with its own read-back already in: the read is the next tick's (Ctrl-C came before that
            # tick was kept), which no record claims; the bus's close waits for its replies
            if in_flight and pending_present is None:
                in_flight = False
                try:
                    present = bus.collect_positions()  # type: ignore[union-attr]
                except (KeyboardInterrupt, Exception) as exc:  # noqa: BLE001 - the run is ending: report, go on
                    present = None
                    log.warning("tick %d: its read-back is lost: %s", pending.slot, str(exc) or type(exc).__name__)
            try:
                finish(pending, present, 0.0)
            except KeyboardInterrupt:
                log.info("tick %d: its record was cut short", pending.slot)
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

    index: int  #: of the tick in the TickStats series
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
