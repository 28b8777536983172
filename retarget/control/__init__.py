"""The control loop: a fixed-rate tick loop, clip replay on it, the ``Bus`` protocol, clocks, telemetry, summary.

- :mod:`~retarget.control.loop`: :func:`run_ticks`, one tick after another, :class:`LoopConfig`, :class:`TickRecord`;
  its parts: :mod:`~retarget.control.schedule` (slots, overruns), :mod:`~retarget.control.source` (what a
  :class:`TargetSource` answers, the :class:`TickSolver` it calls), :mod:`~retarget.control.limits` (the step
  limiter), :mod:`~retarget.control.readback` (inline or pipelined read-back), :mod:`~retarget.control.stats`;
- :mod:`~retarget.control.replay`: :class:`ControlLoop`, a clip played through the loop, with its lead-in;
- :mod:`~retarget.control.bus`: :class:`Bus`, the small protocol the loop drives (drivers and sim implement it);
- :mod:`~retarget.control.clock`: :class:`MonotonicClock` for real time, :class:`VirtualClock` for ``--fast`` runs;
- :mod:`~retarget.control.telemetry`: the per-tick CSV; :mod:`~retarget.control.summary`: the run's figures.
"""

from retarget.control.bus import Bus, BusStatus, ShutdownMode, close_after_failure, connected
from retarget.control.clock import Clock, MonotonicClock, VirtualClock
from retarget.control.limits import StepLimiter
from retarget.control.loop import LoopConfig, TickRecord, run_ticks
from retarget.control.readback import InlineReadBack, NoReadBack, PipelinedReadBack, ReadBack
from retarget.control.replay import ClipSource, ControlLoop, LeadIn, run_on_bus
from retarget.control.schedule import Schedule
from retarget.control.source import HOLD, JointGoal, TargetSource, TickGoal, TickSolver, TickTarget
from retarget.control.stats import StatsRecorder, TickSeries, TickStats
from retarget.control.summary import RunSummary, summarize
from retarget.control.telemetry import TelemetryWriter, telemetry_columns

__all__ = [
    "HOLD",
    "Bus",
    "BusStatus",
    "ClipSource",
    "Clock",
    "ControlLoop",
    "InlineReadBack",
    "JointGoal",
    "LeadIn",
    "LoopConfig",
    "MonotonicClock",
    "NoReadBack",
    "PipelinedReadBack",
    "ReadBack",
    "RunSummary",
    "Schedule",
    "ShutdownMode",
    "StatsRecorder",
    "StepLimiter",
    "TargetSource",
    "TelemetryWriter",
    "TickGoal",
    "TickRecord",
    "TickSeries",
    "TickSolver",
    "TickStats",
    "TickTarget",
    "VirtualClock",
    "close_after_failure",
    "connected",
    "run_on_bus",
    "run_ticks",
    "summarize",
    "telemetry_columns",
]
