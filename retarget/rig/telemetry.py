"""A rig run's telemetry: one CSV row per tick, the rig's columns first, then every arm's prefixed by its name.

Columns (units in the names, as in :mod:`retarget.control.telemetry`)::

    time_s, clip_time_s, tick, tick_ms, compute_ms, bus_ms, overrun, lead_in, blocked, min_clearance_mm,
    then per arm, e.g. left/:
    left/target_x_m, left/target_y_m, left/target_z_m, left/<joint>_cmd_rad ..., left/<joint>_present_rad ...,
    left/ik_error_mm, left/ik_converged, left/tracking_mm

``blocked`` and ``min_clearance_mm`` are the rig's (the arms move together: a goal is written for all or none);
``<arm>/target_*`` is that arm's target in its base frame; ``<arm>/tracking_mm`` its tracking error (the mapped
target, unfiltered, to the commanded tool point); ``_present_rad`` is empty in a dry run.  Each row is flushed
as it goes.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from typing import IO, Protocol

from retarget.control.loop import TickRecord
from retarget.control.tracking import TickTracker
from retarget.rig.replay import RigReplay
from retarget.rig.spec import Rig

__all__ = ["RigTelemetry", "rig_columns"]

_RIG = ("time_s", "clip_time_s", "tick", "tick_ms", "compute_ms", "bus_ms", "overrun", "lead_in", "blocked",
        "min_clearance_mm")  # fmt: skip


class RigRecords(Protocol):
    """What the telemetry reads of a rig run: its rig and each arm's part of a tick's record (a :class:`RigReplay`,
    or a teleop's :class:`~retarget.rig.teleop.RigTeleopRecords`)."""

    @property
    def rig(self) -> Rig: ...

    def arm_record(self, record: TickRecord, name: str) -> TickRecord: ...


def rig_columns(replay: RigRecords) -> list[str]:
    """The header of ``replay``'s telemetry CSV."""
    columns = list(_RIG)
    for a in replay.rig.arms:
        p = f"{a.name}/"
        columns += [f"{p}target_x_m", f"{p}target_y_m", f"{p}target_z_m"]
        columns += [f"{p}{j}_cmd_rad" for j in a.arm.joint_names] + [f"{p}{j}_present_rad" for j in a.arm.joint_names]
        columns += [f"{p}ik_error_mm", f"{p}ik_converged", f"{p}tracking_mm"]
    return columns


class RigTelemetry:
    """Writes a rig run's tick records to ``target`` (a path, or an open text stream); a context manager, and
    callable as ``on_tick``.  ``trackers``: each arm's tracking error, by arm name (default a replay's, against its
    clip's mapped targets).

    >>> import io
    >>> from retarget.bvh.parse import DEMO_CLIP, load_bvh
    >>> from retarget.control.clock import VirtualClock
    >>> from retarget.control.loop import LoopConfig
    >>> from retarget.rig import load_rig, rig_targets
    >>> rig = load_rig("wx250s-pair")
    >>> replay = RigReplay(rig, rig_targets(load_bvh(DEMO_CLIP), rig), config=LoopConfig(max_ticks=3),
    ...                    clock=VirtualClock())
    >>> text = io.StringIO()
    >>> with RigTelemetry(text, replay) as telemetry:
    ...     replay.on_tick = telemetry
    ...     _ = replay.run(None)
    >>> rows = text.getvalue().splitlines()
    >>> len(rows), rows[0].split(",")[10]
    (4, 'left/target_x_m')
    """

    def __init__(
        self,
        target: str | os.PathLike[str] | IO[str],
        replay: RigRecords,
        *,
        trackers: Mapping[str, TickTracker] | None = None,
    ):
        self.target, self.replay = target, replay
        self.columns = rig_columns(replay)
        if trackers is None:  # a clip's: its mapped targets by clip time
            if not isinstance(replay, RigReplay):
                raise TypeError("Expected each arm's tracker (trackers=) for a run that is not a RigReplay")
            trackers = {a.name: TickTracker.for_clip(a.arm, replay.targets.arms[a.name].reference)
                        for a in replay.rig.arms}  # fmt: skip
        self._trackers = dict(trackers)
        self._file: IO[str] | None = None
        self._owns = False

    def __enter__(self) -> RigTelemetry:
        if isinstance(self.target, str | os.PathLike):
            self._file = open(self.target, "w", newline="", encoding="utf-8")  # noqa: SIM115 (closed in __exit__)
            self._owns = True
        else:
            self._file = self.target
        self._file.write(",".join(self.columns) + "\n")
        self._file.flush()
        return self

    def __exit__(self, *exc: object) -> None:
        if self._file is not None:
            self._file.flush()
            if self._owns:
                self._file.close()
            self._file = None

    def __call__(self, r: TickRecord) -> None:
        if self._file is None:
            raise ValueError("Expected an open RigTelemetry, got a closed one (use it as a context manager)")
        cells = [f"{r.time:.6f}", f"{r.clip_time:.6f}", str(r.tick), f"{(r.compute_time + r.bus_time) * 1e3:.4f}",
                 f"{r.compute_time * 1e3:.4f}", f"{r.bus_time * 1e3:.4f}", str(int(r.overrun)), str(int(r.lead_in)),
                 str(int(r.blocked)), _mm(r.min_clearance)]  # fmt: skip
        for a in self.replay.rig.arms:
            own = self.replay.arm_record(r, a.name)
            present = [""] * a.arm.n_joints if own.q_present is None else [f"{v:.6f}" for v in own.q_present]
            tracking, _ = self._trackers[a.name](own)
            cells += [f"{v:.6f}" for v in own.target] + [f"{v:.6f}" for v in own.q_cmd] + present
            cells += [f"{own.ik_error * 1e3:.4f}", str(int(own.ik_converged)), _mm(tracking)]
        self._file.write(",".join(cells) + "\n")
        self._file.flush()


def _mm(metres: float) -> str:
    return "" if not math.isfinite(metres) else f"{metres * 1e3:.3f}"
