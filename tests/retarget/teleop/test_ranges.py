"""Issue 16, item 10: the teleop knobs and angles have ranges (tolerance <= 0.1 m, rpy within +-360 degrees)."""

from __future__ import annotations

import pytest

from retarget.control.clock import VirtualClock
from retarget.control.loop import LoopConfig
from retarget.errors import ConfigError
from retarget.teleop.follower import MAX_TOLERANCE, Follower, run_teleop
from retarget.teleop.gate import BasePose, Reject, TargetBounds, TargetGate, TargetRejected, parse_message
from retarget.teleop.sources import OneShotSource


@pytest.fixture
def gate(arm):
    return TargetGate(TargetBounds.for_arm(arm), clock=VirtualClock(5.0))


@pytest.mark.parametrize("tolerance", [1e300, 0.1001, float("inf")])
def test_a_follower_tolerance_past_the_range_names_the_field(arm, gate, tolerance):
    source = OneShotSource(gate, "0.3,0,0.2")
    with pytest.raises(ConfigError, match=r"^tolerance: Expected a") as info:
        Follower(arm, source, clock=gate.clock, rate=100.0, tolerance=tolerance)
    assert info.value.key == "tolerance"


def test_a_teleop_run_refuses_a_tolerance_that_makes_every_target_reached(arm, gate):
    follower = Follower(arm, OneShotSource(gate, "0.3,0,0.2"), clock=gate.clock, rate=100.0)
    with pytest.raises(ConfigError, match=r"^tolerance: Expected a tolerance > 0 and <= 0\.1 m \(got 1e\+300\)$"):
        run_teleop(arm, follower, config=LoopConfig(max_ticks=5), clock=gate.clock, tolerance=1e300)


def test_the_largest_tolerance_is_accepted(arm, gate):
    follower = Follower(arm, OneShotSource(gate, "0.3,0,0.2"), clock=gate.clock, rate=100.0, tolerance=MAX_TOLERANCE)
    assert follower.tolerance == 0.1


@pytest.mark.parametrize("rpy", ["1e308,0,0", "0,361,0", "0,0,-360.5"])
def test_a_one_shot_rpy_out_of_range_is_rejected_naming_rpy(gate, rpy):
    with pytest.raises(TargetRejected, match=r"^rpy: Expected R,P,Y from -360 to 360 degrees") as info:
        OneShotSource(gate, "0.3,0,0.2", rpy=rpy)
    assert info.value.key == "rpy" and info.value.reason is Reject.MALFORMED


def test_rpy_at_360_degrees_is_accepted(gate):
    OneShotSource(gate, "0.3,0,0.2", rpy="360,-360,0")


@pytest.mark.parametrize(
    "text",
    ["0.3 0 0.2 1e308 0 0", '{"x": 0.3, "y": 0, "z": 0.2, "rpy": [0, 400, 0]}', '{"x":0.3,"y":0,"z":0.2,"yaw":-999}'],
)
def test_a_stream_message_with_rpy_out_of_range_is_rejected(text):
    with pytest.raises(TargetRejected, match=r"^target: Expected roll, pitch and yaw from -360 to 360 degrees") as info:
        parse_message(text)
    assert info.value.reason is Reject.MALFORMED


@pytest.mark.parametrize(
    ("xyz", "rpy"), [((0, 0, 0), (1e308, 0, 0)), ((0, 0, 0), (0, 0, 361)), ((float("nan"), 0, 0), (0, 0, 0))]
)
def test_a_base_pose_out_of_range_names_base_pose(xyz, rpy):
    with pytest.raises(
        ConfigError, match=r"^base_pose: Expected finite numbers, roll, pitch and yaw from -360"
    ) as info:
        BasePose.from_xyz_rpy(xyz, rpy)
    assert info.value.key == "base_pose"
