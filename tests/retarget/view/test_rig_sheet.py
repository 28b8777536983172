"""``retarget view --rig``: every arm drawn at its base pose in the rig's world frame (checked against FK and a base
transform computed here), the skeleton where the rig's mapping puts it, the contact sheet and the Rerun recording
written, and the options that name one arm or a one-arm output refused in one line."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from retarget.cli import build_parser, main
from retarget.cli.view import solve_rig
from retarget.control.loop import TickRecord
from retarget.rig.plant import RigPlant
from retarget.view.rig import RigScene, arm_columns

#: a rig whose bases are turned and raised, so a missing rotation or offset shows
RIG = """\
[[arms]]
name = "port"
arm = "wx250s"
xyz = [0.05, 0.32, 0.02]
rpy = [0.0, 0.0, 20.0]
side = "left"

[[arms]]
name = "starboard"
arm = "wx250s"
xyz = [0.05, -0.32, 0.02]
rpy = [0.0, 0.0, -25.0]
side = "right"
"""
POSES = {"port": ((0.05, 0.32, 0.02), 20.0), "starboard": ((0.05, -0.32, 0.02), -25.0)}


def base_transform(xyz, yaw_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """World from base: a turn about z by ``yaw_deg`` then ``xyz`` (the rig file's pose, computed here)."""
    c, s = math.cos(math.radians(yaw_deg)), math.sin(math.radians(yaw_deg))
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]), np.array(xyz)


@pytest.fixture(scope="module")
def rig_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("rig") / "turned.toml"
    path.write_text(RIG)
    return path


@pytest.fixture(scope="module")
def solved(rig_file):
    args = build_parser().parse_args(["view", "--rig", str(rig_file), "--end", "1.5", "--no-filter"])
    inputs, replay, records = solve_rig(args)
    scene = RigScene.for_clip(inputs.motion, inputs.rig, inputs.targets)
    return inputs, scene, arm_columns(records, replay.arm_record, inputs.rig, rate=replay.config.rate)


def test_each_arm_is_drawn_at_its_base_pose(solved):
    inputs, scene, cols = solved
    rows = np.array([0, 40, 97, len(cols["port"]) - 1])
    for name, (xyz, yaw) in POSES.items():
        arm = inputs.rig[name].arm
        R, t = base_transform(xyz, yaw)
        q = cols[name].q_cmd[rows]
        links, tools = scene.arm_points(name, q)
        for k, row in enumerate(q):
            T, points = arm.fk(row)
            np.testing.assert_allclose(links[k], points @ R.T + t, atol=1e-12)
            np.testing.assert_allclose(tools[k, :3, 3], R @ T[:3, 3] + t, atol=1e-12)
            np.testing.assert_allclose(tools[k, :3, :3], R @ T[:3, :3], atol=1e-12)
        capsules = scene.capsules(name, q)
        own = scene[name].scene.links.capsules(q)  # the arm's capsules in its base frame
        np.testing.assert_allclose(capsules, own @ R.T + t, atol=1e-12)
    # the two arms are apart where their bases are: the waists' origins 0.64 m apart across y
    waists = [scene.arm_points(n, cols[n].q_cmd[:1])[0][0, 0] for n in POSES]
    assert waists[0][1] - waists[1][1] == pytest.approx(0.64, abs=1e-9)


def test_each_arms_velocity_limited_marks_are_its_own_not_the_rigs_flag(solved):
    """The rig's limiter flag is one for both arms: each arm's marks come from its own commanded speeds."""
    rig = solved[0].rig
    plant = RigPlant.of(rig)
    port, starboard = plant.slices
    vmax = rig.arms[0].arm.max_velocity
    records = []
    for tick in range(5):  # port's waist at its full speed from tick 1 on, starboard still; the rig flag always set
        q = plant.join({a.name: a.arm.home for a in rig.arms})
        q[port.start] += vmax[0] / 100.0 * tick
        records.append(TickRecord(tick=tick, time=tick / 100, clip_time=tick / 100, target=np.zeros(6), q_cmd=q,
                                  q_present=None, ik_error=0.0, ik_sweeps=0, ik_converged=True, compute_time=0.0,
                                  bus_time=0.0, clamped=False, velocity_limited=True, overrun=False, bus_retries=0,
                                  lead_in=False))  # fmt: skip

    def split(record: TickRecord, name: str) -> TickRecord:
        part = port if name == "port" else starboard
        i = rig.names.index(name)
        return dataclasses.replace(record, q_cmd=record.q_cmd[part], target=record.target[3 * i : 3 * i + 3])

    columns = arm_columns(records, split, rig, rate=100.0)
    assert columns["port"].velocity_limited.tolist() == [False, True, True, True, True]
    assert columns["starboard"].velocity_limited.tolist() == [False] * 5


def test_each_human_wrist_lands_on_its_own_arms_world_target(solved):
    inputs, scene, cols = solved
    human = scene.human
    for name, raw_world in inputs.targets.world.items():
        wrist = scene.chains[name][2]
        for frame in (0, 33, 90):
            np.testing.assert_allclose(human.human_points(frame)[wrist], raw_world[frame], atol=1e-9)
        # and the raw target the sheet draws is the same point (no filter: the clamp is all that moves it)
        t = cols[name].clip_time[:5]
        np.testing.assert_allclose(scene.raw_targets(name, t)[0], raw_world[0], atol=1e-9)
    port, starboard = (scene.chains[n][2] for n in POSES)
    assert port != starboard  # each arm follows its own hand


def test_rig_sheet_png_shows_both_arms_in_their_colours(rig_file, tmp_path, capsys):
    pytest.importorskip("matplotlib", reason="the viz extra (matplotlib) is not installed")
    from matplotlib.image import imread

    from retarget.view.rig_sheet import ARM_COLORS

    path = tmp_path / "rig.png"
    assert main(["view", "--rig", str(rig_file), "--end", "1.5", "--moments", "3", "--png", str(path)]) == 0
    assert "ticks of demo.bvh on rig turned" in capsys.readouterr().err
    image = imread(path)[..., :3]
    assert image.shape[1] > 900 and image.shape[0] > 600
    for color in ARM_COLORS[:2]:
        rgb = np.array([int(color[i : i + 2], 16) for i in (1, 3, 5)]) / 255
        assert np.count_nonzero(np.abs(image - rgb).max(axis=-1) < 0.02) > 200, color  # each arm's solid lines


def test_rig_record_places_each_arm_under_its_base_transform(solved, rig_file, tmp_path):
    rr_chunk = pytest.importorskip("rerun.chunk", reason="the viz extra (rerun-sdk) is not installed")
    inputs, _, cols = solved
    path = tmp_path / "rig.rrd"
    assert main(["view", "--rig", str(rig_file), "--end", "1.5", "--no-filter", "--record", str(path)]) == 0
    rows: dict[str, dict[str, object]] = {}
    joints: dict[str, dict[int, list]] = {}
    for chunk in rr_chunk.RrdReader(path).stream():
        batch = chunk.to_record_batch().to_pylist()
        if chunk.entity_path.endswith("/robot/joints"):
            joints.setdefault(chunk.entity_path, {}).update({r["tick"]: r for r in batch if "tick" in r})
        else:
            rows.setdefault(chunk.entity_path, {}).update(batch[-1])
    for name, (xyz, yaw) in POSES.items():
        R, t = base_transform(xyz, yaw)
        pose = rows[f"/world/arms/{name}"]
        np.testing.assert_allclose(np.reshape(pose["Transform3D:mat3x3"][0], (3, 3)).T, R, atol=1e-6)  # columns
        np.testing.assert_allclose(pose["Transform3D:translation"][0], t, atol=1e-6)
        logged = joints[f"/world/arms/{name}/robot/joints"]
        assert sorted(logged) == list(range(len(cols[name])))
        _, points = inputs.rig[name].arm.fk(cols[name].q_cmd[57])
        np.testing.assert_allclose(logged[57]["Points3D:positions"], points, atol=1e-5)  # its base frame
    assert {f"/plots/{n}/joints/waist/cmd" for n in POSES} <= set(rows)
    assert {f"/world/human/arm/{n}" for n in POSES} <= set(rows) | set(joints)


@pytest.mark.parametrize(
    ("extra", "says"),
    [
        (["--arm", "vx300s"], "--arm"),
        (["--side", "left"], "--side"),
        (["--layout", "side"], "--layout"),
        (["run.rrd", "--web"], "--rig"),
    ],
    ids=["arm", "side", "layout-side", "serve-recording"],
)
def test_options_a_rig_view_cannot_take_are_one_line_and_exit_2(extra, says, capsys, tmp_path):
    code = main(["view", "--rig", "aloha", *extra, "--png", str(tmp_path / "x.png")])
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert len(err.splitlines()) == 1 and says in err and "Traceback" not in err
    assert not (tmp_path / "x.png").exists()
