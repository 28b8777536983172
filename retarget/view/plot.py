"""A telemetry CSV (``--telemetry``, :mod:`retarget.control.telemetry`) as a PNG (matplotlib, Agg: no GUI).

One panel per joint: commanded and present angle in degrees, the joint's limits shaded beyond them; then the
IK error and the tracking error (mm) with the clamped and velocity-limited ticks marked, then the tick and bus
times (ms) with the overruns marked.  The x axis is the run time (s); lead-in rows are shaded.  A rig's telemetry
(:mod:`retarget.rig.telemetry`: every arm's columns prefixed by its name) is drawn the same way, each arm's joints
in a column of their own and each arm's errors in its own colour.

    plot_telemetry(read_telemetry(Path("run.csv")), Path("run.png"), limits=(arm.lower, arm.upper))
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.artist import Artist  # noqa: E402
from matplotlib.axes import Axes  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402
from matplotlib.patches import Patch  # noqa: E402

from retarget.errors import ConfigError  # noqa: E402

__all__ = ["Telemetry", "plot_telemetry", "read_telemetry"]

CMD, PRESENT, LIMIT, LEAD, IK = "#2a6edc", "#ff8c00", "#dc1e1e", "#cccccc", "#6a3d9a"
ARM_COLOURS = (IK, "#1b9e77", "#d95f02")  #: each arm's errors, in rig order (one arm's: IK's), then again


@dataclass(frozen=True)
class Telemetry:
    """A telemetry file's columns by name (``(n_rows,)`` float64, NaN where empty), its joint names and its arms.

    ``arms``: ``("",)`` for one arm's file; a rig's arm names in column order (``("left", "right")``), its joints
    then named with their arm's prefix (``"left/waist"``), as its columns are."""

    path: Path
    columns: dict[str, np.ndarray]
    joints: tuple[str, ...]
    arms: tuple[str, ...] = ("",)

    def __getitem__(self, name: str) -> np.ndarray:
        return self.columns[name]


def read_telemetry(path: Path) -> Telemetry:
    """Read a telemetry CSV; ConfigError naming the file for one that is not (no rows, a missing column)."""
    with open(path, newline="", encoding="utf-8") as f:
        reader = csv.reader(f)
        header = next(reader, None)
        rows = list(reader)
    arms = tuple(name[: -len("/ik_error_mm")] for name in header or [] if name.endswith("/ik_error_mm")) or ("",)
    needed = {"time_s", "tick_ms", "bus_ms", "overrun"} | {f"{_prefix(arm)}ik_error_mm" for arm in arms}
    if arms == ("",):
        needed |= {"clamped", "velocity_limited"}
    if header is None or not needed <= set(header):
        missing = sorted(needed - set(header or []))
        raise ConfigError(f"Expected a telemetry CSV written by --telemetry, missing columns {', '.join(missing)}",
                          path=path)  # fmt: skip
    if not rows:
        raise ConfigError("Expected at least one row of telemetry, got only the header", path=path)
    data = np.full((len(rows), len(header)), np.nan)
    for i, row in enumerate(rows):
        if len(row) != len(header):
            raise ConfigError(f"Expected {len(header)} fields on line {i + 2}, got {len(row)}", path=path)
        for k, value in enumerate(row):
            if value:
                try:
                    data[i, k] = float(value)
                except ValueError:
                    raise ConfigError(f"Expected a number on line {i + 2}", path=path, key=header[k],
                                      value=value[:40]) from None  # fmt: skip
    joints = tuple(name[: -len("_cmd_rad")] for name in header if name.endswith("_cmd_rad"))
    return Telemetry(path, {name: data[:, k] for k, name in enumerate(header)}, joints, arms)


def _prefix(arm: str) -> str:
    """A rig arm's column prefix (``"left/"``); ``""`` for one arm's file."""
    return f"{arm}/" if arm else ""


def _panels(telemetry: Telemetry) -> tuple[list[tuple[int, int]], int, int]:
    """Each joint's panel (row, column), the joint rows and the columns: a rig's arms a column each (two arms or
    three), one arm's joints in two columns when there are more than three."""
    arms = telemetry.arms
    if 1 < len(arms) <= 3:
        places: list[tuple[int, int]] = []
        rows = dict.fromkeys(arms, 0)  # the panels of each arm so far
        for name in telemetry.joints:
            arm = name.split("/", 1)[0]
            places.append((rows[arm], arms.index(arm)))
            rows[arm] += 1
        return places, max(rows.values()), len(arms)
    n = len(telemetry.joints)
    cols = 2 if n > 3 else 1
    return [(j // cols, j % cols) for j in range(n)], math.ceil(n / cols), cols


def plot_telemetry(
    telemetry: Telemetry, path: Path, *, limits: tuple[np.ndarray, np.ndarray] | None = None, title: str = ""
) -> None:
    """Draw ``telemetry`` to ``path`` (PNG); ``limits`` ``(lower, upper)`` radians per joint, shaded when given."""
    places, joint_rows, cols = _panels(telemetry)
    fig = plt.figure(figsize=(10 if cols <= 2 else 13, 1.55 * joint_rows + 3.9), dpi=100)
    grid = fig.add_gridspec(joint_rows + 2, cols, height_ratios=[1.0] * joint_rows + [1.1, 1.1], hspace=0.35,
                            wspace=0.18, left=0.08, right=0.98, top=1 - 0.8 / fig.get_figheight(),
                            bottom=0.45 / fig.get_figheight())  # fmt: skip
    t = telemetry["time_s"]
    lead = telemetry.columns.get("lead_in", np.zeros_like(t)) > 0
    first: Axes | None = None
    axes: list[Axes] = []
    for j, name in enumerate(telemetry.joints):
        ax = fig.add_subplot(grid[places[j]], sharex=first)
        first = first or ax
        lo_hi = None if limits is None else (math.degrees(limits[0][j]), math.degrees(limits[1][j]))
        _joint(ax, t, telemetry, name, lo_hi)
        axes.append(ax)
    ik = fig.add_subplot(grid[joint_rows, :], sharex=first)
    timing = fig.add_subplot(grid[joint_rows + 1, :], sharex=ik)
    _ik(ik, t, telemetry)
    _timing(timing, t, telemetry)
    for ax in (*axes, ik, timing):
        _lead(ax, t, lead)
        ax.grid(alpha=0.3)
        ax.tick_params(labelsize=7, labelbottom=True)
    span = float(np.nanmax(t) - np.nanmin(t)) or 1.0
    timing.set_xlim(float(np.nanmin(t)) - 0.01 * span, float(np.nanmax(t)) + 0.01 * span)
    timing.set_xlabel("run time (s)", fontsize=9)
    fig.suptitle(title or telemetry.path.name, fontsize=11, y=1 - 0.2 / fig.get_figheight())
    rows = _legend(fig, [*axes, ik, timing], bool(lead.any()))
    grid.update(top=1 - (0.8 + 0.15 * max(rows - 1, 0)) / fig.get_figheight())  # room for the legend's rows
    fig.savefig(path)
    plt.close(fig)


def _legend(fig: Figure, axes: list[Axes], lead_in: bool) -> int:
    """One legend for the figure, at the top: each label once, in the order the panels drew them, in as few rows as
    fit the figure's width; returns the rows."""
    seen: dict[str, Artist] = {}
    for ax in axes:
        for handle, label in zip(*ax.get_legend_handles_labels(), strict=True):
            seen.setdefault(label, handle)
    if lead_in:
        seen["lead-in (to the first pose)"] = Patch(color=LEAD, alpha=0.4, lw=0)
    renderer = fig.canvas.get_renderer()  # type: ignore[attr-defined]  # (Agg's canvas has one)
    top = (0.5, 1 - 0.35 / fig.get_figheight())
    for rows in range(1, len(seen) + 1):  # as few rows as fit the figure's width (a rig's labels are longer)
        legend = fig.legend(list(seen.values()), list(seen), loc="upper center", ncol=math.ceil(len(seen) / rows),
                            fontsize=8, frameon=False, bbox_to_anchor=top)  # fmt: skip
        if rows == len(seen) or legend.get_window_extent(renderer).width <= 0.98 * fig.bbox.width:
            return rows  # (one label a row is kept even when a label is wider than the figure)
        legend.remove()
    return 0


def _joint(ax: Axes, t: np.ndarray, tel: Telemetry, name: str, lo_hi: tuple[float, float] | None) -> None:
    cmd = np.degrees(tel[f"{name}_cmd_rad"])
    ax.plot(t, cmd, color=CMD, lw=1.3, label="commanded")
    present = tel.columns.get(f"{name}_present_rad")
    shown = [cmd]
    if present is not None and not np.isnan(present).all():
        ax.plot(t, np.degrees(present), color=PRESENT, lw=1.0, ls="--", label="present")
        shown.append(np.degrees(present))
    if lo_hi is not None:
        bottom, top = y_range(np.concatenate(shown), lo_hi)
        lo, hi = lo_hi
        if bottom < lo:
            ax.axhspan(bottom, lo, color=LIMIT, alpha=0.12, lw=0)
        if hi < top:
            ax.axhspan(hi, top, color=LIMIT, alpha=0.12, lw=0, label="beyond the limits")
        ax.set_ylim(bottom, top)
    ax.set_ylabel(f"{name}\n(deg)", fontsize=8)


def y_range(values: np.ndarray, limits: tuple[float, float]) -> tuple[float, float]:
    """The y range of a joint's panel (degrees): the angles and both (finite) limits, with a margin of 8 % of
    that (at least 5 degrees), so the shading beyond the limits always shows, a constant joint's too.

    >>> y_range(np.array([10.0, 10.0]), (-180.0, 180.0))
    (-208.8, 208.8)
    >>> y_range(np.array([-20.0, 30.0]), (-float("inf"), 90.0))
    (-28.8, 98.8)
    """
    finite = [v for v in (*limits, float(np.nanmin(values)), float(np.nanmax(values))) if math.isfinite(v)]
    low, high = min(finite), max(finite)
    margin = max(0.08 * (high - low), 5.0)
    return round(low - margin, 6), round(high + margin, 6)


def _ik(ax: Axes, t: np.ndarray, tel: Telemetry) -> None:
    """The IK error (solid) and the tracking error (thin, where the file has it) of each arm, in mm."""
    top = 1.0
    for k, arm in enumerate(tel.arms):  # (every arm: a rig of more arms than colours repeats them)
        color = ARM_COLOURS[k % len(ARM_COLOURS)]
        name = f"{arm} " if arm else ""
        ik = tel[f"{_prefix(arm)}ik_error_mm"]
        ax.plot(t, ik, color=color, lw=0.8, label=f"{name}IK error")
        top = max(top, float(np.nanmax(ik)) if not np.isnan(ik).all() else 0.0)
        tracking = tel.columns.get(f"{_prefix(arm)}tracking_mm")
        if tracking is not None and not np.isnan(tracking).all():
            ax.plot(t, tracking, color=color, lw=0.7, ls=":", label=f"{name}tracking error")
            top = max(top, float(np.nanmax(tracking)))
    for flag, color, y in (("clamped", "#e000e0", 1.05), ("velocity_limited", "#28a028", 1.12)):
        rows = tel.columns.get(flag, np.zeros_like(t)) > 0
        if rows.any():
            ax.plot(
                t[rows],
                np.full(int(rows.sum()), top * y),
                "|",
                color=color,
                ms=6,
                label=flag.replace("_", "-").replace("clamped", "target clamped"),
            )
    ax.set_ylim(0, top * 1.2)
    ax.set_ylabel("error\n(mm)", fontsize=8)


def _timing(ax: Axes, t: np.ndarray, tel: Telemetry) -> None:
    ax.plot(t, tel["tick_ms"], color="k", lw=0.8, label="tick time")
    ax.plot(t, tel["bus_ms"], color=CMD, lw=0.8, label="bus time")
    over = tel["overrun"] > 0
    top = max(float(np.nanmax(tel["tick_ms"])), 1.0)
    if over.any():
        ax.plot(t[over], np.full(int(over.sum()), top * 1.05), "v", color=LIMIT, ms=4, label="overrun")
    ax.set_ylim(0, top * 1.15)
    ax.set_ylabel("time\n(ms)", fontsize=8)


def _lead(ax: Axes, t: np.ndarray, lead: np.ndarray) -> None:
    if lead.any():
        ax.axvspan(float(t[lead].min()), float(t[lead].max()), color=LEAD, alpha=0.4, lw=0)
