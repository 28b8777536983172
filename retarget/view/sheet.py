"""A contact sheet of a solved clip (matplotlib, Agg: no GUI): evenly spaced moments, lettered, up to three to a
row; in each the skeleton (the driving arm highlighted) and the posed robot arm side by side, at the same scale
(the mapping's: the human arm is as long as the robot arm it drives) and from the same camera, each standing on
a 10 cm floor grid; below them the commanded joint angles in degrees over the clip, the moments marked with
their letters.  In the overlay layout each moment is one picture: the human in the robot's frame.

    contact_sheet(scene, columns, Path("sheet.png"), moments=6)
"""

from __future__ import annotations

import math
import string
from dataclasses import dataclass
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.axes import Axes  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402

from retarget.arm.model import Arm  # noqa: E402
from retarget.view.columns import TickColumns  # noqa: E402
from retarget.view.scene import Layout, Scene, frame_index, project, robot_points  # noqa: E402

__all__ = ["contact_sheet", "draw_arm", "layout_sheet", "moment_ticks", "stadium"]

HUMAN, CHAIN, ROBOT, TARGET, RAW, GRID = "#9a9aa4", "#ff8c00", "#2a6edc", "#dc1e1e", "#e000e0", "#d8d8d8"
AXES_COLORS = ("#e62828", "#28be28", "#285af0")
#: the camera: from the robot's front right, a little above (azimuth 0 looks along -x at the robot's front)
VIEW = {"azimuth": -50.0, "elevation": 16.0}
WIDTH, DPI = 10.4, 96  #: inches, dots per inch: about 1000 px, a README's width
GRID_STEP = 0.1  #: metres between the floor grid's lines
PAD = 0.03  #: metres of margin around what a picture shows


@dataclass(frozen=True)
class _Moments:
    """What the sheet draws at its ``n`` moments, display frame (metres, robot base frame, z up)."""

    rows: np.ndarray  #: ``(n,)`` tick rows
    arm: np.ndarray  #: ``(n, n_joints + 1, 3)`` joint origins and tool point
    tools: np.ndarray  #: ``(n, 4, 4)`` tool frames
    capsules: np.ndarray | None  #: ``(n, n_capsules, 2, 3)`` link capsules' end points
    human: np.ndarray | None  #: ``(n, n_points, 3)`` skeleton points
    raw: np.ndarray | None  #: ``(n, 3)`` targets before the workspace clamp


def moment_ticks(n_ticks: int, moments: int) -> np.ndarray:
    """``moments`` evenly spaced row indices into ``n_ticks`` ticks, first and last included.

    >>> moment_ticks(101, 5).tolist()
    [0, 25, 50, 75, 100]
    """
    return np.unique(np.rint(np.linspace(0, n_ticks - 1, min(moments, n_ticks))).astype(np.intp))


def per_row(moments: int) -> int:
    """How many moments share a row of the sheet: three (two for four), up to four when there are many.

    >>> [per_row(n) for n in (1, 2, 3, 4, 6, 9, 12, 24)]
    [1, 2, 3, 2, 3, 3, 4, 4]
    """
    if moments == 4:
        return 2
    return min(moments, 3 if moments <= 9 else 4)


def contact_sheet(scene: Scene, cols: TickColumns, path: Path, *, moments: int = 6, title: str = "") -> None:
    """Draw the sheet to ``path`` (PNG), about 1000 px wide."""
    m = _moments(scene, cols, moment_ticks(len(cols), moments))
    pictures = _frames(scene, cols, m)
    fig, cells, strips = layout_sheet(pictures, cols.clip_time[m.rows])
    for i, cell in enumerate(cells):
        for ax, f in cell:
            _picture(ax, scene, cols, m, i, human=f.human, robot=f.robot)
    angle_strip(strips[0], scene.arm, cols, m.rows)
    layout = "the skeleton beside the arm, same scale" if scene.layout is Layout.SIDE else "the skeleton in its frame"
    height = fig.get_figheight()
    fig.text(0.5, 1 - 0.22 / height, f"{title} on {scene.arm.title or scene.arm.name}: {layout}",
             ha="center", va="center", fontsize=11)  # fmt: skip
    clamped = m.raw is not None and bool(cols.clamped[m.rows].any())
    legend(fig, 1 - 0.5 / height, _handles(clamped=clamped))
    fig.savefig(path, dpi=DPI)
    plt.close(fig)


def layout_sheet(
    pictures: list[Frame], times: np.ndarray, *, strips: int = 1, strip_height: float = 1.6
) -> tuple[Figure, list[list[tuple[Axes, Frame]]], list[Axes]]:
    """The sheet's figure, about 1000 px wide: a title and legend band on top, then the moments (``times``
    ``(n,)`` s, lettered) up to four to a row, each as the ``pictures`` side by side at one scale (inches per
    metre), then ``strips`` plots over the clip's time, one under the other.  Returns the figure, each moment's
    (axes, picture) pairs with the view limits set, and the strips' axes (top first)."""
    n, k = len(times), per_row(len(times))
    n_rows = math.ceil(n / k)
    left, right, gap, head, label, foot = 0.25, 0.25, 0.3, 0.75, 0.28, 0.85  # inches
    cell_w = (WIDTH - left - right - gap * (k - 1)) / k
    span = sum(f.width for f in pictures) + PAD * (len(pictures) - 1)
    height_m = max(f.height for f in pictures)
    cell_h = min(0.7 * cell_w, 3.6)  # the sheet's size depends on the number of moments only
    scale = min(cell_w / span, cell_h / height_m)  # inches per metre, every picture
    height = head + n_rows * (label + cell_h) + 0.35 + strips * (strip_height + foot)
    fig = plt.figure(figsize=(WIDTH, height), dpi=DPI)
    cells: list[list[tuple[Axes, Frame]]] = []
    for i in range(n):
        r, c = divmod(i, k)
        x0 = left + c * (cell_w + gap) + (cell_w - span * scale) / 2
        top = height - head - r * (label + cell_h)
        fig.text((left + c * (cell_w + gap) + cell_w / 2) / WIDTH, (top - label / 2) / height,
                 f"{letter(i)}   t = {times[i]:.2f} s", ha="center", va="center", fontsize=9,
                 weight="bold")  # fmt: skip
        cells.append([])
        for f in pictures:
            w = f.width * scale
            bottom = top - label - (cell_h + height_m * scale) / 2
            ax = fig.add_axes((x0 / WIDTH, bottom / height, w / WIDTH, height_m * scale / height))
            x0 += w + PAD * scale
            x_lo, y_lo = f.corners[i]
            ax.set_xlim(x_lo, x_lo + f.width)
            ax.set_ylim(y_lo, y_lo + height_m)
            ax.set_aspect("equal", adjustable="datalim")
            ax.axis("off")
            cells[-1].append((ax, f))
    axes = [fig.add_axes((0.75 / WIDTH, (foot + (strips - 1 - j) * (strip_height + foot)) / height,
                          (WIDTH - 0.95) / WIDTH, strip_height / height)) for j in range(strips)]  # fmt: skip
    return fig, cells, axes


def stadium(ends: np.ndarray, radius: float, *, segments: int = 10) -> np.ndarray:
    """The outline ``(2 * segments + 2, 2)`` of a capsule seen orthographically: the points within ``radius`` of
    the projected segment ``ends`` ``(2, 2)`` (a sphere projects to a circle of its own radius).

    >>> (stadium(np.array([[0.0, 0.0], [2.0, 0.0]]), 1.0, segments=2).round(3) + 0.0).tolist()
    [[2.0, -1.0], [3.0, 0.0], [2.0, 1.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]]
    """
    a, b = ends
    d = b - a
    base = math.atan2(d[1], d[0]) if np.hypot(*d) > 1e-12 else 0.0
    arc = np.linspace(-math.pi / 2, math.pi / 2, segments + 1)
    around_b = b + radius * np.stack([np.cos(base + arc), np.sin(base + arc)], axis=-1)
    around_a = a + radius * np.stack([np.cos(base + math.pi + arc), np.sin(base + math.pi + arc)], axis=-1)
    return np.concatenate([around_b, around_a])


def floor_grid(points: np.ndarray, *, step: float = GRID_STEP) -> list[np.ndarray]:
    """The floor grid (z = 0) under ``points`` ``(m, 3)``: lines ``(2, 3)`` every ``step`` metres along x and y,
    covering the points' footprint rounded out to whole steps.

    >>> [line.tolist() for line in floor_grid(np.array([[0.05, 0.02, 0.3], [0.15, 0.08, 0.0]]))]
    [[[0.0, 0.0, 0.0], [0.0, 0.1, 0.0]], [[0.1, 0.0, 0.0], [0.1, 0.1, 0.0]], [[0.2, 0.0, 0.0], [0.2, 0.1, 0.0]], \
[[0.0, 0.0, 0.0], [0.2, 0.0, 0.0]], [[0.0, 0.1, 0.0], [0.2, 0.1, 0.0]]]
    """
    lo = np.floor(points[:, :2].min(axis=0) / step + 1e-9)
    hi = np.ceil(points[:, :2].max(axis=0) / step - 1e-9)
    xs, ys = np.arange(lo[0], hi[0] + 1) * step, np.arange(lo[1], hi[1] + 1) * step
    lines = [np.array([[x, ys[0], 0.0], [x, ys[-1], 0.0]]) for x in xs]
    lines += [np.array([[xs[0], y, 0.0], [xs[-1], y, 0.0]]) for y in ys]
    return [line.round(9) + 0.0 for line in lines]


def letter(i: int) -> str:
    """The label of moment ``i``: A, B, ... Z, then numbers."""
    return string.ascii_uppercase[i] if i < 26 else str(i + 1)


def _moments(scene: Scene, cols: TickColumns, rows: np.ndarray) -> _Moments:
    arm, tools = robot_points(scene.arm, cols.q_cmd[rows])
    capsules = None if scene.links is None else scene.links.capsules(cols.q_cmd[rows])
    human = None
    if scene.points is not None and scene.targets is not None:
        frames = frame_index(cols.clip_time[rows], scene.targets.frame_time, scene.points.shape[0])
        human = np.stack([scene.human_points(int(f)) for f in frames])
    return _Moments(rows, arm, tools, capsules, human, scene.raw_targets(cols.clip_time[rows]))


def _robot_extent(m: _Moments, cols: TickColumns) -> np.ndarray:
    """``(k, 3)`` points that bound what the robot's picture draws (before the capsules' radii)."""
    parts = [m.arm.reshape(-1, 3), cols.target[m.rows], np.zeros((1, 3))]
    if m.capsules is not None:
        parts.append(m.capsules.reshape(-1, 3))
    if m.raw is not None:
        parts.append(m.raw[cols.clamped[m.rows]])
    return np.concatenate(parts)


@dataclass(frozen=True)
class Frame:
    """One picture of every moment: its size (projected metres, the same at every moment) and where it looks."""

    width: float
    height: float
    corners: np.ndarray  #: ``(n, 2)`` the lower left corner at each moment
    human: bool  #: draws the skeleton
    robot: bool  #: draws the robot


def _frames(scene: Scene, cols: TickColumns, m: _Moments) -> list[Frame]:
    """The skeleton's and the robot's pictures (side by side), or one of both (overlay, or no skeleton).  The
    robot's (and the overlay's) looks at the same box every moment; the skeleton's pans with the human, which
    stands on its box's bottom edge, centred across."""
    radius = 0.0 if scene.links is None else float(scene.links.radii.max())
    robot = _robot_extent(m, cols)
    robot = np.concatenate([robot, *floor_grid(robot)])
    if m.human is None or scene.layout is Layout.OVERLAY:
        both = robot if m.human is None else np.concatenate([robot, m.human.reshape(-1, 3)])
        return [fixed_frame(both, radius, len(m.rows), human=m.human is not None)]
    flat = [project(np.concatenate([h, *floor_grid(h)]), **VIEW) for h in m.human]
    lo = np.stack([f.min(axis=0) for f in flat]) - PAD
    hi = np.stack([f.max(axis=0) for f in flat]) + PAD
    width, height = float((hi - lo)[:, 0].max()), float((hi - lo)[:, 1].max())
    corners = np.stack([(lo[:, 0] + hi[:, 0]) / 2 - width / 2, lo[:, 1]], axis=-1)
    return [Frame(width, height, corners, True, False), fixed_frame(robot, radius, len(m.rows), human=False)]


def fixed_frame(
    points: np.ndarray, radius: float, n: int, *, human: bool, view: dict[str, float] | None = None
) -> Frame:
    """A picture that looks at the same box at each of ``n`` moments: the projection of ``points`` ``(m, 3)``
    (display frame, metres), widened by ``radius`` and :data:`PAD`."""
    flat = project(points, **(view or VIEW))
    lo, hi = flat.min(axis=0) - radius - PAD, flat.max(axis=0) + radius + PAD
    return Frame(float(hi[0] - lo[0]), float(hi[1] - lo[1]), np.tile(lo, (n, 1)), human, True)


def _picture(ax: Axes, scene: Scene, cols: TickColumns, m: _Moments, i: int, *, human: bool, robot: bool) -> None:
    row = int(m.rows[i])
    if human and m.human is not None and scene.skeleton is not None:
        _skeleton(ax, scene, m.human[i])
    if robot:
        _robot(ax, scene, cols, m, i, row)


def grid_lines(ax: Axes, lines: list[np.ndarray], *, view: dict[str, float] | None = None) -> None:
    """The floor grid's ``lines`` (each ``(2, 3)`` metres), light, under everything else."""
    for line in lines:
        p = project(line, **(view or VIEW))
        ax.plot(p[:, 0], p[:, 1], color=GRID, lw=0.6, zorder=0.1)


def _skeleton(ax: Axes, scene: Scene, points: np.ndarray) -> None:
    assert scene.skeleton is not None
    if scene.layout is Layout.SIDE:  # in the overlay the human is in the robot's frame, not on its floor
        grid_lines(ax, floor_grid(points))
    p = project(points, **VIEW)
    for a, b in scene.skeleton.bones:
        ax.plot(p[[a, b], 0], p[[a, b], 1], color=HUMAN, lw=2.0, solid_capstyle="round")
    chain = p[list(scene.skeleton.chain)]
    ax.plot(chain[:, 0], chain[:, 1], "-o", color=CHAIN, lw=3.2, ms=3.5, solid_capstyle="round")


def _robot(ax: Axes, scene: Scene, cols: TickColumns, m: _Moments, i: int, row: int) -> None:
    grid_lines(ax, floor_grid(_robot_extent(m, cols)))
    capsules = None if m.capsules is None else m.capsules[i]
    radii = None if scene.links is None else scene.links.radii
    raw = m.raw[i] if m.raw is not None and cols.clamped[row] else None
    draw_arm(ax, m.arm[i], m.tools[i], cols.target[row], capsules=capsules, radii=radii, raw=raw)


def draw_arm(
    ax: Axes,
    points: np.ndarray,
    tool: np.ndarray,
    target: np.ndarray,
    *,
    capsules: np.ndarray | None = None,
    radii: np.ndarray | None = None,
    raw: np.ndarray | None = None,
    color: str = ROBOT,
    target_color: str = TARGET,
    view: dict[str, float] | None = None,
) -> None:
    """One posed arm, display frame (metres): its link ``capsules`` ``(n_capsules, 2, 3)`` (``radii``
    ``(n_capsules,)``) shaded, its joint origins and tool point ``points`` ``(n_joints + 1, 3)``, the tool frame
    ``tool`` ``(4, 4)``'s axes, the ``target`` ``(3,)`` circled and, where the reach clamp moved it, the ``raw``
    target ``(3,)`` crossed and joined to it; seen from ``view`` (default :data:`VIEW`)."""
    view = view or VIEW
    if capsules is not None and radii is not None:
        for ends, radius in zip(capsules, radii, strict=True):
            outline = stadium(project(ends, **view), float(radius))
            ax.fill(outline[:, 0], outline[:, 1], color=color, alpha=0.15, lw=0, zorder=0.5)
    q = project(points, **view)
    ax.plot(q[:, 0], q[:, 1], "-o", color=color, lw=3.2, ms=3.5)
    _axes(ax, tool[:3, 3], tool[:3, :3].T * 0.05, view)
    t = project(target, **view)
    ax.plot([t[0]], [t[1]], "o", color=target_color, ms=6, mfc="none", mew=1.6, zorder=3)
    if raw is not None:
        r = project(raw, **view)
        ax.plot([r[0], t[0]], [r[1], t[1]], ":", color=RAW, lw=1.0, zorder=3)
        ax.plot([r[0]], [r[1]], "x", color=RAW, ms=6, mew=1.6, zorder=3)


def _axes(ax: Axes, origin: np.ndarray, axes: np.ndarray, view: dict[str, float]) -> None:
    o = project(origin, **view)
    for vec, color in zip(axes, AXES_COLORS, strict=True):
        e = project(origin + vec, **view)
        ax.plot([o[0], e[0]], [o[1], e[1]], color=color, lw=1.0)


def angle_strip(ax: Axes, arm: Arm, cols: TickColumns, rows: np.ndarray, *, label: str = "commanded (deg)") -> None:
    """The commanded joint angles of ``arm`` in degrees over the clip (``cols``), the moments ``rows`` marked
    with their letters, the clamped and velocity-limited ticks flagged; its legend below it."""
    t = cols.clip_time
    colors = plt.get_cmap("tab10").colors  # type: ignore[attr-defined]
    for j, name in enumerate(arm.joint_names):
        ax.plot(t, np.degrees(cols.q_cmd[:, j]), color=colors[j % 10], lw=1.4, label=name)
    bottom, top = ax.get_ylim()
    ax.set_ylim(bottom - 0.06 * (top - bottom), top + 0.06 * (top - bottom))  # room for the flags' ticks
    band = ax.get_xaxis_transform()  # x in data, y in axes fractions
    for flag, color, y, what in ((cols.clamped, RAW, 0.975, "target clamped"),
                                 (cols.velocity_limited, "k", 0.025, "velocity-limited")):  # fmt: skip
        hits = np.flatnonzero(flag)
        if hits.size:
            ax.plot(t[hits], np.full(hits.size, y), "|", color=color, ms=5, transform=band, label=what)
    for i, row in enumerate(rows):
        ax.axvline(t[row], color="#888888", lw=0.8, ls="--", zorder=0)
        ax.text(t[row], 1.02, letter(i), transform=ax.get_xaxis_transform(), ha="center", va="bottom",
                fontsize=9, weight="bold")  # fmt: skip
    ax.set_xlabel("clip time (s)", fontsize=9)
    ax.set_ylabel(label, fontsize=9)
    ax.tick_params(labelsize=8)
    span = float(t[-1] - t[0]) or 1.0
    ax.set_xlim(t[0] - 0.01 * span, t[-1] + 0.01 * span)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, ncol=min(8, arm.n_joints + 2), loc="upper center", bbox_to_anchor=(0.5, -0.32),
              frameon=False)  # fmt: skip


def _handles(*, clamped: bool) -> list[Line2D]:
    handles = [
        Line2D([], [], color=HUMAN, lw=2, label="skeleton"),
        Line2D([], [], color=CHAIN, lw=3, marker="o", ms=3.5, label="the arm that drives the robot"),
        Line2D([], [], color=ROBOT, lw=3, marker="o", ms=3.5, label="robot arm"),
        Line2D([], [], color=TARGET, marker="o", mfc="none", mew=1.6, lw=0, label="target"),
    ]
    if clamped:
        handles.append(raw_handle())
    handles.append(Line2D([], [], color=GRID, lw=1.5, label=f"floor, {GRID_STEP * 100:.0f} cm grid"))
    return handles


def raw_handle() -> Line2D:
    return Line2D([], [], color=RAW, marker="x", mew=1.6, lw=0, label="target before the reach clamp")


def legend(fig: Figure, y: float, handles: list[Line2D], *, ncol: int | None = None) -> None:
    """The sheet's legend, centred across at height ``y`` (figure fraction), in ``ncol`` columns (default one row)."""
    fig.legend(handles=handles, loc="center", bbox_to_anchor=(0.5, y), ncol=ncol or len(handles), fontsize=8.5,
               frameon=False)  # fmt: skip
