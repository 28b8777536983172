"""The summary of a rig's run: the rig's ticks and timing, and how each arm followed its own hand.

:class:`RigSummary` holds one :class:`~retarget.control.summary.RunSummary` for the rig (tick times, bus
counters, overruns, blocked goals and the least clearance: shared by the arms, which tick together) and one per
arm: the rig's counters with that arm's IK outcome, velocity-limited ticks (from its own commanded speeds), tracking
error and joint accelerations.  ``to_dict`` is the ``--json`` form: ``{"rig": {...}, "arms": {"left": {...}}}``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from retarget.control.summary import RunSummary

__all__ = ["RigSummary"]


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
