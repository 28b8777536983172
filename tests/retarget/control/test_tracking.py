"""A measure of following: the tracking error (mapped target to the commanded tool point), the filter's
deviation, and the commanded joints' acceleration and jerk, in the summary and the telemetry."""

from __future__ import annotations

import csv
import io

import numpy as np
import pytest

import retarget
from retarget.control import ControlLoop, LoopConfig, TickRecord
from retarget.control.clock import VirtualClock
from retarget.control.summary import summarize
from retarget.control.telemetry import TelemetryWriter
from retarget.control.tracking import TickTracker, Trajectory, derivatives, following
from retarget.mapping import Targets, retarget_targets
from retarget.mapping.config import MappingConfig
from retarget.mapping.filter import AUTO
from tests.helpers import SHARED_BVH, wx250s_tool

CLIP = SHARED_BVH / "motion_dance.bvh"
needs_clip = pytest.mark.skipif(not CLIP.is_file(), reason=f"{CLIP} not found (set RETARGET_SHARED_BVH)")
END = 4.0  #: clip seconds of the dance each run plays (400 ticks)


def _cutoff(arm: retarget.Arm, cutoff_hz: float) -> MappingConfig:
    return MappingConfig.from_table(arm.mapping, overrides={"cutoff_hz": cutoff_hz})


def _unfiltered(arm: retarget.Arm) -> MappingConfig:
    return _cutoff(arm, 0.0)


def _dry_run(arm: retarget.Arm, targets: Targets, on_tick=None):
    loop = ControlLoop(arm, targets, config=LoopConfig(end=END), clock=VirtualClock(), on_tick=on_tick)
    return loop.run(None, q_start=loop.initial_pose())


@needs_clip
def test_tracking_figures_match_an_independent_fk_of_the_telemetry(arm) -> None:
    """The telemetry's tracking column and the summary's figures against a plain chain of 4x4 transforms
    (tests/helpers.py, from the arm's URDF numbers, not the library's FK) of the commanded angles written, and
    the unfiltered targets of the clip mapped without a filter."""
    motion = retarget.load_bvh(CLIP)
    targets = retarget_targets(motion, arm, _cutoff(arm, 6.0))  # filtered (auto leaves this clean clip as it is)
    out = io.StringIO()
    with TelemetryWriter(out, arm.joint_names, tracking=TickTracker.for_clip(arm, targets.reference)) as telemetry:
        summary = _dry_run(arm, targets, telemetry)
    rows = list(csv.DictReader(io.StringIO(out.getvalue())))
    assert len(rows) == summary.ticks == 401
    q = np.array([[float(r[f"{name}_cmd_rad"]) for name in arm.joint_names] for r in rows])
    tool = np.array([wx250s_tool(x) for x in q])
    times = np.array([float(r["clip_time_s"]) for r in rows])
    clean, _, _ = retarget_targets(motion, arm, _unfiltered(arm)).sample(times)
    tracking = 1e3 * np.linalg.norm(tool - clean, axis=1)
    steered = np.array([[float(r[f"target_{c}_m"]) for c in "xyz"] for r in rows])
    deviation = 1e3 * np.linalg.norm(steered - clean, axis=1)
    np.testing.assert_allclose([float(r["tracking_mm"]) for r in rows], tracking, rtol=0, atol=0.01)
    np.testing.assert_allclose([float(r["filter_mm"]) for r in rows], deviation, rtol=0, atol=0.01)
    got = (summary.tracking_median_mm, summary.tracking_p95_mm, summary.tracking_max_mm)
    np.testing.assert_allclose(got, [np.median(tracking), np.percentile(tracking, 95), tracking.max()], atol=0.01)
    np.testing.assert_allclose((summary.filter_p95_mm, summary.filter_max_mm), (np.percentile(deviation, 95),
                               deviation.max()), atol=0.01)  # fmt: skip
    assert summary.filter_max_mm > 1.0  # the filter did move the targets, and the tracking counts that in
    # apart from the IK error, which is measured to the filtered target the loop solved for
    ik = np.array([float(r["ik_error_mm"]) for r in rows])
    assert not np.allclose(ik, tracking, atol=0.01)


@needs_clip
def test_acceleration_and_jerk_are_the_commanded_trajectorys_differences(arm) -> None:
    records: list[TickRecord] = []
    summary = _dry_run(arm, retarget_targets(retarget.load_bvh(CLIP), arm), records.append)
    q = np.array([r.q_cmd for r in records])
    accel, jerk = np.diff(q, 2, axis=0) * 100.0**2, np.diff(q, 3, axis=0) * 100.0**3
    assert summary.accel_peak_rad_s2 == pytest.approx(np.abs(accel).max(), rel=1e-9)
    assert summary.accel_rms_rad_s2 == pytest.approx(np.sqrt(np.mean(accel**2)), rel=1e-9)
    assert summary.jerk_peak_rad_s3 == pytest.approx(np.abs(jerk).max(), rel=1e-9)
    assert summary.jerk_rms_rad_s3 == pytest.approx(np.sqrt(np.mean(jerk**2)), rel=1e-9)
    assert summary.accel_peak_by_joint is not None and summary.jerk_peak_by_joint is not None
    np.testing.assert_allclose(list(summary.accel_peak_by_joint.values()), np.abs(accel).max(axis=0), rtol=1e-9)
    np.testing.assert_allclose(list(summary.jerk_peak_by_joint.values()), np.abs(jerk).max(axis=0), rtol=1e-9)
    assert list(summary.accel_peak_by_joint) == list(arm.joint_names)
    doc = summary.to_dict()
    assert doc["accel_peak_by_joint"]["waist"] == round(summary.accel_peak_by_joint["waist"], 4)
    assert "following: tracking error median" in summary.format() and "jerk peak" in summary.format()


@needs_clip
def test_a_noisy_clip_filtered_commands_no_more_jerk_than_the_clean_clip(arm) -> None:
    """The dance with 2 mm of seeded noise on its mapped targets.  The default filter (auto: 11.5 Hz here) takes the
    targets' own jerk down 56x (tests/retarget/mapping/test_filter.py); the look-ahead plan's jerk cost smooths the
    rest, so the commanded joints' RMS jerk is no higher than the clean clip's (measured 495 rad/s^3 against 516;
    the noise unfiltered: 559, 1.13x more; a fixed 6 Hz: 378, for cutting the dance's own moves too).  The noise
    moves the tool less than unfiltered (median 1.07 mm from the clean clip's run against 1.09; 6 Hz: 0.86), and the
    arm follows the clean clip at least as well as at 6 Hz (tracking p95 12.1 mm against 12.6)."""
    clean = retarget_targets(retarget.load_bvh(CLIP), arm, _unfiltered(arm))
    noisy = clean.raw + np.random.default_rng(7).normal(0.0, 0.002, clean.raw.shape)
    runs, clean_runs, noise_moved = {}, {}, {}
    for cutoff in (0.0, 6.0, AUTO):
        tools = []
        for raw, figures in ((noisy, runs), (clean.raw, clean_runs)):
            targets = Targets.from_raw(raw, frame_time=clean.frame_time, workspace=clean.workspace, cutoff_hz=cutoff)
            trajectory = Trajectory()
            _dry_run(arm, targets, trajectory)
            tools.append(arm.chain.tool_points(np.array(trajectory.q_cmd)))
            figures[cutoff] = following(arm, trajectory, rate=100.0, reference=clean.reference)
        noise_moved[cutoff] = float(np.median(np.linalg.norm(tools[0] - tools[1], axis=1)))
    raw, six, auto, clean_run = runs[0.0], runs[6.0], runs[AUTO], clean_runs[0.0]
    assert raw is not None and six is not None and auto is not None and clean_run is not None
    assert six.jerk_rms < auto.jerk_rms <= clean_run.jerk_rms < raw.jerk_rms
    assert auto.accel_rms < raw.accel_rms
    assert noise_moved[6.0] < noise_moved[AUTO] < noise_moved[0.0]  # the noise is not followed (tool to tool)
    assert auto.tracking_p95_mm <= six.tracking_p95_mm


def test_derivatives_over_skipped_slots() -> None:
    """After an overrun the loop skips slots: the differences use the slots' times, so a constant acceleration
    (q = a t^2 / 2) reads as that, with no jerk, across the gap."""
    slots = np.array([0, 1, 2, 5, 6, 7, 9], dtype=np.float64)
    t = slots / 100.0
    q = np.stack([0.5 * 3.0 * t**2, -0.5 * 40.0 * t**2], axis=-1)
    accel, jerk = derivatives(q, t)
    np.testing.assert_allclose(accel, np.broadcast_to([3.0, -40.0], accel.shape), rtol=1e-9)
    np.testing.assert_allclose(jerk, 0.0, atol=1e-6)


def test_a_trajectory_without_ticks_has_no_figures(arm) -> None:
    assert following(arm, Trajectory(), rate=100.0) is None
    plain = summarize(
        arm="a", clip="c", dry_run=True, interrupted=False, frames=0, rate=100.0, duration_s=0.0, run_time_s=0.0,
        wall_time_s=0.0, ik_error_m=np.zeros(0), ik_sweeps=np.zeros(0), ik_converged=np.zeros(0, bool),
        clamped=np.zeros(0, bool), velocity_limited=np.zeros(0, bool), compute_s=np.zeros(0), bus_s=np.zeros(0),
        overruns=0, skipped_ticks=0,
    )  # fmt: skip
    assert plain.tracking_p95_mm is None and plain.accel_peak_by_joint is None
    assert "following" not in plain.format()


def test_lead_in_ticks_are_left_out_and_a_live_reference_is_used(arm) -> None:
    """The lead-in moves to the clip's first pose (not following anything); a live run's reference comes with
    each tick (None before its first target: no figure)."""
    refs = iter([None, np.array([0.3, 0.0, 0.2]), np.array([0.3, 0.0, 0.2])])
    trajectory = Trajectory(reference=lambda _r: next(refs))
    q = arm.home
    tool = wx250s_tool(q)
    for tick, lead_in in ((-1, True), (0, False), (1, False), (2, False)):
        trajectory(TickRecord(tick=tick, time=tick / 100, clip_time=0.0, target=tool, q_cmd=q, q_present=None,
                              ik_error=0.0, ik_sweeps=0, ik_converged=True, compute_time=0.0, bus_time=0.0,
                              clamped=False, velocity_limited=False, overrun=False, bus_retries=0,
                              lead_in=lead_in))  # fmt: skip
    assert len(trajectory) == 3
    f = following(arm, trajectory, rate=100.0)
    assert f is not None
    expected = 1e3 * np.linalg.norm(tool - [0.3, 0.0, 0.2])
    assert f.tracking_median_mm == pytest.approx(expected) and f.tracking_max_mm == pytest.approx(expected)
    assert f.accel_peak == f.jerk_peak == 0.0  # standing still
