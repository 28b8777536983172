"""Forward kinematics of Motion against an independent per-frame 4x4 reference."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from retarget.bvh import parse_bvh
from tests.helpers import POS_XYZ, J, bvh_text, joints_in_order, n_channels, random_frames, reference_fk

ORDERS = ["".join(p) for p in itertools.permutations("XYZ")]


def chain(orders: list[str], *, six_channel_at: int | None = None) -> J:
    """A root with 6 channels and a chain of joints with the given rotation orders."""
    rng = np.random.default_rng(len(orders))
    root = J("root", (1.0, 2.0, 3.0), ("Yposition", "Xposition", "Zposition", "Zrotation", "Xrotation", "Yrotation"))
    parent = root
    for k, order in enumerate(orders):
        channels = tuple(f"{a}rotation" for a in order)
        if k == six_channel_at:
            channels = ("Zposition", "Xposition", "Yposition") + channels
        joint = J(f"j{k}", tuple(rng.uniform(-10, 10, 3)), channels)
        parent.children.append(joint)
        parent = joint
    parent.end = (0.0, 5.0, 1.0)
    return root


@pytest.mark.parametrize("order", ORDERS, ids=ORDERS)
def test_fk_matches_reference_for_every_rotation_order(order):
    root = chain([order] * 4)
    for j in joints_in_order(root):
        if len(j.channels) == 6:
            j.channels = (*j.channels[:3], *(f"{a}rotation" for a in order))
    frames = random_frames(root, 12, seed=ORDERS.index(order))
    motion = parse_bvh(bvh_text(root, frames, fmt="{:.17g}"))
    rot_ref, pos_ref, end_ref = reference_fk(root, frames)
    rot, pos = motion.global_transforms()
    np.testing.assert_allclose(pos, pos_ref, rtol=0, atol=1e-9 * np.abs(pos_ref).max())
    np.testing.assert_allclose(rot, rot_ref, rtol=0, atol=1e-9)
    np.testing.assert_allclose(motion.end_site_positions(), end_ref, rtol=0, atol=1e-9 * np.abs(end_ref).max())


def test_fk_mixed_orders_and_six_channel_joint_below_the_root():
    root = chain(ORDERS + ["ZX", ""], six_channel_at=2)
    frames = random_frames(root, 20, seed=11)
    motion = parse_bvh(bvh_text(root, frames, fmt="{:.17g}"))
    assert motion.layout[3].position_axes == "ZXY"
    rot_ref, pos_ref, end_ref = reference_fk(root, frames)
    rot, pos = motion.global_transforms()
    np.testing.assert_allclose(pos, pos_ref, rtol=0, atol=1e-9 * np.abs(pos_ref).max())
    np.testing.assert_allclose(rot, rot_ref, rtol=0, atol=1e-9)
    np.testing.assert_allclose(motion.end_site_positions(), end_ref, rtol=0, atol=1e-9 * np.abs(end_ref).max())


def test_position_channels_replace_the_offset():
    root = J("root", (100.0, 200.0, 300.0), (*POS_XYZ, "Zrotation"))
    root.children.append(J("child", (0.0, 10.0, 0.0), ("Yposition", "Xrotation")))
    frames = np.array([[1.0, 2.0, 3.0, 0.0, 7.0, 0.0]])
    motion = parse_bvh(bvh_text(root, frames))
    pos = motion.positions()
    np.testing.assert_allclose(pos[0, 0], [1.0, 2.0, 3.0])  # not offset + channels
    np.testing.assert_allclose(pos[0, 1], [1.0, 2.0 + 7.0, 3.0])  # Y replaced, X and Z kept from the OFFSET (0)


def test_positions_only_then_full_transforms_agree():
    root = chain(["ZXY", "YXZ", "XZY"])
    frames = random_frames(root, 5, seed=2)
    a = parse_bvh(bvh_text(root, frames))
    b = parse_bvh(bvh_text(root, frames))
    pos_first = a.positions().copy()
    rot, pos = b.global_transforms()
    np.testing.assert_array_equal(pos_first, pos)
    assert a.positions() is a.positions()  # cached
    np.testing.assert_array_equal(a.global_transforms()[0], rot)


def test_results_are_read_only():
    motion = parse_bvh(bvh_text(chain(["ZXY"]), random_frames(chain(["ZXY"]), 3, seed=0)))
    for array in (motion.positions(), motion.global_transforms()[0], motion.channels, motion.parents, motion.offsets):
        with pytest.raises(ValueError, match="read-only"):
            array[...] = 0


def test_zero_frames_give_empty_arrays():
    root = chain(["ZXY", "XYZ"])
    motion = parse_bvh(bvh_text(root, np.zeros((0, n_channels(root)))))
    assert motion.n_frames == 0 and motion.duration == 0.0
    assert motion.positions().shape == (0, 3, 3)
    assert motion.global_transforms()[0].shape == (0, 3, 3, 3)
    assert motion.end_site_positions().shape == (0, 1, 3)


def test_scaled_scales_every_length_and_keeps_angles():
    root = chain(["ZXY", "YZX"], six_channel_at=1)
    frames = random_frames(root, 6, seed=5)
    motion = parse_bvh(bvh_text(root, frames))
    half = motion.scaled(0.5)
    np.testing.assert_allclose(half.positions(), motion.positions() * 0.5, atol=1e-12)
    np.testing.assert_allclose(half.end_site_positions(), motion.end_site_positions() * 0.5, atol=1e-12)
    np.testing.assert_allclose(half.global_transforms()[0], motion.global_transforms()[0], atol=1e-12)
    with pytest.raises(ValueError, match="Expected a positive finite scale factor, got -1.0"):
        motion.scaled(-1)


def test_info_properties():
    root = chain(["ZXY", "XYZ"])
    motion = parse_bvh(bvh_text(root, np.zeros((90, n_channels(root))), frame_time=1 / 120), path="a/clip.bvh")
    assert motion.n_frames == 90 and motion.n_joints == 3
    assert motion.fps == pytest.approx(120.0)
    assert motion.duration == pytest.approx(0.75)
    assert motion.rotation_orders == ("ZXY", "ZXY", "XYZ")
    assert motion.joint_index("j1") == 2
    assert motion.children(0) == [1]
    with pytest.raises(KeyError, match="Expected a joint name of this clip, got 'nope'"):
        motion.joint_index("nope")
    assert "clip.bvh" in repr(motion) and "90 frames" in repr(motion)
    np.testing.assert_allclose(motion.rest_positions()[0], [1.0, 2.0, 3.0])


@pytest.mark.parametrize("first", ["positions", "end_sites", "rotations"])
def test_any_order_of_requests_gives_the_reference(first):
    root = chain(["ZXY", "YXZ", "XZY"])
    root.children.append(J("leaf", (1.0, 2.0, 3.0), ("Xrotation", "Zrotation")))  # no children, no End Site
    root.children[0].children.append(J("twig", (0.0, 3.0, 0.0), ("Yrotation",), end=(0.0, 1.0, 0.0)))
    frames = random_frames(root, 7, seed=9)
    motion = parse_bvh(bvh_text(root, frames, fmt="{:.17g}"))
    rot_ref, pos_ref, end_ref = reference_fk(root, frames)
    calls = {
        "positions": motion.positions,
        "end_sites": motion.end_site_positions,
        "rotations": lambda: motion.global_transforms()[0],
    }
    got = {name: calls[name]() for name in [first, *[n for n in calls if n != first]]}
    tol = 1e-9 * np.abs(pos_ref).max()
    np.testing.assert_allclose(got["positions"], pos_ref, rtol=0, atol=tol)
    np.testing.assert_allclose(got["end_sites"], end_ref, rtol=0, atol=tol)
    np.testing.assert_allclose(got["rotations"], rot_ref, rtol=0, atol=1e-9)
    assert motion.positions() is got["positions"]  # arrays handed out stay the cached ones
