"""The views' scene (pure numpy): where the human is drawn, the workspace wireframe, the projection."""

from __future__ import annotations

import numpy as np
import pytest

import retarget
from retarget.bvh import DEMO_CLIP
from retarget.mapping import MappingConfig, retarget_targets
from retarget.view.scene import Layout, Scene, frame_index, project, workspace_strips


@pytest.fixture(scope="module")
def demo():
    motion = retarget.load_bvh(DEMO_CLIP)
    arm = retarget.load_arm("wx250s")
    return motion, arm, retarget_targets(motion, arm)


@pytest.mark.parametrize("side", ["right", "left"])
def test_overlay_puts_the_human_wrist_on_the_raw_target(demo, side):
    motion, arm, _ = demo
    # unfiltered (cutoff 0): the wrist lands on the mapped point, which the target filter would move by mm
    targets = retarget_targets(motion, arm, MappingConfig.from_table({}, overrides={"side": side, "cutoff_hz": 0}))
    scene = Scene.for_clip(motion, arm, targets, layout=Layout.OVERLAY)
    wrist = scene.skeleton.chain[2]
    for frame in (0, 200, motion.n_frames - 1):
        np.testing.assert_allclose(scene.human_points(frame)[wrist], targets.raw[frame], atol=1e-9)


def test_side_layout_stands_the_human_on_the_floor_beside_the_robot(demo):
    motion, arm, targets = demo
    scene = Scene.for_clip(motion, arm, targets, layout=Layout.SIDE)
    placed = np.stack([scene.human_points(f) for f in range(0, motion.n_frames, 10)])
    assert placed[..., 2].min() == pytest.approx(0.0, abs=0.02)
    assert placed[..., 1].max() < 0  # on the robot's right (-y), clear of its base at y = 0
    upper, fore = np.linalg.norm(np.diff(scene.human_points(0)[list(scene.skeleton.chain)], axis=0), axis=1)
    # the mapping's scale: the human arm is arm_scale x the robot's reach long (median over the clip)
    assert 0.1 < upper + fore < 1.0


def test_skeleton_has_every_bone_and_the_chain(demo):
    motion, arm, targets = demo
    sk = Scene.for_clip(motion, arm, targets).skeleton
    assert len(sk.names) == motion.n_joints + len(motion.end_sites)
    assert len(sk.bones) == motion.n_joints - 1 + len(motion.end_sites)
    chain = motion.arm_points("right")
    assert sk.names[sk.chain[0]] == chain.names[0] and sk.names[sk.chain[1]] == chain.names[1]


def test_workspace_strips_stay_above_the_floor(demo):
    _, _, targets = demo
    ws = targets.workspace
    strips = workspace_strips(ws)
    for s in strips:
        assert np.all(s[:, 2] >= ws.floor - 1e-9)
        r = np.linalg.norm(s - ws.center, axis=1)
        assert np.all(r <= ws.r_max + 1e-9)
    assert np.allclose(strips[-1][:, 2], ws.floor)  # the floor's circle comes last


@pytest.mark.parametrize(("t", "expected"), [(0.0, 0), (0.0249, 1), (0.031, 2), (99.0, 9), (-1.0, 0)], ids=str)
def test_frame_index_nearest_within_the_clip(t, expected):
    assert int(frame_index(t, 0.02, 10)) == expected


def test_project_keeps_lengths_across_the_view():
    p = project(np.array([[0.0, 1.0, 0.0], [0.0, -1.0, 0.0]]), azimuth=0.0, elevation=0.0)
    np.testing.assert_allclose(p, [[1.0, 0.0], [-1.0, 0.0]], atol=1e-12)
