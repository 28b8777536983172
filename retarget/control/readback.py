"""The read-back of the present positions, inline or pipelined, and when a tick's record may go out.

A tick's record needs its read-back, so the read-back decides when to **report** a tick.  One interface,
:class:`ReadBack`, three ways:

- :class:`NoReadBack` (a dry run, no bus): no bus call; each tick is reported at once, without positions;
- :class:`InlineReadBack`: ``bus.write_goals`` then ``bus.read_positions`` within the tick; reported at once;
- :class:`PipelinedReadBack`: ``bus.write_goals`` then ``bus.request_positions()`` right after it; the next
  tick collects the reply after its own target, IK and step limit, just before its write, and only then reports
  the tick before (adding the collect's time to its bus time).  Collect, write and request are one
  ``bus.exchange`` (a rig's bus goes arm by arm in it), timed as one: the collect's time that goes to the tick
  before includes this tick's write and request, whose own bus time is then 0 (the total is the same).  The
  host computes while the status packets are on the wire instead of leaving the wire idle while it computes;
  the wire carries the same packets in the same order (write k, read k, write k + 1, ...).  The last tick's
  read-back is collected after the loop (:meth:`ReadBack.finish`); on Ctrl-C the tick whose goals went out is
  still reported (:meth:`ReadBack.interrupt`).
"""

from __future__ import annotations

import abc
import logging
import time
from collections.abc import Callable
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from retarget.control.bus import Bus

__all__ = ["InlineReadBack", "NoReadBack", "PipelinedReadBack", "ReadBack", "Report", "SentTick", "read_back_for"]

log = logging.getLogger(__name__)


class SentTick(NamedTuple):
    """What the loop keeps of a tick whose goals went out, until its read-back is in and it is reported."""

    row: int  #: the tick's index in its phase's series (see ``retarget.control.stats``)
    slot: int
    time: float  #: the slot's time since the run's start, loop clock
    target: npt.NDArray[np.float64]  #: ``(3,)`` metres
    q_cmd: npt.NDArray[np.float64]  #: ``(n_joints,)`` rad, the goals sent
    error: float  #: metres
    sweeps: int
    converged: bool
    clamped: bool
    velocity_limited: bool
    overrun: bool
    compute_time: float  #: real seconds
    bus_time: float  #: real seconds of its own bus calls (pipelined: its read-back's collect comes on top)
    ended: float  #: ``time.perf_counter`` when its bus calls returned
    blocked: bool = False  #: its goal collided and was not written (the last goal was sent again)
    min_clearance: float = float("nan")  #: metres, of the motion written (nan without a collision model)


#: Reports a tick: ``(tick, present positions (n_joints,) rad or None, seconds its read-back took to collect)``.
Report = Callable[[SentTick, npt.NDArray[np.float64] | None, float], None]


class ReadBack(abc.ABC):
    """The bus side of each tick: :meth:`send` its goals, :meth:`record` it once it is in the stats.

    ``present`` is the last positions read (None before the first, and in a dry run); ``ended`` the
    ``time.perf_counter`` at which the last :meth:`send`'s bus calls returned.
    """

    def __init__(self, report: Report):
        self.report = report
        self.present: npt.NDArray[np.float64] | None = None
        self.ended = 0.0

    @abc.abstractmethod
    def send(self, q_cmd: npt.NDArray[np.float64], started: float) -> float:
        """Send goals ``q_cmd`` (and read, or request the read); ``started`` is the ``perf_counter`` reading
        before.  Returns the real seconds of this tick's own bus calls."""

    def record(self, tick: SentTick) -> None:
        """``tick`` was sent and counted: report it now, or once its read-back is in."""
        self.report(tick, self.present, 0.0)

    def finish(self) -> None:
        """After the last tick: report what is still waiting for its read-back (here nothing waits)."""
        return None

    def interrupt(self) -> None:
        """On Ctrl-C: report the tick whose goals went out without a report, with its read-back if possible (here
        every tick was reported as it was recorded)."""
        return None


class NoReadBack(ReadBack):
    """A dry run: no bus, every tick reported at once without present positions."""

    def send(self, q_cmd: npt.NDArray[np.float64], started: float) -> float:
        self.ended = started
        return 0.0


class InlineReadBack(ReadBack):
    """``bus.write_goals`` then ``bus.read_positions`` within the tick; every tick reported at once."""

    def __init__(self, bus: Bus, report: Report):
        super().__init__(report)
        self.bus = bus

    def send(self, q_cmd: npt.NDArray[np.float64], started: float) -> float:
        self.bus.write_goals(q_cmd)
        self.present = self.bus.read_positions()
        self.ended = ended = time.perf_counter()
        return ended - started


class PipelinedReadBack(ReadBack):
    """``bus.write_goals`` then ``bus.request_positions``; the next tick collects the reply before its write and
    then reports the tick before.  See the module docstring."""

    def __init__(self, bus: Bus, report: Report):
        super().__init__(report)
        self.bus = bus
        self.pending: SentTick | None = None  #: the tick whose read-back is on the wire (or collected)
        self.collected: npt.NDArray[np.float64] | None = None  #: that read-back, once collected
        self.collect_time = 0.0  #: real seconds the last collect took
        self.in_flight = False  #: request_positions returned and collect_positions was not called since

    def send(self, q_cmd: npt.NDArray[np.float64], started: float) -> float:
        bus, perf = self.bus, time.perf_counter
        collect_time = 0.0
        if self.in_flight:  # the last tick's read-back, on the wire while this tick computed; then this tick's
            self.in_flight = False
            self.present = self.collected = bus.exchange(q_cmd)
            collect_time = perf() - started  # (this tick's write and request in it: see the module docstring)
        else:
            bus.write_goals(q_cmd)
            bus.request_positions()
        self.in_flight = True
        self.ended = ended = perf()
        self.collect_time = collect_time
        return ended - started - collect_time

    def record(self, tick: SentTick) -> None:
        done, self.pending = self.pending, tick
        present, self.collected = self.collected, None
        if done is not None:
            self.report(done, present, self.collect_time)

    def finish(self) -> None:
        if self.pending is None:
            return
        self.in_flight = False
        started = time.perf_counter()
        self.present = present = self.bus.collect_positions()
        done, self.pending = self.pending, None
        self.report(done, present, time.perf_counter() - started)

    def interrupt(self) -> None:
        """Its goals went out: report the pending tick, with its read-back if that is still to collect.  A read in
        flight while the pending tick's own read-back is already in belongs to the next tick (Ctrl-C came before
        it was counted), which no record claims; the bus's close waits for its replies."""
        pending = self.pending
        if pending is None:
            return
        present = self.collected
        if self.in_flight and present is None:
            self.in_flight = False
            try:
                present = self.bus.collect_positions()
            except (KeyboardInterrupt, Exception) as exc:  # noqa: BLE001 - the run is ending: report, go on
                present = None
                log.warning("tick %d: its read-back is lost: %s", pending.slot, str(exc) or type(exc).__name__)
        self.present = present
        try:
            self.report(pending, present, 0.0)
        except KeyboardInterrupt:
            log.info("tick %d: its record was cut short", pending.slot)


def read_back_for(bus: Bus | None, report: Report, *, pipeline: bool) -> ReadBack:
    """The read-back of a run on ``bus`` (None: a dry run), pipelined or inline."""
    if bus is None:
        return NoReadBack(report)
    return PipelinedReadBack(bus, report) if pipeline else InlineReadBack(bus, report)
