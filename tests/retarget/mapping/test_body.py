"""The body frame of every frame of a clip: one-armed rigs and coinciding shoulders framed from the spine,
held frames, one log line, one error when nothing gives a frame; a fixed forward axis."""

from __future__ import annotations

import logging

import numpy as np
import pytest

import retarget
from retarget.bvh import parse_bvh
from retarget.errors import BvhError, ConfigError
from retarget.mapping.body import FROM_SHOULDERS, FROM_SPINE, HELD, clip_body_frames, hold_good_frames
from retarget.mapping.config import Axis, MappingConfig
from retarget.mapping.targets import retarget_targets
from retarget.mapping.torso import body_frames
from tests.helpers import bvh_text as rig_text
from tests.helpers import coinciding, joints_in_order, moving, pose, rig, t_pose, targets_of


@pytest.mark.parametrize("side", ["left", "right"])
def test_a_one_armed_rig_takes_its_body_frame_from_the_spine(arm, caplog, side):
    values = moving()
    both = parse_bvh(rig_text(rig(), pose(rig(), 40, values)))
    one = rig(arms=(side,), legs=False)  # no legs: the structure has no other limb to mistake for an arm
    motion = parse_bvh(rig_text(one, pose(one, 40, values)), path="one_arm.bvh")
    with caplog.at_level(logging.INFO, logger="retarget.mapping.body"):
        body = clip_body_frames(motion, motion.arm_points(side))
    assert body.count(FROM_SPINE) == 40 and body.torso == "Chest"
    truth = body_frames(
        both.positions()[:, 0], both.arm_points("left").points[:, 0], both.arm_points("right").points[:, 0]
    )
    np.testing.assert_allclose(body.frames, truth, atol=1e-9)
    [record] = caplog.records
    assert record.levelno == logging.INFO
    assert record.getMessage().startswith(f"one_arm.bvh: body frame from the spine, Chest carrying the {side} shoulder")
    config = MappingConfig(side=retarget.mapping.Side(side))
    np.testing.assert_allclose(
        retarget_targets(motion, arm, config).raw, retarget_targets(both, arm, config).raw, atol=1e-9
    )


def test_a_fixed_forward_axis_needs_no_other_arm(arm, caplog):
    one = rig(arms=("left",))
    motion = parse_bvh(rig_text(one, pose(one, 5, moving(5))))
    with caplog.at_level(logging.INFO, logger="retarget.mapping.body"):
        targets = retarget_targets(motion, arm, MappingConfig(side=retarget.mapping.Side.LEFT, forward=Axis.PZ))
    assert np.isfinite(targets.raw).all() and not caplog.records


def test_frames_whose_shoulders_coincide_come_from_the_spine(arm, caplog):
    kinect = rig(positions=("LeftShoulder", "RightShoulder", "LeftArm", "RightArm"))
    bad = [0, 7, 8, 9, 39]
    motion = parse_bvh(rig_text(kinect, pose(kinect, 40, coinciding(40, bad))), path="kinect.bvh")
    reference = parse_bvh(rig_text(rig(), pose(rig(), 40, moving())))
    with caplog.at_level(logging.INFO, logger="retarget.mapping.body"):
        body = clip_body_frames(motion, motion.arm_points("right"))
    assert np.flatnonzero(body.source == FROM_SPINE).tolist() == bad and body.count(FROM_SHOULDERS) == 35
    truth = clip_body_frames(reference, reference.arm_points("right")).frames
    np.testing.assert_allclose(body.frames, truth, atol=1e-9)  # the clavicles are still: the spine frames are exact
    [record] = caplog.records
    assert record.levelno == logging.WARNING
    assert "kinect.bvh: the shoulders RightArm and LeftArm coincide or line up with the spine in 5 of 40" in (
        record.getMessage()
    )
    assert np.isfinite(retarget_targets(motion, arm).raw).all()


def test_frames_with_no_body_frame_hold_the_previous_good_one(caplog):
    """Shoulders on the chest, and the chest moved so far down that the hips sit between them: no frame at all."""
    kinect = rig(positions=("Chest", "LeftShoulder", "RightShoulder", "LeftArm", "RightArm"))
    bad = [0, 1, 5, 6]
    values = coinciding(10, bad)
    chest_y = np.full(10, 30.0)
    chest_y[bad] = -17.0  # the shoulders' mean offset from the chest is (0, 17, 0): their midpoint lands on the hips
    values[("Chest", "Yposition")] = chest_y
    for channel in ("Xrotation", "Yrotation"):  # and the chest turns with the hips
        values[("Chest", channel)] = np.where(np.isin(np.arange(10), bad), 0.0, values[("Chest", channel)])
    motion = parse_bvh(rig_text(kinect, pose(kinect, 10, values)))
    with caplog.at_level(logging.INFO, logger="retarget.mapping.body"):
        body = clip_body_frames(motion, motion.arm_points("left"))
    assert body.source.tolist() == [HELD, HELD, 0, 0, 0, HELD, HELD, 0, 0, 0]
    for k, source in [(0, 2), (1, 2), (5, 4), (6, 4)]:  # the first good frame for the leading ones
        np.testing.assert_array_equal(body.frames[k], body.frames[source])
    assert "4 hold the previous good frame" in caplog.text


def test_hold_good_frames():
    values = np.arange(6.0)[:, None] * [1.0, 2.0]
    held = hold_good_frames(values, np.array([False, False, True, False, True, False]))
    np.testing.assert_array_equal(held[:, 0], [2, 2, 2, 2, 4, 4])
    with pytest.raises(ValueError, match="Expected at least one good frame, got none"):
        hold_good_frames(values, np.zeros(6, dtype=bool))


def test_no_body_frame_in_any_frame_is_a_bvh_error(arm):
    """Every joint placed by its position channels, the shoulders on the chest, and OFFSETs of zero (no rest pose)."""
    kinect = rig(positions=tuple(j.name for j in joints_in_order(rig())))
    for j in joints_in_order(kinect):
        j.offset = (0.0, 0.0, 0.0)
    values = {("Chest", "Yposition"): 30.0, ("LeftForeArm", "Xposition"): 28.0, ("RightForeArm", "Xposition"): -28.0}
    values |= {("LeftHand", "Xposition"): 25.0, ("RightHand", "Xposition"): -25.0}
    motion = parse_bvh(rig_text(kinect, pose(kinect, 3, values)), path="zeros.bvh")
    match = (
        r"^zeros\.bvh: Expected a torso for the body frame in at least one of the 3 frames, got none: the shoulders "
        r"LeftArm and RightArm and the spine \(Chest\) coincide"
    )
    with pytest.raises(BvhError, match=match):
        retarget_targets(motion, arm, MappingConfig(side=retarget.mapping.Side.LEFT))
    assert retarget_targets(motion, arm, MappingConfig(forward=Axis.PZ)).n_frames == 3  # no torso needed


def test_fixed_forward_must_be_horizontal(arm):
    with pytest.raises(ConfigError, match=r"mapping\.forward: Expected a forward axis perpendicular to up \(\+y\)"):
        targets_of(t_pose(), arm, MappingConfig(forward=Axis.PY))
