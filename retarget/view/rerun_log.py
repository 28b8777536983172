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

A rig (:func:`log_rig_scene`, :func:`log_rig_ticks`): ``world`` is the rig's world frame; ``world/table``;
``world/arms/<name>`` holds each arm's base pose (a static transform) and, under it, that arm's entities as above
(``robot/...``, ``target/...``, ``workspace/...``, in its base frame); its plots go under ``plots/<name>/...``;
``world/human`` is placed as the rig's mapping places it (per tick), each human arm under
``world/human/arm/<name>`` in its robot arm's colour.

Timelines: ``tick`` (the slot, a sequence), ``time`` (run time) and ``clip_time``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from retarget.view.columns import TickColumns
from retarget.view.rig import RigArmScene, RigScene
from retarget.view.scene import Layout, Scene, capsule_poses, frame_index, robot_points, workspace_strips

__all__ = ["blueprint", "log_rig_scene", "log_rig_ticks", "log_scene", "log_ticks", "rig_blueprint"]

HUMAN, ARM_CHAIN, ROBOT, TARGET, RAW = (160, 160, 170), (255, 140, 0), (40, 110, 220), (220, 30, 30), (255, 0, 255)
AXES = ([230, 40, 40], [40, 190, 40], [40, 90, 240])  # x/forward red, y/left green, z/up blue
TOOL_AXIS_M = 0.05
EVENTS = ("clamped", "velocity_limited", "overrun", "stale")
#: a rig's arms, in rig order (the contact sheet's blue, green, purple, brown); its table
RIG_COLORS = ((42, 110, 220), (30, 158, 70), (142, 68, 173), (160, 82, 45))
TABLE = (241, 233, 220, 200)


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


def log_scene(
    rec: rr.RecordingStream, scene: Scene, *, world: str = "world", plots: str = "plots", color: Any = ROBOT
) -> None:
    """The static part: workspace, styles, series names, and the side layout's human placement.  ``world``: the
    entity the arm's 3D entities go under (its base frame); ``plots``: the one its plots go under; ``color``:
    the arm's RGB."""
    ws = scene.workspace
    rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    *shell, floor = workspace_strips(ws)
    rec.log(f"{world}/workspace/shell", rr.LineStrips3D(shell, colors=[150, 150, 150, 90], radii=-0.75), static=True)
    rec.log(f"{world}/workspace/floor", rr.LineStrips3D([floor], colors=[120, 90, 40], radii=-1.0), static=True)
    rec.log(f"{world}/robot/base", rr.Points3D([[0.0, 0.0, 0.0]], colors=[color], radii=-6.0, labels=["base"]),
            static=True)  # fmt: skip
    rec.log(f"{world}/robot/links", rr.LineStrips3D.from_fields(colors=[color], radii=-4.0), static=True)
    rec.log(f"{world}/robot/joints", rr.Points3D.from_fields(colors=[color], radii=-5.0), static=True)
    rec.log(f"{world}/robot/present", rr.LineStrips3D.from_fields(colors=[[40, 200, 200, 160]], radii=-2.0),
            static=True)  # fmt: skip
    rec.log(f"{world}/robot/tool", rr.Arrows3D.from_fields(colors=AXES, radii=-1.5, labels=["x", "y", "z"]),
            static=True)  # fmt: skip
    rec.log(f"{world}/target/clamped", rr.Points3D.from_fields(colors=[TARGET], radii=-6.0), static=True)
    if scene.links is not None:
        shapes = scene.links
        rec.log(f"{world}/robot/capsules", rr.Capsules3D.from_fields(radii=shapes.radii, colors=[(*color[:3], 60)],
                labels=list(shapes.names), show_labels=False), static=True)  # fmt: skip
        if shapes.base_boxes:
            _, centres, halves = zip(*shapes.base_boxes, strict=True)
            rec.log(f"{world}/robot/base_boxes", rr.Boxes3D(centers=centres, half_sizes=halves,
                    colors=[(*color[:3], 60)], labels=[b[0] for b in shapes.base_boxes], show_labels=False),
                    static=True)  # fmt: skip
    rec.log(f"{world}/target/raw", rr.Points3D.from_fields(colors=[RAW], radii=-5.0, labels=["raw"]), static=True)
    rec.log(f"{world}/target/pull", rr.LineStrips3D.from_fields(colors=[RAW], radii=-1.0), static=True)
    for name, lo, hi in zip(scene.arm.joint_names, scene.arm.lower, scene.arm.upper, strict=True):
        base = f"{plots}/joints/{name}"
        rec.log(f"{base}/cmd", rr.SeriesLines(names=f"{name} cmd", widths=1.5), static=True)
        rec.log(f"{base}/present", rr.SeriesLines(names=f"{name} present", widths=1.0), static=True)
        for which, value in (("lower", lo), ("upper", hi)):
            rec.log(f"{base}/{which}", rr.SeriesLines(names=f"{name} {which} {np.degrees(value):.0f}°", widths=0.5),
                    static=True)  # fmt: skip
    for event in EVENTS:
        rec.log(f"{plots}/events/{event}", rr.SeriesPoints(names=event, markers="cross", marker_sizes=4.0),
                static=True)  # fmt: skip
    if scene.skeleton is not None:
        _log_human_styles(rec, scene, chain=True)


def _log_human_styles(rec: rr.RecordingStream, scene: Scene, *, chain: bool) -> None:
    """The skeleton's static styles under ``world/human`` (and the side layout's placement there)."""
    rec.log("world/human/joints", rr.Points3D.from_fields(colors=[HUMAN], radii=-3.0), static=True)
    rec.log("world/human/bones", rr.LineStrips3D.from_fields(colors=[HUMAN], radii=-2.0), static=True)
    if chain:
        rec.log("world/human/arm", rr.LineStrips3D.from_fields(colors=[ARM_CHAIN], radii=-4.0), static=True)
    rec.log("world/human/torso", rr.Arrows3D.from_fields(colors=AXES, radii=-1.5, labels=["fwd", "left", "up"]),
            static=True)  # fmt: skip
    if scene.layout is Layout.SIDE and scene.human_linear is not None and scene.human_offset is not None:
        rec.log("world/human", rr.Transform3D(mat3x3=scene.human_linear[0], translation=scene.human_offset[0]),
                static=True)  # fmt: skip


def _sender(rec: rr.RecordingStream, cols: TickColumns) -> Any:
    """``send(path, columns, rows=None)``: one entity's rows on the ticks' timelines (every tick, or ``rows``)."""

    def send(path: str, columns: Any, rows: np.ndarray | None = None) -> None:
        at = slice(None) if rows is None else rows
        index = [
            rr.TimeColumn("tick", sequence=cols.tick[at]),
            rr.TimeColumn("time", duration=cols.time[at]),
            rr.TimeColumn("clip_time", duration=cols.clip_time[at]),
        ]
        rec.send_columns(path, indexes=index, columns=columns)

    return send


def log_ticks(
    rec: rr.RecordingStream, scene: Scene, cols: TickColumns, *, world: str = "world", plots: str = "plots"
) -> None:
    """Every entity's rows for the ticks in ``cols``, as columns (one call per entity); ``world``, ``plots`` as in
    :func:`log_scene`."""
    n = len(cols)
    send = _sender(rec, cols)
    points, tools = robot_points(scene.arm, cols.q_cmd)
    send(f"{world}/robot/links", rr.LineStrips3D.columns(strips=points).partition(np.ones(n, dtype=np.int64)))
    joints = rr.Points3D.columns(positions=points.reshape(-1, 3)).partition(_each(n, points.shape[1]))
    send(f"{world}/robot/joints", joints)
    origins = np.repeat(tools[:, :3, 3], 3, axis=0)
    vectors = np.transpose(tools[:, :3, :3], (0, 2, 1)).reshape(-1, 3) * TOOL_AXIS_M
    send(f"{world}/robot/tool", rr.Arrows3D.columns(origins=origins, vectors=vectors).partition(_each(n, 3)))
    if scene.links is not None:
        ends = scene.links.capsules(cols.q_cmd)  # (n, n_caps, 2, 3)
        lengths, quats, at = capsule_poses(ends.reshape(-1, 2, 3))
        columns = rr.Capsules3D.columns(lengths=lengths, quaternions=quats, translations=at)
        send(f"{world}/robot/capsules", columns.partition(_each(n, ends.shape[1])))
    if cols.q_present is not None:
        read = ~np.isnan(cols.q_present).any(axis=1)
        if read.any():
            present, _ = robot_points(scene.arm, cols.q_present[read])
            strips = rr.LineStrips3D.columns(strips=present).partition(np.ones(int(read.sum()), dtype=np.int64))
            send(f"{world}/robot/present", strips, np.flatnonzero(read))
    clamped = rr.Points3D.columns(positions=cols.target).partition(np.ones(n, dtype=np.int64))
    send(f"{world}/target/clamped", clamped)
    raw = scene.raw_targets(cols.clip_time)
    if raw is not None:
        moved = cols.clamped.astype(np.int64)
        send(f"{world}/target/raw", rr.Points3D.columns(positions=raw[cols.clamped]).partition(moved))
        pulls = np.stack([raw, cols.target], axis=1)[cols.clamped]
        send(f"{world}/target/pull", rr.LineStrips3D.columns(strips=pulls).partition(moved))
    _log_human(send, scene, cols)
    _log_series(send, scene, cols, plots)


def _log_human(send: Any, scene: Scene, cols: TickColumns, *, chain: bool = True) -> None:
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
    arm = pts[:, list(sk.chain)]  # (n, 3, 3)
    if chain:
        send("world/human/arm", rr.LineStrips3D.columns(strips=arm).partition(np.ones(n, dtype=np.int64)))
    if scene.torso is not None and scene.body is not None:
        upper, fore = (np.linalg.norm(arm[:, i + 1] - arm[:, i], axis=-1) for i in (0, 1))
        length = 0.5 * float(np.median(upper + fore))
        origins = np.repeat(scene.torso[frames], 3, axis=0)
        vectors = np.transpose(scene.body[frames], (0, 2, 1)).reshape(-1, 3) * length
        send("world/human/torso", rr.Arrows3D.columns(origins=origins, vectors=vectors).partition(_each(n, 3)))
    if scene.layout is Layout.OVERLAY and scene.human_linear is not None and scene.human_offset is not None:
        columns = rr.Transform3D.columns(mat3x3=scene.human_linear[frames], translation=scene.human_offset[frames])
        send("world/human", columns)


def rig_blueprint(scene: RigScene) -> rrb.Blueprint:
    """A rig's default layout: the world left, each arm's joint angles and IK error right."""
    names = [a.name for a in scene.arms]
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial3DView(origin="world", name=f"human and rig {scene.rig.name}"),
            rrb.Vertical(
                *(rrb.TimeSeriesView(origin=f"plots/{name}/joints", name=f"{name} joints (deg)") for name in names),
                *(
                    rrb.TimeSeriesView(origin=f"plots/{name}/ik", name=f"{name} IK error (mm), sweeps")
                    for name in names
                ),
            ),
            column_shares=[3, 2],
        ),
        collapse_panels=True,
    )


def log_rig_scene(rec: rr.RecordingStream, scene: RigScene) -> None:
    """A rig's static part: the table, each arm's base pose (``world/arms/<name>``, a transform) and, under it,
    its scene as one arm's (:func:`log_scene`, its plots under ``plots/<name>``), and the skeleton's styles."""
    rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    corners = np.concatenate([_footprint(a) for a in scene.arms])
    lo, hi = corners.min(axis=0), corners.max(axis=0)
    if scene.table:
        rec.log("world/table", rr.Boxes3D(centers=[[*(lo + hi) / 2, -0.005]], half_sizes=[[*(hi - lo) / 2, 0.005]],
                colors=[TABLE], fill_mode="solid", labels=["table"], show_labels=False), static=True)  # fmt: skip
    for k, a in enumerate(scene.arms):
        T = a.placement.matrix
        rec.log(f"world/arms/{a.name}", rr.Transform3D(translation=T[:3, 3], mat3x3=T[:3, :3]), static=True)
        log_scene(rec, a.scene, world=f"world/arms/{a.name}", plots=f"plots/{a.name}", color=arm_color(k))
    _log_human_styles(rec, scene.human, chain=False)
    for k, a in enumerate(scene.arms):
        rec.log(f"world/human/arm/{a.name}", rr.LineStrips3D.from_fields(colors=[arm_color(k)], radii=-4.0),
                static=True)  # fmt: skip


def log_rig_ticks(rec: rr.RecordingStream, scene: RigScene, cols: dict[str, TickColumns]) -> None:
    """Every arm's ticks (``cols``, by arm name: its part of each rig tick) under its base pose, and the skeleton
    placed in the world as the rig's mapping places it, each human arm under ``world/human/arm/<name>``."""
    for a in scene.arms:
        log_ticks(rec, a.scene, cols[a.name], world=f"world/arms/{a.name}", plots=f"plots/{a.name}")
    first = cols[scene.arms[0].name]
    send = _sender(rec, first)
    human = scene.human
    _log_human(send, human, first, chain=False)
    if human.points is None or human.targets is None:
        return
    frames = frame_index(first.clip_time, human.targets.frame_time, human.points.shape[0])
    ones = np.ones(len(first), dtype=np.int64)
    for name, chain in scene.chains.items():
        strips = rr.LineStrips3D.columns(strips=human.points[frames][:, list(chain)]).partition(ones)
        send(f"world/human/arm/{name}", strips)


def arm_color(k: int) -> tuple[int, int, int]:
    """The RGB of a rig's ``k``-th arm (the contact sheet's colours)."""
    return RIG_COLORS[k % len(RIG_COLORS)]


def _footprint(a: RigArmScene) -> np.ndarray:
    """``(4, 2)`` metres, world: the corners of the square of the arm's reach around its base, on the table."""
    r = a.scene.workspace.r_max
    square = np.array([[-r, -r, 0.0], [r, -r, 0.0], [r, r, 0.0], [-r, r, 0.0]]) + [*a.scene.workspace.center[:2], 0]
    corners: np.ndarray = a.to_world(square)[:, :2]
    return corners


def _log_series(send: Any, scene: Scene, cols: TickColumns, plots: str) -> None:
    n = len(cols)
    for j, (name, lo, hi) in enumerate(zip(scene.arm.joint_names, scene.arm.lower, scene.arm.upper, strict=True)):
        base = f"{plots}/joints/{name}"
        send(f"{base}/cmd", rr.Scalars.columns(scalars=np.degrees(cols.q_cmd[:, j])))
        send(f"{base}/lower", rr.Scalars.columns(scalars=np.full(n, np.degrees(lo))))
        send(f"{base}/upper", rr.Scalars.columns(scalars=np.full(n, np.degrees(hi))))
        if cols.q_present is not None:
            read = np.flatnonzero(~np.isnan(cols.q_present[:, j]))
            if read.size:
                send(f"{base}/present", rr.Scalars.columns(scalars=np.degrees(cols.q_present[read, j])), read)
    send(f"{plots}/ik/error_mm", rr.Scalars.columns(scalars=cols.ik_error * 1e3))
    send(f"{plots}/ik/sweeps", rr.Scalars.columns(scalars=cols.ik_sweeps.astype(np.float64)))
    send(f"{plots}/timing/compute_ms", rr.Scalars.columns(scalars=cols.compute_time * 1e3))
    send(f"{plots}/timing/bus_ms", rr.Scalars.columns(scalars=cols.bus_time * 1e3))
    send(f"{plots}/bus/retries", rr.Scalars.columns(scalars=cols.bus_retries.astype(np.float64)))
    flags = {"clamped": cols.clamped, "velocity_limited": cols.velocity_limited, "overrun": cols.overrun,
             "stale": cols.stale > 0}  # fmt: skip
    for level, event in enumerate(EVENTS, start=1):
        rows = np.flatnonzero(flags[event])
        if rows.size:
            send(f"{plots}/events/{event}", rr.Scalars.columns(scalars=np.full(rows.size, float(level))), rows)


def _each(n: int, k: int) -> np.ndarray:
    return np.full(n, k, dtype=np.int64)
