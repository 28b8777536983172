"""The summary of a rig's run: the rig's ticks and timing, and how each arm followed its own hand.

:class:`RigSummary` holds one :class:`~retarget.control.summary.RunSummary` for the rig (tick times, bus
counters, overruns, blocked goals and the least clearance: shared by the arms, which tick together) and one per
arm: the rig's counters with that arm's IK outcome, velocity-limited ticks (from its own commanded speeds), tracking
error and joint accelerations.  ``to_dict`` is the ``--json`` form: ``{"rig": {...}, "arms": {"left": {...}}}``.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np

from retarget.control.loop import TickRecord
from retarget.control.stats import TickStats
from retarget.control.summary import RunSummary
from retarget.control.tracking import Trajectory, following

if TYPE_CHECKING:
    from retarget.rig.replay import RigReplay

__all__ = ["RigSummary", "summarize_rig"]


@dataclass(frozen=True)
class RigSummary:
    """A rig run's summary: ``rig`` (shared ticks, timing, bus and collision counters) and ``arms`` (by arm name)."""

    rig: RunSummary
    arms: dict[str, RunSummary]

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready dict: ``{"rig": {...}, "arms": {name: {...}}}``."""
        return {"rig": self.rig.to_dict(), "arms": {name: s.to_dict() for name, s in self.arms.items()}}

    def format(self) -> str:
        """Human text for stderr: the rig's summary, then one IK and following line per arm."""
        lines = [self.rig.format()]
        for name, s in self.arms.items():
            tracking = "" if s.tracking_p95_mm is None else (
                f", tracking p95 {s.tracking_p95_mm:.1f} mm (max {s.tracking_max_mm:.1f}), "
                f"acceleration peak {s.accel_peak_rad_s2:.1f} rad/s^2"
            )  # fmt: skip
            lines.append(
                f"  {name}: IK {s.ik_converged_pct:.1f}% converged (p95 {s.ik_error_p95_mm:.2f} mm){tracking}; "
                f"velocity-limited {s.velocity_limited_ticks} ticks"
            )
        return "\n".join(lines)


def summarize_rig(replay: RigReplay, ticks: TickStats, records: list[TickRecord], *, duration_s: float) -> RigSummary:
    """The summary of ``replay``'s run that ended with ``ticks``, from its tick ``records`` (the rig's)."""
    rig = ticks.summary(arm=replay.rig.name, clip=replay.clip_name, frames=replay.frames, duration_s=duration_s)
    clip = [r for r in records if not r.lead_in]
    rate = replay.config.rate
    arms = {}
    for a, part in zip(replay.rig.arms, replay.plant.slices, strict=True):
        own = [replay.arm_record(r, a.name) for r in clip]
        trajectory = Trajectory()
        for r in own:
            trajectory(r)
        err_mm = np.array([r.ik_error for r in own]) * 1e3
        q = np.array([r.q_cmd for r in own]).reshape(len(own), -1)
        speeds = np.abs(np.diff(q, axis=0)) * rate
        limited = int(np.count_nonzero(np.any(speeds >= 0.999 * replay.plant.max_velocity[part], axis=1)))
        n = len(own)
        summary = replace(
            rig,
            arm=f"{a.name} ({a.arm.name})",
            ik_converged_pct=100.0 * sum(r.ik_converged for r in own) / n if n else 0.0,
            ik_error_median_mm=float(np.median(err_mm)) if n else 0.0,
            ik_error_p95_mm=float(np.percentile(err_mm, 95)) if n else 0.0,
            ik_error_max_mm=float(err_mm.max()) if n else 0.0,
            ik_sweeps_mean=float(np.mean([r.ik_sweeps for r in own])) if n else 0.0,
            velocity_limited_ticks=limited,
        )
        reference = replay.targets.arms[a.name].reference
        arms[a.name] = summary.with_following(following(a.arm, trajectory, rate=rate, reference=reference))
    return RigSummary(rig=rig, arms=arms)
