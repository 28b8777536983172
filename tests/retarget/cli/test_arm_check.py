"""``retarget arm A --check Q``: each collision pair's clearance, as text and JSON, and bad poses."""

from __future__ import annotations

import json
import math
import re

import numpy as np
import pytest

from retarget import load_arm
from retarget.cli import main
from retarget.collision import CollisionModel


def run(capsys, *argv):
    code = main(["arm", *argv])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.parametrize("arm", ["wx250s", "vx300s", "px100", "omx", "koch"])
def test_json_matches_the_model_at_rest(capsys, arm):
    code, out, _ = run(capsys, arm, "--check", "rest", "--json")
    assert code == 0
    check = json.loads(out)["check"]
    model = CollisionModel.for_arm(load_arm(arm))
    d = model.distances(model.arm.rest)
    want = dict(zip(model.pair_names, (d * 1e3).tolist(), strict=True))
    got = {p["pair"]: p["clearance_mm"] for p in check["pairs"]}
    assert got.keys() == want.keys()
    assert all(abs(got[k] - want[k]) <= 5e-4 for k in want)
    values = [p["clearance_mm"] for p in check["pairs"]]
    assert values == sorted(values)  # worst first
    assert check["clear"] is True and check["clearance_mm"] == 10.0 and check["within_limits"] is True


def test_text_lists_every_pair_and_flags_a_folded_pose(capsys):
    q_deg = [0, 80, 80, 110]  # OpenMANIPULATOR-X folded: gripper onto its own shoulder
    code, out, _ = run(capsys, "omx", "--check", ",".join(map(str, q_deg)))
    assert code == 0
    model = CollisionModel.for_arm(load_arm("omx"))
    d = model.distances(np.radians(q_deg))
    assert "check q (deg) 0.00 80.00 80.00 110.00: NOT clear, clearance 10 mm" in out
    rows = dict(re.findall(r"^    (\S+)\s+(-?[\d.]+) mm", out, re.M))
    assert set(rows) == set(model.pair_names)
    for name, value in zip(model.pair_names, d, strict=True):
        assert float(rows[name]) == pytest.approx(value * 1e3, abs=0.051)
    worst = model.pair_names[int(np.argmin(d))]
    assert re.search(rf"^    {re.escape(worst)}\s+-[\d.]+ mm  <$", out, re.M)


def test_a_pose_outside_the_limits_is_checked_and_said(capsys):
    code, out, _ = run(capsys, "px100", "--check", "0,0,0,170", "--json")
    check = json.loads(out)["check"]
    assert code == 0 and check["within_limits"] is False and check["q_deg"] == [0, 0, 0, 170]
    assert math.isfinite(check["pairs"][0]["clearance_mm"])


@pytest.mark.parametrize(
    "pose", ["1,2", "a,b,c,d,e,f", "0,0,0,0,0,nan", "sleep", ""], ids=["short", "text", "nan", "name", "empty"]
)
def test_bad_pose_is_one_line_exit_2(capsys, pose):
    code, out, err = run(capsys, "wx250s", "--check", pose)
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and "--check: expected home, rest or 6 finite angles in degrees" in err
