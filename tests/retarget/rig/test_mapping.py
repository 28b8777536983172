"""Both arms of a clip onto a rig: one body frame and one scale, so the two hands keep their relation."""

from __future__ import annotations

import numpy as np
import pytest

from retarget.bvh.parse import DEMO_CLIP, load_bvh
from retarget.errors import ConfigError
from retarget.mapping.config import MappingConfig
from retarget.rig import load_rig
from retarget.rig.mapping import rig_targets
from tests.helpers import shared_clip_params


@pytest.fixture(scope="module")
def demo():
    return load_bvh(DEMO_CLIP)


@pytest.mark.parametrize("rig_name", ["wx250s-pair", "aloha"])
def test_the_distance_between_the_hands_is_kept_scaled(demo, rig_name):
    """Independently of the module's math: the world targets' distance is the scale times the distance of the
    wrists as the clip's own joint positions give them, on every frame neither target was clamped."""
    rig = load_rig(rig_name)
    targets = rig_targets(demo, rig)
    left, right = demo.arm_points("left").points[:, 2], demo.arm_points("right").points[:, 2]
    human = np.linalg.norm(left - right, axis=1)
    robot = np.linalg.norm(targets.world["left"] - targets.world["right"], axis=1)
    free = ~(targets.arms["left"].clamped | targets.arms["right"].clamped)
    assert free.mean() > 0.5
    np.testing.assert_allclose(robot[free], targets.scale * human[free], rtol=1e-9)
    assert np.ptp(human) > 0.1 * human.max()  # the hands did move relative to each other


def test_each_arm_gets_its_own_hand_in_its_own_base_frame(demo):
    rig = load_rig("wx250s-pair")
    targets = rig_targets(demo, rig)
    for rig_arm in rig.arms:
        raw = targets.arms[rig_arm.name].raw
        np.testing.assert_allclose(rig_arm.placement.to_world(raw), targets.world[rig_arm.name], atol=1e-12)
    # the left hand's targets lie on the left (+y) of the right hand's, on most frames
    assert np.mean(targets.world["left"][:, 1] > targets.world["right"][:, 1]) > 0.9


def test_hands_that_meet_meet_in_front_of_the_rig(demo):
    """The frame where the wrists are closest: the two targets are as close (scaled), between the bases and in
    front of them."""
    rig = load_rig("wx250s-pair")
    targets = rig_targets(demo, rig)
    left, right = demo.arm_points("left").points[:, 2], demo.arm_points("right").points[:, 2]
    k = int(np.argmin(np.linalg.norm(left - right, axis=1)))
    mid = 0.5 * (targets.world["left"][k] + targets.world["right"][k])
    gap = np.linalg.norm(targets.world["left"][k] - targets.world["right"][k])
    assert gap == pytest.approx(targets.scale * np.linalg.norm(left[k] - right[k]), rel=1e-9)
    assert abs(mid[1]) < 0.3 and mid[0] > 0.0  # between the two bases (y = +-0.3), ahead of them


def test_the_middle_of_the_shoulders_lands_between_symmetric_bases(demo):
    targets = rig_targets(demo, load_rig("wx250s-pair"))
    assert targets.origin.shape == (3,) and abs(targets.origin[1]) < 1e-9 and targets.origin[0] > 0


def test_orientation_is_refused_on_a_rig(demo):
    rig = load_rig("wx250s-pair")
    config = MappingConfig(orientation_weight=0.5)
    with pytest.raises(ConfigError, match=r"^mapping\.orientation_weight: Expected 0 for a rig .*\(got 0\.5\)$"):
        rig_targets(demo, rig, config)


@pytest.mark.parametrize("clip", shared_clip_params())
def test_every_shared_clip_maps_onto_the_aloha_rig(clip):
    motion = load_bvh(clip)
    targets = rig_targets(motion, load_rig("aloha"))
    for name, t in targets.arms.items():
        assert t.positions.shape == (motion.n_frames, 3) and np.isfinite(t.positions).all(), name
