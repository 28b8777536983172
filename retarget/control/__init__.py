"""The control loop: a fixed-rate tick loop, clip replay, the ``Bus`` protocol, clocks, telemetry and the summary.

- :mod:`~retarget.control.bus`: :class:`Bus`, the small protocol the loop drives (drivers and sim implement it);
- :mod:`~retarget.control.clock`: :class:`MonotonicClock` for real time, :class:`VirtualClock` for ``--fast`` runs;
- :mod:`~retarget.control.loop`: :func:`run_ticks`, one tick after another, and :class:`LoopConfig`;
- :mod:`~retarget.control.replay`: :class:`ControlLoop`, a clip played through the loop, with its lead-in;
- :mod:`~retarget.control.telemetry`: the per-tick CSV; :mod:`~retarget.control.summary`: the run's figures.
"""

from retarget.control.bus import Bus, BusStatus, ShutdownMode, close_after_failure, connected
from retarget.control.clock import Clock, MonotonicClock, VirtualClock
from retarget.control.loop import JointGoal, LoopConfig, TargetSource, TickRecord, TickStats, run_ticks
from retarget.control.replay import ClipSource, ControlLoop, LeadIn, run_on_bus
from retarget.control.summary import RunSummary, summarize
from retarget.control.telemetry import TelemetryWriter, telemetry_columns

__all__ = [
    "Bus",
    "BusStatus",
    "ClipSource",
    "Clock",
    "ControlLoop",
    "JointGoal",
    "LeadIn",
    "LoopConfig",
    "MonotonicClock",
    "RunSummary",
    "ShutdownMode",
    "TargetSource",
    "TelemetryWriter",
    "TickRecord",
    "TickStats",
    "VirtualClock",
    "close_after_failure",
    "connected",
    "run_on_bus",
    "run_ticks",
    "summarize",
    "telemetry_columns",
]
