"""The speed-motivated pieces of the BVH core against their plain equivalents: ``cos_sin_degrees`` against
``np.cos``/``np.sin``, the block-wise FK against one block, and the number reader's dot pairing."""

from __future__ import annotations

import math

import numpy as np
import pytest

from retarget.bvh import fk as bvh_fk
from retarget.bvh import numbers as bvh_numbers
from retarget.bvh import parse_bvh
from retarget.bvh.rotations import cos_sin_degrees
from tests.helpers import POS_XYZ, J, bvh_text, random_frames, reference_fk


@pytest.mark.parametrize("seed", range(3))
def test_cos_sin_degrees_matches_numpy(seed):
    rng = np.random.default_rng(seed)
    angles = np.concatenate([rng.uniform(-720, 720, 20000), rng.normal(0, 1e-3, 1000), np.arange(-720, 720, 15.0)])
    cos, sin = cos_sin_degrees(angles.reshape(-1, 3))  # any shape
    assert cos.shape == sin.shape == (angles.size // 3, 3)
    # numpy's own error grows with the angle: radians(720) is only known to ~1e-15
    np.testing.assert_allclose(cos.ravel(), np.cos(np.radians(angles)), rtol=0, atol=2e-15)
    np.testing.assert_allclose(sin.ravel(), np.sin(np.radians(angles)), rtol=0, atol=2e-15)


@pytest.mark.parametrize(
    ("degrees", "cos", "sin"),
    [(0.0, 1.0, 0.0), (90.0, 0.0, 1.0), (180.0, -1.0, 0.0), (270.0, 0.0, -1.0), (-90.0, 0.0, -1.0), (-720.0, 1, 0)],
    ids=["0", "90", "180", "270", "-90", "-720"],
)
def test_cos_sin_degrees_is_exact_on_quarter_turns(degrees, cos, sin):
    c, s = cos_sin_degrees(np.array([degrees]))
    assert (c[0], s[0]) == (cos, sin)


@pytest.mark.parametrize("quarter_turns", [-3, -1, 0, 1, 2, 5], ids=lambda k: f"{90 * k:+d}deg")
def test_cos_sin_degrees_is_within_an_ulp_in_every_quadrant(quarter_turns):
    # on [-45, 45] radians() is exact to 2**-54, so libm gives the true values to ~1 ulp; other quadrants follow
    # from exact symmetries, which an exact reduction in degrees must reproduce
    r = np.arange(-45, 45.001, 1 / 64)
    true_cos = np.array([math.cos(math.radians(a)) for a in r])
    true_sin = np.array([math.sin(math.radians(a)) for a in r])
    k = quarter_turns % 4
    want_cos = (true_cos, -true_sin, -true_cos, true_sin)[k]
    want_sin = (true_sin, true_cos, -true_sin, -true_cos)[k]
    cos, sin = cos_sin_degrees(r + 90.0 * quarter_turns)
    np.testing.assert_allclose(cos, want_cos, rtol=0, atol=2.3e-16)
    np.testing.assert_allclose(sin, want_sin, rtol=0, atol=2.3e-16)


def test_cos_sin_degrees_non_finite_gives_nan_without_warnings():
    with np.errstate(all="raise"):
        cos, sin = cos_sin_degrees(np.array([np.nan, np.inf, -np.inf, 10.0]))
    assert np.isnan(cos[:3]).all() and np.isnan(sin[:3]).all()
    assert cos[3] == pytest.approx(math.cos(math.radians(10.0)))


def _branching_skeleton() -> J:
    """Levels mixing joints with and without children, End Sites, several children per joint, mixed rotation
    orders, a joint without rotation channels and a position channel below the root."""
    rng = np.random.default_rng(7)

    def joint(name: str, channels: tuple[str, ...], *children: J, end: bool = False) -> J:
        offset = tuple(rng.uniform(-10, 10, 3))
        return J(name, offset, channels, list(children), end=tuple(rng.uniform(-3, 3, 3)) if end else None)

    zxy, yxz, xzy = (
        ("Zrotation", "Xrotation", "Yrotation"),
        ("Yrotation", "Xrotation", "Zrotation"),
        ("Xrotation", "Zrotation", "Yrotation"),
    )
    arm = joint("arm", zxy, joint("fore", yxz, joint("hand", zxy, end=True)))
    spine = joint(
        "spine",
        xzy,
        arm,
        joint("neck", ("Zrotation", "Xrotation"), joint("head", zxy, end=True)),
        joint("shoulder", (), joint("other_arm", yxz)),
    )
    leg = joint("leg", ("Yposition", *yxz), joint("foot", zxy, end=True))
    return J("root", (1.0, 2.0, 3.0), (*POS_XYZ, *zxy), [spine, leg, joint("tail", xzy)])


@pytest.mark.parametrize("block", [16, 100, 1 << 20], ids=["tiny-blocks", "odd-blocks", "one-block"])
def test_fk_is_the_same_for_any_block_size(monkeypatch, block):
    root = _branching_skeleton()
    frames = random_frames(root, 157, seed=4)
    motion = parse_bvh(bvh_text(root, frames, fmt="{:.17g}"))
    want_rot, want_pos, want_sites = reference_fk(root, frames)
    monkeypatch.setattr(bvh_fk, "BLOCK_ELEMENTS", block)
    rot, pos = motion.global_transforms()
    np.testing.assert_allclose(pos, want_pos, rtol=0, atol=1e-9)
    np.testing.assert_allclose(rot, want_rot, rtol=0, atol=1e-12)
    np.testing.assert_allclose(motion.end_site_positions(), want_sites, rtol=0, atol=1e-9)


@pytest.mark.parametrize(
    "line",
    ["1 2.3.4", "1.2.3 4", "1.5 2 3.5.", ".1.2 3 4", "-1 -2.5.5"],
    ids=["dot-count-matches-but-shifted", "two-dots-first", "trailing-dot", "leading-dots", "signs"],
)
def test_number_reader_never_trusts_a_misplaced_dot(line):
    block = line.encode() + b"\n"
    padded = bvh_numbers.pad_block(block)
    starts, ends = bvh_numbers.token_bounds(padded[bvh_numbers.PAD : bvh_numbers.PAD + len(block)])
    values, slow = bvh_numbers.parse_tokens(padded, bvh_numbers.PAD, starts, ends)
    for token, value, is_slow in zip(line.split(), values, slow, strict=True):
        try:
            expected = float(token)
        except ValueError:
            assert is_slow, token
            continue
        assert is_slow or value == expected, token


def test_number_reader_writes_into_out_and_checks_its_shape():
    block = b"1.5 -2.25\n"
    padded = bvh_numbers.pad_block(block)
    starts, ends = bvh_numbers.token_bounds(padded[bvh_numbers.PAD : bvh_numbers.PAD + len(block)])
    out = np.zeros(2)
    values, slow = bvh_numbers.parse_tokens(padded, bvh_numbers.PAD, starts, ends, out=out)
    assert values is out and out.tolist() == [1.5, -2.25] and not slow.any()
    with pytest.raises(ValueError, match=r"Expected out of shape \(2,\), got \(3,\)"):
        bvh_numbers.parse_tokens(padded, bvh_numbers.PAD, starts, ends, out=np.zeros(3))
