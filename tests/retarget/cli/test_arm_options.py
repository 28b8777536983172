"""``--arm/--base/--tip`` shared by replay, export, teleop and sim: a URDF whose chain has two leaves."""

from __future__ import annotations

import argparse
import csv
import io
import json
import re

import numpy as np
import pytest

import retarget
from retarget.cli import main
from retarget.cli import sim as sim_cli
from retarget.errors import ConfigError
from tests.helpers import urdf_text

# A 4-joint arm; a camera hangs off the upper arm, so the chain from base_link has two leaves.
JOINTS = [
    ("waist", "revolute", "base_link", "shoulder_link", "0 0 0.08", "0 0 1", (-3.1, 3.1)),
    ("shoulder", "revolute", "shoulder_link", "upper_link", "0 0 0.04", "0 1 0", (-1.8, 1.8)),
    ("elbow", "revolute", "upper_link", "forearm_link", "0.05 0 0.2", "0 1 0", (-2.0, 1.6)),
    ("wrist", "revolute", "forearm_link", "hand_link", "0.2 0 0", "0 1 0", (-1.7, 2.1)),
    ("tool", "fixed", "hand_link", "tool_link", "0.08 0 0", None, None),
    ("camera", "fixed", "upper_link", "camera_link", "0 0 0.05", None, None),
]
SERVOS = """\
name = "twoleaf"
[joints.waist]
servos = [{ id = 1, model = "XL430-W250" }]
[joints.shoulder]
servos = [{ id = 2, model = "XL430-W250" }]
[joints.elbow]
servos = [{ id = 3, model = "XL430-W250" }]
[joints.wrist]
servos = [{ id = 4, model = "XL430-W250" }]
"""
AMBIGUOUS = "--tip: cannot tell the tip link: leaves camera_link, tool_link; name one"


@pytest.fixture
def urdf(tmp_path) -> str:
    path = tmp_path / "twoleaf.urdf"
    path.write_text(urdf_text(JOINTS))
    (tmp_path / "twoleaf.servos.toml").write_text(SERVOS)
    return str(path)


def cli(capsys, *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def one_line_error(code: int, out: str, err: str) -> str:
    assert code == 2 and out == ""
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("retarget: "), err
    return lines[0]


COMMANDS = {
    "replay": ["replay", "--dry-run", "--fast", "--end", "0.5"],
    "export": ["export", "--end", "0.5", "-o", "-"],
    "teleop": ["teleop", "--to", "0.25,0,0.25", "--fast"],
}


@pytest.mark.parametrize("command", list(COMMANDS))
def test_an_ambiguous_urdf_names_the_leaves_and_the_option(capsys, urdf, command):
    line = one_line_error(*cli(capsys, *COMMANDS[command], "--arm", urdf))
    assert line == f"retarget: {urdf}: {AMBIGUOUS}"


@pytest.mark.parametrize("command", list(COMMANDS))
@pytest.mark.parametrize(
    ("extra", "match"),
    [
        (["--tip", "nowhere"], r": --tip: no link named 'nowhere'; links: "),
        (["--base", "nowhere", "--tip", "tool_link"], r": --base: no link named 'nowhere'; links: "),
        (["--base", "upper_link", "--tip", "shoulder_link"], r": --tip: tip link 'shoulder_link' is not below"),
    ],
    ids=["unknown-tip", "unknown-base", "tip-above-base"],
)
def test_bad_links_name_the_option(capsys, urdf, command, extra, match):
    line = one_line_error(*cli(capsys, *COMMANDS[command], "--arm", urdf, *extra))
    assert re.search(match, line), line


@pytest.mark.parametrize("command", list(COMMANDS))
@pytest.mark.parametrize("option", ["--base", "--tip"])
def test_base_and_tip_need_a_urdf(capsys, command, option):
    line = one_line_error(*cli(capsys, *COMMANDS[command], option, "x"))
    assert line == f"retarget: {option}: {option} only applies to a URDF --arm, not wx250s.toml (got 'x')"


def test_export_with_tip_writes_the_chains_trajectory(capsys, urdf):
    code, out, err = cli(capsys, "export", "--arm", urdf, "--base", "base_link", "--tip", "tool_link", "--end", "2")
    assert code == 0, err
    arm = retarget.load_arm(urdf, tip="tool_link")
    assert arm.joint_names == ("waist", "shoulder", "elbow", "wrist") and arm.tool_xyz == pytest.approx((0.08, 0, 0))
    rows = list(csv.reader(io.StringIO(out)))
    assert rows[0] == ["time_s", "waist_rad", "shoulder_rad", "elbow_rad", "wrist_rad"]
    data = np.array(rows[1:], dtype=np.float64)
    assert len(data) == 201 and "201 ticks of twoleaf" in err
    q = data[:, 1:]
    assert np.all(q >= arm.lower - 1e-6) and np.all(q <= arm.upper + 1e-6)
    assert np.all(np.abs(np.diff(q, axis=0)) <= arm.max_velocity / 100 + 2e-6)
    assert np.ptp(q, axis=0).max() > 0.1  # it moves


def test_replay_and_teleop_with_tip_run_on_the_simulated_arm(capsys, urdf):
    code, out, err = cli(capsys, "replay", "--arm", urdf, "--tip", "tool_link", "--fast", "--json", "--end", "0.5")
    assert code == 0, err
    summary = json.loads(out)
    assert summary["arm"] == "twoleaf" and summary["ticks"] == 51 and summary["bus_errors"] == 0
    code, out, err = cli(capsys, "teleop", "--arm", urdf, "--tip", "tool_link", "--to", "0.25,0,0.25", "--fast",
                         "--json")  # fmt: skip
    assert code == 0, err
    doc = json.loads(out)["teleop"]
    assert doc["reached"] is True and doc["residual_mm"] <= 5 and len(doc["joints_deg"]) == 4
    # the reached point is the tool link's: FK of the joints the servos report, through the URDF chain's tool
    arm = retarget.load_arm(urdf, tip="tool_link")
    np.testing.assert_allclose(arm.fk(np.radians(doc["joints_deg"]))[0][:3, 3], [0.25, 0, 0.25], atol=5e-3)


def sim_args(*argv: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="retarget")
    sim_cli.add_parser(parser.add_subparsers(dest="command"))
    return parser.parse_args(["sim", *argv])


def test_sim_serves_a_urdf_arm_with_tip(urdf):
    with pytest.raises(ConfigError, match=re.escape(AMBIGUOUS)):
        sim_cli.build_bus(sim_args("--arm", urdf))
    bus = sim_cli.build_bus(sim_args("--arm", urdf, "--tip", "tool_link"))
    assert bus.ids == (1, 2, 3, 4)
    with pytest.raises(ConfigError, match=r"--tip: --tip goes with a URDF --arm, not --ids"):
        sim_cli.build_bus(sim_args("--ids", "1-3", "--tip", "tool_link"))
    with pytest.raises(ConfigError, match=r"--base: --base only applies to a URDF --arm, not wx250s\.toml"):
        sim_cli.build_bus(sim_args("--base", "base_link"))
