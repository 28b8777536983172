"""Forward kinematics against hand-computed poses, and the three FK paths against each other."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from retarget import load_arm
from retarget.arm.kinematics import fk, fk_batch, matrix_rpy, rpy_matrix
from retarget.ik import CCDSolver

ARMS = ["wx250s", "vx300s", "px100", "omx", "koch"]

# Tool point at q = 0, summed by hand from the origins in config/arms/*.toml (all rpy = 0 there).
ZERO_TOOL = {
    "wx250s": (0.04975 + 0.175 + 0.075 + 0.065 + 0.093575, 0.0, 0.072 + 0.03865 + 0.25),
    "vx300s": (0.05955 + 0.2 + 0.1 + 0.069744 + 0.1072, 0.0, 0.079 + 0.04805 + 0.3),
    "px100": (0.035 + 0.1 + 0.113575, 0.0, 0.05085 + 0.04225 + 0.1),
    "omx": (0.012 + 0.024 + 0.124 + 0.126, 0.0, 0.0595 + 0.128),
    "koch": (
        0.012 - 0.0148 - 0.10048 - 0.045 - 0.01315,
        -0.0209 + 0.0065 + 0.00005 + 0.013097 - 0.0075,
        0.0409 + 0.0154 + 0.1083 + 0.0026999 + 0.0145,
    ),
}


@pytest.mark.parametrize("name", ARMS)
def test_zero_pose_tool_point(name):
    arm = load_arm(name)
    T, points = arm.fk(np.zeros(arm.n_joints))
    np.testing.assert_allclose(T[:3, 3], ZERO_TOOL[name], atol=1e-12)
    np.testing.assert_allclose(T[:3, :3], np.eye(3), atol=1e-12)
    assert points.shape == (arm.n_joints + 1, 3)
    np.testing.assert_allclose(points[0], arm.joints[0].origin_xyz)
    np.testing.assert_allclose(points[-1], T[:3, 3])


def test_wx250s_hand_computed_poses():
    arm = load_arm("wx250s")
    reach, height = 0.04975 + 0.175 + 0.075 + 0.065 + 0.093575, 0.072 + 0.03865 + 0.25
    # waist +90 deg: the arm turns to +y
    T, _ = arm.fk([math.pi / 2, 0, 0, 0, 0, 0])
    np.testing.assert_allclose(T[:3, 3], [0.0, reach, height], atol=1e-12)
    # shoulder +90 deg about y: (x, z) -> (z, -x) around the shoulder pivot at z = 0.11065
    T, points = arm.fk([0, math.pi / 2, 0, 0, 0, 0])
    np.testing.assert_allclose(points[2], [0.25, 0.0, 0.11065 - 0.04975], atol=1e-12)  # the elbow
    np.testing.assert_allclose(T[:3, 3], [0.25, 0.0, 0.11065 - 0.04975 - (reach - 0.04975)], atol=1e-12)
    # wrist_angle -90 deg points the tool straight up from the wrist
    T, points = arm.fk([0, 0, 0, 0, -math.pi / 2, 0])
    np.testing.assert_allclose(T[:3, 3], [0.04975 + 0.175 + 0.075, 0.0, height + 0.065 + 0.093575], atol=1e-12)
    np.testing.assert_allclose(T[:3, 0], [0, 0, 1], atol=1e-12)  # tool x axis up


def test_omx_home_pose():
    arm = load_arm("omx")  # home [0, -1, 1, 0] rad: upper arm tilted back, forearm level again
    T, _ = arm.fk(arm.home)
    assert arm.home[1] == pytest.approx(-1.0, abs=1e-6) and arm.home[1] + arm.home[2] == 0.0
    c, s = math.cos(arm.home[1]), math.sin(arm.home[1])
    elbow = np.array([0.012 + c * 0.024 + s * 0.128, 0, 0.0595 - s * 0.024 + c * 0.128])
    np.testing.assert_allclose(T[:3, 3], elbow + [0.124 + 0.126, 0, 0], atol=1e-12)


@pytest.mark.parametrize("name", ARMS)
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_fk_paths_agree(name, seed):
    arm = load_arm(name)
    rng = np.random.default_rng(seed)
    Q = rng.uniform(arm.lower, arm.upper, (20, arm.n_joints))
    batch = fk_batch(arm, Q)
    np.testing.assert_allclose(arm.chain.tool_points(Q), batch[:, :3, 3], atol=1e-12)
    solver = CCDSolver(arm)
    for q, Tb in zip(Q, batch, strict=True):
        T, _ = fk(arm, q)
        np.testing.assert_allclose(Tb, T, atol=1e-12)
        f = solver._fk(q.tolist())
        np.testing.assert_allclose(f[:3], T[:3, 3], atol=1e-12)
        np.testing.assert_allclose(np.reshape(f[3:], (3, 3)), T[:3, :3], atol=1e-12)


@pytest.mark.parametrize("name", ARMS)
@pytest.mark.parametrize("seed", [0, 1])
def test_tool_jacobians_are_the_tool_points_derivatives(name, seed):
    """Each column against a central difference of the tool point (1e-6 rad each way), on random poses."""
    arm = load_arm(name)
    Q = np.random.default_rng(seed).uniform(arm.lower, arm.upper, (15, arm.n_joints))
    points, J = arm.chain.tool_jacobians(Q)
    assert J.shape == (15, 3, arm.n_joints)
    np.testing.assert_allclose(points, arm.chain.tool_points(Q), atol=1e-14)
    for j in range(arm.n_joints):
        step = np.zeros(arm.n_joints)
        step[j] = 1e-6
        moved = (arm.chain.tool_points(Q + step) - arm.chain.tool_points(Q - step)) / 2e-6
        np.testing.assert_allclose(J[:, :, j], moved, atol=1e-7)


def test_origin_rpy_and_general_axes():
    """A joint with an rpy origin, a skew axis and a tool rotation: all FK paths agree with a direct product."""
    arm = load_arm("px100")
    joints = list(arm.joints)
    joints[1] = replace(joints[1], origin_rpy=(0.3, -0.2, 0.5), axis=tuple(np.array([1.0, 2.0, 2.0]) / 3))
    joints[3] = replace(joints[3], axis=(0.0, -1.0, 0.0))
    arm = replace(arm, joints=tuple(joints), tool_rpy=(0.1, 0.2, 0.3))
    q = np.array([0.4, -0.3, 0.7, 1.1])
    expected = np.eye(4)
    for j, angle in zip(arm.joints, q, strict=True):
        origin = np.eye(4)
        origin[:3, :3], origin[:3, 3] = rpy_matrix(j.origin_rpy), j.origin_xyz
        k = np.array(j.axis)
        K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
        rot = np.eye(4)
        rot[:3, :3] = np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K
        expected = expected @ origin @ rot
    tool = np.eye(4)
    tool[:3, :3], tool[:3, 3] = rpy_matrix(arm.tool_rpy), arm.tool_xyz
    expected = expected @ tool
    T, _ = arm.fk(q)
    np.testing.assert_allclose(T, expected, atol=1e-12)
    np.testing.assert_allclose(fk_batch(arm, q[None])[0], expected, atol=1e-12)
    f = CCDSolver(arm)._fk(q.tolist())
    np.testing.assert_allclose(f[:3], expected[:3, 3], atol=1e-12)
    np.testing.assert_allclose(np.reshape(f[3:], (3, 3)), expected[:3, :3], atol=1e-12)


@pytest.mark.parametrize("seed", range(5))
def test_rpy_round_trip(seed):
    rng = np.random.default_rng(seed)
    for _ in range(50):
        rpy = rng.uniform([-math.pi, -math.pi / 2, -math.pi], [math.pi, math.pi / 2, math.pi])
        np.testing.assert_allclose(rpy_matrix(matrix_rpy(rpy_matrix(rpy))), rpy_matrix(rpy), atol=1e-12)


def test_rpy_gimbal_lock():
    R = rpy_matrix((0.0, math.pi / 2, 0.7))
    np.testing.assert_allclose(rpy_matrix(matrix_rpy(R)), R, atol=1e-12)


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda arm: arm.fk(np.zeros(5)), r"Expected q of shape \(\.\.\., 6\) for 6 joints, got \(5,\)"),
        (lambda arm: arm.fk(np.zeros((2, 6))), r"use fk_batch"),
        (lambda arm: fk_batch(arm, np.zeros(6)), r"Expected Q of shape \(n, 6\), got \(6,\)"),
        (lambda arm: arm.chain.tool_points(np.zeros(6)), r"Expected Q of shape \(n, 6\), got \(6,\)"),
        (lambda arm: arm.chain.tool_jacobians(np.zeros(6)), r"Expected Q of shape \(n, 6\), got \(6,\)"),
        (lambda arm: arm.chain.tool_jacobians(np.zeros((3, 5))), r"Expected Q of shape \(\.\.\., 6\) for 6 joints"),
    ],
    ids=[
        "short-q",
        "batch-to-fk",
        "vector-to-batch",
        "vector-to-tool-points",
        "vector-to-jacobians",
        "short-jacobians",
    ],
)
def test_fk_shape_errors(call, message):
    with pytest.raises(ValueError, match=message):
        call(load_arm("wx250s"))
