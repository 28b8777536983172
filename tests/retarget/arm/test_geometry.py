"""The arm file's [collision] and [world] tables: what they load to, and every error path."""

# ruff: noqa: E501  (the table of error cases reads best one case per line)

from __future__ import annotations

from pathlib import Path

import pytest

from retarget import ConfigError, load_arm
from retarget.collision import BASE_FRAME, Box, Capsule, CollisionModel, Sphere

TOY = """\
name = "toy"
[tool]
xyz = [0.1, 0.0, 0.0]
[poses]
home = [0, 0]
[[joints]]
name = "a"
xyz = [0, 0, 0.05]
axis = [0, 0, 1]
limits = [-90, 90]
max_velocity = 180
servos = [{ id = 1, model = "XM430-W350" }]
[[joints]]
name = "b"
xyz = [0, 0, 0.05]
axis = [0, 1, 0]
limits = [-120, 120]
max_velocity = 180
servos = [{ id = 2, model = "XM430-W350" }]
"""

COLLISION = """
[collision]
source = "made up"
allowed = [["tip", "base"]]
nest = [["arm", "base", 0.01]]
[[collision.links]]
name = "base"
frame = "base"
box = { center = [0, 0, 0.02], half_size = [0.03, 0.03, 0.02] }
[[collision.links]]
name = "turret"
frame = "a"
capsule = { a = [0, 0, 0], b = [0, 0, 0.04], radius = 0.02 }
[[collision.links]]
name = "arm"
frame = "b"
capsule = { a = [0, 0, 0], b = [0.1, 0, 0], radius = 0.015 }
[[collision.links]]
name = "tip"
frame = "b"
sphere = { center = [0.1, 0, 0], radius = 0.02 }
"""

WORLD = """
[world]
table = false
keep_out = [
    { box = { center = [0.3, 0.2, 0.1], half_size = [0.05, 0.05, 0.1] } },
    { sphere = { center = [0.3, -0.2, 0.1], radius = 0.05 } },
]
"""


def load(tmp_path: Path, text: str):
    path = tmp_path / "toy.toml"
    path.write_text(text)
    return load_arm(path)


def test_collision_and_world_tables_load(tmp_path):
    arm = load(tmp_path, TOY + COLLISION + WORLD)
    g = arm.geometry
    assert g.names() == ("base", "turret", "arm", "tip") and g.source == "made up"
    assert [link.frame for link in g.links] == [BASE_FRAME, 1, 2, 2]
    assert g.links[0].shape == Box((0, 0, 0.02), (0.03, 0.03, 0.02))
    assert g.links[3].shape == Capsule((0.1, 0, 0), (0.1, 0, 0), 0.02)  # a sphere is a capsule of zero length
    assert g.allowed == (("base", "tip"),) and g.nest == (("arm", "base", 0.01),)
    assert arm.world.table is False
    assert arm.world.keep_out == (Box((0.3, 0.2, 0.1), (0.05, 0.05, 0.1)), Sphere((0.3, -0.2, 0.1), 0.05))
    names = CollisionModel.for_arm(arm).pair_names
    assert "arm/base" in names and "tip/base" not in names and "arm/keep_out[1]" in names


def test_without_the_tables(tmp_path):
    arm = load(tmp_path, TOY)
    assert arm.geometry is None and arm.world.table is True and arm.world.keep_out == ()


def replaced(old: str, new: str) -> str:
    text = TOY + COLLISION + WORLD
    assert old in text, old
    return text.replace(old, new, 1)


@pytest.mark.parametrize(
    ("old", "new", "match"),
    [
        ('source = "made up"', "colour = 1", r"collision\.colour: unknown key"),
        ('frame = "base"\nbox', 'frame = "base"\nmass = 1\nbox', r"collision\.links\[0\]\.mass: unknown key"),
        ("table = false", "table = false\nfloor = 1", r"world\.floor: unknown key"),
        ("box = { center = [0, 0, 0.02], half_size = [0.03, 0.03, 0.02] }", "", r"collision\.links\[0\]: expected exactly one of capsule, box, sphere"),
        ("box = { center", "sphere = { center = [0, 0, 0], radius = 1 }\nbox = { center", r"collision\.links\[0\]: expected exactly one of .*got \['box', 'sphere'\]"),
        ("radius = 0.015", "radius = -0.015", r"collision\.links\[2\]\.capsule\.radius: expected a radius from 0 to 10 m"),
        ("radius = 0.015", "radius = 11", r"collision\.links\[2\]\.capsule\.radius: expected a radius from 0 to 10 m"),
        ("radius = 0.02 }\n[[collision.links]]\nname = \"arm\"", "radius = 'x' }\n[[collision.links]]\nname = \"arm\"", r"collision\.links\[1\]\.capsule\.radius"),
        ("b = [0.1, 0, 0], radius", "b = [0.1, 0], radius", r"collision\.links\[2\]\.capsule\.b"),
        ("half_size = [0.03, 0.03, 0.02]", "half_size = [0.03, -0.03, 0.02]", r"collision\.links\[0\]\.box\.half_size: expected half sizes >= 0"),
        ('capsule = { a = [0, 0, 0], b = [0, 0, 0.04], radius = 0.02 }', 'capsule = { a = [0, 0, 0], b = [0, 0, 0.04] }', r"collision\.links\[1\]\.capsule\.radius: missing required key"),
        ('name = "turret"\nframe = "a"', 'name = "turret"\nframe = "elbow"', r"collision\.links\[1\]\.frame: expected 'base' or a joint name: a, b"),
        ('name = "tip"', 'name = "arm"', r"collision\.links: Expected unique link names"),
        ('name = "tip"', 'name = "table"', r"collision\.links\[3\]\.name: .*not 'table'"),
        ('allowed = [["tip", "base"]]', 'allowed = [["tip", "nope"]]', r"collision\.allowed\[0\]: unknown link; links: base, turret, arm, tip \(got 'nope'\)"),
        ('allowed = [["tip", "base"]]', 'allowed = [["tip", "tip"]]', r"collision\.allowed\[0\]: Expected two different links"),
        ('allowed = [["tip", "base"]]', 'allowed = [["tip"]]', r"collision\.allowed\[0\]: expected a pair of link names"),
        ('allowed = [["tip", "base"]]', 'allowed = "tip"', r"collision\.allowed: expected a list of \[link, link\] pairs"),
        ('nest = [["arm", "base", 0.01]]', 'nest = [["arm", "nope", 0.01]]', r"collision\.nest\[0\]: unknown link"),
        ('nest = [["arm", "base", 0.01]]', 'nest = [["arm", "base", 0.5]]', r"collision\.nest\[0\]: expected a depth from 0 to 0\.2 m"),
        ('nest = [["arm", "base", 0.01]]', 'nest = [["arm", "base"]]', r"collision\.nest\[0\]: expected \[link, link, depth in metres\]"),
        ("table = false", "table = 1", r"world\.table: expected true or false"),
        ("{ box = { center = [0.3, 0.2, 0.1], half_size = [0.05, 0.05, 0.1] } },", "{ capsule = { a = [0, 0, 0], b = [0, 0, 1], radius = 1 } },", r"world\.keep_out\[0\]\.capsule: unknown key"),
        ("{ box = { center = [0.3, 0.2, 0.1], half_size = [0.05, 0.05, 0.1] } },", "{},", r"world\.keep_out\[0\]: expected exactly one of box, sphere"),
        ("radius = 0.05 }", "radius = -1 }", r"world\.keep_out\[1\]\.sphere\.radius: expected a radius from 0 to 10 m"),
        ("half_size = [0.05, 0.05, 0.1]", "half_size = [0.05, 0.05]", r"world\.keep_out\[0\]\.box\.half_size"),
    ],
    ids=["collision-unknown-key", "link-unknown-key", "world-unknown-key", "no-shape", "two-shapes",
         "negative-radius", "huge-radius", "text-radius", "short-end", "negative-half-size", "no-radius",
         "unknown-frame", "duplicate-name", "name-table", "allowed-unknown-link", "allowed-same-link",
         "allowed-not-a-pair", "allowed-not-a-list", "nest-unknown-link", "nest-too-deep", "nest-no-depth",
         "table-not-bool", "keep-out-capsule", "keep-out-empty", "keep-out-negative-radius",
         "keep-out-short-half-size"],
)  # fmt: skip
def test_collision_and_world_errors(tmp_path, old, new, match):
    with pytest.raises(ConfigError, match=match) as info:
        load(tmp_path, replaced(old, new))
    assert "toy.toml" in str(info.value) and "\n" not in str(info.value)


def test_links_must_be_a_non_empty_list(tmp_path):
    with pytest.raises(ConfigError, match=r"collision\.links: expected a non-empty list of link tables"):
        load(tmp_path, TOY + "[collision]\nlinks = []\n")
    with pytest.raises(ConfigError, match=r"collision\.links: missing required key"):
        load(tmp_path, TOY + '[collision]\nsource = "x"\n')


def test_keep_out_must_be_a_list(tmp_path):
    with pytest.raises(ConfigError, match=r"world\.keep_out: expected a list of zone tables \(got 3\)"):
        load(tmp_path, TOY + "[world]\nkeep_out = 3\n")
