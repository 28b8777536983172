"""The tick loop's figures: per-tick series and counters, with a lead-in's ticks kept apart from the clip's.

A :class:`TickSeries` holds one phase's ticks.  :class:`StatsRecorder` puts each tick of slot < 0 (a
lead-in, before the run's clock starts) into one and the ticks of slots >= 0 into the run's
:class:`TickStats`, which is a :class:`TickSeries` too, plus the run's totals; the lead-in only leaves its
counts there (``lead_in_*``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from retarget.control.summary import RunSummary, summarize

if TYPE_CHECKING:
    from retarget.control.tracking import Following

__all__ = ["StatsRecorder", "TickSeries", "TickStats"]


@dataclass
class TickSeries:
    """Per-tick series (one entry per tick that ran) and counters of one phase of a run.

    Errors metres, times real seconds.
    """

    errors: list[float] = field(default_factory=list)  #: IK error, metres (0 without IK)
    sweeps: list[int] = field(default_factory=list)  #: IK sweeps
    converged: list[bool] = field(default_factory=list)
    clamped: list[bool] = field(default_factory=list)  #: the target was pulled into the workspace
    velocity_limited: list[bool] = field(default_factory=list)  #: a joint's step was cut
    compute: list[float] = field(default_factory=list)  #: target + IK + step limit
    bus: list[float] = field(default_factory=list)  #: the tick's bus calls (pipelined: its collect too, later)
    holds: int = 0  #: ticks that held the pose (the source had no target; no IK ran)
    overruns: int = 0  #: ticks that ended after the next slot began
    skipped: int = 0  #: slots skipped after those overruns
    blocked: int = 0  #: ticks whose goal collided and was not written (the arm held); needs a collision model
    min_clearance: float = math.inf  #: metres, the least clearance of the motion written (inf: not checked)
    ik_blocked: int = 0  #: ticks whose IK ended short of the target at the nearest clear pose (not converged)

    def note_clearance(self, metres: float) -> None:
        """A tick wrote a motion whose min clearance is ``metres``."""
        if metres < self.min_clearance:
            self.min_clearance = metres

    def add(
        self,
        error: float,
        sweeps: int,
        converged: bool,
        clamped: bool,
        velocity_limited: bool,
        compute: float,
        bus: float,
        overrun: bool,
        skipped: int,
    ) -> int:
        """Append one tick (``skipped``: the slots its overrun skipped); returns its index in the series."""
        if overrun:
            self.overruns += 1
            self.skipped += skipped
        self.errors.append(error)
        self.sweeps.append(sweeps)
        self.converged.append(converged)
        self.clamped.append(clamped)
        self.velocity_limited.append(velocity_limited)
        self.compute.append(compute)
        self.bus.append(bus)
        return len(self.bus) - 1


@dataclass(kw_only=True)
class TickStats(TickSeries):
    """What one :func:`~retarget.control.loop.run_ticks` run did (times seconds, errors metres).

    The series, counters, ``wall_time`` and ``run_time`` cover the ticks of slots >= 0 (a clip's ticks);
    the lead-in's ticks (slots < 0) are counted apart in ``lead_in_*``.  ``bus_errors``/``bus_retries`` and
    the ``stale_*`` counts cover the whole run.
    """

    rate: float  #: ticks per second
    dry_run: bool
    interrupted: bool = False  #: ended by ``stop`` or Ctrl-C
    last_slot: int = -1  #: the slot of the last tick that sent its goals
    wall_time: float = 0.0  #: real seconds of the clip's ticks
    bus_errors: int = 0
    bus_retries: int = 0
    stale_reads: int = 0  #: servo reads that came back stale (the servo's last position stood in)
    stale_ticks: int = 0  #: read-backs with at least one stale servo
    bus_reboots: int = 0  #: servos rebooted after a hardware error (recover=True), whole run
    late_packets: int = 0  #: status packets that came too late and were dropped, whole run
    worst_stale: int = 0  #: the longest run of consecutive stale reads of one servo (since the bus connected)
    q_cmd: npt.NDArray[np.float64] | None = None  #: the last goals sent ``(n_joints,)`` rad
    q_present: npt.NDArray[np.float64] | None = None  #: the last positions read ``(n_joints,)`` rad
    lead_in_slots: int = 0  #: slots the source's lead-in planned (``-first slot``)
    lead_in_ticks: int = 0  #: lead-in ticks that ran
    lead_in_time: float = 0.0  #: loop-clock seconds of the lead-in slots that ran (at most ``lead_in_slots / rate``)
    lead_in_wall_time: float = 0.0  #: real seconds the lead-in took
    lead_in_blocked: int = 0  #: lead-in ticks whose goal was blocked
    collision_checked: bool = False  #: the goals were checked against a collision model
    lead_in_min_clearance: float = math.inf  #: metres, the lead-in's least clearance

    @property
    def ticks(self) -> int:
        """Ticks of slots >= 0 that ran."""
        return len(self.errors)

    @property
    def run_time(self) -> float:
        """Loop-clock seconds from the first slot to the end of the last one."""
        return (self.last_slot + 1) / self.rate if self.last_slot >= 0 else 0.0

    def summary(
        self, *, arm: str, clip: str, frames: int, duration_s: float, following: Following | None = None
    ) -> RunSummary:
        """The run's :class:`~retarget.control.summary.RunSummary` (``frames``/``duration_s``: what was played;
        ``following``: how the arm followed, :func:`~retarget.control.tracking.following`)."""
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
            stale_reads=self.stale_reads,
            stale_ticks=self.stale_ticks,
            worst_stale_ticks=self.worst_stale,
            bus_reboots=self.bus_reboots,
            late_packets=self.late_packets,
            lead_in_ticks=self.lead_in_ticks,
            lead_in_s=self.lead_in_time,
            blocked_ticks=self.blocked + self.lead_in_blocked if self.collision_checked else None,
            ik_blocked_ticks=self.ik_blocked if self.collision_checked else None,
            min_clearance_m=min(self.min_clearance, self.lead_in_min_clearance) if self.collision_checked else None,
            following=following,
        )


class StatsRecorder:
    """Records a run's ticks into the lead-in's :class:`TickSeries` (slots < 0) or the clip's :class:`TickStats`.

    ``first`` is the run's first slot (``-n`` for an ``n``-slot lead-in), ``wall0`` the real time
    (``time.perf_counter``) it started at.  The clip's wall time starts with its first tick (with a lead-in),
    else at ``wall0``.

    >>> recorder = StatsRecorder(rate=100.0, dry_run=True, first=-2, wall0=0.0)
    >>> for slot in (-2, -1, 0):
    ...     recorder.begin(slot, now=1.0 + slot)
    ...     _ = recorder.series.add(0.0, 0, True, False, False, 1e-4, 0.0, False, 0)
    >>> stats = recorder.finish(wall1=5.0, last_slot=0)
    >>> stats.ticks, stats.lead_in_ticks, stats.wall_time, stats.lead_in_wall_time
    (1, 2, 4.0, 1.0)
    """

    def __init__(self, *, rate: float, dry_run: bool, first: int, wall0: float):
        self.stats = TickStats(rate=rate, dry_run=dry_run)
        self.lead_in = TickSeries()
        self.series: TickSeries = self.lead_in if first < 0 else self.stats  #: the phase of the running tick
        self.first = first
        self.wall0 = self.wall_clip = wall0

    @property
    def clip_ticks(self) -> int:
        """Ticks of slots >= 0 so far."""
        return len(self.stats.errors)

    def begin(self, slot: int, now: float) -> None:
        """A tick of ``slot`` begins at real time ``now``: the first of slot >= 0 ends the lead-in."""
        if slot >= 0 and self.series is self.lead_in:
            self.series = self.stats
            self.wall_clip = now

    def add_bus_time(self, slot: int, row: int, seconds: float) -> float:
        """Add ``seconds`` to the bus time of the tick of ``slot`` at ``row`` of its series; returns the total."""
        bus = (self.lead_in if slot < 0 else self.stats).bus
        bus[row] += seconds
        return bus[row]

    def finish(self, *, wall1: float, last_slot: int) -> TickStats:
        """The run's :class:`TickStats`, the run having ended at real time ``wall1`` after ``last_slot``."""
        st, first = self.stats, self.first
        st.last_slot = last_slot
        if first < 0:
            if self.series is self.lead_in:  # it never reached slot 0
                self.wall_clip = wall1
            st.lead_in_slots, st.lead_in_ticks = -first, len(self.lead_in.errors)
            st.lead_in_time = (min(last_slot, -1) - first + 1) / st.rate
            st.lead_in_wall_time = self.wall_clip - self.wall0
            st.lead_in_blocked, st.lead_in_min_clearance = self.lead_in.blocked, self.lead_in.min_clearance
        st.wall_time = wall1 - self.wall_clip
        return st
