"""A contact sheet of a clip on a rig (matplotlib, Agg: no GUI): evenly spaced moments, lettered, each one picture
of the rig's world frame seen from behind the operator (the left arm on the left): the table with a 10 cm grid,
every arm posed at its base pose in its own colour with its target, and the human's upper body where the rig's
mapping puts it (the middle of the shoulders on the mapping's origin, one scale for both hands), each human arm in
the colour of the robot arm it drives, its wrist on that arm's target before the reach clamp.  Below, each arm's
commanded joint angles over the clip, the moments marked.  The picture helpers are the one-arm sheet's
(:mod:`retarget.view.sheet`).

    rig_contact_sheet(scene, {"left": cols_left, "right": cols_right}, Path("rig.png"), moments=6)
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.axes import Axes  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402

from retarget.view import sheet  # noqa: E402
from retarget.view.columns import TickColumns  # noqa: E402
from retarget.view.rig import RigScene  # noqa: E402
from retarget.view.scene import frame_index, project  # noqa: E402

__all__ = ["ARM_COLORS", "RIG_VIEW", "RigMoments", "rig_contact_sheet", "rig_moments"]

#: one colour per arm, in rig order: blue, green, purple, brown
ARM_COLORS = ("#2a6edc", "#1e9e46", "#8e44ad", "#a0522d")
TABLE = "#f1e9dc"  #: the table top's fill
#: the camera: behind the operator (azimuth 180 looks along +x, the rig's forward), a little to the right, above
RIG_VIEW = {"azimuth": -165.0, "elevation": 40.0}


@dataclass(frozen=True)
class RigMoments:
    """What the rig's sheet draws at its ``n`` moments, metres, world frame."""

    rows: np.ndarray  #: ``(n,)`` tick rows
    arms: dict[str, np.ndarray]  #: per arm: ``(n, n_joints + 1, 3)`` joint origins and tool point
    tools: dict[str, np.ndarray]  #: per arm: ``(n, 4, 4)`` world from tool
    capsules: dict[str, np.ndarray | None]  #: per arm: ``(n, n_capsules, 2, 3)`` link capsules' end points
    targets: dict[str, np.ndarray]  #: per arm: ``(n, 3)`` after the workspace clamp
    raw: dict[str, np.ndarray]  #: per arm: ``(n, 3)`` before the clamp
    human: np.ndarray  #: ``(n, n_points, 3)`` skeleton points


def rig_moments(scene: RigScene, cols: dict[str, TickColumns], rows: np.ndarray) -> RigMoments:
    """The world-frame geometry of the ticks ``rows`` of every arm's ``cols`` (by arm name)."""
    first = cols[scene.arms[0].name]
    arms, tools, capsules, targets, raw = {}, {}, {}, {}, {}
    for a in scene.arms:
        c = cols[a.name]
        arms[a.name], tools[a.name] = scene.arm_points(a.name, c.q_cmd[rows])
        capsules[a.name] = scene.capsules(a.name, c.q_cmd[rows])
        targets[a.name] = a.to_world(c.target[rows])
        raw[a.name] = scene.raw_targets(a.name, c.clip_time[rows])
    human = scene.human
    assert human.points is not None and human.targets is not None  # a clip's scene
    frames = frame_index(first.clip_time[rows], human.targets.frame_time, human.points.shape[0])
    placed = np.stack([human.human_points(int(f)) for f in frames])
    return RigMoments(rows, arms, tools, capsules, targets, raw, placed)


def rig_contact_sheet(
    scene: RigScene, cols: dict[str, TickColumns], path: Path, *, moments: int = 6, title: str = ""
) -> None:
    """Draw the rig's sheet to ``path`` (PNG), about 1000 px wide; ``cols``: every arm's ticks, by arm name."""
    first = cols[scene.arms[0].name]
    m = rig_moments(scene, cols, sheet.moment_ticks(len(first), moments))
    drawn = _drawn_points(scene, cols, m)
    radius = max((float(a.scene.links.radii.max()) for a in scene.arms if a.scene.links is not None), default=0.0)
    picture = sheet.fixed_frame(np.concatenate([drawn, *_table(drawn)]), radius, len(m.rows), human=True,
                                view=RIG_VIEW)  # fmt: skip
    fig, cells, strips = sheet.layout_sheet([picture], first.clip_time[m.rows], strips=len(scene.arms),
                                            strip_height=1.25)  # fmt: skip
    for i, cell in enumerate(cells):
        for ax, _ in cell:
            _picture(ax, scene, cols, m, i, drawn)
    for ax, a in zip(strips, scene.arms, strict=True):
        sheet.angle_strip(ax, a.scene.arm, cols[a.name], m.rows, label=f"{a.name} (deg)")
    height = fig.get_figheight()
    models = ", ".join(sorted({a.scene.arm.title or a.scene.arm.name for a in scene.arms}))
    fig.text(0.5, 1 - 0.22 / height, f"{title} on rig {scene.rig.name} ({models}): the skeleton in the rig's frame",
             ha="center", va="center", fontsize=11)  # fmt: skip
    clamped = any(bool(cols[a.name].clamped[m.rows].any()) for a in scene.arms)
    sheet.legend(fig, 1 - 0.5 / height, _handles(scene, clamped=clamped))
    fig.savefig(path, dpi=sheet.DPI)
    plt.close(fig)


def _drawn_points(scene: RigScene, cols: dict[str, TickColumns], m: RigMoments) -> np.ndarray:
    """``(k, 3)`` points that bound what the pictures draw (before the capsules' radii): the arms, their bases,
    targets and clamped raw targets, and the skeleton's upper body."""
    parts = [m.human[:, _upper_points(scene)].reshape(-1, 3)]
    for a in scene.arms:
        parts += [m.arms[a.name].reshape(-1, 3), m.targets[a.name], a.to_world(np.zeros((1, 3)))]
        capsules = m.capsules[a.name]
        if capsules is not None:
            parts.append(capsules.reshape(-1, 3))
        parts.append(m.raw[a.name][cols[a.name].clamped[m.rows]])
    return np.concatenate(parts)


def _upper_points(scene: RigScene) -> np.ndarray:
    """The skeleton point indices the upper body's bones join."""
    assert scene.human.skeleton is not None
    return np.unique(scene.human.skeleton.bones[scene.upper])


def _table(points: np.ndarray) -> list[np.ndarray]:
    """The table's grid lines (z = 0, every 10 cm) under ``points`` ``(k, 3)``; their ends bound the table top."""
    return sheet.floor_grid(points)


def _picture(ax: Axes, scene: RigScene, cols: dict[str, TickColumns], m: RigMoments, i: int, drawn: np.ndarray) -> None:
    view = RIG_VIEW
    grid = _table(drawn)
    corners = np.concatenate(grid)
    lo, hi = corners[:, :2].min(axis=0), corners[:, :2].max(axis=0)
    top = project(np.array([[lo[0], lo[1], 0], [hi[0], lo[1], 0], [hi[0], hi[1], 0], [lo[0], hi[1], 0]]), **view)
    if scene.table:
        ax.fill(top[:, 0], top[:, 1], color=TABLE, lw=0, zorder=0.05)
    sheet.grid_lines(ax, grid, view=view)
    human = scene.human
    assert human.skeleton is not None
    p = project(m.human[i], **view)
    for a, b in human.skeleton.bones[scene.upper]:
        ax.plot(p[[a, b], 0], p[[a, b], 1], color=sheet.HUMAN, lw=2.2, solid_capstyle="round", zorder=1)
    for k, a in enumerate(scene.arms):
        color = ARM_COLORS[k % len(ARM_COLORS)]
        chain = p[list(scene.chains[a.name])]
        ax.plot(chain[:, 0], chain[:, 1], "--", color=color, lw=2.0, alpha=0.8, dash_capstyle="round", zorder=1.5)
        c = cols[a.name]
        row = int(m.rows[i])
        base = project(a.to_world(np.zeros(3)), **view)
        ax.plot([base[0]], [base[1]], "s", color=color, ms=6, zorder=2)
        ax.annotate(a.name, (base[0], base[1]), xytext=(0, -9), textcoords="offset points", ha="center", va="top",
                    fontsize=7.5, color=color, weight="bold")  # fmt: skip
        capsules = m.capsules[a.name]
        sheet.draw_arm(
            ax,
            m.arms[a.name][i],
            m.tools[a.name][i],
            m.targets[a.name][i],
            capsules=None if capsules is None else capsules[i],
            radii=None if a.scene.links is None else a.scene.links.radii,
            raw=m.raw[a.name][i] if c.clamped[row] else None,
            color=color,
            target_color=color,
            view=view,
        )


def _handles(scene: RigScene, *, clamped: bool) -> list[Line2D]:
    handles = [
        Line2D(
            [],
            [],
            color=ARM_COLORS[k % len(ARM_COLORS)],
            lw=3,
            marker="o",
            ms=3.5,
            label=f"{a.name} arm \u2190 {a.side.value} hand",
        )
        for k, a in enumerate(scene.arms)
    ]
    handles += [
        Line2D([], [], color=sheet.HUMAN, lw=2, label="skeleton"),
        Line2D([], [], color="#555555", lw=2, ls="--", label="its arms"),
        Line2D([], [], color="#555555", marker="o", mfc="none", mew=1.6, lw=0, label="target"),
    ]
    if clamped:
        handles.append(sheet.raw_handle())
    table = "table" if scene.table else "z = 0"  # the collision world's table (off with --no-table)
    handles.append(Line2D([], [], color=sheet.GRID, lw=1.5, label=f"{table}, {sheet.GRID_STEP * 100:.0f} cm grid"))
    return handles
