"""Euler channels -> rotation matrices, checked against Rodrigues products computed independently."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from retarget.bvh.rotations import axis_rotation, compose_cos_sin, euler_to_matrix, matrix_to_rotvec

ORDERS = ["".join(p) for p in itertools.permutations("XYZ")]
UNIT = {"X": np.array([1.0, 0, 0]), "Y": np.array([0, 1.0, 0]), "Z": np.array([0, 0, 1.0])}


def rodrigues(axis: np.ndarray, angle: float) -> np.ndarray:
    """R = I + sin(a) K + (1 - cos(a)) K^2 for a unit axis: no Euler code involved."""
    k = axis / np.linalg.norm(axis)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


@pytest.mark.parametrize("order", ORDERS, ids=ORDERS)
def test_euler_matches_rodrigues_product_in_listed_order(order):
    rng = np.random.default_rng(sum(map(ord, order)))
    angles = rng.uniform(-np.pi, np.pi, size=(50, 3))
    got = euler_to_matrix(angles, order)
    assert got.shape == (50, 3, 3)
    for a, R in zip(angles, got, strict=True):
        want = rodrigues(UNIT[order[0]], a[0]) @ rodrigues(UNIT[order[1]], a[1]) @ rodrigues(UNIT[order[2]], a[2])
        np.testing.assert_allclose(R, want, atol=1e-12)


def test_zxy_is_rz_rx_ry_intrinsic():
    # a 90 deg Z then 90 deg X (intrinsic): x -> y; the local z axis ends up along world x
    R = euler_to_matrix(np.radians([90.0, 90.0, 0.0]), "ZXY")
    np.testing.assert_allclose(R @ [1.0, 0, 0], [0, 1.0, 0], atol=1e-12)
    np.testing.assert_allclose(R @ [0, 0, 1.0], [1.0, 0, 0], atol=1e-12)


@pytest.mark.parametrize("order", ["", "Z", "XY", "ZXZ", "XYZX"], ids=["none", "one", "two", "repeat", "four"])
def test_any_number_of_axes(order):
    rng = np.random.default_rng(len(order))
    angles = rng.uniform(-3, 3, size=(4, 2, len(order)))
    got = euler_to_matrix(angles, order)
    assert got.shape == (4, 2, 3, 3)
    for idx in np.ndindex(4, 2):
        want = np.eye(3)
        for axis, a in zip(order, angles[idx], strict=True):
            want = want @ rodrigues(UNIT[axis], a)
        np.testing.assert_allclose(got[idx], want, atol=1e-12)


def test_results_are_rotations():
    rng = np.random.default_rng(7)
    R = euler_to_matrix(rng.uniform(-10, 10, size=(200, 3)), "YXZ")
    np.testing.assert_allclose(R @ np.swapaxes(R, -1, -2), np.broadcast_to(np.eye(3), R.shape), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-12)


@pytest.mark.parametrize("axis", ["X", "Y", "Z", 0, 1, 2, "z"], ids=str)
def test_axis_rotation_matches_rodrigues(axis):
    letter = "XYZ"[axis] if isinstance(axis, int) else axis.upper()
    np.testing.assert_allclose(axis_rotation(axis, 0.7), rodrigues(UNIT[letter], 0.7), atol=1e-14)


@pytest.mark.parametrize("axis", ["W", 3, -1, True, None], ids=str)
def test_bad_axis(axis):
    with pytest.raises(ValueError, match="Expected an axis 'X', 'Y', 'Z' or 0, 1, 2, got"):
        axis_rotation(axis, 0.0)


def test_bad_angle_shape():
    with pytest.raises(ValueError, match=r"Expected angles of shape \(\.\.\., 3\) for order 'ZXY', got \(5, 2\)"):
        euler_to_matrix(np.zeros((5, 2)), "ZXY")


def test_compose_cos_sin_without_axes_is_identity():
    out = compose_cos_sin([], [np.zeros(4)], [np.zeros(4)])
    np.testing.assert_array_equal(out, np.broadcast_to(np.eye(3), (4, 3, 3)))


def test_rotvec_round_trip():
    rng = np.random.default_rng(3)
    axes = rng.normal(size=(100, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    angles = rng.uniform(0.01, 3.0, size=100)
    R = np.array([rodrigues(a, t) for a, t in zip(axes, angles, strict=True)])
    np.testing.assert_allclose(matrix_to_rotvec(R), axes * angles[:, None], atol=1e-9)
    with pytest.raises(ValueError, match=r"Expected matrices of shape \(\.\.\., 3, 3\), got \(2, 3\)"):
        matrix_to_rotvec(np.zeros((2, 3)))
