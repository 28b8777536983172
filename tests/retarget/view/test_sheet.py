"""The contact sheet's framing: every picture holds what it draws at every moment (nothing clipped), and the
skeleton and the robot share one scale."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("matplotlib", reason="the viz extra (matplotlib) is not installed")

from retarget.cli import build_parser  # noqa: E402
from retarget.cli.view import solve  # noqa: E402
from retarget.view import sheet  # noqa: E402
from retarget.view.columns import TickColumns  # noqa: E402
from retarget.view.scene import Layout, Scene, project  # noqa: E402


def solved(*argv: str) -> tuple[Scene, TickColumns]:
    args = build_parser().parse_args(["view", "--end", "4", *argv])
    inputs, records = solve(args)
    return Scene.for_clip(inputs.motion, inputs.arm, inputs.targets, layout=Layout(args.layout)), TickColumns.of(
        records
    )


def inside(points: np.ndarray, frame, i: int) -> bool:
    flat = project(points, **sheet.VIEW)
    lo = frame.corners[i]
    return bool((flat >= lo).all() and (flat <= lo + [frame.width, frame.height]).all())


@pytest.mark.parametrize("layout", ["side", "overlay"], ids=["side", "overlay"])
def test_every_picture_holds_the_skeleton_arm_and_target_at_every_moment(layout):
    scene, cols = solved("--layout", layout)
    m = sheet._moments(scene, cols, sheet.moment_ticks(len(cols), 5))
    frames = sheet._frames(scene, cols, m)
    assert [(f.human, f.robot) for f in frames] == (
        [(True, False), (False, True)] if layout == "side" else [(True, True)]
    )
    for i, row in enumerate(m.rows):
        human = next(f for f in frames if f.human)
        robot = next(f for f in frames if f.robot)
        assert inside(m.human[i], human, i)
        assert inside(m.arm[i], robot, i) and inside(cols.target[row][None], robot, i)
        assert not inside(m.arm[i] + [0.0, 0.0, 5.0], robot, i)  # the box is not everything
    if layout == "side":  # the human pans with the clip, the robot stays put: one box, moved
        assert np.ptp(frames[1].corners, axis=0).max() == 0.0


def test_floor_grid_covers_the_footprint_in_whole_steps():
    lines = sheet.floor_grid(np.array([[0.31, -0.12, 0.5], [-0.05, 0.02, 0.0]]))
    ends = np.concatenate(lines)
    assert ends[:, 2].max() == 0.0
    np.testing.assert_allclose(ends[:, :2].min(axis=0), [-0.1, -0.2], atol=1e-12)
    np.testing.assert_allclose(ends[:, :2].max(axis=0), [0.4, 0.1], atol=1e-12)
    assert len(lines) == 6 + 4  # x = -0.1 ... 0.4, y = -0.2 ... 0.1
