"""``retarget export``: the joint trajectory as CSV; safety over every shared clip and both sides."""

from __future__ import annotations

import csv
import io
import re

import numpy as np
import pytest

import retarget
from retarget.cli import main
from tests.helpers import SHARED_BVH, shared_clip_params

DANCE = SHARED_BVH / "motion_dance.bvh"


def export(capsys, *args: str) -> tuple[int, str, str]:
    code = main(["export", *args])
    out, err = capsys.readouterr()
    return code, out, err


def trajectory(text: str, arm) -> tuple[np.ndarray, np.ndarray]:
    rows = list(csv.reader(io.StringIO(text)))
    assert rows[0] == ["time_s", *(f"{j}_rad" for j in arm.joint_names)]
    data = np.array(rows[1:], dtype=np.float64)
    return data[:, 0], data[:, 1:]


def check_safe(t: np.ndarray, q: np.ndarray, arm, rate: float) -> None:
    np.testing.assert_allclose(np.diff(t), 1 / rate, atol=2e-6)
    assert np.all(q >= arm.lower - 1e-6) and np.all(q <= arm.upper + 1e-6)  # 6-decimal rounding
    assert np.all(np.abs(np.diff(q, axis=0)) <= arm.max_velocity / rate + 2e-6)


@pytest.mark.parametrize("arm_name", ["wx250s", "px100"])
def test_export_demo_to_a_file(capsys, tmp_path, arm_name):
    arm = retarget.load_arm(arm_name)
    out_path = tmp_path / "traj.csv"
    code, out, err = export(capsys, "--arm", arm_name, "-o", str(out_path), "--end", "4")
    assert code == 0, err
    assert out == ""
    assert f"401 ticks of {arm_name}" in err and "-> " + str(out_path) in err
    t, q = trajectory(out_path.read_text(), arm)
    assert len(t) == 401 and t[0] == 0 and t[-1] == pytest.approx(4.0)
    check_safe(t, q, arm, 100)
    # it starts on the first target's solution, not at the rest pose
    assert np.max(np.abs(q[0] - arm.rest)) > 0.3


def test_export_to_stdout_at_another_rate_matches_the_dry_run_replay(capsys):
    arm = retarget.load_arm("wx250s")
    code, out, _ = export(capsys, "-o", "-", "--rate", "50", "--start", "1", "--end", "2", "--side", "left")
    assert code == 0
    t, q = trajectory(out, arm)
    assert len(t) == 51
    check_safe(t, q, arm, 50)


@pytest.mark.shared
@pytest.mark.parametrize("side", ["left", "right"])
@pytest.mark.parametrize("clip", shared_clip_params())
def test_every_shared_clip_and_side_stays_within_limits(capsys, tmp_path, clip, side):
    """Zero commanded angles outside the limits and zero velocity-limit violations."""
    arm = retarget.load_arm("wx250s")
    out_path = tmp_path / "traj.csv"
    code, _, err = export(capsys, str(clip), "--side", side, "-o", str(out_path))
    assert code == 0, err
    t, q = trajectory(out_path.read_text(), arm)
    motion = retarget.load_bvh(clip)
    last_frame = (motion.n_frames - 1) * motion.frame_time
    assert last_frame - 0.01 < t[-1] <= last_frame  # the whole clip, at 100 Hz
    check_safe(t, q, arm, 100)
    # every tick converged, but those where IK stopped short at the nearest pose clear of a collision
    m = re.search(r"(\d+) ticks .*IK ([\d.]+)% converged.*IK stopped short by a collision (\d+)\)", err)
    assert m, err
    ticks, pct, short = int(m.group(1)), float(m.group(2)), int(m.group(3))
    assert round(100.0 * (ticks - short) / ticks, 1) == pct, err


@pytest.mark.parametrize(
    ("args", "match"),
    [
        (["missing.bvh"], r"missing\.bvh"),
        (["--rate", "-5"], r"--rate: Expected a tick rate > 0 Hz"),
        (["--rate", "fast"], r"--rate: Expected a number \(got 'fast'\)"),
        (["--arm", "nope"], r"nope"),
        (["--end", "0"], r"--end: Expected an end time after start \(0 s\)"),
        (["-o", "/nonexistent/dir/traj.csv"], r"/nonexistent/dir/traj\.csv"),
        (["--jerk-cost", "-1"], r"--jerk-cost: Expected a jerk cost from 0 to 1 \(0: none\) \(got -1\.0\)"),
        (["--jerk-cost", "2"], r"--jerk-cost: Expected a jerk cost from 0 to 1 \(0: none\) \(got 2\.0\)"),
        (["--jerk-cost", "nan"], r"--jerk-cost: Expected a jerk cost from 0 to 1 \(0: none\) \(got nan\)"),
    ],
    ids=["missing-clip", "rate", "rate-text", "arm", "end", "output-dir", "jerk-negative", "jerk-high", "jerk-nan"],
)
def test_bad_input_exits_2_with_one_line(capsys, args, match):
    import re

    code, out, err = export(capsys, *args)
    assert code == 2
    assert out == ""
    lines = err.strip().splitlines()
    assert len(lines) == 1 and re.search(match, lines[0]), err


@pytest.mark.skipif(not DANCE.is_file(), reason=f"{DANCE} not found (set RETARGET_SHARED_BVH)")
def test_jerk_cost_trades_following_for_smoothness(capsys):
    """The plan's jerk cost: 0 follows the clip as closely as the limits allow, a higher one trades that for a
    smoother acceleration, the default between (3 s of motion_dance, whose joints need planning; the RMS of the
    commanded joints' third differences)."""
    arm = retarget.load_arm("wx250s")
    runs = {}
    for cost in ("0", None, "0.01", "0.0003"):
        flags = () if cost is None else ("--jerk-cost", cost)
        code, out, err = export(capsys, str(DANCE), "--end", "3", *flags)
        assert code == 0, err
        runs[cost] = trajectory(out, arm)[1]
    jerk = {k: float(np.sqrt(np.mean(np.diff(q, 3, axis=0) ** 2))) for k, q in runs.items()}
    assert jerk["0.01"] < jerk[None] < jerk["0"]
    assert np.array_equal(runs["0.0003"], runs[None])  # the default is plan.JERK_COST


def test_help_has_examples(capsys):
    with pytest.raises(SystemExit):
        main(["export", "--help"])
    out = capsys.readouterr().out
    assert "examples:" in out and "retarget export dance.bvh --arm wx250s -o traj.csv" in out
