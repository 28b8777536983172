"""The ``[collision]`` and ``[world]`` tables of an arm file (and of a URDF's servo file).

Lengths in metres, in the frame named by ``frame``: ``"base"`` (the base frame, which never moves) or a joint's
name (the child frame of that joint, which turns with it: the URDF frame of the joint's child link)::

    [collision]
    source = "Interbotix wx250s meshes, measured"   # optional, documentary
    allowed = [["gripper", "upper_arm"]]            # optional: pairs never checked (neighbours on the
                                                    # chain never are)
    nest = [["lower_forearm", "upper_arm", 0.02]]   # optional: pairs whose capsules may overlap by this
                                                    # depth (m), e.g. where they nest in the sleep pose
    [[collision.links]]
    name = "base"                                   # unique; pairs are named "upper_arm/base", "gripper/table"
    frame = "base"
    box = { center = [0, 0, 0.036], half_size = [0.07, 0.07, 0.036] }   # axis-aligned in its frame

    [[collision.links]]
    name = "upper_arm"
    frame = "shoulder"
    capsule = { a = [0, 0, 0.04], b = [0.05, 0, 0.25], radius = 0.03 }  # segment a-b and radius
    # sphere = { center = [...], radius = ... }      # a ball (a capsule of zero length)

    [world]                                         # optional
    table = true                                    # the table plane z = 0 of the base frame (default on)
    keep_out = [                                    # optional zones, base frame
        { box = { center = [0.3, 0.2, 0.1], half_size = [0.05, 0.05, 0.1] } },
        { sphere = { center = [0.3, -0.2, 0.1], radius = 0.05 } },
    ]

Every problem is a :class:`~retarget.errors.ConfigError` naming the file and the key path.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from typing import TYPE_CHECKING, Any, Protocol

from retarget.collision.shapes import BASE_FRAME, Box, Capsule, Geometry, KeepOut, LinkShape, Sphere, World
from retarget.errors import ConfigError

if TYPE_CHECKING:
    from retarget.arm.model import Joint

__all__ = ["COLLISION_KEYS", "read_collision", "read_shape", "read_world"]


class ArmFileReader(Protocol):
    """The validating readers of :class:`retarget.arm.config.ArmFileReader` used here."""

    def error(self, message: str, key: str, value: object = ...) -> ConfigError: ...
    def table(
        self, value: object, key: str, allowed: Iterable[str], required: Iterable[str] = ()
    ) -> Mapping[str, Any]: ...
    def number(self, value: object, key: str, *, positive: bool = False) -> float: ...
    def xyz(self, value: object, key: str) -> tuple[float, float, float]: ...
    def string(self, value: object, key: str) -> str: ...


#: the keys of an arm file's ``[collision]`` table (a URDF's servo file adds ``radius``)
COLLISION_KEYS = frozenset({"source", "allowed", "nest", "links"})
_LINK_KEYS = {"name", "frame", "capsule", "box", "sphere"}
_SHAPES = ("capsule", "box", "sphere")
_WORLD_KEYS = {"table", "keep_out"}


def _radius(reader: ArmFileReader, value: object, key: str) -> float:
    r = reader.number(value, key)
    if r < 0 or r > 10.0:
        raise reader.error("expected a radius from 0 to 10 m", key, value)
    return r


def _half(reader: ArmFileReader, value: object, key: str) -> tuple[float, float, float]:
    x, y, z = reader.xyz(value, key)
    if min(x, y, z) < 0:
        raise reader.error("expected half sizes >= 0", key, value)
    return (x, y, z)


def read_shape(
    reader: ArmFileReader, table: Mapping[str, Any], key: str, kinds: Sequence[str] = _SHAPES
) -> Capsule | Box | Sphere:
    """The one shape of ``table`` (a link or a keep-out zone): one of ``kinds`` (capsule, box, sphere)."""
    given = [k for k in kinds if k in table]
    if len(given) != 1:
        raise reader.error(f"expected exactly one of {', '.join(kinds)}", key, sorted(given) or None)
    kind = given[0]
    sub = f"{key}.{kind}"
    if kind == "capsule":
        t = reader.table(table[kind], sub, ("a", "b", "radius"), ("a", "b", "radius"))
        return Capsule(reader.xyz(t["a"], f"{sub}.a"), reader.xyz(t["b"], f"{sub}.b"),
                       _radius(reader, t["radius"], f"{sub}.radius"))  # fmt: skip
    if kind == "box":
        t = reader.table(table[kind], sub, ("center", "half_size"), ("center", "half_size"))
        return Box(reader.xyz(t["center"], f"{sub}.center"), _half(reader, t["half_size"], f"{sub}.half_size"))
    t = reader.table(table[kind], sub, ("center", "radius"), ("center", "radius"))
    return Sphere(reader.xyz(t["center"], f"{sub}.center"), _radius(reader, t["radius"], f"{sub}.radius"))


def _frame(reader: ArmFileReader, value: object, key: str, joints: Sequence[Joint]) -> int:
    name = reader.string(value, key)
    if name == "base":
        return BASE_FRAME
    names = [j.name for j in joints]
    if name not in names:
        raise reader.error(f"expected 'base' or a joint name: {', '.join(names)}", key, value)
    return names.index(name) + 1


def read_collision(
    reader: ArmFileReader,
    value: object,
    joints: Sequence[Joint],
    key: str = "collision",
    *,
    extra_keys: Iterable[str] = (),
    required: Iterable[str] = ("links",),
    more: Sequence[LinkShape] = (),
) -> Geometry:
    """The ``[collision]`` table: link shapes (``links``, after any ``more``) and allowed pairs."""
    t = reader.table(value, key, COLLISION_KEYS | set(extra_keys), required)
    raw = t.get("links", [])
    if not isinstance(raw, list) or (not raw and not more):
        raise reader.error("expected a non-empty list of link tables", f"{key}.links", raw)
    links = list(more)
    for i, entry in enumerate(raw):
        lk = f"{key}.links[{i}]"
        lt = reader.table(entry, lk, _LINK_KEYS, ("name", "frame"))
        name = reader.string(lt["name"], f"{lk}.name")
        frame = _frame(reader, lt["frame"], f"{lk}.frame", joints)
        shape = read_shape(reader, lt, lk)
        if isinstance(shape, Sphere):
            shape = Capsule(shape.center, shape.center, shape.radius)
        try:
            links.append(LinkShape(name, frame, shape))
        except ConfigError as exc:
            raise reader.error(exc.message, f"{lk}.name", name) from exc
    allowed = _pairs(reader, t.get("allowed", []), f"{key}.allowed")
    nest = _nests(reader, t.get("nest", []), f"{key}.nest")
    source = reader.string(t["source"], f"{key}.source") if "source" in t else ""
    return _geometry(reader, tuple(links), allowed, nest, source, key)


def _nests(reader: ArmFileReader, value: object, key: str) -> tuple[tuple[str, str, float], ...]:
    if not isinstance(value, list):
        raise reader.error("expected a list of [link, link, depth] entries", key, value)
    out = []
    for i, entry in enumerate(value):
        ok = isinstance(entry, list) and len(entry) == 3 and all(isinstance(n, str) and n for n in entry[:2])
        if not ok:
            raise reader.error("expected [link, link, depth in metres]", f"{key}[{i}]", entry)
        depth = reader.number(entry[2], f"{key}[{i}]")
        if not 0 <= depth <= 0.2:
            raise reader.error("expected a depth from 0 to 0.2 m", f"{key}[{i}]", entry)
        out.append((entry[0], entry[1], depth))
    return tuple(out)


def _pairs(reader: ArmFileReader, value: object, key: str) -> tuple[tuple[str, str], ...]:
    if not isinstance(value, list):
        raise reader.error("expected a list of [link, link] pairs", key, value)
    pairs = []
    for i, pair in enumerate(value):
        if not (isinstance(pair, list) and len(pair) == 2 and all(isinstance(n, str) and n for n in pair)):
            raise reader.error("expected a pair of link names", f"{key}[{i}]", pair)
        pairs.append((pair[0], pair[1]))
    return tuple(pairs)


def _geometry(
    reader: ArmFileReader,
    links: tuple[LinkShape, ...],
    allowed: tuple[tuple[str, str], ...],
    nest: tuple[tuple[str, str, float], ...],
    source: str,
    key: str,
) -> Geometry:
    try:
        return Geometry(links, allowed, source, nest)
    except ConfigError as exc:
        raise reader.error(exc.message, f"{key}.{exc.key}", exc.value) from exc


def read_world(reader: ArmFileReader, value: object, key: str = "world") -> World:
    """The ``[world]`` table: ``table`` (bool, default true) and ``keep_out`` zones."""
    t = reader.table(value, key, _WORLD_KEYS)
    table = t.get("table", True)
    if not isinstance(table, bool):
        raise reader.error("expected true or false", f"{key}.table", table)
    raw = t.get("keep_out", [])
    if not isinstance(raw, list):
        raise reader.error("expected a list of zone tables", f"{key}.keep_out", raw)
    zones: list[KeepOut] = []
    for i, entry in enumerate(raw):
        zk = f"{key}.keep_out[{i}]"
        shape = read_shape(reader, reader.table(entry, zk, ("box", "sphere")), zk, ("box", "sphere"))
        assert not isinstance(shape, Capsule)  # noqa: S101 - read_shape only returns a capsule for "capsule"
        zones.append(shape)
    return World(table=table, keep_out=tuple(zones))
