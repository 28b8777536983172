"""Collision shapes of a URDF chain: its ``<collision>`` primitives, capsules for meshes and bare links.

Each link on the chain from base to tip carries the shapes of its ``<collision>`` elements, in the frame of the
arm it moves with (the base frame, or the child frame of the last movable joint above it, through any fixed
joints between):

- ``<box size="x y z">`` on the base frame: an axis-aligned :class:`~retarget.collision.shapes.Box` (a rotated
  origin: the axis-aligned box enclosing it); on a moving link: the capsule enclosing that box, along its
  longest side (the collision model checks no box against another box);
- ``<cylinder radius length>``: the capsule over its axis segment with its radius (encloses it);
- ``<sphere radius>``: a capsule of zero length;
- a ``<mesh>``, or a link without ``<collision>``: a capsule from the link's frame origin to the next movable
  joint's origin (the last: to the tool point), of the servo file's ``[collision] radius`` (default
  :data:`DEFAULT_RADIUS`), once per frame; two such capsules with only a short link between them (shorter than two
  radii plus :data:`SHORT_LINK_GAP`) meet round its joint and are an allowed pair.

Shapes are named after their link (``link``, then ``link_2``, ``link_3`` for more elements of one link); links
off the chain (side branches such as mimic fingers) are not included.  Lengths in metres.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from retarget.arm.kinematics import transform
from retarget.collision.shapes import BASE_FRAME, Box, Capsule, LinkShape
from retarget.errors import ConfigError

__all__ = ["DEFAULT_RADIUS", "SHORT_LINK_GAP", "UrdfCollision", "chain_shapes", "read_collisions"]

#: Radius of the capsule of a mesh or a bare link, metres, unless the servo file sets ``[collision] radius``
#: (an XM430 servo is 28.5 mm wide).
DEFAULT_RADIUS = 0.02

#: metres: two bare capsules one short link apart are allowed to touch when that link is shorter than two radii
#: plus this gap (the default clearance, 10 mm: closer than that they would read as a collision at every pose)
SHORT_LINK_GAP = 0.010

_PRIMITIVES = {"box": (("size", 3),), "cylinder": (("radius", 1), ("length", 1)), "sphere": (("radius", 1),)}


@dataclass(frozen=True)
class UrdfCollision:
    """One ``<collision>``: ``kind`` box, cylinder, sphere or mesh; its origin (metres, radians) and sizes."""

    kind: str
    xyz: tuple[float, float, float]
    rpy: tuple[float, float, float]
    dims: Mapping[str, tuple[float, ...]]


def _numbers(text: str | None, n: int, key: str, path: Path, *, sizes: bool) -> tuple[float, ...]:
    try:
        values = tuple(float(v) for v in (text or "").split())
    except ValueError:
        values = ()
    ok = len(values) == n and all(math.isfinite(v) and (v >= 0 or not sizes) for v in values)
    if not ok:
        what = f"{n} finite number{'s' if n > 1 else ''}" + (" >= 0 (metres)" if sizes else "")
        raise ConfigError(f"expected {what}", path=path, key=key, value=text)
    return values


def _one(el: ET.Element, key: str, path: Path) -> UrdfCollision:
    origin = el.find("origin")
    get = origin.get if origin is not None else (lambda _name: None)
    xyz = get("xyz")
    rpy = get("rpy")
    x, y, z = _numbers(xyz, 3, f"{key}.origin.xyz", path, sizes=False) if xyz is not None else (0.0, 0.0, 0.0)
    r, p, w = _numbers(rpy, 3, f"{key}.origin.rpy", path, sizes=False) if rpy is not None else (0.0, 0.0, 0.0)
    geometry = el.find("geometry")
    shape = geometry[0] if geometry is not None and len(geometry) else None
    if shape is None or shape.tag not in (*_PRIMITIVES, "mesh"):
        tag = None if shape is None else shape.tag
        raise ConfigError("expected <geometry> with a box, cylinder, sphere or mesh", path=path, key=key, value=tag)
    dims = {
        attr: _numbers(shape.get(attr), n, f"{key}.{shape.tag}.{attr}", path, sizes=True)
        for attr, n in _PRIMITIVES.get(shape.tag, ())
    }
    return UrdfCollision(shape.tag, (x, y, z), (r, p, w), dims)


def read_collisions(root: ET.Element, path: Path) -> dict[str, tuple[UrdfCollision, ...]]:
    """Every link's ``<collision>`` elements, by link name; a ConfigError names the link and the attribute."""
    out = {}
    for link in root.findall("link"):
        name = link.get("name", "")
        out[name] = tuple(
            _one(el, f"link[{name}].collision[{i}]", path) for i, el in enumerate(link.findall("collision"))
        )
    return out


def _capsule_of_box(center: np.ndarray, R: np.ndarray, half: np.ndarray) -> Capsule:
    """The capsule along the box's longest side that encloses it: segment of that side, radius the half diagonal
    of the other two."""
    k = int(np.argmax(half))
    others = [half[i] for i in range(3) if i != k]
    u = R[:, k] * half[k]
    radius = math.hypot(*others)
    return Capsule(tuple((center - u).tolist()), tuple((center + u).tolist()), radius)


def _shape(c: UrdfCollision, T: np.ndarray, base: bool) -> Capsule | Box:
    """The shape of primitive ``c`` in its arm frame; ``T`` (4, 4) link frame -> arm frame."""
    M = T @ transform(c.xyz, c.rpy)
    R, centre = M[:3, :3], M[:3, 3]
    if c.kind == "box":
        half = np.array(c.dims["size"]) / 2
        if base:
            return Box(tuple(centre.tolist()), tuple((np.abs(R) @ half).tolist()))
        return _capsule_of_box(centre, R, half)
    (radius,) = c.dims["radius"]
    half_length = c.dims["length"][0] / 2 if c.kind == "cylinder" else 0.0
    u = R[:, 2] * half_length
    return Capsule(tuple((centre - u).tolist()), tuple((centre + u).tolist()), radius)


def chain_shapes(
    links: Sequence[tuple[str, int, np.ndarray]],
    collisions: Mapping[str, tuple[UrdfCollision, ...]],
    ends: Sequence[tuple[float, float, float]],
    radius: float,
) -> tuple[tuple[LinkShape, ...], tuple[tuple[str, str], ...]]:
    """Shapes of the chain's ``links`` (name, frame index, (4, 4) link -> frame transform), base first.

    ``ends[f]``: the point in frame ``f`` where the next movable joint (or the tool point) sits, metres: the far
    end of the capsule of a frame whose links are meshes or bare.  Also returns the pairs of bare capsules allowed
    to touch (see :func:`_through_short_links`).
    """
    out: list[LinkShape] = []
    bare: dict[int, str] = {}
    for name, frame, T in links:
        own = collisions.get(name, ())
        prims = [c for c in own if c.kind != "mesh"]
        if len(prims) < len(own) or not own:
            bare.setdefault(frame, name)
        for i, c in enumerate(prims):
            label = name if i == 0 else f"{name}_{i + 1}"
            out.append(_link_shape(label, frame, _shape(c, T, frame == BASE_FRAME), name))
    taken = {s.name for s in out}
    labels = {}
    for frame, name in sorted(bare.items()):
        labels[frame] = name if name not in taken else f"{name}_joints"
        out.append(_link_shape(labels[frame], frame, Capsule((0.0, 0.0, 0.0), ends[frame], radius), name))
    return tuple(out), _through_short_links(labels, ends, radius)


def _through_short_links(
    labels: Mapping[int, str], ends: Sequence[Sequence[float]], radius: float
) -> tuple[tuple[str, str], ...]:
    """Bare capsules on frames ``f`` and ``f + 2`` whose link between is shorter than two radii plus
    :data:`SHORT_LINK_GAP`: they meet round that joint (its servo), so the pair is allowed."""
    pairs = []
    for f, name in labels.items():
        between = f + 1
        if f + 2 in labels and between in labels and math.hypot(*ends[between]) < 2 * radius + SHORT_LINK_GAP:
            pairs.append((name, labels[f + 2]))
    return tuple(pairs)


def _link_shape(label: str, frame: int, shape: Capsule | Box, link: str) -> LinkShape:
    try:
        return LinkShape(label, frame, shape)
    except ConfigError as exc:
        raise ConfigError(exc.message, key=f"link[{link}]", value=label) from exc
