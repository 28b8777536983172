"""Bimanual teleop (dry runs): two-arm messages, each arm's part through its own gate, each arm following its own
targets, and the arms never brought within their clearance."""

from __future__ import annotations

import math
import random
from dataclasses import replace

import numpy as np
import pytest

from retarget.collision import CollisionModel
from retarget.control.clock import VirtualClock
from retarget.control.loop import LoopConfig
from retarget.mapping import arm_geometry
from retarget.rig import Placement, RigGate, RigInput, load_rig, parse_rig_message, rig_followers, run_rig_teleop
from retarget.teleop import Reject, TargetBounds, TargetRejected
from tests.helpers import garbage, sampled_min_clearance, wx250s_tool

NAMES = ("left", "right")


# ------------------------------------------------------------------ parsing


@pytest.mark.parametrize(
    "text, expected",
    [
        pytest.param("left 0.3 0.35 0.2 right 0.3 -0.35 0.2", {"left": [0.3, 0.35, 0.2], "right": [0.3, -0.35, 0.2]},
                     id="both"),
        pytest.param("right 0.1,0.2,0.3", {"right": [0.1, 0.2, 0.3]}, id="one-arm-commas"),
        pytest.param("  right 1 2 3   left -1e-1 +2 .5  ", {"right": [1, 2, 3], "left": [-0.1, 2, 0.5]}, id="order"),
        pytest.param('{"left": {"x": 0.3, "y": 0.35, "z": 0.2}, "right": {"x": 0.3, "y": -0.35, "z": 0.2}}',
                     {"left": [0.3, 0.35, 0.2], "right": [0.3, -0.35, 0.2]}, id="json"),
        pytest.param('{"right": {"x": 1, "y": 2, "z": 3}}', {"right": [1, 2, 3]}, id="json-one-arm"),
    ],
)  # fmt: skip
def test_good_messages_give_each_named_arm_its_point(text, expected):
    for data in (text, text.encode()):
        parts = parse_rig_message(data, NAMES)
        assert list(parts) == list(expected)
        for name, position in expected.items():
            np.testing.assert_allclose(parts[name].position, position)
            assert parts[name].rpy is None


def test_orientation_per_arm_in_degrees_both_forms():
    a = parse_rig_message("left 0.3 0.35 0.2 0 90 -45 right 0.3 -0.35 0.2", NAMES)
    b = parse_rig_message('{"left": {"x": 0.3, "y": 0.35, "z": 0.2, "rpy": [0, 90, -45]}}', NAMES)
    c = parse_rig_message('{"left": {"x": 0.3, "y": 0.35, "z": 0.2, "pitch": 90, "yaw": -45}}', NAMES)
    for parts in (a, b, c):
        np.testing.assert_allclose(parts["left"].rpy, [0.0, math.pi / 2, -math.pi / 4])
    assert a["right"].rpy is None


@pytest.mark.parametrize("text", ["", "   ", "# left 1 2 3", b"\n"], ids=["empty", "spaces", "comment", "newline"])
def test_blank_and_comment_lines_are_no_message(text):
    assert parse_rig_message(text, NAMES) is None


@pytest.mark.parametrize(
    "data, reason, match",
    [
        pytest.param(b"left " + b"0.3 " * 300, Reject.OVERSIZE, r"at most 1024 bytes", id="oversize"),
        pytest.param(b"left \xff\xfe 0 0", Reject.MALFORMED, r"UTF-8", id="not-utf8"),
        pytest.param("0.3 0 0.2", Reject.MALFORMED, r"Expected 'NAME x y z", id="no-arm-name"),
        pytest.param("middle 0.3 0 0.2", Reject.MALFORMED, r"an arm of the rig \(left, right\).*middle", id="unknown"),
        pytest.param("left 1 2 3 left 1 2 3", Reject.MALFORMED, r"each arm at most once, got left twice", id="twice"),
        pytest.param("left 0.3 0.35", Reject.MALFORMED, r"target\.left: Expected 'x y z'", id="two-numbers"),
        pytest.param("left 1 2 3 4", Reject.MALFORMED, r"target\.left: Expected 'x y z'", id="four-numbers"),
        pytest.param("left right 1 2 3", Reject.MALFORMED, r"Expected x y z after left", id="empty-arm"),
        pytest.param("left 1 2 3 g=1", Reject.MALFORMED, r"target\.left", id="gripper-field"),
        pytest.param("left 1 2 3 400 0 0", Reject.MALFORMED, r"from -360 to 360 degrees", id="angle-range"),
        pytest.param("left nan 0 0.2", Reject.NON_FINITE, r"target\.left: Expected finite", id="nan"),
        pytest.param("right 0.3 -inf 0.2", Reject.NON_FINITE, r"target\.right: Expected finite", id="inf"),
        pytest.param("left 1e999 0 0", Reject.NON_FINITE, r"Expected finite", id="overflow"),
        pytest.param('{"left": {"x": 0.3, "y": 0.3}}', Reject.MALFORMED, r'Expected \{"x"', id="json-missing-z"),
        pytest.param('{"left": [0.3, 0.3, 0.2]}', Reject.MALFORMED, r'Expected \{"x"', id="json-list"),
        pytest.param('{"left": {"x": "0.3", "y": 0, "z": 0}}', Reject.MALFORMED, r"Expected numbers", id="json-str"),
        pytest.param('{"left": {"x": true, "y": 0, "z": 0}}', Reject.MALFORMED, r"Expected numbers", id="json-bool"),
        pytest.param('{"left": {"x": NaN, "y": 0, "z": 0}}', Reject.NON_FINITE, r"finite", id="json-nan"),
        pytest.param('{"left": {"x": 1' + "0" * 400 + ', "y": 0, "z": 0}}', Reject.NON_FINITE, r"finite",
                     id="json-huge-int"),
        pytest.param('{"mid": {"x": 0, "y": 0, "z": 0}}', Reject.MALFORMED, r"an arm of the rig", id="json-unknown"),
        pytest.param('{"left": {"x": 0, "y": 0, "z": 0}, "left": {"x": 1, "y": 0, "z": 0}}', Reject.MALFORMED,
                     r"each key once, got 'left' twice", id="json-twice"),
        pytest.param("{}", Reject.MALFORMED, r"Expected 'NAME x y z", id="json-empty"),
        pytest.param('{"left": {"x": 0, "y": 0, "z": 0}', Reject.MALFORMED, r"a JSON object", id="json-cut"),
        pytest.param("[1, 2, 3]", Reject.MALFORMED, r"Expected 'NAME x y z", id="json-array"),
    ],
)  # fmt: skip
def test_garbage_is_rejected_with_its_reason(data, reason, match):
    with pytest.raises(TargetRejected, match=match) as info:
        parse_rig_message(data, NAMES)
    assert info.value.reason is reason


# ------------------------------------------------------------------ the gate: world -> each arm's base, per-arm bounds


def test_each_part_goes_to_its_arms_base_frame():
    rig = load_rig("wx250s-pair")
    turned = replace(rig.arms[1], placement=Placement((0.1, -0.3, 0.0), (0.0, 0.0, math.pi / 2)))
    rig = replace(rig, arms=(rig.arms[0], turned))
    gate = RigGate.for_rig(rig, clock=VirtualClock())
    targets = gate.accept("left 0.3 0.35 0.2 right 0.1 -0.05 0.25")
    np.testing.assert_allclose(targets["left"].position, [0.3, 0.05, 0.2], atol=1e-12)
    # right's base: at (0.1, -0.3), x along world +y; world (0.1, -0.05) is 0.25 m ahead of it
    np.testing.assert_allclose(targets["right"].position, [0.25, 0.0, 0.25], atol=1e-12)
    assert (targets["left"].seq, targets["right"].seq, gate.accepted) == (0, 0, 1)


def per_arm_garbage(rig, models):
    """``(message, arm, reason)``: messages whose one part fails its own arm's gate (the other part is fine)."""
    left = rig["left"]
    bounds = TargetBounds.for_arm(left.arm)  # the gate's: reach + 0.2 m around the shoulder, and the cube around it
    assert bounds.max_radius == pytest.approx(arm_geometry(left.arm).reach + 0.2)
    far = left.placement.to_world(bounds.center + 0.7 * bounds.max_radius * np.array([1.0, 1.0, 0.5]))  # box corner
    base = left.placement.to_world([0.0, 0.0, 0.02])  # at the base: blocked
    assert models["left"].point_blocked([0.0, 0.0, 0.02])
    ok = "left 0.3 0.35 0.2"
    return [
        (f"{ok} right 5 -0.3 0.2", "right", Reject.OUT_OF_BOX),
        ("left 0.3 0.35 -0.1 right 0.3 -0.3 0.2", "left", Reject.OUT_OF_BOX),  # below the table
        ("left {:.4f} {:.4f} {:.4f}".format(*far), "left", Reject.OUT_OF_REACH),
        ("right 0.3 -0.3 0.2 left {:.4f} {:.4f} {:.4f}".format(*base), "left", Reject.BLOCKED),
    ]


def test_a_part_out_of_its_arms_bounds_rejects_the_whole_message_counted_for_that_arm():
    rig = load_rig("wx250s-pair")
    models = {a.name: CollisionModel.for_arm(a.arm) for a in rig.arms}
    gate = RigGate.for_rig(rig, clock=VirtualClock(), models=models)
    expected = {name: {r.value: 0 for r in Reject} for name in NAMES}
    for text, name, reason in per_arm_garbage(rig, models):
        assert gate.accept(text) is None, text
        expected[name][reason.value] += 1
    assert {name: gate.arm_counts(name) for name in NAMES} == expected
    assert sum(gate.counts().values()) == 0 and gate.accepted == 0
    assert gate.totals()["out_of_box"] == 2


def test_one_shot_raises_and_steers_a_blocked_part_to_the_nearest_safe_point():
    rig = load_rig("wx250s-pair")
    models = {a.name: CollisionModel.for_arm(a.arm) for a in rig.arms}
    gate = RigGate.for_rig(rig, clock=VirtualClock(), models=models)
    with pytest.raises(TargetRejected, match=r"to\.right: .*inside the box") as info:
        gate.one_shot("left 0.3 0.35 0.2 right 5 0 0")
    assert info.value.reason is Reject.OUT_OF_BOX
    with pytest.raises(TargetRejected, match=r"^to: Expected 'NAME"):
        gate.one_shot("# nothing")
    targets = gate.one_shot("left 0 0.3 0.02")  # at the left base
    aim, model = targets["left"].aim, models["left"]
    assert aim is not None and model.point_margin(aim) >= model.clearance - 1e-6  # on the clear zone's edge
    assert gate.arm_counts("left")["blocked"] == 1


# ------------------------------------------------------------------ runs


def world_tool(rig_arm, q):
    """The tool point (3,) m in the world: the independent wx250s FK, then the base's offset (no rotation here)."""
    assert rig_arm.arm.name == "wx250s" and rig_arm.placement.rpy == (0.0, 0.0, 0.0)
    return wx250s_tool(q) + np.asarray(rig_arm.placement.xyz)


def dry_run(rig, rig_input, *, models=None, records=None, **knobs):
    clock = rig_input.gate.gates["left"].clock
    followers = rig_followers(rig, rig_input, clock=clock, rate=100.0, **knobs)
    return run_rig_teleop(rig, followers, config=LoopConfig(max_ticks=3000), clock=clock, models=models,
                          rig_input=rig_input, on_tick=None if records is None else records.append)  # fmt: skip


def test_a_stream_with_garbage_mixed_in_moves_each_arm_to_its_own_last_valid_target():
    rig = load_rig("wx250s-pair")
    models = {a.name: CollisionModel.for_arm(a.arm) for a in rig.arms}
    rig_input = RigInput(RigGate.for_rig(rig, clock=VirtualClock(), models=models))
    rng = random.Random(19)
    junk = garbage(rng, 60)  # one-arm garbage: none of it names an arm
    bad = per_arm_garbage(rig, models)
    valid = [
        "left 0.3 0.35 0.2 right 0.3 -0.35 0.2",
        '{"right": {"x": 0.25, "y": -0.25, "z": 0.3}}',
        "left 0.35,0.3,0.15",
        '{"left": {"x": 0.28, "y": 0.4, "z": 0.25}, "right": {"x": 0.32, "y": -0.4, "z": 0.12}}',
        "right 0.3 -0.28 0.22",
    ]
    stream = []
    for k, text in enumerate(valid):
        stream += [text, *junk[12 * k : 12 * k + 12], bad[k % len(bad)][0]]
    for message in stream:
        rig_input.feed(message.encode() if isinstance(message, str) else message)
    rig_input.close()
    result = dry_run(rig, rig_input, models=models)
    last = {"left": [0.28, 0.4, 0.25], "right": [0.3, -0.28, 0.22]}
    for a in rig.arms:
        r = result.arms[a.name]
        np.testing.assert_allclose(world_tool(a, r.q_final), last[a.name], atol=2e-3)
        assert r.reached_target and r.received == {"left": 3, "right": 4}[a.name] and all(v.reached for v in r.visits)
    assert result.reached_targets
    # every garbage message counted once, by its reason: the message's, or the arm whose part failed
    junk_reasons = {}
    for m in junk:
        try:
            parse_rig_message(m, NAMES)
        except TargetRejected as exc:
            junk_reasons[exc.reason.value] = junk_reasons.get(exc.reason.value, 0) + 1
    assert sum(junk_reasons.values()) == len(junk)
    assert {k: v for k, v in result.rejects.items() if v} == junk_reasons
    arm_rejects = {name: {k: v for k, v in result.arms[name].rejects.items() if v} for name in NAMES}
    assert arm_rejects == {"left": {"out_of_box": 1, "out_of_reach": 1, "blocked": 1}, "right": {"out_of_box": 2}}


def test_targets_that_would_make_the_arms_touch_stop_them_at_the_clearance():
    rig = load_rig("wx250s-pair")
    models = {a.name: CollisionModel.for_arm(a.arm) for a in rig.arms}
    rig_input = RigInput(RigGate.for_rig(rig, clock=VirtualClock(), models=models))
    rig_input.feed("left 0.3 0.3 0.2 right 0.3 -0.3 0.2")
    rig_input.feed("left 0.3 -0.05 0.2 right 0.3 0.05 0.2")  # each tool past the other's: they would cross
    rig_input.close()
    records = []
    result = dry_run(rig, rig_input, models=models, records=records)
    assert result.summary.blocked_ticks > 0 and not result.reached_targets
    assert result.summary.min_clearance_mm >= min(m.clearance for m in models.values()) * 1e3 - 1e-6
    poses = [dict(zip(NAMES, (r.q_cmd[:6], r.q_cmd[6:]), strict=True)) for r in records]
    for pose in poses[::4] + poses[-1:]:  # never touching, by the independent brute-force check
        assert sampled_min_clearance(rig, pose, spacing=0.004) > 0.005
    assert sampled_min_clearance(rig, poses[-1], spacing=0.004) < 0.04  # they came close, and stopped
    for name in NAMES:
        assert [v.reached for v in result.arms[name].visits] == [True, False]  # the first reached, the second not
