"""``retarget plot`` and ``retarget view --png``: real pictures (size, content, traces where the data says)."""

from __future__ import annotations

import numpy as np
import pytest

import retarget
from retarget.cli import main
from retarget.control.telemetry import telemetry_columns

image = pytest.importorskip("matplotlib.image", reason="the viz extra (matplotlib) is not installed")

CMD = np.array([0x2A, 0x6E, 0xDC]) / 255  # the commanded trace's colour in retarget.view.plot


def telemetry_csv(path, waist_deg: np.ndarray) -> None:
    """A telemetry file of wx250s: the waist as given (degrees), the other joints 0, one clamp and one overrun."""
    arm = retarget.load_arm("wx250s")
    n = len(waist_deg)
    cols = telemetry_columns(arm.joint_names)
    rows = []
    for k in range(n):
        row = dict.fromkeys(cols, 0.0)
        row.update(time_s=k / 100, clip_time_s=k / 100, tick=k, ik_error_mm=0.5, tick_ms=2.0, bus_ms=1.0)
        row.update(clamped=int(k == 40), overrun=int(k == 60))
        for j, name in enumerate(arm.joint_names):
            row[f"{name}_cmd_rad"] = row[f"{name}_present_rad"] = np.radians(waist_deg[k]) if j == 0 else 0.0
        rows.append([row[c] for c in cols])
    path.write_text("\n".join([",".join(cols), *(",".join(str(v) for v in r) for r in rows)]) + "\n")


def trace_rows(png, box: tuple[float, float, float, float]) -> np.ndarray:
    """Per pixel column of the region ``box`` (fractions left, top, right, bottom), the mean row of the
    commanded trace's pixels (NaN where none)."""
    img = image.imread(png)[..., :3]
    h, w = img.shape[:2]
    left, top, right, bottom = int(box[0] * w), int(box[1] * h), int(box[2] * w), int(box[3] * h)
    region = img[top:bottom, left:right]
    hit = np.linalg.norm(region - CMD, axis=-1) < 0.08
    rows = np.arange(region.shape[0])[:, None]
    with np.errstate(invalid="ignore"):
        return np.where(hit.any(axis=0), (hit * rows).sum(axis=0) / hit.sum(axis=0), np.nan)


def test_plot_draws_the_waist_trace_where_the_telemetry_says(capsys, tmp_path):
    up, down = tmp_path / "up.csv", tmp_path / "down.csv"
    telemetry_csv(up, np.linspace(-60, 60, 100))
    telemetry_csv(down, np.linspace(60, -60, 100))
    for csv_path in (up, down):
        assert main(["plot", str(csv_path), "-o", str(csv_path.with_suffix(".png"))]) == 0, capsys.readouterr().err
    a, b = image.imread(tmp_path / "up.png"), image.imread(tmp_path / "down.png")
    assert a.shape[:2] == b.shape[:2] and a.shape[1] >= 600 and a.shape[0] >= 500
    assert np.ptp(a[..., :3]) > 0.5 and not np.array_equal(a, b)
    box = (0.0, 0.03, 0.5, 0.2)  # the waist: the first joint panel, top left
    rise, fall = trace_rows(tmp_path / "up.png", box), trace_rows(tmp_path / "down.png", box)
    for rows, rising in ((rise, True), (fall, False)):
        drawn = rows[~np.isnan(rows)]
        assert drawn.size > 20  # a trace across the panel (between the dashes of the present trace)
        first, last = drawn[: drawn.size // 5].mean(), drawn[-drawn.size // 5 :].mean()
        assert (last < first) == rising  # image rows grow downwards: a rising angle ends higher up


def test_plot_rejects_a_file_that_is_not_telemetry(capsys, tmp_path):
    bad = tmp_path / "bad.csv"
    bad.write_text("a,b\n1,2\n")
    assert main(["plot", str(bad), "-o", str(tmp_path / "x.png")]) == 2
    err = capsys.readouterr().err
    assert "missing columns" in err and "bad.csv" in err and len(err.strip().splitlines()) == 1


def test_view_png_is_a_contact_sheet_that_depends_on_the_clip(capsys, tmp_path):
    a, b = tmp_path / "right.png", tmp_path / "left.png"
    assert main(["view", "--end", "3", "--moments", "3", "--png", str(a)]) == 0, capsys.readouterr().err
    assert main(["view", "--end", "3", "--moments", "3", "--side", "left", "--png", str(b)]) == 0
    ia, ib = image.imread(a)[..., :3], image.imread(b)[..., :3]
    assert ia.shape == ib.shape and ia.shape[1] >= 500
    assert np.ptp(ia) > 0.5  # not a single colour
    assert np.abs(ia - ib).mean() > 1e-3  # the other arm drives: other poses, other angles
    arm_blue = np.linalg.norm(ia - np.array([0x2A, 0x6E, 0xDC]) / 255, axis=-1) < 0.08
    orange = np.linalg.norm(ia - np.array([0xFF, 0x8C, 0x00]) / 255, axis=-1) < 0.08
    assert arm_blue.sum() > 200 and orange.sum() > 100  # the robot arm and the driving human arm are drawn
    tint = 1 - 0.15 * (1 - np.array([0x2A, 0x6E, 0xDC]) / 255)  # a link capsule (robot blue, alpha 0.15, on white)
    assert (np.abs(ia - tint).max(axis=-1) < 0.02).sum() > 100  # wx250s has link geometry: its capsules are drawn


def test_a_constant_joint_shows_its_limits(capsys, tmp_path):
    """The shoulder stays at 0: its panel still spans both limits, so the shading beyond them is drawn."""
    path = tmp_path / "run.csv"
    telemetry_csv(path, np.linspace(-60, 60, 100))
    assert main(["plot", str(path), "-o", str(tmp_path / "run.png")]) == 0, capsys.readouterr().err
    img = image.imread(tmp_path / "run.png")[..., :3]
    h, w = img.shape[:2]
    shaded = 1 - 0.12 * (1 - np.array([0xDC, 0x1E, 0x1E]) / 255)  # the limit colour at alpha 0.12 on white
    for box in ((0.0, 0.03, 0.5, 0.2), (0.5, 0.03, 1.0, 0.2)):  # waist (moving), shoulder (constant)
        region = img[int(box[1] * h) : int(box[3] * h), int(box[0] * w) : int(box[2] * w)]
        hits = (np.abs(region - shaded).max(axis=-1) < 0.02).sum()
        assert hits > 1000, (box, hits)


def rig_csv(path, left_deg: np.ndarray, right_deg: np.ndarray) -> None:
    """A telemetry file of the wx250s-pair rig (retarget.rig.telemetry's columns): each arm's waist as given
    (degrees), every other joint 0."""
    from retarget.rig import load_rig

    rig = load_rig("wx250s-pair")
    cols = ["time_s", "clip_time_s", "tick", "tick_ms", "compute_ms", "bus_ms", "overrun", "lead_in", "blocked",
            "min_clearance_mm"]  # fmt: skip
    for a in rig.arms:
        p = f"{a.name}/"
        cols += [f"{p}target_x_m", f"{p}target_y_m", f"{p}target_z_m"]
        cols += [f"{p}{j}_{kind}_rad" for kind in ("cmd", "present") for j in a.arm.joint_names]
        cols += [f"{p}ik_error_mm", f"{p}ik_converged", f"{p}tracking_mm"]
    rows = []
    for k in range(len(left_deg)):
        row = dict.fromkeys(cols, 0.0)
        row.update(time_s=k / 100, tick=k, tick_ms=2.0, bus_ms=1.0)
        for side, deg in (("left", left_deg[k]), ("right", right_deg[k])):
            row[f"{side}/waist_cmd_rad"] = row[f"{side}/waist_present_rad"] = np.radians(deg)
            row[f"{side}/ik_error_mm"], row[f"{side}/tracking_mm"] = 0.5, 3.0
        rows.append([row[c] for c in cols])
    path.write_text("\n".join([",".join(cols), *(",".join(str(v) for v in r) for r in rows)]) + "\n")


def test_plot_draws_a_rigs_arms_side_by_side(capsys, tmp_path):
    """The left arm's joints in the left column, the right arm's in the right: each waist's trace where its own
    columns say (here the left rises while the right falls)."""
    path = tmp_path / "rig.csv"
    rig_csv(path, np.linspace(-60, 60, 100), np.linspace(60, -60, 100))
    png = tmp_path / "rig.png"
    assert main(["plot", str(path), "--rig", "wx250s-pair", "-o", str(png)]) == 0, capsys.readouterr().err
    assert "100 ticks" in capsys.readouterr().err
    for box, rising in (((0.0, 0.05, 0.5, 0.13), True), ((0.5, 0.05, 1.0, 0.13), False)):
        drawn = trace_rows(png, box)
        drawn = drawn[~np.isnan(drawn)]
        assert drawn.size > 20, box
        first, last = drawn[: drawn.size // 5].mean(), drawn[-drawn.size // 5 :].mean()
        assert (last < first) == rising, box
    assert main(["plot", str(path), "-o", str(tmp_path / "bare.png")]) == 0  # no --rig: no limits, still drawn


@pytest.mark.parametrize(
    "args, option, match",
    [
        pytest.param(["--arm", "wx250s"], "--arm", "Expected --rig for a rig's telemetry", id="arm-for-a-rig"),
        pytest.param(["--rig", "KOCH_PAIR"], "--rig", "Expected the joints left/waist", id="another-rig"),
    ],
)
def test_plot_of_a_rig_refuses_options_that_do_not_fit(capsys, tmp_path, args, option, match):
    path, koch_pair = tmp_path / "rig.csv", tmp_path / "koch-pair.toml"
    rig_csv(path, np.zeros(5), np.zeros(5))
    arms = [f'[[arms]]\nname = "{s}"\narm = "koch"\nxyz = [0, {y}, 0]\nrpy = [0, 0, 0]\nside = "{s}"\n'
            for s, y in (("left", 0.2), ("right", -0.2))]  # fmt: skip
    koch_pair.write_text('[rig]\nname = "koch-pair"\n\n' + "\n".join(arms))
    args = [str(koch_pair) if a == "KOCH_PAIR" else a for a in args]
    assert main(["plot", str(path), *args, "-o", str(tmp_path / "x.png")]) == 2
    err = capsys.readouterr().err
    assert match in err and option in err and len(err.strip().splitlines()) == 1, err
    assert not (tmp_path / "x.png").exists()


def test_plot_of_one_arms_file_refuses_a_rig_and_draws_another_arms_file_without_limits(capsys, tmp_path):
    path = tmp_path / "run.csv"
    telemetry_csv(path, np.linspace(-60, 60, 100))
    assert main(["plot", str(path), "--rig", "wx250s-pair", "-o", str(tmp_path / "x.png")]) == 2
    assert "Expected a rig's telemetry with --rig" in capsys.readouterr().err
    koch = tmp_path / "koch.csv"  # another arm's joints: without --arm it is drawn without limits, not refused
    koch.write_text(path.read_text().replace("waist", "shoulder_pan"))
    assert main(["plot", str(koch), "-o", str(tmp_path / "koch.png")]) == 0, capsys.readouterr().err
    assert main(["plot", str(koch), "--arm", "wx250s", "-o", str(tmp_path / "koch.png")]) == 2
    assert "Expected the joints shoulder_pan" in capsys.readouterr().err


@pytest.mark.parametrize(("labels", "rows"), [(4, 1), (8, 2), (16, 4)], ids=["4-labels", "8-labels", "16-labels"])
def test_the_legend_wraps_into_as_few_rows_as_fit_the_figure(labels: int, rows: int) -> None:
    """The figure's legend takes one row while it fits the width, more when its labels are many or long (a rig's
    'right tracking error'), and never runs off the figure's edges."""
    import matplotlib.pyplot as plt

    from retarget.view.plot import _legend

    fig = plt.figure(figsize=(10, 6), dpi=100)
    ax = fig.add_subplot()
    for k in range(labels):
        ax.plot([0, 1], [k, k], label=f"arm {k} tracking error")
    assert _legend(fig, [ax], lead_in=False) == rows
    (legend,) = fig.legends
    extent = legend.get_window_extent(fig.canvas.get_renderer())  # type: ignore[attr-defined]
    assert 0 <= extent.x0 and extent.x1 <= fig.bbox.width
    plt.close(fig)


def test_a_label_wider_than_the_figure_still_gets_its_legend() -> None:
    """No row count fits: the legend is kept, a label a row (it used to be removed with the last try)."""
    import matplotlib.pyplot as plt

    from retarget.view.plot import _legend

    fig = plt.figure(figsize=(2, 3), dpi=100)
    ax = fig.add_subplot()
    for k in range(3):
        ax.plot([0, 1], [k, k], label=f"arm {k} with a label far wider than this small figure")
    assert _legend(fig, [ax], lead_in=False) == 3
    assert len(fig.legends) == 1
    plt.close(fig)
