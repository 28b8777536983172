"""Teleop target input: parsing, bounds, frames, the gate's counted rejections, the Cartesian step limit."""

from __future__ import annotations

import logging
import random

import numpy as np
import pytest

from retarget.control.clock import VirtualClock
from retarget.errors import ConfigError
from retarget.teleop.gate import (
    BasePose,
    Reject,
    TargetBounds,
    TargetGate,
    TargetRejected,
    parse_message,
    step_toward,
)
from tests.helpers import garbage


@pytest.fixture
def gate(arm):
    return TargetGate(TargetBounds.for_arm(arm), clock=VirtualClock(5.0))


# ------------------------------------------------------------------------------------------------ parsing


@pytest.mark.parametrize(
    ("text", "position", "rpy_deg"),
    [
        ("0.3 0 0.2", (0.3, 0, 0.2), None),
        ("0.3,0,0.2", (0.3, 0, 0.2), None),
        ("  0.3 ,\t-0.1 , .2  ", (0.3, -0.1, 0.2), None),
        ("3e-1 0 2E-1", (0.3, 0, 0.2), None),
        ("0.3 0 0.2 10 20 30", (0.3, 0, 0.2), (10, 20, 30)),
        ('{"x": 0.3, "y": 0, "z": 0.2}', (0.3, 0, 0.2), None),
        ('{"x": 0.3, "y": 0, "z": 0.2, "rpy": [0, 90, 0]}', (0.3, 0, 0.2), (0, 90, 0)),
        ('{"z": 0.2, "y": 1, "x": 0.3, "yaw": 45}', (0.3, 1, 0.2), (0, 0, 45)),
        (b"0.1 0.2 0.3", (0.1, 0.2, 0.3), None),
    ],
    ids=["spaces", "commas", "mixed", "exponent", "six", "json", "json-rpy", "json-yaw", "bytes"],
)
def test_parse_valid_forms(text, position, rpy_deg):
    m = parse_message(text)
    np.testing.assert_allclose(m.position, position)
    if rpy_deg is None:
        assert m.rpy is None
    else:
        np.testing.assert_allclose(m.rpy, np.radians(rpy_deg))


@pytest.mark.parametrize("text", ["", "   ", "# a comment", b"\n"], ids=["empty", "blank", "comment", "newline"])
def test_parse_skips_blank_and_comments(text):
    assert parse_message(text) is None


@pytest.mark.parametrize(
    ("text", "reason", "match"),
    [
        ("0.3 0", Reject.MALFORMED, "x y z"),
        ("0.3 0 0.2 1", Reject.MALFORMED, "x y z"),
        ("1_0 0 0", Reject.MALFORMED, "x y z"),
        ("0x1 0 0", Reject.MALFORMED, "x y z"),
        ("a b c", Reject.MALFORMED, "x y z"),
        ('{"x": 0.3, "y": 0', Reject.MALFORMED, "JSON object"),
        ("[0.3, 0, 0.2]", Reject.MALFORMED, "x y z"),
        ('{"x": 0.3, "y": 0}', Reject.MALFORMED, r'\{"x"'),
        ('{"x": 0.3, "y": 0, "z": 0.2, "w": 1}', Reject.MALFORMED, r'\{"x"'),
        ('{"x": "0.3", "y": 0, "z": 0.2}', Reject.MALFORMED, "numbers"),
        ('{"x": true, "y": 0, "z": 0.2}', Reject.MALFORMED, "numbers"),
        ('{"x": 0, "y": 0, "z": 0, "rpy": [1, 2]}', Reject.MALFORMED, "rpy"),
        ('{"x": 0, "y": 0, "z": 0, "rpy": [1, 2, 3], "yaw": 1}', Reject.MALFORMED, "not both"),
        ("[" * 5000, Reject.OVERSIZE, "at most"),
        (b"\xff\xfe 1 2", Reject.MALFORMED, "UTF-8"),
        ("nan 0 0", Reject.NON_FINITE, "finite"),
        ("0 -inf 0", Reject.NON_FINITE, "finite"),
        ("1e999 0 0", Reject.NON_FINITE, "finite"),
        ('{"x": NaN, "y": 0, "z": 0}', Reject.NON_FINITE, "finite"),
        ('{"x": Infinity, "y": 0, "z": 0}', Reject.NON_FINITE, "finite"),
        ('{"x": 1' + "0" * 400 + ', "y": 0, "z": 0}', Reject.NON_FINITE, "finite"),
    ],
    ids=lambda v: v.name if isinstance(v, Reject) else None,
)
def test_parse_rejects(text, reason, match):
    with pytest.raises(TargetRejected, match=match) as info:
        parse_message(text)
    assert info.value.reason is reason


def test_size_limit_is_in_bytes():
    line = "0.3 0 0.2" + " " * 91  # 100 bytes
    assert parse_message(line, max_bytes=100) is not None
    with pytest.raises(TargetRejected, match="at most 99 bytes, got 100"):
        parse_message(line, max_bytes=99)
    with pytest.raises(TargetRejected, match="got 12"):
        parse_message("0.3 0 0.2 é", max_bytes=10)  # 11 characters, 12 bytes


# ------------------------------------------------------------------------------------------------ bounds, frames


def test_bounds_for_arm(arm):
    b = TargetBounds.for_arm(arm, margin=0.1)
    from retarget.mapping import arm_geometry

    g = arm_geometry(arm)
    assert b.max_radius == pytest.approx(g.reach + 0.1)
    assert b.lower[2] == 0.0  # cut at the mounting plane
    b.check(g.pivot + [g.reach + 0.05, 0, 0])  # unreachable but within the margin: accepted
    with pytest.raises(TargetRejected, match="within") as info:
        b.check(g.pivot + np.array([1, 1, 1]) * (g.reach + 0.1) * 0.9)  # a corner of the cube
    assert info.value.reason is Reject.OUT_OF_REACH
    with pytest.raises(TargetRejected, match="inside the box") as info:
        b.check([0.3, 0.0, -0.01])
    assert info.value.reason is Reject.OUT_OF_BOX


def test_bounds_custom_box(arm):
    b = TargetBounds.for_arm(arm, box=(0, -0.1, 0.1, 0.4, 0.1, 0.5))
    b.check([0.2, 0, 0.3])
    with pytest.raises(TargetRejected, match="inside the box"):
        b.check([0.2, 0.2, 0.3])


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"box": (0, 0, 0, 1, 1)}, "6 finite numbers"),
        ({"box": (0, 0, 0, 1, 1, float("nan"))}, "6 finite numbers"),
        ({"box": (0, 0, 1, 1, 1, 0.5)}, "minimum below its maximum"),
        ({"margin": -1}, "margin"),
    ],
    ids=["short", "nan", "inverted", "margin"],
)
def test_bounds_errors(arm, kwargs, match):
    with pytest.raises(ConfigError, match=match):
        TargetBounds.for_arm(arm, **kwargs)


def test_base_pose_round_trip():
    rng = np.random.default_rng(3)
    for _ in range(20):
        pose = BasePose.from_xyz_rpy(rng.uniform(-1, 1, 3), rng.uniform(-180, 180, 3))
        p = rng.uniform(-1, 1, 3)
        R = BasePose.from_xyz_rpy((0, 0, 0), rng.uniform(-180, 180, 3)).rotation
        base, Rb = pose.to_base(pose.to_world(p), pose.rotation @ R)
        np.testing.assert_allclose(base, p, atol=1e-12)
        np.testing.assert_allclose(Rb, R, atol=1e-12)


def test_gate_world_frame(arm):
    pose = BasePose.from_xyz_rpy((1.0, 2.0, 0.0), (0, 0, 90))  # base at (1, 2), turned 90 deg
    gate = TargetGate(TargetBounds.for_arm(arm), clock=VirtualClock(), frame_pose=pose)
    t = gate.accept("1.0 2.3 0.2")  # 0.3 m along world +y = base +x
    np.testing.assert_allclose(t.position, [0.3, 0, 0.2], atol=1e-12)


# ------------------------------------------------------------------------------------------------ the gate


def test_gate_accepts_and_stamps(gate):
    t = gate.accept('{"x": 0.3, "y": 0, "z": 0.2, "rpy": [0, 90, 0]}')
    assert t.received == 5.0 and t.seq == 0
    np.testing.assert_allclose(t.rotation @ [1, 0, 0], [0, 0, -1], atol=1e-12)  # pitch 90: tool x points down
    gate.clock.advance(1.0)
    assert gate.accept("0.3 0 0.25").received == 6.0
    assert gate.accepted == 2 and gate.rejects.total == 0


def test_garbage_is_counted_and_never_accepted(gate):
    rng = random.Random(7)
    messages = garbage(rng, 1000)
    for m in messages:
        assert gate.accept(m) is None
    counts = gate.rejects.counts()
    assert sum(counts.values()) == 1000
    assert gate.accepted == 0
    assert all(counts[r.value] > 0 for r in (Reject.OVERSIZE, Reject.MALFORMED, Reject.NON_FINITE, Reject.OUT_OF_BOX))


def test_rejections_warn_rate_limited(gate, caplog):
    with caplog.at_level(logging.WARNING, logger="retarget.teleop.gate"):
        for _ in range(250):
            gate.accept("nan 0 0")
    lines = [r.getMessage() for r in caplog.records]
    assert len(lines) == 3 + 2  # the first three, then the 100th and 200th
    assert "200 non_finite so far" in lines[-1]


def test_step_toward():
    a, b = np.zeros(3), np.array([3.0, 4.0, 0.0])
    np.testing.assert_allclose(step_toward(a, b, 1.0), [0.6, 0.8, 0])
    np.testing.assert_allclose(step_toward(a, b, 5.0), b)
    np.testing.assert_allclose(step_toward(a, b, float("inf")), b)
    rng = np.random.default_rng(0)
    for _ in range(50):  # never farther than the limit, never overshoots
        p, q, d = rng.normal(size=3), rng.normal(size=3), rng.uniform(0, 2)
        s = step_toward(p, q, d)
        assert np.linalg.norm(s - p) <= d + 1e-12
        assert np.linalg.norm(q - s) <= np.linalg.norm(q - p) + 1e-12
