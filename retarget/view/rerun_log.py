"""Log a :class:`~retarget.view.scene.Scene` and batches of ticks to a Rerun recording (needs the ``viz`` extra).

Entities (display frame = the robot's base frame, metres, z up; angles in the plots in degrees):

- ``world/workspace/shell``, ``world/workspace/floor`` (static): the workspace the targets are clamped into;
- ``world/robot/links`` (one polyline through the joint origins to the tool point), ``world/robot/joints``,
  ``world/robot/tool`` (the tool frame's x, y, z axes), ``world/robot/present`` (the pose read back, live);
- where the arm file has link geometry: ``world/robot/capsules`` (its capsules, posed as the collision checks
  pose them) and ``world/robot/base_boxes`` (static);
- ``world/target/clamped``, and where the clamp moved it ``world/target/raw`` and ``world/target/pull``;
- ``world/human`` (the placement transform: static for the side layout, per tick for the overlay), under it, in
  BVH file units and the BVH world frame, ``joints`` (joints then End Sites), ``bones``, ``arm`` (the driving
  chain) and ``torso`` (the body frame's forward, left, up);
- ``plots/joints/<joint>/{cmd,present,lower,upper}`` degrees, ``plots/ik/{error_mm,sweeps}``,
  ``plots/events/{clamped,velocity_limited,overrun,stale}``, ``plots/timing/{compute_ms,bus_ms}``,
  ``plots/bus/retries``.

Timelines: ``tick`` (the slot, a sequence), ``time`` (run time) and ``clip_time``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from retarget.view.columns import TickColumns
from retarget.view.scene import Layout, Scene, capsule_poses, frame_index, robot_points, workspace_strips

__all__ = ["log_scene", "log_ticks", "blueprint"]

HUMAN, ARM_CHAIN, ROBOT, TARGET, RAW = (160, 160, 170), (255, 140, 0), (40, 110, 220), (220, 30, 30), (255, 0, 255)
SHAPES = (40, 110, 220, 60)  # the link geometry: the robot's blue, see-through
AXES = ([230, 40, 40], [40, 190, 40], [40, 90, 240])  # x/forward red, y/left green, z/up blue
TOOL_AXIS_M = 0.05
EVENTS = ("clamped", "velocity_limited", "overrun", "stale")


def blueprint(scene: Scene) -> rrb.Blueprint:
    """The default layout: the 3D scene left, joint angles, IK and events right."""
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial3DView(origin="world", name="human and robot"),
            rrb.Vertical(
                rrb.TimeSeriesView(origin="plots/joints", name="joints (deg)"),
                rrb.TimeSeriesView(origin="plots/ik", name="IK error (mm), sweeps"),
                rrb.TimeSeriesView(origin="plots/events", name="clamped, velocity-limited, overrun"),
                rrb.TimeSeriesView(origin="plots/timing", name="tick times (ms)"),
            ),
            column_shares=[3, 2],
        ),
        collapse_panels=True,
    )


def log_scene(rec: rr.RecordingStream, scene: Scene) -> None:
    """The static part: workspace, styles, series names, and the side layout's human placement."""
    ws = scene.workspace
    rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    *shell, floor = workspace_strips(ws)
    rec.log("world/workspace/shell", rr.LineStrips3D(shell, colors=[150, 150, 150, 90], radii=-0.75), static=True)
    rec.log("world/workspace/floor", rr.LineStrips3D([floor], colors=[120, 90, 40], radii=-1.0), static=True)
    rec.log(
        "world/robot/base", rr.Points3D([[0.0, 0.0, 0.0]], colors=[ROBOT], radii=-6.0, labels=["base"]), static=True
    )
    rec.log("world/robot/links", rr.LineStrips3D.from_fields(colors=[ROBOT], radii=-4.0), static=True)
    rec.log("world/robot/joints", rr.Points3D.from_fields(colors=[ROBOT], radii=-5.0), static=True)
    rec.log("world/robot/present", rr.LineStrips3D.from_fields(colors=[[40, 200, 200, 160]], radii=-2.0), static=True)
    rec.log("world/robot/tool", rr.Arrows3D.from_fields(colors=AXES, radii=-1.5, labels=["x", "y", "z"]), static=True)
    rec.log("world/target/clamped", rr.Points3D.from_fields(colors=[TARGET], radii=-6.0), static=True)
    if scene.links is not None:
        shapes = scene.links
        rec.log("world/robot/capsules", rr.Capsules3D.from_fields(radii=shapes.radii, colors=[SHAPES],
                labels=list(shapes.names), show_labels=False), static=True)  # fmt: skip
        if shapes.base_boxes:
            _, centres, halves = zip(*shapes.base_boxes, strict=True)
            rec.log("world/robot/base_boxes", rr.Boxes3D(centers=centres, half_sizes=halves, colors=[SHAPES],
                    labels=[b[0] for b in shapes.base_boxes], show_labels=False), static=True)  # fmt: skip
    rec.log("world/target/raw", rr.Points3D.from_fields(colors=[RAW], radii=-5.0, labels=["raw"]), static=True)
    rec.log("world/target/pull", rr.LineStrips3D.from_fields(colors=[RAW], radii=-1.0), static=True)
    for name, lo, hi in zip(scene.arm.joint_names, scene.arm.lower, scene.arm.upper, strict=True):
        base = f"plots/joints/{name}"
        rec.log(f"{base}/cmd", rr.SeriesLines(names=f"{name} cmd", widths=1.5), static=True)
        rec.log(f"{base}/present", rr.SeriesLines(names=f"{name} present", widths=1.0), static=True)
        for which, value in (("lower", lo), ("upper", hi)):
            rec.log(f"{base}/{which}", rr.SeriesLines(names=f"{name} {which} {np.degrees(value):.0f}°", widths=0.5),
                    static=True)  # fmt: skip
    for event in EVENTS:
        rec.log(f"plots/events/{event}", rr.SeriesPoints(names=event, markers="cross", marker_sizes=4.0), static=True)
    if scene.skeleton is None:
        return
    rec.log("world/human/joints", rr.Points3D.from_fields(colors=[HUMAN], radii=-3.0), static=True)
    rec.log("world/human/bones", rr.LineStrips3D.from_fields(colors=[HUMAN], radii=-2.0), static=True)
    rec.log("world/human/arm", rr.LineStrips3D.from_fields(colors=[ARM_CHAIN], radii=-4.0), static=True)
    rec.log("world/human/torso", rr.Arrows3D.from_fields(colors=AXES, radii=-1.5, labels=["fwd", "left", "up"]),
            static=True)  # fmt: skip
    if scene.layout is Layout.SIDE and scene.human_linear is not None and scene.human_offset is not None:
        rec.log("world/human", rr.Transform3D(mat3x3=scene.human_linear[0], translation=scene.human_offset[0]),
                static=True)  # fmt: skip


def log_ticks(rec: rr.RecordingStream, scene: Scene, cols: TickColumns) -> None:
    """Every entity's rows for the ticks in ``cols``, as columns (one call per entity)."""
    n = len(cols)

    def send(path: str, columns: Any, rows: np.ndarray | None = None) -> None:
        """One entity's rows: every tick, or the ticks ``rows``."""
        at = slice(None) if rows is None else rows
        index = [
            rr.TimeColumn("tick", sequence=cols.tick[at]),
            rr.TimeColumn("time", duration=cols.time[at]),
            rr.TimeColumn("clip_time", duration=cols.clip_time[at]),
        ]
        rec.send_columns(path, indexes=index, columns=columns)

    points, tools = robot_points(scene.arm, cols.q_cmd)
    send("world/robot/links", rr.LineStrips3D.columns(strips=points).partition(np.ones(n, dtype=np.int64)))
    send(
        "world/robot/joints", rr.Points3D.columns(positions=points.reshape(-1, 3)).partition(_each(n, points.shape[1]))
    )
    origins = np.repeat(tools[:, :3, 3], 3, axis=0)
    vectors = np.transpose(tools[:, :3, :3], (0, 2, 1)).reshape(-1, 3) * TOOL_AXIS_M
    send("world/robot/tool", rr.Arrows3D.columns(origins=origins, vectors=vectors).partition(_each(n, 3)))
    if scene.links is not None:
        ends = scene.links.capsules(cols.q_cmd)  # (n, n_caps, 2, 3)
        lengths, quats, at = capsule_poses(ends.reshape(-1, 2, 3))
        columns = rr.Capsules3D.columns(lengths=lengths, quaternions=quats, translations=at)
        send("world/robot/capsules", columns.partition(_each(n, ends.shape[1])))
    if cols.q_present is not None:
        read = ~np.isnan(cols.q_present).any(axis=1)
        if read.any():
            present, _ = robot_points(scene.arm, cols.q_present[read])
            strips = rr.LineStrips3D.columns(strips=present).partition(np.ones(int(read.sum()), dtype=np.int64))
            send("world/robot/present", strips, np.flatnonzero(read))
    send("world/target/clamped", rr.Points3D.columns(positions=cols.target).partition(np.ones(n, dtype=np.int64)))
    raw = scene.raw_targets(cols.clip_time)
    if raw is not None:
        moved = cols.clamped.astype(np.int64)
        send("world/target/raw", rr.Points3D.columns(positions=raw[cols.clamped]).partition(moved))
        pulls = np.stack([raw, cols.target], axis=1)[cols.clamped]
        send("world/target/pull", rr.LineStrips3D.columns(strips=pulls).partition(moved))
    _log_human(send, scene, cols)
    _log_series(send, scene, cols)


def _log_human(send: Any, scene: Scene, cols: TickColumns) -> None:
    if scene.skeleton is None or scene.points is None or scene.targets is None:
        return
    n = len(cols)
    sk = scene.skeleton
    frames = frame_index(cols.clip_time, scene.targets.frame_time, scene.points.shape[0])
    pts = scene.points[frames]  # (n, n_points, 3) file units
    send("world/human/joints", rr.Points3D.columns(positions=pts.reshape(-1, 3)).partition(_each(n, pts.shape[1])))
    bones = pts[:, sk.bones]  # (n, n_bones, 2, 3)
    send(
        "world/human/bones", rr.LineStrips3D.columns(strips=bones.reshape(-1, 2, 3)).partition(_each(n, len(sk.bones)))
    )
    chain = pts[:, list(sk.chain)]  # (n, 3, 3)
    send("world/human/arm", rr.LineStrips3D.columns(strips=chain).partition(np.ones(n, dtype=np.int64)))
    if scene.torso is not None and scene.body is not None:
        upper, fore = (np.linalg.norm(chain[:, i + 1] - chain[:, i], axis=-1) for i in (0, 1))
        length = 0.5 * float(np.median(upper + fore))
        origins = np.repeat(scene.torso[frames], 3, axis=0)
        vectors = np.transpose(scene.body[frames], (0, 2, 1)).reshape(-1, 3) * length
        send("world/human/torso", rr.Arrows3D.columns(origins=origins, vectors=vectors).partition(_each(n, 3)))
    if scene.layout is Layout.OVERLAY and scene.human_linear is not None and scene.human_offset is not None:
        columns = rr.Transform3D.columns(mat3x3=scene.human_linear[frames], translation=scene.human_offset[frames])
        send("world/human", columns)


def _log_series(send: Any, scene: Scene, cols: TickColumns) -> None:
    n = len(cols)
    for j, (name, lo, hi) in enumerate(zip(scene.arm.joint_names, scene.arm.lower, scene.arm.upper, strict=True)):
        base = f"plots/joints/{name}"
        send(f"{base}/cmd", rr.Scalars.columns(scalars=np.degrees(cols.q_cmd[:, j])))
        send(f"{base}/lower", rr.Scalars.columns(scalars=np.full(n, np.degrees(lo))))
        send(f"{base}/upper", rr.Scalars.columns(scalars=np.full(n, np.degrees(hi))))
        if cols.q_present is not None:
            read = np.flatnonzero(~np.isnan(cols.q_present[:, j]))
            if read.size:
                send(f"{base}/present", rr.Scalars.columns(scalars=np.degrees(cols.q_present[read, j])), read)
    send("plots/ik/error_mm", rr.Scalars.columns(scalars=cols.ik_error * 1e3))
    send("plots/ik/sweeps", rr.Scalars.columns(scalars=cols.ik_sweeps.astype(np.float64)))
    send("plots/timing/compute_ms", rr.Scalars.columns(scalars=cols.compute_time * 1e3))
    send("plots/timing/bus_ms", rr.Scalars.columns(scalars=cols.bus_time * 1e3))
    send("plots/bus/retries", rr.Scalars.columns(scalars=cols.bus_retries.astype(np.float64)))
    flags = {"clamped": cols.clamped, "velocity_limited": cols.velocity_limited, "overrun": cols.overrun,
             "stale": cols.stale > 0}  # fmt: skip
    for level, event in enumerate(EVENTS, start=1):
        rows = np.flatnonzero(flags[event])
        if rows.size:
            send(f"plots/events/{event}", rr.Scalars.columns(scalars=np.full(rows.size, float(level))), rows)


def _each(n: int, k: int) -> np.ndarray:
    return np.full(n, k, dtype=np.int64)
