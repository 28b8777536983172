"""Telemetry CSV: columns named with joints and units, one row per tick, flushed as it goes."""

from __future__ import annotations

import csv
import dataclasses
import io

import numpy as np
import pytest

from retarget.control import ControlLoop, LoopConfig, TickRecord
from retarget.control.clock import VirtualClock
from retarget.control.telemetry import TelemetryWriter, telemetry_columns
from retarget.mapping import Targets, Workspace


def line_targets(arm) -> Targets:
    t = np.linspace(0.0, 1.0, 31)
    raw = np.stack([0.3 + 0.1 * t, -0.1 + 0.2 * t, 0.25 + 0 * t], axis=-1)
    return Targets.from_raw(raw, frame_time=1 / 30, workspace=Workspace.for_arm(arm))


def record(arm, *, present: bool) -> TickRecord:
    q = np.linspace(-0.5, 0.5, arm.n_joints)
    return TickRecord(
        tick=7,
        time=0.07,
        clip_time=0.14,
        target=np.array([0.3, -0.05, 0.2]),
        q_cmd=q,
        q_present=q + 0.001 if present else None,
        ik_error=0.00042,
        ik_sweeps=3,
        ik_converged=True,
        compute_time=0.00012,
        bus_time=0.0008,
        clamped=True,
        velocity_limited=False,
        overrun=True,
        bus_retries=2,
    )


def test_columns_name_the_joints_and_units(arm):
    cols = telemetry_columns(arm.joint_names)
    assert cols[:6] == ["time_s", "clip_time_s", "tick", "target_x_m", "target_y_m", "target_z_m"]
    assert "waist_cmd_rad" in cols and "wrist_rotate_present_rad" in cols
    assert cols[-8:-4] == ["clamped", "velocity_limited", "overrun", "bus_retries"]
    assert cols[-4] == "lead_in"  # the flag of the lead-in's rows
    assert cols[-3] == "stale"  # the servos whose read-back missed (added after lead_in)
    assert cols[-2:] == ["blocked", "min_clearance_mm"]  # the collision check, last
    i = cols.index("ik_error_mm")  # the tracking error and the filter's deviation beside the IK error, apart
    assert cols[i : i + 3] == ["ik_error_mm", "tracking_mm", "filter_mm"]
    assert len(cols) == len(set(cols)) == 6 + 2 * arm.n_joints + 16


@pytest.mark.parametrize("present", [True, False], ids=["bus", "dry-run"])
def test_row_values(arm, present):
    out = io.StringIO()
    with TelemetryWriter(out, arm.joint_names) as telemetry:
        telemetry(record(arm, present=present))
    rows = list(csv.DictReader(io.StringIO(out.getvalue())))
    assert len(rows) == 1
    row = rows[0]
    assert float(row["time_s"]) == pytest.approx(0.07)
    assert int(row["tick"]) == 7
    assert float(row["target_y_m"]) == pytest.approx(-0.05)
    assert float(row["waist_cmd_rad"]) == pytest.approx(-0.5)
    assert float(row["wrist_rotate_cmd_rad"]) == pytest.approx(0.5)
    if present:
        assert float(row["waist_present_rad"]) == pytest.approx(-0.499)
    else:
        assert row["waist_present_rad"] == ""
    assert float(row["ik_error_mm"]) == pytest.approx(0.42)
    assert float(row["tick_ms"]) == pytest.approx(0.92)
    assert float(row["bus_ms"]) == pytest.approx(0.8)
    assert (row["clamped"], row["velocity_limited"], row["overrun"], row["bus_retries"]) == ("1", "0", "1", "2")
    assert row["lead_in"] == "0" and row["stale"] == "0"
    assert row["blocked"] == "0" and row["min_clearance_mm"] == ""  # no collision model: no clearance
    assert row["tracking_mm"] == row["filter_mm"] == ""  # no tracking measure given
    assert not out.closed  # a stream given by the caller stays open


def test_lead_in_rows_are_flagged(arm):
    out = io.StringIO()
    lead = dataclasses.replace(record(arm, present=True), tick=-3, time=-0.03, clip_time=0.0, lead_in=True)
    with TelemetryWriter(out, arm.joint_names) as telemetry:
        telemetry(lead)
        telemetry(record(arm, present=True))
    rows = list(csv.DictReader(io.StringIO(out.getvalue())))
    assert [(r["tick"], r["time_s"], r["lead_in"]) for r in rows] == [("-3", "-0.030000", "1"), ("7", "0.070000", "0")]


def test_one_row_per_tick_flushed_as_it_goes(arm, tmp_path):
    path = tmp_path / "run.csv"
    seen: list[int] = []
    with TelemetryWriter(path, arm.joint_names) as telemetry:

        def on_tick(r: TickRecord) -> None:
            telemetry(r)
            # already on disk, before the writer is closed
            seen.append(len(path.read_text().splitlines()) - 1)

        summary = ControlLoop(arm, line_targets(arm), config=LoopConfig(), clock=VirtualClock(), on_tick=on_tick).run(
            None
        )
    assert seen == list(range(1, summary.ticks + 1))
    rows = list(csv.DictReader(path.open()))
    assert len(rows) == summary.ticks == telemetry.rows
    q = np.array([[float(row[f"{j}_cmd_rad"]) for j in arm.joint_names] for row in rows])
    assert np.all(q >= arm.lower - 1e-6) and np.all(q <= arm.upper + 1e-6)
    assert sum(int(r["velocity_limited"]) for r in rows) == summary.velocity_limited_ticks


def test_writing_to_a_closed_writer_fails(arm, tmp_path):
    telemetry = TelemetryWriter(tmp_path / "x.csv", arm.joint_names)
    with pytest.raises(ValueError, match="Expected an open TelemetryWriter, got a closed one"):
        telemetry(record(arm, present=True))
    telemetry.open()
    telemetry.close()
    telemetry.close()  # twice is fine
    with pytest.raises(ValueError, match="closed"):
        telemetry.write(record(arm, present=True))


def test_unwritable_path_raises_oserror(arm, tmp_path):
    with pytest.raises(OSError), TelemetryWriter(tmp_path / "missing" / "run.csv", arm.joint_names):
        pass


def test_stale_column_counts_the_servos_whose_read_back_missed(arm):
    out = io.StringIO()
    with TelemetryWriter(out, arm.joint_names) as telemetry:
        telemetry(dataclasses.replace(record(arm, present=True), stale=2))
    (row,) = csv.DictReader(io.StringIO(out.getvalue()))
    assert row["stale"] == "2" and float(row["waist_present_rad"]) == pytest.approx(-0.499)
