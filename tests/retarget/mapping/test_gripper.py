"""The gripper from the clip's hand (retarget.mapping.gripper): a hand that pinches closes the gripper at the right
times (the pinch rule: thumb tip to index tip over the forearm); a hand without a thumb that makes a fist, by the
curl rule; fixed values and CSV tracks."""

from __future__ import annotations

import numpy as np
import pytest

from retarget.bvh.parse import parse_bvh
from retarget.errors import ConfigError
from retarget.mapping.gripper import GripperTrack, hand_gripper_track
from tests.helpers import bvh_text, pinching_hand_bvh, pose, rig

FPS = 30


def _profile() -> np.ndarray:
    """3 s: open until 1 s, closing over 0.2 s, closed until 2 s, opening over 0.2 s, open."""
    t = np.arange(3 * FPS) / FPS
    return np.clip(np.minimum((t - 0.9) / 0.2, (2.1 - t) / 0.2), 0.0, 1.0)


def _crossings(track: GripperTrack) -> list[float]:
    c = track.closure
    return [float(track.times[k]) for k in range(1, c.size) if (c[k - 1] < 0.5) != (c[k] < 0.5)]


@pytest.mark.parametrize("thumb", [pytest.param(True, id="pinch"), pytest.param(False, id="curl")])
def test_a_hand_that_closes_and_opens_gives_a_track_that_closes_and_opens_on_time(thumb):
    motion = parse_bvh(pinching_hand_bvh(_profile(), thumb=thumb, frame_time=1 / FPS))
    track = hand_gripper_track(motion, motion.arm_points("left"))
    assert track is not None
    assert track.rule == ("pinch" if thumb else "curl")
    assert track.at(0.3) < 0.1 and track.at(2.7) < 0.1  # open
    assert track.at(1.5) > 0.9  # closed
    up, down = _crossings(track)
    assert up == pytest.approx(1.0, abs=0.1) and down == pytest.approx(2.0, abs=0.1)


def test_the_filter_removes_single_frame_noise():
    closed = np.zeros(3 * FPS)
    closed[45] = 1.0  # one frame of a glitch
    motion = parse_bvh(pinching_hand_bvh(closed, frame_time=1 / FPS))
    track = hand_gripper_track(motion, motion.arm_points("left"))
    assert track is not None and track.closure.max() < 0.3


def test_no_fingers_no_track():
    root = rig()
    motion = parse_bvh(bvh_text(root, pose(root, 10)))
    assert hand_gripper_track(motion, motion.arm_points("left")) is None


def test_fixed_and_csv_tracks(tmp_path):
    assert GripperTrack.constant(1.0).at(12.0) == 1.0
    with pytest.raises(ValueError, match="from 0 .open. to 1"):
        GripperTrack.constant(1.5)
    path = tmp_path / "g.csv"
    path.write_text("time_s,closure\n0,0\n1,1\n2,0.5\n")
    track = GripperTrack.from_csv(path)
    assert (track.at(-1), track.at(0.5), track.at(1.5), track.at(9)) == (0.0, 0.5, 0.75, 0.5)
    assert track.rule == f"csv {path}"


@pytest.mark.parametrize(
    ("text", "match"),
    [
        pytest.param("0,0\n1,x\n", "line 2: Expected time_s,closure", id="not-a-number"),
        pytest.param("0,0\n1,2\n", "line 2: Expected increasing times and closures 0..1", id="closure-above-1"),
        pytest.param("1,0\n0,1\n", "line 2: Expected increasing", id="time-backwards"),
        pytest.param("time_s,closure\n", "at least one", id="empty"),
    ],
)
def test_bad_csv_tracks(tmp_path, text, match):
    path = tmp_path / "g.csv"
    path.write_text(text)
    with pytest.raises(ConfigError, match=match):
        GripperTrack.from_csv(path)
