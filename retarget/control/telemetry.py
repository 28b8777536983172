"""Per-tick telemetry as CSV, one row per control tick, flushed as it goes (a crash loses nothing).

Columns (units in the names; angles radians, lengths metres or millimetres,
times seconds or milliseconds; flags 0/1)::

    time_s, clip_time_s, tick, target_x_m, target_y_m, target_z_m,
    <joint>_cmd_rad ...,  <joint>_present_rad ...,
    ik_error_mm, tracking_mm, filter_mm, ik_sweeps, ik_converged, tick_ms, compute_ms, bus_ms,
    clamped, velocity_limited, overrun, bus_retries, lead_in, stale, blocked, min_clearance_mm

``target_*`` is the target the loop steered to (after the target filter and the workspace clamp).
``tracking_mm`` is the tracking error: the mapped target (unfiltered, clamped) to the commanded tool point, FK of
the ``_cmd_rad`` goals (:mod:`~retarget.control.tracking`), apart from ``ik_error_mm`` (the IK solution to the
target steered to); ``filter_mm`` is how far the filter moved the target steered to from the mapped one.  Both
are empty without a ``tracking`` measure (and on lead-in rows, and before a live run's first target).
``<joint>_present_rad`` is empty in a dry run (no bus, nothing was read).  ``lead_in`` is 1 on
the rows of the lead-in to the clip's first pose that a replay on a bus runs before the clip
(their ``time_s`` and ``tick`` are negative, ``clip_time_s`` is the clip's start, no IK ran:
``ik_sweeps`` 0, and the target is the clip's first).  ``stale`` counts the servos whose read-back missed
that tick after the bus's retries (0: every reading is fresh); their ``_present_rad`` is the last one read.
``blocked`` is 1 when the tick's goal collided and was not written (the arm held the last goal);
``min_clearance_mm`` is the least clearance of the motion written that tick (empty without a collision model).
With ``gripper=True`` three columns follow: ``gripper_cmd`` (closure commanded, 0 open .. 1 closed),
``gripper_present_rad`` (the last reading of its shaft, read every watch period) and ``gripper_current_a``
(its Present Current, A; on XL430 the Present Load fraction); empty before the first command or reading.

    with TelemetryWriter("run.csv", arm.joint_names) as telemetry:
        ControlLoop(arm, targets, on_tick=telemetry).run(bus)
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Sequence
from typing import IO

from retarget.control.loop import TickRecord

#: one tick's (tracking error, filter deviation) in metres, nan for none (``tracking.TickTracker``)
Tracking = Callable[[TickRecord], tuple[float, float]]

__all__ = ["TelemetryWriter", "telemetry_columns"]

FLAG_COLUMNS = ("clamped", "velocity_limited", "overrun", "bus_retries", "lead_in", "stale", "blocked",
                "min_clearance_mm")  # fmt: skip


GRIPPER_COLUMNS = ("gripper_cmd", "gripper_present_rad", "gripper_current_a")


def telemetry_columns(joint_names: Sequence[str], *, gripper: bool = False) -> list[str]:
    """The header of a telemetry CSV for an arm with these joints (and ``GRIPPER_COLUMNS`` with ``gripper``)."""
    return [
        "time_s",
        "clip_time_s",
        "tick",
        "target_x_m",
        "target_y_m",
        "target_z_m",
        *(f"{name}_cmd_rad" for name in joint_names),
        *(f"{name}_present_rad" for name in joint_names),
        "ik_error_mm",
        "tracking_mm",
        "filter_mm",
        "ik_sweeps",
        "ik_converged",
        "tick_ms",
        "compute_ms",
        "bus_ms",
        *FLAG_COLUMNS,
        *(GRIPPER_COLUMNS if gripper else ()),
    ]


class TelemetryWriter:
    """Writes :class:`~retarget.control.loop.TickRecord` rows to ``target`` (a path, or an open text stream).

    A context manager; callable, so it can be passed as ``on_tick``.  A path is
    opened (truncated) on ``__enter__``/``open()``; a stream is left open on close.  ``tracking`` fills the
    ``tracking_mm`` and ``filter_mm`` columns (None: empty).
    """

    def __init__(
        self,
        target: str | os.PathLike[str] | IO[str],
        joint_names: Sequence[str],
        *,
        gripper: bool = False,
        tracking: Tracking | None = None,
    ):
        self.target = target
        self.tracking = tracking
        self.joint_names = tuple(joint_names)
        self.gripper = gripper
        self.columns = telemetry_columns(self.joint_names, gripper=gripper)
        self.rows = 0
        self._file: IO[str] | None = None
        self._owns = False
        self._blank = ",".join([""] * len(self.joint_names))

    def open(self) -> TelemetryWriter:
        """Open the file (a path) and write the header; a no-op when open."""
        if self._file is not None:
            return self
        target = self.target
        if isinstance(target, str | os.PathLike):
            file: IO[str] = open(target, "w", newline="", encoding="utf-8")  # noqa: SIM115 (closed in close())
            self._owns = True
        else:
            file = target
        file.write(",".join(self.columns) + "\n")
        file.flush()
        self._file = file
        return self

    def close(self) -> None:
        if self._file is None:
            return
        try:
            self._file.flush()
            if self._owns:
                self._file.close()
        finally:
            self._file = None

    def __enter__(self) -> TelemetryWriter:
        return self.open()

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __call__(self, record: TickRecord) -> None:
        self.write(record)

    def write(self, r: TickRecord) -> None:
        """Append one row and flush it."""
        if self._file is None:
            raise ValueError("Expected an open TelemetryWriter, got a closed one (use it as a context manager)")
        target = ",".join(f"{v:.6f}" for v in r.target)
        cmd = ",".join(f"{v:.6f}" for v in r.q_cmd)
        present = self._blank if r.q_present is None else ",".join(f"{v:.6f}" for v in r.q_present)
        clearance = "" if math.isnan(r.min_clearance) else f"{r.min_clearance * 1e3:.3f}"
        tracking = self._tracking_cells(r)
        self._file.write(
            f"{r.time:.6f},{r.clip_time:.6f},{r.tick},{target},{cmd},{present},"
            f"{r.ik_error * 1e3:.4f},{tracking},{r.ik_sweeps},{int(r.ik_converged)},"
            f"{(r.compute_time + r.bus_time) * 1e3:.4f},{r.compute_time * 1e3:.4f},{r.bus_time * 1e3:.4f},"
            f"{int(r.clamped)},{int(r.velocity_limited)},{int(r.overrun)},{r.bus_retries},{int(r.lead_in)},{r.stale},"
            f"{int(r.blocked)},{clearance}{self._gripper_cells(r)}\n"
        )
        self._file.flush()
        self.rows += 1

    def _tracking_cells(self, r: TickRecord) -> str:
        if self.tracking is None:
            return ","
        return ",".join("" if math.isnan(v) else f"{v * 1e3:.4f}" for v in self.tracking(r))

    def _gripper_cells(self, r: TickRecord) -> str:
        if not self.gripper:
            return ""
        cells = (r.gripper_cmd, r.gripper_present, r.gripper_current)
        return "".join("," if math.isnan(v) else f",{v:.6f}" for v in cells)
