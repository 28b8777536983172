"""Rig files: the bundled rigs, placements in the world, port overrides and every error path."""

from __future__ import annotations

import math
import textwrap

import numpy as np
import pytest

from retarget.arm.config import resolve_arm
from retarget.errors import ConfigError
from retarget.mapping.config import Side
from retarget.rig import Placement, list_rigs, load_rig

GOOD = """
[rig]
name = "bench"

[[arms]]
name = "a"
arm = "wx250s"
xyz = [0.1, 0.3, 0.02]
rpy = [0.0, 0.0, 90.0]
side = "left"

[[arms]]
name = "b"
arm = "koch"
xyz = [0.1, -0.3, 0.0]
port = "/dev/ttyUSB1"
side = "right"
"""


def write(tmp_path, text, name="rig.toml"):
    path = tmp_path / name
    path.write_text(textwrap.dedent(text))
    return path


def test_the_bundled_rigs_load_and_are_listed():
    assert {"aloha", "wx250s-pair"} <= set(list_rigs())
    aloha = load_rig("aloha")
    assert [a.arm.name for a in aloha.arms] == ["vx300s", "vx300s"]
    assert [a.side for a in aloha.arms] == [Side.LEFT, Side.RIGHT]
    left, right = (np.array(a.placement.xyz) for a in aloha.arms)
    assert 0.6 <= np.linalg.norm(left - right) <= 0.8  # the ALOHA spacing
    assert all(a.placement.rpy == (0.0, 0.0, 0.0) for a in aloha.arms)  # both facing forward


def test_a_rig_file_reads_every_field(tmp_path):
    rig = load_rig(write(tmp_path, GOOD))
    assert rig.name == "bench" and rig.names == ("a", "b") and rig.path == tmp_path / "rig.toml"
    a, b = rig.arms
    assert a.arm.name == "wx250s" and b.arm.name == "koch"
    assert a.placement.xyz == (0.1, 0.3, 0.02) and a.placement.rpy == pytest.approx((0.0, 0.0, math.pi / 2))
    assert (a.port, b.port) == ("sim://wx250s", "/dev/ttyUSB1")  # sim://<arm> unless given
    assert (a.side, b.side) == (Side.LEFT, Side.RIGHT)


def test_the_name_defaults_to_the_file_stem_and_arm_paths_are_relative_to_the_rig(tmp_path):
    (tmp_path / "arms").mkdir()
    (tmp_path / "arms" / "mine.toml").write_text(resolve_arm("omx").read_text())
    text = GOOD.replace('[rig]\nname = "bench"\n', "").replace('arm = "koch"', 'arm = "arms/mine.toml"')
    rig = load_rig(write(tmp_path, text, "desk.toml"))
    assert rig.name == "desk" and rig["b"].arm.name == "omx"


@pytest.mark.parametrize(
    ("q_seed", "rpy_deg"), [(0, (0, 0, 0)), (1, (0, 0, 90)), (2, (10, -20, 135))], ids=["identity", "yaw", "tilted"]
)
def test_world_points_go_through_the_placement_and_back(q_seed, rpy_deg):
    """A seeded round trip: base -> world -> base is the identity, and the world tool point is the rotated,
    shifted base tool point (written here with an explicit rotation, not the module's)."""
    rng = np.random.default_rng(q_seed)
    xyz = tuple(rng.uniform(-0.5, 0.5, 3))
    place = Placement(xyz, tuple(math.radians(v) for v in rpy_deg))
    points = rng.uniform(-1, 1, (50, 3))
    np.testing.assert_allclose(place.to_base(place.to_world(points)), points, atol=1e-12)
    r, p, y = (math.radians(v) for v in rpy_deg)
    Rx = np.array([[1, 0, 0], [0, math.cos(r), -math.sin(r)], [0, math.sin(r), math.cos(r)]])
    Ry = np.array([[math.cos(p), 0, math.sin(p)], [0, 1, 0], [-math.sin(p), 0, math.cos(p)]])
    Rz = np.array([[math.cos(y), -math.sin(y), 0], [math.sin(y), math.cos(y), 0], [0, 0, 1]])
    np.testing.assert_allclose(place.to_world(points), points @ (Rz @ Ry @ Rx).T + xyz, atol=1e-12)


def test_an_arms_tool_point_is_in_the_world():
    rig = load_rig("wx250s-pair")
    left = rig["left"]
    base_tool = left.arm.fk(left.arm.home)[0][:3, 3]
    np.testing.assert_allclose(left.tool_point(left.arm.home), base_tool + [0.0, 0.3, 0.0], atol=1e-12)


def test_ports_are_overridden_by_arm_name():
    rig = load_rig("aloha").with_ports({"left": "/dev/ttyUSB0", "right": "tcp://127.0.0.1:4000"})
    assert [a.port for a in rig.arms] == ["/dev/ttyUSB0", "tcp://127.0.0.1:4000"]
    with pytest.raises(ConfigError, match=r"^rig\.arm: Expected one of the rig's arms left, right \(got 'middle'\)$"):
        load_rig("aloha").with_ports({"middle": "/dev/ttyUSB0"})


ONE_ARM = '[[arms]]\nname = "a"\narm = "wx250s"\nxyz = [0, 0, 0]\nside = "left"\n'
#: (id, text replaced in GOOD, its replacement, the error's pattern)
BAD = [
    (
        "unknown-table",
        "[rig]",
        "[extra]\n[rig]",
        r"rig\.toml: extra: Expected only the tables \[rig\] and",
    ),
    ("one-arm", GOOD, ONE_ARM, r"rig\.toml: arms: Expected two or more \[\[arms\]\] tables$"),
    ("unknown-key", 'side = "left"', 'side = "left"\ncolour = 1', r"arms\[0\]\.colour: Expected one of arm, name"),
    ("missing-xyz", "xyz = [0.1, 0.3, 0.02]\n", "", r"arms\[0\]\.xyz: Expected this key$"),
    ("bad-side", 'side = "left"', 'side = "middle"', r"arms\[0\]\.side: Expected 'left' or 'right' \(got 'middle'\)"),
    ("same-side", 'side = "right"', 'side = "left"', r"arms\[1\]\.side: Expected a different side .* \(got 'left'\)"),
    ("same-name", 'name = "b"', 'name = "a"', r"arms\[1\]\.name: Expected a different name .* \(got 'a'\)"),
    ("bad-name", 'name = "b"', 'name = "b c"', r"arms\[1\]\.name: Expected a name of letters"),
    (
        "far-xyz",
        "[0.1, 0.3, 0.02]",
        "[0.1, 30.0, 0.02]",
        r"arms\[0\]\.xyz: Expected 3 numbers within \+-10 \(got",
    ),
    ("short-rpy", "[0.0, 0.0, 90.0]", "[0.0, 90.0]", r"arms\[0\]\.rpy: Expected 3 numbers within \+-360"),
    ("text-xyz", "[0.1, 0.3, 0.02]", '"0.1 0.3 0"', r"arms\[0\]\.xyz: Expected 3 numbers"),
    ("unknown-arm", 'arm = "koch"', 'arm = "koch9"', r"rig\.toml: arms\[1\]\.arm: unknown arm 'koch9'"),
    ("empty-port", '"/dev/ttyUSB1"', '""', r"arms\[1\]\.port: Expected a non-empty string"),
    ("bad-toml", "[rig]", "[rig", r"rig\.toml: line \d+: invalid TOML"),
]


@pytest.mark.parametrize(("old", "new", "message"), [b[1:] for b in BAD], ids=[b[0] for b in BAD])
def test_a_bad_rig_file_names_the_file_the_key_and_the_value(tmp_path, old, new, message):
    assert old in GOOD
    with pytest.raises(ConfigError, match=message):
        load_rig(write(tmp_path, GOOD.replace(old, new)))


def test_a_missing_rig_is_named():
    with pytest.raises(ConfigError, match=r"^rig: unknown rig 'nope'; known rigs: aloha, wx250s-pair"):
        load_rig("nope")
    with pytest.raises(ConfigError, match=r"nowhere\.toml: rig file not found$"):
        load_rig("nowhere.toml")
