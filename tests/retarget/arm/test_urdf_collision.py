"""URDF import of <collision> geometry: primitives, meshes and bare links, rotated origins, error paths."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from retarget import ConfigError, load_arm
from retarget.arm.urdf_collision import DEFAULT_RADIUS
from retarget.collision import Box, Capsule, CollisionModel

SERVOS = """\
[joints.j1]
servos = [{ id = 1, model = "XM430-W350" }]
[joints.j2]
servos = [{ id = 2, model = "XM430-W350" }]
[joints.j3]
servos = [{ id = 3, model = "XM430-W350" }]
"""


def urdf(base="", l1="", l2="", l2b="", l3="") -> str:
    """base -j1(z)-> l1 -j2(y)-> l2 -fixed-> l2b -j3(y)-> l3 -fixed-> tip; each link's inner XML given."""
    joint = '<joint name="{}" type="{}"><parent link="{}"/><child link="{}"/><origin xyz="{}"/>{}</joint>'
    lim = '<axis xyz="{}"/><limit lower="-2" upper="2" velocity="3"/>'
    return "\n".join([
        '<robot name="t">',
        *(f'<link name="{n}">{body}</link>' for n, body in
          [("base", base), ("l1", l1), ("l2", l2), ("l2b", l2b), ("l3", l3), ("tip", "")]),
        joint.format("j1", "revolute", "base", "l1", "0 0 0.04", lim.format("0 0 1")),
        joint.format("j2", "revolute", "l1", "l2", "0 0 0.1", lim.format("0 1 0")),
        joint.format("f2", "fixed", "l2", "l2b", "0.1 0 0", ""),
        joint.format("j3", "revolute", "l2b", "l3", "0.05 0 0", lim.format("0 1 0")),
        joint.format("ft", "fixed", "l3", "tip", "0.05 0 0", ""),
        "</robot>",
    ])  # fmt: skip


def col(geometry: str, xyz: str = "0 0 0", rpy: str = "0 0 0") -> str:
    return f'<collision><origin xyz="{xyz}" rpy="{rpy}"/><geometry>{geometry}</geometry></collision>'


def load(tmp_path: Path, text: str, servos: str = SERVOS):
    (tmp_path / "t.urdf").write_text(text)
    (tmp_path / "t.servos.toml").write_text(servos)
    return load_arm(tmp_path / "t.urdf")


def shapes(arm) -> dict[str, tuple[int, Capsule | Box]]:
    return {link.name: (link.frame, link.shape) for link in arm.geometry.links}


def same(got: tuple[int, Capsule | Box], frame: int, shape: Capsule | Box) -> bool:
    """Same frame, same kind of shape, numbers equal to 1e-12."""
    numbers = lambda s: np.hstack([np.ravel(v) for v in vars(s).values()])  # noqa: E731
    return got[0] == frame and type(got[1]) is type(shape) and np.allclose(numbers(got[1]), numbers(shape), atol=1e-12)


def test_primitives_meshes_and_bare_links(tmp_path):
    arm = load(tmp_path, urdf(
        base=col('<box size="0.1 0.1 0.04"/>', "0 0 0.02"),
        l1=col('<cylinder radius="0.02" length="0.1"/>', "0 0 0.05"),
        l2b=col('<sphere radius="0.03"/>'),
        l3=col('<mesh filename="package://t/l3.stl"/>'),
    ))  # fmt: skip
    got = shapes(arm)
    assert same(got["base"], 0, Box((0, 0, 0.02), (0.05, 0.05, 0.02)))
    assert same(got["l1"], 1, Capsule((0, 0, 0), (0, 0, 0.1), 0.02))  # the cylinder's axis segment, its radius
    assert same(got["l2b"], 2, Capsule((0.1, 0, 0), (0.1, 0, 0), 0.03))  # through the fixed joint f2
    # l2 has no <collision>: joint origin to the next movable joint's (f2 folded in); l3 a mesh: to the tool point
    assert same(got["l2"], 2, Capsule((0, 0, 0), (0.15, 0, 0), DEFAULT_RADIUS))
    assert same(got["l3"], 3, Capsule((0, 0, 0), (0.05, 0, 0), DEFAULT_RADIUS))
    model = CollisionModel.for_arm(arm)
    assert "l3/l1" in model.pair_names and "l3/table" in model.pair_names


def test_the_servo_file_sets_the_radius_allowed_pairs_and_more_links(tmp_path):
    servos = (
        SERVOS
        + """
[collision]
radius = 0.035
allowed = [["l3", "base"]]
[[collision.links]]
name = "camera"
frame = "j3"
sphere = { center = [0.02, 0, 0.03], radius = 0.01 }
"""
    )
    arm = load(tmp_path, urdf(), servos)
    got = shapes(arm)
    assert same(got["l3"], 3, Capsule((0, 0, 0), (0.05, 0, 0), 0.035))
    assert same(got["base"], 0, Capsule((0, 0, 0), (0, 0, 0.04), 0.035))  # bare base: to the first joint
    assert same(got["camera"], 3, Capsule((0.02, 0, 0.03), (0.02, 0, 0.03), 0.01))
    assert arm.geometry.allowed == (("base", "l3"),)


def test_rotated_origins(tmp_path):
    arm = load(tmp_path, urdf(
        base=col('<box size="0.1 0.2 0.04"/>', rpy=f"0 0 {math.pi / 2}"),  # axis-aligned: sizes swap
        l1=col('<box size="0.02 0.04 0.2"/>', "0 0 0.05", f"{math.pi / 2} 0 0"),  # moving box: enclosing capsule
        l2=col('<cylinder radius="0.01" length="0.2"/>', rpy=f"0 {math.pi / 2} 0"),  # axis along x
        l3=col('<box size="0.1 0.1 0.1"/>') + col('<box size="0.02 0.02 0.02"/>', rpy="0 0 0.5"),
    ))  # fmt: skip
    got = shapes(arm)
    frame, box = got["base"]
    np.testing.assert_allclose(box.half_size, (0.1, 0.05, 0.02), atol=1e-12)
    frame, cap = got["l1"]  # longest side (z, 0.2) turned onto -y by roll pi/2
    np.testing.assert_allclose(np.abs(np.subtract(cap.b, cap.a)), (0, 0.2, 0), atol=1e-12)
    assert cap.radius == pytest.approx(math.hypot(0.01, 0.02))
    _, cyl = got["l2"]
    np.testing.assert_allclose(sorted([cyl.a[0], cyl.b[0]]), (-0.1, 0.1), atol=1e-12)
    assert {"l3", "l3_2"} <= set(got)  # two elements on one link


def test_a_rotated_box_on_the_base_is_enclosed(tmp_path):
    arm = load(tmp_path, urdf(base=col('<box size="0.1 0.1 0.04"/>', rpy=f"0 0 {math.pi / 4}")))
    _, box = shapes(arm)["base"]
    np.testing.assert_allclose(box.half_size, (0.05 * math.sqrt(2), 0.05 * math.sqrt(2), 0.02), atol=1e-12)


@pytest.mark.parametrize(
    ("link", "body", "match"),
    [
        ("base", col('<box size="0.1 -0.1 0.1"/>'), r"link\[base\]\.collision\[0\]\.box\.size: expected 3 finite"),
        ("l1", col('<box size="0.1 0.1"/>'), r"link\[l1\]\.collision\[0\]\.box\.size"),
        ("l1", col('<cylinder radius="0.02"/>'), r"link\[l1\]\.collision\[0\]\.cylinder\.length: expected 1"),
        ("l2", col('<sphere radius="abc"/>'), r"link\[l2\]\.collision\[0\]\.sphere\.radius"),
        ("l2", col('<sphere radius="nan"/>'), r"link\[l2\]\.collision\[0\]\.sphere\.radius"),
        ("l3", "<collision><geometry/></collision>", r"link\[l3\]\.collision\[0\]: expected <geometry> with a box"),
        ("l3", col('<capsule radius="1" length="1"/>'), r"link\[l3\]\.collision\[0\]: .*got 'capsule'"),
        ("l1", col('<sphere radius="0.1"/>', xyz="0 0"), r"link\[l1\]\.collision\[0\]\.origin\.xyz: expected 3"),
    ],
    ids=["negative-size", "two-sizes", "no-length", "text-radius", "nan-radius", "no-shape", "unknown-shape",
         "bad-origin"],
)  # fmt: skip
def test_bad_collision_elements(tmp_path, link, body, match):
    with pytest.raises(ConfigError, match=match) as info:
        load(tmp_path, urdf(**{link: body}))
    assert "\n" not in str(info.value) and "t.urdf" in str(info.value)


@pytest.mark.parametrize(
    ("table", "match"),
    [
        ("radius = -0.01", r"t\.servos\.toml: collision\.radius: expected a radius from 0 to 1 m"),
        ("radius = 'big'", r"collision\.radius"),
        ("allowed = [['l3', 'nope']]", r"collision\.allowed\[0\]: unknown link"),
        ("shape = 1", r"collision\.shape: unknown key 'shape'"),
    ],
    ids=["negative-radius", "text-radius", "unknown-allowed", "unknown-key"],
)
def test_bad_servo_file_collision_tables(tmp_path, table, match):
    with pytest.raises(ConfigError, match=match):
        load(tmp_path, urdf(), SERVOS + "[collision]\n" + table + "\n")


def test_a_link_named_table_is_refused(tmp_path):
    text = urdf(l3=col('<sphere radius="0.01"/>')).replace('"l3"', '"table"')
    with pytest.raises(ConfigError, match=r"t\.urdf: link\[table\]: .*not 'table'"):
        load(tmp_path, text)


@pytest.mark.parametrize(("radius", "allowed"), [(0.02, ()), (0.05, (("base", "l2"),))], ids=["thin", "thick"])
def test_bare_capsules_round_a_short_link_are_allowed(tmp_path, radius, allowed):
    arm = load(tmp_path, urdf(), SERVOS + f"[collision]\nradius = {radius}\n")  # l1 is 0.1 m long
    assert arm.geometry.allowed == allowed
    model = CollisionModel.for_arm(arm)
    assert ("l2/base" in model.pair_names) is not bool(allowed)
