"""retarget.collision: distance primitives against hand-computed cases and a brute force, the bundled arms'
known colliding and clear poses, joint-space segments and target points."""

from __future__ import annotations

import math

import numpy as np
import pytest

from retarget.arm.load import load_arm
from retarget.collision import Box, CollisionModel, Sphere, World
from retarget.collision.distance import point_box, segment_box, segment_segment
from retarget.errors import ConfigError
from tests.helpers import brute_force_min_clearance

A = np.array


@pytest.mark.parametrize(
    ("p1", "q1", "p2", "q2", "expected"),
    [
        ((0, 0, 0), (1, 0, 0), (0.5, 1, 0), (0.5, 2, 0), 1.0),  # T shape
        ((0, 0, 0), (1, 0, 0), (0, 1, 0), (1, 1, 0), 1.0),  # parallel
        ((0, 0, 0), (1, 0, 0), (2, 0, 0), (3, 0, 0), 1.0),  # collinear, apart
        ((0, 0, 0), (1, 0, 0), (0.5, -1, 1), (0.5, 1, 1), 1.0),  # crossing, above
        ((0, 0, 0), (0, 0, 0), (3, 4, 0), (3, 4, 0), 5.0),  # two points
        ((0, 0, 0), (1, 0, 0), (2, 1, 0), (2, 1, 0), math.sqrt(2)),  # a point past the end
    ],
    ids=["t", "parallel", "collinear", "crossing", "points", "point-end"],
)
def test_segment_segment_hand_cases(p1, q1, p2, q2, expected):
    assert float(segment_segment(A(p1, float), A(q1, float), A(p2, float), A(q2, float))) == pytest.approx(expected)


@pytest.mark.parametrize(
    ("a", "b", "expected"),
    [
        ((0, 0, 2), (0, 0, 3), 1.0),  # above the top face
        ((2, 2, 0), (2, 2, 0), math.sqrt(2)),  # a point off an edge
        ((3, -3, 2), (3, 3, 2), math.sqrt(5)),  # passing an edge diagonally
        ((-3, 0, 0), (3, 0, 0), -1.0),  # straight through: negative
    ],
    ids=["face", "edge-point", "edge-pass", "through"],
)
def test_segment_box_hand_cases(a, b, expected):
    got = float(segment_box(A(a, float), A(b, float), np.zeros(3), np.ones(3)))
    assert got == pytest.approx(expected) if expected > 0 else got < 0


def test_primitives_match_a_brute_force_on_random_cases():
    rng = np.random.default_rng(7)
    t = np.linspace(0, 1, 401)
    for _ in range(40):
        p1, q1, p2, q2 = rng.uniform(-1, 1, (4, 3))
        brute = np.linalg.norm((p1 + t[:, None] * (q1 - p1))[:, None] - (p2 + t[:, None] * (q2 - p2))[None], axis=2)
        assert float(segment_segment(p1, q1, p2, q2)) == pytest.approx(brute.min(), abs=5e-3)
        c, h = rng.uniform(-0.3, 0.3, 3), rng.uniform(0.05, 0.3, 3)
        pts = p1 + t[:, None] * (q1 - p1)
        got = float(segment_box(p1, q1, c, h))
        want = float(point_box(pts, c, h).min())
        assert got == pytest.approx(want, abs=5e-3) if want > 0 else got <= want + 5e-3


@pytest.fixture(scope="module")
def wx():
    return CollisionModel.for_arm(load_arm("wx250s"))


@pytest.mark.parametrize("name", ["wx250s", "vx300s", "px100", "omx", "koch"])
def test_home_and_rest_of_every_bundled_arm_are_clear(name):
    arm = load_arm(name)
    model = CollisionModel.for_arm(arm)
    assert model.is_clear(arm.home), model.worst_pair(arm.home)
    assert model.is_clear(arm.rest), model.worst_pair(arm.rest)


@pytest.mark.parametrize(
    ("q_deg", "pair"),
    [
        ((0, -109, 149, 0, 0, 0), "upper_forearm/base_rear"),  # elbow folded into the base
        ((0, 97, 29, 0, 57, 0), "gripper/table"),  # gripper through the table
        ((0, 0, 149, 0, 0, 0), "upper_forearm/upper_arm"),  # forearm through the upper arm
    ],
    ids=["elbow-into-base", "gripper-through-table", "forearm-through-upper-arm"],
)
def test_known_colliding_wx250s_poses_are_detected(wx, q_deg, pair):
    q = np.radians(q_deg)
    d = dict(zip(wx.pair_names, wx.distances(q), strict=True))
    assert d[pair] < 0
    assert not wx.is_clear(q)


def test_typical_wx250s_poses_are_clear(wx):
    for q_deg in [(0, 0, 0, 0, 0, 0), (30, -20, 20, 0, 30, 0), (-60, 10, -30, 45, 20, 90), (90, -40, 60, 0, -30, 0)]:
        assert wx.is_clear(np.radians(q_deg)), (q_deg, wx.worst_pair(np.radians(q_deg)))


def test_distances_match_the_brute_force_on_random_poses(wx):
    rng = np.random.default_rng(3)
    world = World(keep_out=(Box((0.3, 0.2, 0.1), (0.05, 0.05, 0.1)), Sphere((0.3, -0.2, 0.2), 0.05)))
    model = CollisionModel.for_arm(wx.arm, world=world)
    Q = rng.uniform(wx.arm.lower, wx.arm.upper, (6, wx.arm.n_joints))
    batch = model.distances(Q)
    for q, row in zip(Q, batch, strict=True):
        brute = brute_force_min_clearance(wx.arm, q, world, samples=24)
        for name, value in zip(model.pair_names, row, strict=True):
            tol = 0.012  # the sampling step of the brute force (a box grid of 24 per axis, capsule axes of 24)
            if name == "shoulder/keep_out[0]":  # a moving box against a keep-out box: its bounding sphere
                assert value <= brute[name] + 1e-9
            elif brute[name] > 0:
                assert value == pytest.approx(brute[name], abs=tol), name
                assert value <= brute[name] + 1e-9, name  # the exact distance never exceeds a sampled one
            else:
                assert value < tol, name


def test_shapes_and_names(wx):
    assert wx.distances(wx.arm.home).shape == (len(wx.pair_names),)
    assert wx.distances(np.zeros((3, 6))).shape == (3, len(wx.pair_names))
    assert "gripper/table" in wx.pair_names and "upper_arm/base" in wx.pair_names
    assert wx.min_clearance(wx.arm.home) == pytest.approx(wx.worst_pair(wx.arm.home)[1])
    with pytest.raises(ValueError, match="Expected q of shape"):
        wx.distances([0.0, 1.0])


def test_segment_clear_finds_the_first_blocked_sample(wx):
    down = np.radians([0, 97, 29, 0, 57, 0])
    check = wx.segment_clear(wx.arm.home, down)
    assert not check.clear and check.blocked_at is not None and 0 < check.blocked_at <= 1
    assert check.samples == wx.samples_for(wx.arm.home, down) >= 2
    before = wx.arm.home + (check.blocked_at - 1 / (check.samples - 1)) * (down - wx.arm.home)
    assert wx.is_clear(before)
    ok = wx.segment_clear(wx.arm.home, wx.arm.rest)
    assert ok.clear and ok.blocked_at is None and ok.min_clearance >= wx.clearance


def test_target_points(wx):
    assert wx.point_blocked([0.3, 0.0, -0.05]) and not wx.point_blocked([0.3, 0.0, 0.2])
    assert wx.point_margin([0.0, 0.0, 0.05]) < 0  # inside the base box
    for p in ([0.3, 0.0, -0.05], [0.0, 0.0, 0.05], [0.01, 0.0, 0.0]):
        out = wx.push_out(p)
        assert wx.point_margin(out) >= wx.clearance - 1e-9
    model = CollisionModel.for_arm(wx.arm, world=World(keep_out=(Sphere((0.3, 0, 0.2), 0.05),)))
    assert model.push_out([0.3, 0.0, 0.21]).tolist() == pytest.approx([0.3, 0.0, 0.26])


def test_many_points_margins_are_each_points_own():
    """``point_margins`` of a cloud (one vectorised call) against ``point_margin`` point by point, with every kind of
    zone (table, keep-out box and sphere, the base's shapes)."""
    world = World(keep_out=(Box((0.25, 0.15, 0.1), (0.05, 0.05, 0.1)), Sphere((0.25, -0.15, 0.15), 0.06)))
    model = CollisionModel.for_arm(load_arm("wx250s"), world=world)
    points = np.random.default_rng(3).uniform([-0.1, -0.3, -0.1], [0.4, 0.3, 0.4], (300, 3))
    expected = [model.point_margin(p) for p in points]
    assert model.point_margins(points).tolist() == pytest.approx(expected, abs=1e-15)
    assert (model.point_margins(points) < 0).any() and (model.point_margins(points) > 0.05).any()
    points[7, 1] = math.nan
    with pytest.raises(ValueError, match=r"Expected finite points, got \[.*nan.*\] \(point 7\)"):
        model.point_margins(points)
    with pytest.raises(ValueError, match=r"Expected points of shape \(n, 3\), got \(3,\)"):
        model.point_margins(points[0])


def test_world_validation():
    with pytest.raises(ConfigError, match="radius"):
        Sphere((0, 0, 0), -1)
    with pytest.raises(ConfigError, match="half_size"):
        Box((0, 0, 0), (1, math.nan, 1))
    with pytest.raises(ConfigError, match="Box or a Sphere"):
        World(keep_out=("box",))  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="clearance"):
        CollisionModel.for_arm(load_arm("px100"), clearance=-1.0)


def test_vx300s_elbow_folded_through_the_upper_arm_is_detected():
    # the fat forearm capsule meets the upper arm at the zero pose (neighbours), but the elbow folds: past its
    # range (the forearm through the upper arm) the pair is checked, with the depth the elbow's own range needs
    model = CollisionModel.for_arm(load_arm("vx300s"))
    assert ("upper_arm", "upper_forearm") in {(a, b) for a, b, _ in model.geometry.nest}
    folded = np.radians([0, 0, 120, 0, 0, 0])
    d = dict(zip(model.pair_names, model.distances(folded), strict=True))
    assert d["upper_forearm/upper_arm"] < 0
    assert not model.is_clear(folded)
    arm = model.arm
    for q in (arm.home, arm.rest, *(np.radians(x) for x in [(30, -20, 20, 0, 30, 0), (90, -40, 60, 0, -30, 0)])):
        assert model.is_clear(q), model.worst_pair(q)
    # anywhere in the elbow's own range, the pair keeps the clearance
    Q = np.zeros((50, 6))
    Q[:, 2] = np.linspace(arm.lower[2], arm.upper[2], 50)
    assert model.distances(Q)[:, model.pair_names.index("upper_forearm/upper_arm")].min() >= model.clearance


@pytest.mark.parametrize("name", ["wx250s", "vx300s", "px100", "omx", "koch"])
def test_the_one_pose_path_equals_the_batch_path(name):
    arm = load_arm(name)
    world = World(keep_out=(Box((0.25, 0.15, 0.1), (0.05, 0.05, 0.1)), Sphere((0.25, -0.15, 0.15), 0.06)))
    rng = np.random.default_rng(11)
    for model in (CollisionModel.for_arm(arm), CollisionModel.for_arm(arm, world=world)):
        Q = rng.uniform(arm.lower, arm.upper, (150, arm.n_joints))
        batch = model.distances(Q)
        one = np.array([model.distances(q) for q in Q])
        outside = (batch > 0) & (one > 0)
        assert np.abs(one - batch)[outside].max() < 1e-12
        assert np.array_equal(one < 0, batch < 0)  # a penetrating segment/box pair: both negative (depths differ)
        least = np.array([model.min_clearance(q) for q in Q])
        assert np.abs(least - one.min(axis=1)).max() < 1e-12  # the bounded search is exact
        assert [model.is_clear(q) for q in Q] == (one.min(axis=1) >= model.clearance).tolist()


def test_scalar_kernels_match_the_numpy_kernels():
    from retarget.collision import scalar

    rng = np.random.default_rng(4)
    for _ in range(300):
        p1, q1, p2, q2 = rng.uniform(-1, 1, (4, 3))
        q1 = p1 if rng.random() < 0.2 else q1  # a point
        a, e = float((q1 - p1) @ (q1 - p1)), float((q2 - p2) @ (q2 - p2))
        inv = [1 / x if x > 1e-18 else 0.0 for x in (a, e)]
        got = scalar.segment_segment(p1.tolist(), q1.tolist(), p2.tolist(), q2.tolist(), *inv)
        assert got == pytest.approx(float(segment_segment(p1, q1, p2, q2)), abs=1e-12)
        h = rng.uniform(0.05, 0.5, 3)
        want = float(segment_box(p1, q1, np.zeros(3), h))
        got = scalar.segment_box(p1.tolist(), (q1 - p1).tolist(), h.tolist())
        assert got == pytest.approx(want, abs=1e-12) if want > 0 else got <= 0


def test_a_short_move_is_checked_pose_by_pose_as_a_long_one(wx):
    rng = np.random.default_rng(8)
    for _ in range(40):
        a = rng.uniform(wx.arm.lower * 0.7, wx.arm.upper * 0.7)
        b = a + rng.normal(0.0, 0.05, 6)
        check = wx.segment_clear(a, b)
        frac = np.linspace(0.0, 1.0, check.samples)
        worst = wx.distances(a + frac[:, None] * (b - a)).min(axis=1)
        assert check.min_clearance == pytest.approx(worst.min(), abs=1e-12)
        bad = np.flatnonzero(worst < wx.clearance)
        assert check.blocked_at == (pytest.approx(frac[bad[0]]) if bad.size else None)
        again = wx.segment_clear(b, b + 0.01)  # starts where the last one ended: its clearance is remembered
        assert again.min_clearance <= wx.min_clearance(b) + 1e-12
