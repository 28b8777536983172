"""``retarget replay`` end to end on the in-process simulator (``--fast``), its output, Ctrl-C and bad input."""

from __future__ import annotations

import csv
import json
import re
import signal
import time

import numpy as np
import pytest

import retarget
from retarget.cli import main
from tests.helpers import SignalAfterSyncWrites, servo_angles, torque


def replay(capsys, *args: str) -> tuple[int, str, str]:
    code = main(["replay", *args])
    out, err = capsys.readouterr()
    return code, out, err


def read_csv(path) -> list[dict[str, str]]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def test_demo_clip_end_to_end(arm, registered, capsys, tmp_path):
    simbus, url = registered
    csv_path = tmp_path / "run.csv"
    code, out, err = replay(
        capsys, "--port", url, "--fast", "--json", "--shutdown", "hold", "--end", "3", "--telemetry", str(csv_path)
    )
    assert code == 0, err
    summary = json.loads(out)
    assert summary["clip"] == "demo.bvh" and summary["arm"] == "wx250s"
    assert summary["ticks"] == 301 and summary["rate_hz"] == 100
    assert summary["ik_converged_pct"] > 95 and summary["bus_errors"] == 0 and not summary["interrupted"]
    assert "replay: demo.bvh on wx250s" in err and "IK:" in err  # the human summary on stderr
    all_rows = read_csv(csv_path)
    # the lead-in from the rest pose comes first (lead_in 1, negative times), then the clip's rows
    lead = [r for r in all_rows if r["lead_in"] == "1"]
    rows = [r for r in all_rows if r["lead_in"] == "0"]
    assert all_rows == lead + rows and len(lead) == summary["lead_in_ticks"] > 0
    assert summary["lead_in_s"] == pytest.approx(len(lead) / 100)
    assert float(lead[0]["time_s"]) == pytest.approx(-summary["lead_in_s"]) and float(lead[-1]["time_s"]) < 0
    assert len(rows) == summary["ticks"]
    assert [float(r["time_s"]) for r in rows[:3]] == [0.0, 0.01, 0.02]
    cmd = np.array([[float(r[f"{j}_cmd_rad"]) for j in arm.joint_names] for r in all_rows])
    present = np.array([[float(r[f"{j}_present_rad"]) for j in arm.joint_names] for r in all_rows])
    assert np.all(cmd >= arm.lower) and np.all(cmd <= arm.upper)
    assert np.all(np.abs(np.diff(cmd, axis=0)) <= arm.max_velocity / 100 + 1e-5)  # 6-decimal CSV rounding
    assert np.max(np.abs(present[-1] - cmd[-1])) < 0.1
    assert sum(int(r["velocity_limited"]) for r in rows) == summary["velocity_limited_ticks"]
    assert max(float(r["ik_error_mm"]) for r in rows) == pytest.approx(summary["ik_error_max_mm"], abs=1e-3)
    # --shutdown hold: the servos stay on and settle on the last solved angles
    simbus.clock.advance(1.0)
    np.testing.assert_allclose(servo_angles(simbus, arm), cmd[-1], atol=2 * 2 * np.pi / 4096 + 1e-6)
    assert torque(simbus, arm) == [1] * 8


@pytest.mark.shared
def test_a_shared_clip_end_to_end_rests_and_turns_torque_off(arm, registered, capsys, shared_bvh):
    simbus, url = registered
    clip = shared_bvh / "motion_dance.bvh"
    code, out, err = replay(capsys, str(clip), "--port", url, "--fast", "--json", "--start", "120f", "--end", "2")
    assert code == 0, err
    summary = json.loads(out)
    assert summary["clip"] == "motion_dance.bvh"
    assert summary["ticks"] == 101  # 1 s (frame 120 at 120 fps) .. 2 s at 100 Hz
    assert summary["frames"] == 121
    assert summary["ik_converged_pct"] == 100.0
    assert torque(simbus, arm) == [0] * 8  # --shutdown rest (default): rest pose, then torque off
    np.testing.assert_allclose(servo_angles(simbus, arm), arm.rest, atol=0.06)


def test_default_in_process_bus_and_dry_run(capsys):
    code, out, err = replay(capsys, "--fast", "--json", "--end", "0.5")
    assert code == 0, err
    assert json.loads(out)["ticks"] == 51 and json.loads(out)["bus_ms_p50"] > 0
    code, out, err = replay(capsys, "--dry-run", "--fast", "--json", "--end", "0.5", "--side", "left")
    assert code == 0, err
    summary = json.loads(out)
    assert summary["dry_run"] and summary["ticks"] == 51 and summary["bus_ms_p50"] == 0
    assert "dry run: demo.bvh" in err


def test_loop_and_telemetry_on_stdout(capsys):
    code, out, err = replay(capsys, "--dry-run", "--fast", "--loop", "--max-ticks", "250", "--start", "1", "--end", "2",
                            "--telemetry", "-")  # fmt: skip
    assert code == 0, err
    rows = list(csv.DictReader(out.splitlines()))
    assert len(rows) == 250
    clip = [float(r["clip_time_s"]) for r in rows]
    assert min(clip) == pytest.approx(1.0) and max(clip) < 2.0
    assert all(r["waist_present_rad"] == "" for r in rows)  # dry run: nothing read back


def test_progress_lines_on_request(capsys):
    """The first tick always reports; later lines come at most once a real second, so how many there are
    depends on the machine's speed: only a bound from the measured run time is checked here (the pacing
    itself is checked with a fake time source in ``test_control.test_progress_is_paced_by_its_time_source``)."""
    began = time.perf_counter()
    code, _, err = replay(capsys, "--dry-run", "--fast", "--end", "2.5", "--progress")
    elapsed = time.perf_counter() - began
    assert code == 0
    progress = [line for line in err.splitlines() if line.startswith("retarget:") and "clip" in line]
    assert len(progress) >= 1 and "t=   0.0 s  clip   0.00/2.50 s" in progress[0]
    assert len(progress) <= 1 + int(elapsed)  # the first tick, then one per second of run time at most
    shown = [float(re.search(r" t=\s*([0-9.]+) s", line).group(1)) for line in progress]
    assert shown == sorted(shown) and all(0.0 <= t <= 2.5 for t in shown)


@pytest.mark.parametrize("lead_in", ["0.05", "0"], ids=["during-the-lead-in", "no-lead-in"])
def test_sigint_stops_cleanly_through_the_shutdown_sequence(arm, registered, capsys, lead_in):
    simbus, url = registered
    simbus.log = SignalAfterSyncWrites(20, maxlen=simbus.log.maxlen)  # Ctrl-C once the loop has sent 20 writes
    # --max-ticks bounds the --loop run (the lead-in is finite too): were no Ctrl-C to come, the run would end
    # with exit 0 and fail below instead of hanging
    before = signal.getsignal(signal.SIGINT)  # (the default, unless the suite runs with SIGINT ignored)
    code, out, err = replay(
        capsys, "--port", url, "--fast", "--loop", "--max-ticks", "2000", "--json", "--lead-in", lead_in
    )
    assert simbus.log.sync_writes >= 20
    assert code == 130
    assert json.loads(out)["interrupted"] is True
    summary = json.loads(out)
    if lead_in == "0":
        assert summary["lead_in_ticks"] == 0 and summary["ticks"] >= 10
    else:  # a 60 s lead-in at 0.05 rad/s: Ctrl-C lands in it, before any clip tick
        assert summary["ticks"] == 0 and 10 <= summary["lead_in_ticks"] < 6000
    assert "stopping" in err and "(interrupted)" in err
    assert torque(simbus, arm) == [0] * 8
    np.testing.assert_allclose(servo_angles(simbus, arm), arm.rest, atol=0.06)
    assert signal.getsignal(signal.SIGINT) is before  # the handler was put back


def test_a_servo_lost_mid_run_reports_that_failure_not_the_shutdown_after_it(capsys, caplog, tmp_path):
    """Servo 4 stops answering at 2 s: exit 4, the one-line error is the lost read (the torque-off that also gets
    no reply during the shutdown is only logged), and the telemetry up to the failure is on disk."""
    csv_path = tmp_path / "run.csv"
    code, _, err = replay(capsys, "--fast", "--port", "sim://wx250s?unplug=4@2", "--telemetry", str(csv_path))
    assert code == 4
    last = err.strip().splitlines()[-1]
    assert re.fullmatch(r"retarget: servo 4: no status packet \(Present Position\) .*", last), last
    assert "shutdown after the failure also failed: servo 4: could not turn torque off" in caplog.text
    rows = list(csv.DictReader(csv_path.read_text().splitlines()))
    # 100 Hz up to the 2 s mark, then at most the driver's stale window (10 reads) on the last positions; the last
    # row fully written
    assert 150 <= len(rows) <= 212
    assert rows[-1]["stale"] != "0"  # the ticks after the unplug went on with servo 4's last position, marked
    assert rows[-1]["bus_retries"] != ""


def no_arms_bvh(tmp_path):
    path = tmp_path / "armless.bvh"
    path.write_text(
        "HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0 0\n  CHANNELS 3 Xposition Yposition Zposition\n"
        "  JOINT Head\n  {\n    OFFSET 0 50 0\n    CHANNELS 3 Zrotation Xrotation Yrotation\n"
        "    End Site\n    {\n      OFFSET 0 10 0\n    }\n  }\n}\n"
        "MOTION\nFrames: 2\nFrame Time: 0.1\n0 90 0 0 0 0\n0 90 0 0 0 0\n"
    )
    return str(path)


def bad_bvh(tmp_path):
    path = tmp_path / "bad.bvh"
    path.write_text("HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0\n")
    return str(path)


@pytest.mark.parametrize(
    ("args", "match"),
    [
        (["missing.bvh"], r"missing\.bvh"),
        ([bad_bvh], r"bad\.bvh:4: "),
        ([no_arms_bvh], r"armless\.bvh: "),
        (["--arm", "nope"], r"nope"),
        (["--rate", "0"], r"--rate: Expected a tick rate > 0 Hz \(got 0\.0\)"),
        (["--rate", "fast"], r"--rate: Expected a number \(got 'fast'\)"),
        (["--speed", "-2"], r"--speed: Expected a speed > 0"),
        (["--start", "soon"], r"--start: Expected seconds \(2\.5, 2\.5s\) or frames \(300f\) \(got 'soon'\)"),
        (["--start", "3", "--end", "2"], r"--end: Expected an end time after start \(3 s\)"),
        (["--start", "99"], r"--start: Expected a start time before the clip's end"),
        (["--max-ticks", "1.5"], r"--max-ticks: Expected an integer"),
        (["--side", "up"], r"--side: Expected 'left' or 'right' \(got 'up'\)"),
        (["--forward", "+q"], r"--forward: Expected one of auto"),
        (["--forward", "+y"], r"--forward: Expected a forward axis perpendicular to up"),
        (["--origin", "1,2"], r"--origin: Expected three numbers"),
        (["--floor", "low"], r"--floor: Expected a finite number of metres \(got 'low'\)"),
        (["--velocity-scale", "2"], r"--velocity-scale: Expected a fraction in \(0, 1\]"),
        (
            ["--lead-in", "-1"],
            r"^retarget: --lead-in: Expected a joint speed >= 0 rad/s \(0: no lead-in\) \(got -1\.0\)$",
        ),
        (["--lead-in", "slow"], r"--lead-in: Expected a number \(got 'slow'\)"),
        (["--lead-in", "nan"], r"--lead-in: Expected a joint speed >= 0 rad/s"),
        (["--shutdown", "later"], r"--shutdown: Expected hold, rest or off \(got 'later'\)"),
        (["--fast", "--port", "/dev/ttyUSB0"], r"--port: --fast needs the simulated bus"),
        (["--dry-run", "--port", "sim://wx250s"], r"--port: --dry-run uses no bus"),
        (["--json", "--telemetry", "-"], r"--telemetry: --telemetry - and --json both write to stdout"),
        (["--fast", "--port", "sim://wx250s?bogus=1"], r"unknown option\(s\) bogus"),
        (["--dry-run", "--telemetry", "/nonexistent/dir/run.csv"], r"/nonexistent/dir/run\.csv"),
    ],
    ids=lambda v: " ".join(v) if isinstance(v, list) and all(isinstance(x, str) for x in v) else None,
)
def test_bad_input_exits_2_with_one_line(capsys, tmp_path, args, match):
    args = [a(tmp_path) if callable(a) else a for a in args]
    code, out, err = replay(capsys, *args, "--fast") if "--port" not in args else replay(capsys, *args)
    assert code == 2
    assert out == ""
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("retarget: ")
    assert re.search(match, lines[0]), lines[0]


def test_help_has_examples(capsys):
    with pytest.raises(SystemExit) as info:
        main(["replay", "--help"])
    assert info.value.code == 0
    out = capsys.readouterr().out
    assert "examples:" in out and "retarget replay --fast --json" in out and "--telemetry" in out
    assert "--lead-in RAD_PER_S" in out and "--lead-in 0.3" in out
    assert "--base LINK" in out and "--tip LINK" in out


def test_the_arm_files_mapping_table_is_used_and_checked(capsys, tmp_path):
    source = retarget.load_arm("wx250s").source.read_text()
    good = tmp_path / "wx_left.toml"
    good.write_text(source + '\n[mapping]\nside = "left"\narm_scale = 0.3\n')

    def first_target(*extra: str) -> list[str]:
        code, out, err = replay(capsys, "--arm", str(good), "--dry-run", "--fast", "--end", "0.1", "--telemetry", "-",
                                *extra)  # fmt: skip
        assert code == 0, err
        row = next(csv.DictReader(out.splitlines()))
        return [row["target_x_m"], row["target_y_m"], row["target_z_m"]]

    left = first_target()
    assert first_target("--side", "left") == left
    assert first_target("--side", "right") != left  # a flag overrides the file
    bad = tmp_path / "wx_bad.toml"
    bad.write_text(source + '\n[mapping]\nside = "up"\n')
    for extra in ([], ["--side", "right"]):  # a flag does not hide a broken file
        code, out, err = replay(capsys, "--arm", str(bad), "--dry-run", "--fast", "--end", "1", *extra)
        assert code == 2
        assert err.strip() == f"retarget: {bad}: mapping.side: Expected 'left' or 'right' (got 'up')"


def test_a_sim_url_with_faults_runs_on_a_virtual_clock_with_fast(capsys):
    code, out, err = replay(capsys, "--port", "sim://wx250s?drop=0.01&seed=2", "--fast", "--json", "--end", "1")
    assert code == 0, err
    summary = json.loads(out)
    assert summary["bus_retries"] > 0 and summary["bus_errors"] == 0
    assert summary["real_time_factor"] > 1  # dropped replies cost virtual time only


# --------------------------------------------------------------------------------------------- the lead-in


def joint_matrix(rows: list[dict[str, str]], arm, kind: str = "cmd") -> np.ndarray:
    return np.array([[float(r[f"{j}_{kind}_rad"]) for j in arm.joint_names] for r in rows])


def demo_first_pose(arm) -> np.ndarray:
    """The IK solution of the demo clip's first target (default mapping), as the loop solves it."""
    from retarget.bvh import DEMO_CLIP
    from retarget.control import ControlLoop
    from retarget.control.clock import VirtualClock
    from retarget.mapping import retarget_targets

    targets = retarget_targets(retarget.load_bvh(DEMO_CLIP), arm)
    return ControlLoop(arm, targets, clock=VirtualClock()).initial_pose()


def test_lead_in_then_the_clip_against_no_lead_in(arm, capsys, tmp_path):
    """In-process simulated bus, from the rest pose: a gentle lead-in to the clip's first pose, then the clip
    with the same clip stats; --lead-in 0 is the old start: full speed from the rest pose."""
    q1 = demo_first_pose(arm)
    runs = {}
    for lead_in in ("0.25", "0"):
        path = tmp_path / f"run-{lead_in}.csv"
        code, out, err = replay(capsys, "--fast", "--json", "--end", "1", "--lead-in", lead_in, "--progress",
                                "--telemetry", str(path))  # fmt: skip
        assert code == 0, err
        runs[lead_in] = (json.loads(out), read_csv(path), err)

    summary, rows, err = runs["0.25"]
    lead = [r for r in rows if r["lead_in"] == "1"]
    clip = rows[len(lead) :]
    assert len(lead) == summary["lead_in_ticks"] > 100 and all(r["lead_in"] == "0" for r in clip)
    assert summary["lead_in_s"] == pytest.approx(len(lead) / 100)
    assert [int(r["tick"]) for r in lead] == list(range(-len(lead), 0))
    assert all(float(r["clip_time_s"]) == 0.0 and r["ik_sweeps"] == "0" for r in lead)
    cmd = joint_matrix(lead, arm)
    steps = np.abs(np.diff(np.vstack([arm.rest, cmd]), axis=0))
    assert np.all(steps <= 0.25 / 100 + 2e-5)  # rest as the servos read it (whole ticks), then 6-decimal rows
    assert np.max(steps) > 0.95 * 0.25 / 100
    np.testing.assert_allclose(cmd[-1], q1, atol=2e-6)  # on the first target's solution before clip tick 0
    assert float(clip[0]["time_s"]) == 0.0 and clip[0]["velocity_limited"] == "0"
    assert np.max(np.abs(joint_matrix(clip[:1], arm)[0] - q1)) < 2e-3  # no jump
    assert "lead-in to the clip's first pose: " in err
    assert "retarget: lead-in t=" in err.splitlines()[0]  # progress: the first tick is the lead-in's

    plain, plain_rows, plain_err = runs["0"]
    assert plain["lead_in_ticks"] == 0 and plain["lead_in_s"] == 0.0 and "lead-in" not in plain_err
    assert all(r["lead_in"] == "0" for r in plain_rows) and float(plain_rows[0]["time_s"]) == 0.0
    steps = np.abs(np.diff(np.vstack([arm.rest, joint_matrix(plain_rows[:50], arm)]), axis=0))
    assert np.max(steps / (arm.max_velocity / 100)) > 0.99  # the old start: full speed out of the rest pose
    # the clip's numbers mean the clip either way; only the start transient is gone
    for key in ("ticks", "frames", "duration_s", "run_time_s", "rate_hz"):
        assert summary[key] == plain[key], key
    assert summary["ticks"] == len(clip) == len(plain_rows) == 101
    assert summary["velocity_limited_ticks"] < plain["velocity_limited_ticks"]
    assert summary["ik_converged_pct"] >= plain["ik_converged_pct"]


def test_a_dry_run_starts_on_the_first_targets_solution_like_export(arm, capsys, tmp_path):
    path = tmp_path / "dry.csv"
    code, out, err = replay(capsys, "--dry-run", "--fast", "--json", "--end", "1", "--telemetry", str(path))
    assert code == 0, err
    summary = json.loads(out)
    rows = read_csv(path)
    assert summary["lead_in_ticks"] == 0 and len(rows) == summary["ticks"] == 101 and "lead-in" not in err
    assert all(r["lead_in"] == "0" for r in rows)
    np.testing.assert_allclose(joint_matrix(rows[:1], arm)[0], demo_first_pose(arm), atol=2e-3)
    assert rows[0]["velocity_limited"] == "0"
    code, out, err = main(["export", "--end", "1", "-o", "-"]), *capsys.readouterr()
    assert code == 0, err
    exported = np.array([line.split(",") for line in out.splitlines()[1:]], dtype=np.float64)
    np.testing.assert_allclose(exported[:, 1:], joint_matrix(rows, arm), atol=2e-6)  # the same trajectory
