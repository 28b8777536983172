"""The target filters' options: ``--filter-cutoff``/``--no-filter`` on the clip commands (zero-phase, by default
at the cutoff chosen from the clip), ``--filter-min-cutoff``/``--filter-beta``/``--no-filter`` on teleop's streams
(One-Euro), their errors and help; the run's measure of following in ``--json`` and the telemetry."""

from __future__ import annotations

import csv
import io
import json

import numpy as np
import pytest

from retarget.cli import main
from tests.helpers import REPO

ONLY_STREAMS = "the stream filter goes with --stdin or --udp (a single target or keys: nothing to smooth)"
WINDOW = ("--end", "2")  #: 2 s of the bundled demo clip


def run(capsys, *args: str) -> tuple[int, str, str]:
    code = main(list(args))
    out, err = capsys.readouterr()
    return code, out, err


def export(capsys, *args: str) -> np.ndarray:
    code, out, err = run(capsys, "export", *WINDOW, *args)
    assert code == 0, err
    return np.loadtxt(io.StringIO(out), delimiter=",", skiprows=1)


def test_export_filters_at_the_auto_cutoff_by_default_and_the_flags_change_it(capsys, tmp_path, caplog):
    with caplog.at_level("INFO", logger="retarget.mapping.targets"):
        default = export(capsys)
    assert "target filter: auto, none (a clean clip)" in caplog.text  # the demo clip: a clean capture
    assert np.array_equal(export(capsys, "--filter-cutoff", "auto"), default)  # the default
    unfiltered = export(capsys, "--no-filter")
    assert np.array_equal(export(capsys, "--filter-cutoff", "0"), unfiltered) and np.array_equal(default, unfiltered)
    six, smoother = export(capsys, "--filter-cutoff", "6"), export(capsys, "--filter-cutoff", "2")
    assert not np.allclose(six, unfiltered) and not np.allclose(six, smoother)
    # an arm file's cutoff_hz is the default the flag overrides
    arm = tmp_path / "arm.toml"
    text = (REPO / "config" / "arms" / "wx250s.toml").read_text(encoding="utf-8")
    assert "\n[mapping]" not in text  # the bundled file keeps the defaults: add the table
    arm.write_text(text + "\n[mapping]\ncutoff_hz = 6\n", encoding="utf-8")
    assert np.array_equal(export(capsys, "--arm", str(arm)), six)
    assert np.array_equal(export(capsys, "--arm", str(arm), "--filter-cutoff", "AUTO"), default)
    arm.write_text(text + '\n[mapping]\ncutoff_hz = "auto"\n', encoding="utf-8")
    assert np.array_equal(export(capsys, "--arm", str(arm)), default)


def test_a_causal_run_reads_auto_as_6_hz(capsys, tmp_path):
    """Without look-ahead the limiter cannot start early for a fast move: 'auto' is the former fixed 6 Hz there
    (retarget.mapping.filter.CAUSAL_CUTOFF_HZ); a number or 0 stays what it says."""
    causal = export(capsys, "--no-look-ahead")
    assert np.array_equal(export(capsys, "--no-look-ahead", "--filter-cutoff", "6"), causal)
    assert np.array_equal(export(capsys, "--no-look-ahead", "--filter-cutoff", "auto"), causal)
    assert not np.allclose(export(capsys, "--no-look-ahead", "--no-filter"), causal)
    assert not np.allclose(export(capsys, "--no-look-ahead", "--filter-cutoff", "3"), causal)
    assert not np.allclose(export(capsys), causal)  # with look-ahead, auto leaves this clean clip unfiltered


@pytest.mark.parametrize("value", ["0.01", "101", "-1", "x", "automatic"])
def test_a_bad_cutoff_names_the_flag(capsys, value):
    code, out, err = run(capsys, "export", *WINDOW, f"--filter-cutoff={value}")
    assert code == 2 and out == ""
    assert err.strip().startswith(
        "retarget: --filter-cutoff: Expected 'auto', a cutoff from 0.1 to 100 Hz, or 0 (no filter)"
    )
    assert "Traceback" not in err


def test_replay_reports_following_in_json_and_telemetry(capsys, tmp_path):
    csv_path = tmp_path / "run.csv"
    code, out, err = run(capsys, "replay", "--dry-run", "--fast", "--json", *WINDOW, "--telemetry", str(csv_path))
    assert code == 0, err
    doc = json.loads(out)
    for key in ("tracking_median_mm", "tracking_p95_mm", "tracking_max_mm", "filter_p95_mm", "accel_peak_rad_s2",
                "accel_rms_rad_s2", "jerk_peak_rad_s3", "jerk_rms_rad_s3"):  # fmt: skip
        assert isinstance(doc[key], float) and doc[key] >= 0, key
    assert set(doc["accel_peak_by_joint"]) == {"waist", "shoulder", "elbow", "forearm_roll", "wrist_angle",
                                               "wrist_rotate"}  # fmt: skip
    assert "following: tracking error median" in err
    with open(csv_path, newline="") as f:
        rows = list(csv.DictReader(f))
    tracking = np.array([float(r["tracking_mm"]) for r in rows])
    assert np.median(tracking) == pytest.approx(doc["tracking_median_mm"], abs=1e-3)
    assert tracking.max() == pytest.approx(doc["tracking_max_mm"], abs=1e-3)


def test_help_states_the_lags(capsys):
    with pytest.raises(SystemExit):
        main(["export", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "zero lag, -6 dB at HZ" in text and "--no-filter" in text
    with pytest.raises(SystemExit):
        main(["teleop", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "31 ms at 0.05 m/s, 15 ms at 0.2 m/s, 5 ms at 1 m/s" in text
    assert "--filter-min-cutoff" in text and "--filter-beta" in text


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (("--to", "0.3,0,0.2", "--no-filter", "--fast"), f"--no-filter: {ONLY_STREAMS}"),
        (("--to", "0.3,0,0.2", "--filter-beta", "5", "--fast"), f"--filter-beta: {ONLY_STREAMS}"),
        (("--interactive", "--no-filter"), f"--no-filter: {ONLY_STREAMS}"),
        (
            ("--stdin", "--filter-min-cutoff", "0", "--fast"),
            "--filter-min-cutoff: Expected a finite number > 0 (got 0.0)",
        ),
        (("--stdin", "--filter-beta", "-2", "--fast"), "--filter-beta: Expected a finite number >= 0 (got -2.0)"),
        (("--stdin", "--filter-beta", "fast", "--fast"), "--filter-beta: Expected a number (got 'fast')"),
    ],
    ids=["no-filter-one-shot", "beta-one-shot", "no-filter-keys", "min-cutoff-0", "beta-negative", "beta-text"],
)
def test_teleop_filter_option_errors(capsys, args, message):
    code, out, err = run(capsys, "teleop", *args)
    assert code == 2 and out == ""
    assert err.strip() == f"retarget: {message}"


def test_a_teleop_stream_is_filtered_unless_told(capsys, monkeypatch, tmp_path):
    """A still hand with 5 mm of jitter on stdin: filtered by default, the arm's setpoint wanders far less than
    when it chases every jittery target (--no-filter); both end on the stream's last point as it came."""
    rng = np.random.default_rng(5)
    lines = "".join(f"0.3 {rng.normal(0, 0.005):.5f} {0.2 + rng.normal(0, 0.005):.5f}\n" for _ in range(150))
    docs, paths = {}, {}
    for flags in ((), ("--no-filter",)):
        monkeypatch.setattr("sys.stdin", io.TextIOWrapper(io.BytesIO(lines.encode())))
        csv_path = tmp_path / f"run{len(flags)}.csv"
        code, out, err = run(capsys, "teleop", "--stdin", "--fast", "--json", "--telemetry", str(csv_path), *flags)
        assert code == 0, err
        docs[flags] = json.loads(out)
        with open(csv_path, newline="") as f:
            setpoints = np.array([[float(r[f"target_{c}_m"]) for c in "xyz"] for r in csv.DictReader(f)])
        paths[flags] = float(np.linalg.norm(np.diff(setpoints, axis=0), axis=1).sum())
    filtered, raw = docs[()], docs[("--no-filter",)]
    assert filtered["teleop"]["reached"] and raw["teleop"]["reached"]
    assert filtered["teleop"]["target_m"] == raw["teleop"]["target_m"]  # the last point, as it came
    assert paths[()] * 2 < paths[("--no-filter",)]
    assert filtered["ticks"] * 2 < raw["ticks"]
