"""The summary of one control-loop run: what was played, how well IK tracked it, how the bus and timing behaved.

:func:`summarize` builds a :class:`RunSummary` from per-tick arrays;
``RunSummary.format()`` is the human text the CLI prints on stderr and
``RunSummary.to_dict()`` the ``--json`` document on stdout.  Times in the
dict carry their unit in the key (``_s``, ``_ms``, ``_mm``, ``_hz``).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace
from typing import TYPE_CHECKING, Any, TypedDict

import numpy as np

if TYPE_CHECKING:
    from retarget.control.tracking import Following

__all__ = ["RunSummary", "summarize"]


@dataclass(frozen=True)
class RunSummary:
    """Counters and percentiles of one run (see the module docstring for units)."""

    arm: str
    clip: str
    dry_run: bool
    interrupted: bool
    frames: int  #: clip frames covered by the played window (start..end)
    duration_s: float  #: clip seconds covered by the ticks that ran
    ticks: int  #: ticks that ran
    rate_hz: float  #: the requested tick rate
    run_time_s: float  #: time on the loop's clock from the first to the last tick's slot end
    wall_time_s: float  #: real seconds the loop took
    real_time_factor: float  #: run_time_s / wall_time_s (1.0 = real time; > 1 faster, e.g. --fast)
    ik_converged_pct: float
    ik_error_median_mm: float
    ik_error_p95_mm: float
    ik_error_max_mm: float
    ik_sweeps_mean: float
    clamped_ticks: int  #: ticks whose target was pulled into the workspace
    velocity_limited_ticks: int  #: ticks where a joint's step was cut to its velocity limit
    bus_errors: int
    bus_retries: int
    tick_ms_p50: float  #: compute + bus, real time
    tick_ms_p99: float
    tick_ms_max: float
    compute_ms_p50: float  #: mapping lookup + IK + bookkeeping, real time
    compute_ms_p99: float
    bus_ms_p50: float  #: write_goals + read_positions, real time
    overruns: int  #: ticks that ended after the next tick's deadline
    skipped_ticks: int  #: schedule slots dropped to catch up after overruns (no drift)
    #: the lead-in on a bus, before the clip's clock starts (not counted in anything above but bus errors/retries)
    lead_in_ticks: int = 0
    lead_in_s: float = 0.0  #: loop-clock seconds of the lead-in
    #: servo reads that missed after the retries (the servo's last position stood in), whole run
    stale_reads: int = 0
    stale_ticks: int = 0  #: read-backs with at least one stale servo, whole run
    worst_stale_ticks: int = 0  #: the longest run of consecutive stale reads of one servo
    bus_reboots: int = 0  #: servos rebooted and configured again after a hardware error (--recover), whole run
    late_packets: int = 0  #: status packets that came after their read timed out, dropped, whole run
    #: goals that collided (within the clearance, or on the way from the last goal) and were not written, whole
    #: run (lead-in included); None: no collision model
    blocked_ticks: int | None = None
    min_clearance_mm: float | None = None  #: the least clearance of the motion written, whole run; None: no model
    #: ticks whose IK stopped short at the nearest clear pose (counted as not converged); None: no model
    ik_blocked_ticks: int | None = None
    pushed_targets: int | None = None  #: clip frames whose target was pushed out of a blocked zone; None: no model
    #: what drove the gripper: "pinch" (thumb tip to index tip), "curl" (fingertips to wrist) of the clip's hand,
    #: "fixed 0.5", "csv FILE"; None: not driven
    gripper: str | None = None
    #: how the arm follows (:mod:`~retarget.control.tracking`; None: not measured): the tracking error, mm from
    #: the mapped target (unfiltered) to the commanded tool point, FK of the goals sent, apart from the IK error
    tracking_median_mm: float | None = None
    tracking_p95_mm: float | None = None
    tracking_max_mm: float | None = None
    #: mm, the targets the loop steered to from the mapped ones: the target filter (and the workspace clamp); in
    #: teleop the speed-limited setpoint too
    filter_p95_mm: float | None = None
    filter_max_mm: float | None = None
    accel_peak_rad_s2: float | None = None  #: the commanded joint acceleration, peak over joints and ticks
    accel_rms_rad_s2: float | None = None  #: its root mean square over joints and ticks
    jerk_peak_rad_s3: float | None = None  #: the commanded joint jerk
    jerk_rms_rad_s3: float | None = None
    accel_peak_by_joint: dict[str, float] | None = None  #: rad/s^2, each joint's peak
    jerk_peak_by_joint: dict[str, float] | None = None  #: rad/s^3

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready dict (floats rounded to 4 decimals, in the per-joint tables too)."""
        return {k: _rounded(v) for k, v in asdict(self).items()}

    def with_following(self, following: Following | None) -> RunSummary:
        """This summary with the figures of ``following`` (None: unchanged)."""
        if following is None:
            return self
        return replace(
            self,
            tracking_median_mm=following.tracking_median_mm,
            tracking_p95_mm=following.tracking_p95_mm,
            tracking_max_mm=following.tracking_max_mm,
            filter_p95_mm=following.filter_p95_mm,
            filter_max_mm=following.filter_max_mm,
            accel_peak_rad_s2=following.accel_peak,
            accel_rms_rad_s2=following.accel_rms,
            jerk_peak_rad_s3=following.jerk_peak,
            jerk_rms_rad_s3=following.jerk_rms,
            accel_peak_by_joint=dict(following.accel_peak_by_joint),
            jerk_peak_by_joint=dict(following.jerk_peak_by_joint),
        )

    def _following_lines(self) -> list[str]:
        if self.tracking_median_mm is None:
            return []
        worst = max((self.accel_peak_by_joint or {"-": 0.0}).items(), key=lambda kv: kv[1])[0]
        return [
            f"  following: tracking error median {self.tracking_median_mm:.2f} mm, p95 {self.tracking_p95_mm:.2f} mm, "
            f"max {self.tracking_max_mm:.2f} mm (mapped target to commanded tool point); targets steered to "
            f"p95 {self.filter_p95_mm:.2f} mm, max {self.filter_max_mm:.2f} mm from the mapped ones (filter, clamp; "
            "teleop: the speed limit's setpoint)",
            f"  joint acceleration peak {self.accel_peak_rad_s2:.1f} rad/s^2 ({worst}), RMS "
            f"{self.accel_rms_rad_s2:.2f}; jerk peak {self.jerk_peak_rad_s3:.0f} rad/s^3, "
            f"RMS {self.jerk_rms_rad_s3:.1f}",
        ]

    def format(self) -> str:
        """Human text, a few lines, for stderr."""
        head = "dry run" if self.dry_run else "replay"
        if self.interrupted:
            head += " (interrupted)"
        lead_in = []
        if self.lead_in_ticks:
            lead_in = [
                f"  lead-in to the clip's first pose: {self.lead_in_s:.2f} s, {self.lead_in_ticks} ticks "
                "(before the clip; of the counts below only the bus errors and retries include it)"
            ]
        stale = []
        if self.stale_reads:
            stale = [
                f"  stale reads: {self.stale_reads} (a servo silent after the retries, its last position used) in "
                f"{self.stale_ticks} ticks; worst {self.worst_stale_ticks} ticks in a row"
            ]
        if self.bus_reboots or self.late_packets:
            stale.append(
                f"  servo reboots (recovery): {self.bus_reboots}; late status packets dropped: {self.late_packets}"
            )
        if self.blocked_ticks is not None:
            clearance = "" if self.min_clearance_mm is None else f", min clearance {self.min_clearance_mm:.1f} mm"
            pushed = "" if self.pushed_targets is None else f"; {self.pushed_targets} targets pushed out of them"
            stale.append(
                f"  collisions: {self.blocked_ticks} blocked goals (not sent), {self.ik_blocked_ticks} ticks with IK "
                f"stopped short by them{clearance}{pushed}"
            )
        if self.gripper is not None:
            stale.append(f"  gripper: {self.gripper}")
        return "\n".join(
            [
                f"{head}: {self.clip} on {self.arm}: {self.frames} frames, {self.duration_s:.2f} s of motion, "
                f"{self.ticks} ticks at {self.rate_hz:g} Hz in {self.wall_time_s:.3f} s "
                f"({self.real_time_factor:.1f}x real time)",
                *lead_in,
                f"  IK: {self.ik_converged_pct:.1f}% converged, error median {self.ik_error_median_mm:.2f} mm, "
                f"p95 {self.ik_error_p95_mm:.2f} mm, max {self.ik_error_max_mm:.2f} mm, "
                f"{self.ik_sweeps_mean:.1f} sweeps/tick",
                *self._following_lines(),
                f"  targets clamped to the workspace: {self.clamped_ticks} ticks; "
                f"velocity-limited: {self.velocity_limited_ticks} ticks",
                f"  bus: {self.bus_errors} errors, {self.bus_retries} retries; "
                f"tick p50 {self.tick_ms_p50:.3f} ms, p99 {self.tick_ms_p99:.3f} ms, max {self.tick_ms_max:.3f} ms "
                f"(compute p99 {self.compute_ms_p99:.3f} ms); overruns {self.overruns}, skipped {self.skipped_ticks}",
                *stale,
            ]
        )


def _rounded(value: Any) -> Any:
    if isinstance(value, float):
        return round(value, 4)
    if isinstance(value, dict):
        return {k: _rounded(v) for k, v in value.items()}
    return value


def _pct(values: np.ndarray, q: float) -> float:
    return float(np.percentile(values, q)) if values.size else 0.0


class IKFigures(TypedDict):
    """The IK fields of a :class:`RunSummary`."""

    ik_converged_pct: float
    ik_error_median_mm: float
    ik_error_p95_mm: float
    ik_error_max_mm: float
    ik_sweeps_mean: float


def ik_figures(ik_error_m: np.ndarray, ik_sweeps: np.ndarray, ik_converged: np.ndarray) -> IKFigures:
    """The IK fields of a :class:`RunSummary` (``ik_converged_pct``, ``ik_error_median_mm``, ...) from per-tick
    arrays ``(n_ticks,)`` (errors metres); 0 for no ticks."""
    err_mm = np.asarray(ik_error_m, dtype=np.float64) * 1e3
    n = int(err_mm.size)
    return IKFigures(
        ik_converged_pct=100.0 * float(np.count_nonzero(ik_converged)) / n if n else 0.0,
        ik_error_median_mm=_pct(err_mm, 50),
        ik_error_p95_mm=_pct(err_mm, 95),
        ik_error_max_mm=float(err_mm.max()) if n else 0.0,
        ik_sweeps_mean=float(np.mean(ik_sweeps)) if n else 0.0,
    )


def summarize(
    *,
    arm: str,
    clip: str,
    dry_run: bool,
    interrupted: bool,
    frames: int,
    rate: float,
    duration_s: float,
    run_time_s: float,
    wall_time_s: float,
    ik_error_m: np.ndarray,
    ik_sweeps: np.ndarray,
    ik_converged: np.ndarray,
    clamped: np.ndarray,
    velocity_limited: np.ndarray,
    compute_s: np.ndarray,
    bus_s: np.ndarray,
    overruns: int,
    skipped_ticks: int,
    bus_errors: int = 0,
    bus_retries: int = 0,
    lead_in_ticks: int = 0,
    lead_in_s: float = 0.0,
    stale_reads: int = 0,
    stale_ticks: int = 0,
    worst_stale_ticks: int = 0,
    bus_reboots: int = 0,
    late_packets: int = 0,
    blocked_ticks: int | None = None,
    min_clearance_m: float | None = None,
    ik_blocked_ticks: int | None = None,
    following: Following | None = None,
) -> RunSummary:
    """A :class:`RunSummary` from per-tick arrays ``(n_ticks,)`` (errors metres, times seconds).

    The arrays and counters are the clip's; ``lead_in_ticks``/``lead_in_s`` describe the lead-in before it.
    ``blocked_ticks``, ``min_clearance_m`` (metres; ``inf``: nothing was checked): the collision checks, None
    without a collision model.  ``following``: how the arm followed (:func:`~retarget.control.tracking.following`).
    """
    err_mm = np.asarray(ik_error_m, dtype=np.float64) * 1e3
    tick_ms = (np.asarray(compute_s) + np.asarray(bus_s)) * 1e3
    compute_ms = np.asarray(compute_s, dtype=np.float64) * 1e3
    n = int(err_mm.size)
    summary = RunSummary(
        arm=arm,
        clip=clip,
        dry_run=dry_run,
        interrupted=interrupted,
        frames=int(frames),
        duration_s=float(duration_s),
        ticks=n,
        rate_hz=float(rate),
        run_time_s=float(run_time_s),
        wall_time_s=float(wall_time_s),
        real_time_factor=(
            float(run_time_s / wall_time_s) if wall_time_s > 0 else float("inf") if run_time_s > 0 else 0.0
        ),
        **ik_figures(ik_error_m, ik_sweeps, ik_converged),
        clamped_ticks=int(np.count_nonzero(clamped)),
        velocity_limited_ticks=int(np.count_nonzero(velocity_limited)),
        bus_errors=int(bus_errors),
        bus_retries=int(bus_retries),
        tick_ms_p50=_pct(tick_ms, 50),
        tick_ms_p99=_pct(tick_ms, 99),
        tick_ms_max=float(tick_ms.max()) if n else 0.0,
        compute_ms_p50=_pct(compute_ms, 50),
        compute_ms_p99=_pct(compute_ms, 99),
        bus_ms_p50=_pct(np.asarray(bus_s, dtype=np.float64) * 1e3, 50),
        overruns=int(overruns),
        skipped_ticks=int(skipped_ticks),
        lead_in_ticks=int(lead_in_ticks),
        lead_in_s=float(lead_in_s),
        stale_reads=int(stale_reads),
        stale_ticks=int(stale_ticks),
        worst_stale_ticks=int(worst_stale_ticks),
        bus_reboots=int(bus_reboots),
        late_packets=int(late_packets),
        blocked_ticks=None if blocked_ticks is None else int(blocked_ticks),
        ik_blocked_ticks=None if ik_blocked_ticks is None else int(ik_blocked_ticks),
        min_clearance_mm=(
            None if min_clearance_m is None or not np.isfinite(min_clearance_m) else float(min_clearance_m) * 1e3
        ),
    )
    return summary.with_following(following)
