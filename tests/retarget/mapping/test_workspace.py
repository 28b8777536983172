"""The arm's side of the mapping: the workspace clamp (vectorised and scalar), IK weights, the shoulder
pivot, reach and forward of an arm."""

from __future__ import annotations

import numpy as np
import pytest

import retarget
from retarget.errors import ConfigError
from retarget.mapping.config import Axis, MappingConfig
from retarget.mapping.targets import Targets
from retarget.mapping.workspace import ROLL_WEIGHT, WRIST_WEIGHT, Workspace, arm_geometry, default_origin, ik_weights
from tests.helpers import t_pose, targets_of


@pytest.fixture
def ws() -> Workspace:
    return Workspace(center=np.array([0.0, 0.0, 0.1]), r_min=0.1, r_max=0.5, floor=0.02)


@pytest.mark.parametrize(
    ("point", "expected"),
    [
        ((0.3, 0.0, 0.2), (0.3, 0.0, 0.2)),  # inside: untouched
        ((1.0, 0.0, 0.1), (0.5, 0.0, 0.1)),  # too far: along the ray
        ((0.0, 0.03, 0.1), (0.0, 0.1, 0.1)),  # too close: pushed out along the ray
        ((0.3, 0.0, -0.05), (0.3, 0.0, 0.02)),  # below the floor: lifted
        ((0.0, 0.0, 0.1), (0.1, 0.0, 0.1)),  # at the centre: pushed forward
    ],
    ids=["inside", "far", "near", "floor", "centre"],
)
def test_workspace_clamp(ws, point, expected):
    out, moved = ws.clamp(np.array([point]))
    np.testing.assert_allclose(out[0], expected, atol=1e-12)
    assert bool(moved[0]) == (point != expected)


def test_workspace_clamp_far_and_below_floor_lands_on_the_rim(ws):
    out, moved = ws.clamp(np.array([[2.0, 0.0, -1.0]]))
    assert moved[0]
    assert out[0, 2] == pytest.approx(0.02)
    assert np.linalg.norm(out[0] - ws.center) == pytest.approx(0.5)
    with pytest.raises(ValueError, match=r"Expected points of shape \(\.\.\., 3\), got \(4, 2\)"):
        ws.clamp(np.zeros((4, 2)))


@pytest.mark.parametrize("seed", [0, 1, 2], ids=lambda s: f"seed{s}")
def test_the_scalar_clamp_and_sample_agree_with_the_vectorized_ones(ws, seed):
    rng = np.random.default_rng(seed)
    points = rng.uniform(-0.8, 0.8, size=(300, 3))
    points[:10] = ws.center + rng.normal(scale=1e-3, size=(10, 3))  # near the centre
    out, moved = ws.clamp(points)
    for p, o, m in zip(points, out, moved, strict=True):
        x, y, z, mm = ws.clamp_point(*p.tolist())
        np.testing.assert_allclose((x, y, z), o, atol=1e-12)
        assert mm == m
    raw = rng.uniform(-0.6, 0.6, size=(40, 3))
    targets = Targets.from_raw(raw, frame_time=0.1, workspace=ws)
    times = rng.uniform(-0.5, 4.5, size=50)
    positions, _, clamped = targets.sample(times)
    for t, p, c in zip(times, positions, clamped, strict=True):
        one, moved = targets.at(float(t))
        np.testing.assert_allclose(one, p, atol=1e-12)
        assert moved == c


def test_default_ik_weights_hold_roll_joints_and_damp_the_wrist(arm):
    w = ik_weights(arm, MappingConfig())
    np.testing.assert_array_equal(w, [1.0, 1.0, 1.0, ROLL_WEIGHT, WRIST_WEIGHT, ROLL_WEIGHT])
    np.testing.assert_array_equal(ik_weights(arm, MappingConfig(orientation_weight=1.0)), np.ones(6))
    named = MappingConfig.from_table({"joint_weights": {"forearm_roll": 0.5}})
    assert ik_weights(arm, named)[3] == 0.5
    every = MappingConfig.from_table({"joint_weights": [1, 1, 1, 1, 1, 1]})
    np.testing.assert_array_equal(ik_weights(arm, every), np.ones(6))
    px100 = retarget.load_arm("px100")
    np.testing.assert_array_equal(ik_weights(px100, MappingConfig()), [1.0, 1.0, 1.0, WRIST_WEIGHT])


@pytest.mark.parametrize(
    ("table", "match"),
    [
        ({"joint_weights": {"wrist": 0.5}}, r"mapping\.joint_weights\.wrist: unknown joint; expected one of waist"),
        ({"joint_weights": [1, 1]}, r"mapping\.joint_weights: Expected 6 joint weights \(got \[1\.0, 1\.0\]\)"),
    ],
    ids=["unknown-joint", "count"],
)
def test_bad_joint_weights(arm, table, match):
    with pytest.raises(ConfigError, match=match):
        ik_weights(arm, MappingConfig.from_table(table))


def test_arm_geometry(arm):
    g = arm_geometry(arm)
    np.testing.assert_allclose(g.pivot, [0.0, 0.0, 0.072 + 0.03865])
    upper = np.hypot(0.04975, 0.25)
    assert g.reach == pytest.approx(upper + 0.175 + 0.075 + 0.065 + 0.093575)


def test_the_robot_forward_comes_from_the_home_pose():
    koch = retarget.load_arm("koch")  # the community URDF points the arm along -x
    g = arm_geometry(koch)
    np.testing.assert_array_equal(g.forward, [-1.0, 0.0, 0.0])
    np.testing.assert_array_equal(g.basis(), [[-1, 0, 0], [0, -1, 0], [0, 0, 1]])
    np.testing.assert_array_equal(g.basis(Axis.PY)[:, 0], [0, 1, 0])
    origin = default_origin(MappingConfig(), g)
    assert origin[0] < g.pivot[0]  # in front of the Koch is behind its base x axis
    # T-pose right arm: the robot's right, whichever way it faces
    targets = targets_of(t_pose(), koch, MappingConfig(arm_scale=0.3))
    np.testing.assert_allclose(targets.raw[0] - origin, [0.0, 0.3 * g.reach, 0.0], atol=1e-9)
    turned = targets_of(t_pose(), koch, MappingConfig(arm_scale=0.3, robot_forward=Axis.PX))
    assert turned.raw[0, 1] < origin[1]
