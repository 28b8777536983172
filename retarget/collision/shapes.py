"""Collision shapes of an arm and its world: frozen specs, validated on construction.

Link geometry (:class:`Geometry`) is a tuple of :class:`LinkShape`, each a named shape fixed in one frame of
the arm: frame 0 is the base frame, frame ``i`` (1..n_joints) the child frame of joint ``i - 1`` (the frame
that turns with that joint, as in :mod:`retarget.arm.kinematics`).  Moving links are capsules (a segment and
a radius, cheap and conservative); links on the base frame may also be an axis-aligned :class:`Box`.

The world (:class:`World`) is the table plane z = 0 of the base frame (on by default) and optional keep-out
zones, each an axis-aligned :class:`Box` or a :class:`Sphere` in the base frame.  Metres throughout.

>>> World(keep_out=(Sphere((0.3, 0.0, 0.1), 0.05),)).keep_out[0].radius
0.05
>>> Box((0, 0, 0), (0.1, -0.1, 0.1))  # doctest: +ELLIPSIS
Traceback (most recent call last):
...
retarget.errors.ConfigError: half_size: Expected three finite numbers >= 0 in metres ...
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field

from retarget.errors import ConfigError

__all__ = [
    "BASE_FRAME",
    "DEFAULT_CLEARANCE",
    "TABLE",
    "Box",
    "Capsule",
    "Geometry",
    "KeepOut",
    "LinkShape",
    "Sphere",
    "World",
]

#: The default clearance, metres: 10 mm.  One degree of joint error at the 0.5 m reach of a WidowX-250 or a
#: ViperX-300 moves the tool point 9 mm; the servos hold a goal to about a degree under load, the geometry is
#: simplified to a few millimetres, and a BVH target can jump between ticks: 10 mm covers these without
#: forbidding the arm's useful poses (the CLI takes the clearance in mm).
DEFAULT_CLEARANCE = 0.010

#: The frame index of the base frame (links that never move).
BASE_FRAME = 0

#: The name of the table plane in pair names ("gripper/table").
TABLE = "table"

Vec3 = tuple[float, float, float]


def _vec3(value: Iterable[float], key: str, *, non_negative: bool = False) -> Vec3:
    try:
        numbers = tuple(float(v) for v in value)
    except (TypeError, ValueError):
        numbers = ()
    ok = len(numbers) == 3 and all(math.isfinite(v) and (v >= 0 or not non_negative) for v in numbers)
    if not ok:
        what = "three finite numbers >= 0" if non_negative else "three finite numbers"
        raise ConfigError(f"Expected {what} in metres", key=key, value=value)
    return (numbers[0], numbers[1], numbers[2])


def _radius(value: float, key: str) -> float:
    try:
        r = float(value)
    except (TypeError, ValueError):
        r = math.nan
    if not (math.isfinite(r) and r >= 0):
        raise ConfigError("Expected a finite radius >= 0 in metres", key=key, value=value)
    return r


@dataclass(frozen=True)
class Capsule:
    """The points within ``radius`` of the segment ``a``-``b`` (metres, in the link's frame)."""

    a: Vec3
    b: Vec3
    radius: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "a", _vec3(self.a, "a"))
        object.__setattr__(self, "b", _vec3(self.b, "b"))
        object.__setattr__(self, "radius", _radius(self.radius, "radius"))


@dataclass(frozen=True)
class Box:
    """An axis-aligned box: ``center`` and ``half_size`` (metres, >= 0 each), in the base frame or its link's."""

    center: Vec3
    half_size: Vec3

    def __post_init__(self) -> None:
        object.__setattr__(self, "center", _vec3(self.center, "center"))
        object.__setattr__(self, "half_size", _vec3(self.half_size, "half_size", non_negative=True))


@dataclass(frozen=True)
class Sphere:
    """A ball: ``center`` and ``radius`` (metres), in the base frame."""

    center: Vec3
    radius: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "center", _vec3(self.center, "center"))
        object.__setattr__(self, "radius", _radius(self.radius, "radius"))


#: A keep-out zone of the world, in the base frame.
KeepOut = Box | Sphere


@dataclass(frozen=True)
class LinkShape:
    """One named shape of the arm, fixed in ``frame`` (0 = base; ``i`` = child frame of joint ``i - 1``).

    A :class:`Box` is axis-aligned in its frame; two boxes must not form a checked pair (no box/box test).
    """

    name: str
    frame: int
    shape: Capsule | Box

    def __post_init__(self) -> None:
        if not self.name or "/" in self.name or self.name == TABLE:
            raise ConfigError(f"Expected a link name without '/', not {TABLE!r}", key="name", value=self.name)
        if self.frame < 0:
            raise ConfigError("Expected a frame index >= 0", key="frame", value=self.frame)


@dataclass(frozen=True)
class Geometry:
    """The collision shapes of an arm and the pairs of links allowed to touch (besides adjacent ones).

    ``allowed``: pairs of link names, each sorted; links attached to neighbouring bodies of the chain are
    always allowed (see :func:`retarget.collision.model.CollisionModel`).  ``source`` says where the
    numbers come from (documentary).
    """

    links: tuple[LinkShape, ...]
    allowed: tuple[tuple[str, str], ...] = ()
    source: str = ""
    #: ``(link, link, depth)``: pairs whose capsules may overlap by ``depth`` metres (they nest, e.g. in the
    #: sleep pose, where the enclosing capsules overlap but the real parts do not): their clearance counts from
    #: ``-depth``.  Still checked, unlike ``allowed`` pairs.
    nest: tuple[tuple[str, str, float], ...] = ()

    def __post_init__(self) -> None:
        names = [link.name for link in self.links]
        dupes = sorted({n for n in names if names.count(n) > 1})
        if dupes:
            raise ConfigError("Expected unique link names", key="links", value=dupes)
        pairs = []
        for i, pair in enumerate(self.allowed):
            a, b = pair
            for n in (a, b):
                if n not in names:
                    raise ConfigError(f"unknown link; links: {', '.join(names)}", key=f"allowed[{i}]", value=n)
            if a == b:
                raise ConfigError("Expected two different links", key=f"allowed[{i}]", value=list(pair))
            pairs.append((min(a, b), max(a, b)))
        object.__setattr__(self, "allowed", tuple(pairs))
        nests = []
        for i, (a, b, depth) in enumerate(self.nest):
            for n in (a, b):
                if n not in names:
                    raise ConfigError(f"unknown link; links: {', '.join(names)}", key=f"nest[{i}]", value=n)
            if not (math.isfinite(depth) and 0 <= depth <= 1):
                raise ConfigError("Expected a depth from 0 to 1 m", key=f"nest[{i}]", value=depth)
            nests.append((min(a, b), max(a, b), float(depth)))
        object.__setattr__(self, "nest", tuple(nests))

    def nest_depth(self, a: str, b: str) -> float:
        """How far the shapes of links ``a`` and ``b`` may overlap (metres; 0 unless listed in ``nest``)."""
        key = (min(a, b), max(a, b))
        return next((d for x, y, d in self.nest if (x, y) == key), 0.0)

    def names(self) -> tuple[str, ...]:
        return tuple(link.name for link in self.links)


@dataclass(frozen=True)
class World:
    """What the arm must keep clear of, in the base frame: the table plane z = 0, and keep-out zones."""

    table: bool = True
    keep_out: tuple[KeepOut, ...] = field(default=())

    def __post_init__(self) -> None:
        zones = tuple(self.keep_out)
        for i, zone in enumerate(zones):
            if not isinstance(zone, Box | Sphere):
                raise ConfigError("Expected a Box or a Sphere", key=f"keep_out[{i}]", value=zone)
        object.__setattr__(self, "keep_out", zones)
        object.__setattr__(self, "table", bool(self.table))

    def zone_names(self) -> tuple[str, ...]:
        """Names of the keep-out zones in pair names: ``keep_out[0]``, ..."""
        return tuple(f"keep_out[{i}]" for i in range(len(self.keep_out)))
