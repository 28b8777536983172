"""``retarget view`` / ``replay --record``: the Rerun recording read back with Rerun's own reader
(``rerun.chunk.RrdReader``) and checked against independent computations; the commands without the extra."""

from __future__ import annotations

import csv
import os
import subprocess
import sys
from collections import defaultdict

import numpy as np
import pytest

import retarget
from retarget.bvh import DEMO_CLIP
from retarget.cli import main

rr_chunk = pytest.importorskip("rerun.chunk", reason="the viz extra (rerun-sdk) is not installed")


def read_rrd(path) -> dict[str, dict[int, object]]:
    """entity path -> {tick: the row's last column (the component's value)}; static rows under tick -1."""
    out: dict[str, dict[int, object]] = defaultdict(dict)
    for chunk in rr_chunk.RrdReader(path).stream():
        batch = chunk.to_record_batch()
        names = batch.schema.names
        values = batch.column(len(names) - 1).to_pylist()
        ticks = batch.column(names.index("tick")).to_pylist() if "tick" in names else [-1] * batch.num_rows
        for tick, value in zip(ticks, values, strict=True):
            key = tick if isinstance(tick, int) else -1
            out[chunk.entity_path][key] = value
    return out


def export_csv(capsys, tmp_path, *args: str) -> np.ndarray:
    path = tmp_path / "traj.csv"
    assert main(["export", *args, "-o", str(path)]) == 0, capsys.readouterr().err
    rows = list(csv.reader(path.open()))
    return np.array(rows[1:], dtype=np.float64)


@pytest.fixture(scope="module")
def demo_rrd(tmp_path_factory):
    path = tmp_path_factory.mktemp("view") / "demo.rrd"
    assert main(["view", "--end", "2", "--record", str(path)]) == 0
    return path, read_rrd(path)


def test_view_records_every_entity_once_per_tick(demo_rrd, capsys, tmp_path):
    _, data = demo_rrd
    arm = retarget.load_arm("wx250s")
    traj = export_csv(capsys, tmp_path, "--end", "2")
    ticks = len(traj)
    for entity in ("/world/robot/links", "/world/robot/joints", "/world/robot/tool", "/world/target/clamped",
                   "/world/human/joints", "/world/human/bones", "/world/human/arm", "/world/human/torso",
                   "/plots/ik/error_mm", *(f"/plots/joints/{j}/cmd" for j in arm.joint_names)):  # fmt: skip
        assert sorted(k for k in data[entity] if k >= 0) == list(range(ticks)), entity  # -1: static style
    for static in ("/world/workspace/shell", "/world/workspace/floor", "/world/human"):
        assert list(data[static]) == [-1], static
    # the commanded angles are export's trajectory (degrees in the plots; CSV rounded to 1e-6 rad)
    cmd = np.array([[data[f"/plots/joints/{j}/cmd"][k][0] for j in arm.joint_names] for k in range(ticks)])
    np.testing.assert_allclose(np.radians(cmd), traj[:, 1:], atol=2e-6)


def test_logged_skeleton_is_the_clips_fk_and_the_arm_is_the_fk_of_the_logged_angles(demo_rrd):
    _, data = demo_rrd
    motion = retarget.load_bvh(DEMO_CLIP)
    arm = retarget.load_arm("wx250s")
    expected = np.concatenate([motion.positions(), motion.end_site_positions()], axis=1)
    for tick in (0, 57, 150, 199):
        frame = round(tick * 0.01 / motion.frame_time)  # clip time of the tick at 100 Hz -> nearest frame
        np.testing.assert_allclose(np.array(data["/world/human/joints"][tick]), expected[frame], rtol=1e-6, atol=1e-4)
        q = np.radians([data[f"/plots/joints/{j}/cmd"][tick][0] for j in arm.joint_names])
        _, points = arm.fk(q)
        np.testing.assert_allclose(np.array(data["/world/robot/joints"][tick]), points, atol=1e-5)
        links = np.array(data["/world/robot/links"][tick][0])
        np.testing.assert_allclose(links, points, atol=1e-5)


def test_replay_on_a_sim_bus_records_the_present_angles(capsys, tmp_path):
    rrd, tel = tmp_path / "live.rrd", tmp_path / "live.csv"
    args = ["replay", "--port", "sim://wx250s", "--fast", "--max-ticks", "60", "--lead-in", "0"]
    code = main([*args, "--record", str(rrd), "--telemetry", str(tel), "--shutdown", "hold"])
    assert code == 0, capsys.readouterr().err
    arm = retarget.load_arm("wx250s")
    rows = list(csv.DictReader(tel.open()))
    data = read_rrd(rrd)
    assert len(rows) == 60
    for row in rows[::7]:
        tick = int(row["tick"])
        present = np.radians([data[f"/plots/joints/{j}/present"][tick][0] for j in arm.joint_names])
        read = np.array([float(row[f"{j}_present_rad"]) for j in arm.joint_names])
        np.testing.assert_allclose(present, read, atol=2e-6)  # the servos' reading (one pulse = 1.5e-3 rad)
        _, points = arm.fk(present)
        np.testing.assert_allclose(np.array(data["/world/robot/present"][tick][0]), points, atol=1e-5)


@pytest.mark.parametrize(
    ("argv", "name"),
    [
        (["view", "--record", "x.rrd"], "rerun"),
        (["view", "--png", "x.png"], "matplotlib"),
        (["plot", "run.csv", "-o", "x.png"], "matplotlib"),
        (["replay", "--dry-run", "--fast", "--record", "x.rrd"], "rerun"),
        (["teleop", "--to", "0.3,0,0.2", "--fast", "--web"], "rerun"),
    ],
    ids=["view", "view-png", "plot", "replay", "teleop"],
)
def test_without_the_extra_one_line_and_exit_2(tmp_path, argv, name):
    (tmp_path / "sitecustomize.py").write_text(
        "import sys\nsys.modules['rerun'] = None\nsys.modules['matplotlib'] = None\n"
    )
    (tmp_path / "run.csv").write_text("time_s\n0\n")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path), os.environ.get("PYTHONPATH", "")])}
    proc = subprocess.run([sys.executable, "-m", "retarget", *argv], cwd=tmp_path, env=env, capture_output=True,
                          text=True, timeout=60)  # fmt: skip
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "pip install 'retarget[viz]'" in lines[0] and name in lines[0], proc.stderr
    assert not (tmp_path / "x.rrd").exists() and not (tmp_path / "x.png").exists()


def read_component(path, entity: str, component: str) -> dict[int, object]:
    """{tick: value} of one component of one entity (static rows under -1)."""
    out: dict[int, object] = {}
    for chunk in rr_chunk.RrdReader(path).stream():
        batch = chunk.to_record_batch()
        if chunk.entity_path != entity or component not in batch.schema.names:
            continue
        names = batch.schema.names
        ticks = batch.column(names.index("tick")).to_pylist() if "tick" in names else [-1] * batch.num_rows
        out.update(zip(ticks, batch.column(names.index(component)).to_pylist(), strict=True))
    return out


def rotate(quats: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``v`` ``(3,)`` turned by each unit quaternion ``(m, 4)`` (x, y, z, w): ``(m, 3)``."""
    xyz, w = quats[:, :3], quats[:, 3:]
    t = 2 * np.cross(xyz, np.broadcast_to(v, xyz.shape))
    return v + w * t + np.cross(xyz, t)


def test_logged_capsules_are_the_collision_models_for_the_logged_angles(demo_rrd):
    from retarget.collision import CollisionModel

    path, data = demo_rrd
    arm = retarget.load_arm("wx250s")
    assert arm.geometry is not None
    model = CollisionModel.for_arm(arm)
    entity = "/world/robot/capsules"
    lengths, quats = (
        read_component(path, entity, "Capsules3D:lengths"),
        read_component(path, entity, "Capsules3D:quaternions"),
    )
    starts, radii = (
        read_component(path, entity, "Capsules3D:translations"),
        read_component(path, entity, "Capsules3D:radii"),
    )
    for tick in (0, 83, 199):
        q = np.radians([data[f"/plots/joints/{j}/cmd"][tick][0] for j in arm.joint_names])
        ends, r = model.capsules(q)
        a = np.array(starts[tick])
        b = a + np.array(lengths[tick])[:, None] * rotate(np.array(quats[tick]), np.array([0.0, 0.0, 1.0]))
        np.testing.assert_allclose(a, ends[:, 0], atol=1e-5)  # float32 in the recording
        np.testing.assert_allclose(b, ends[:, 1], atol=1e-5)
        np.testing.assert_allclose(radii[-1], r, rtol=1e-6)
    moved = np.abs(np.array(starts[199]) - np.array(starts[0])).max()
    assert moved > 0.01  # the capsules follow the arm


@pytest.mark.parametrize("rig", [[], ["--rig", "wx250s-pair"]], ids=["one-arm", "rig"])
def test_the_native_viewer_without_a_display_is_one_line_and_exit_2(capsys, monkeypatch, rig):
    """No display (a server, CI): the native viewer would die at once and the recording wait for it forever; the
    command says so at once instead, with the other ways to look, and solves nothing."""
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr(sys, "platform", "linux")
    monkeypatch.setattr("retarget.cli.view.solve", None)  # nothing is solved first (calling None would raise)
    monkeypatch.setattr("retarget.cli.view.solve_rig", None)
    assert main(["view", "--end", "0.2", *rig]) == 2
    err = capsys.readouterr().err.strip()
    assert err == (
        "retarget: --view: Expected a display for a native Rerun viewer (DISPLAY and WAYLAND_DISPLAY are "
        "unset); use --png, --web or --record (got True)"
    ), err
