"""Import an arm from a URDF file plus a small servo file beside it.

``load_arm("robot.urdf", base=..., tip=...)`` (or :func:`load_urdf_arm`) reads the
serial chain of ``revolute``, ``continuous`` and ``fixed`` joints from a base link to
a tip link with :mod:`xml.etree.ElementTree` (no dependency):

- ``base`` defaults to the root link (the one link that is no joint's child) and
  ``tip`` to the single leaf below it; when either is ambiguous the ConfigError lists
  the candidates and asks for ``base``/``tip`` (CLI: ``--base``/``--tip``);
- fixed joints are folded into the origin of the next movable joint, and those after
  the last movable joint into the tool transform (the tip link is the tool point);
- a ``prismatic``, ``planar`` or ``floating`` joint on the chain, a cycle, a joint naming
  a missing link, a link with two parents: ConfigError naming it;
- ``continuous`` joints get limits of +-180 degrees unless the servo file sets them.

The servo file is ``<urdf stem>.servos.toml`` beside the URDF (degrees, like the arm
files of :mod:`retarget.arm.config`)::

    name = "my_arm"                  # optional (default: the URDF <robot name>)
    title = "My arm"                 # optional
    baud = 1_000_000                 # optional
    base = "base_link"               # optional defaults for base/tip (arguments win)
    tip = "ee_link"

    [joints.shoulder_joint]          # one table per movable chain joint, by URDF joint name
    servos = [{ id = 2, model = "XM430-W350" }, { id = 3, model = "XM430-W350", direction = -1 }]
    limits = [-100, 100]             # optional override of the URDF limits, degrees
    max_velocity = 180               # optional override of the URDF velocity, deg/s (required if the URDF has none)

    [poses]                          # optional: home (default: zeros, clipped into the limits) and rest
    home = [0, 0, 0, 0]

    [gripper]                        # optional, as in the arm files
    servo = { id = 5, model = "XL430-W250" }
    limits = [-20, 70]

    [mapping]                        # optional, read by retarget.mapping.config

    [collision]                      # optional (see retarget.arm.urdf_collision)
    radius = 0.02                    # capsule radius for meshes and links without <collision>, metres
    allowed = [["link3", "link1"]]   # and nest, links: as in the arm files (frames by URDF joint name)

    [world]                          # optional, as in the arm files

Every chain link gets collision shapes from its ``<collision>`` boxes, cylinders and spheres, or a capsule
between the joint origins for a mesh or a bare link (:mod:`retarget.arm.urdf_collision`).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field, replace
from os import PathLike
from pathlib import Path
from typing import Any

import numpy as np

from retarget.arm.config import (
    DEFAULT_BAUD,
    MAX_ANGLE,
    MAX_LENGTH,
    MAX_VELOCITY,
    MIN_VELOCITY,
    ArmFileReader,
    read_toml,
)
from retarget.arm.geometry import COLLISION_KEYS, read_collision, read_world
from retarget.arm.kinematics import matrix_rpy, transform
from retarget.arm.model import Arm, Joint
from retarget.arm.urdf_collision import DEFAULT_RADIUS, UrdfCollision, chain_shapes, read_collisions
from retarget.collision.shapes import Geometry
from retarget.errors import ConfigError

__all__ = ["UrdfJoint", "UrdfModel", "parse_urdf", "find_chain", "load_urdf_arm", "servo_file"]

_MOVABLE = ("revolute", "continuous")
_SUPPORTED = (*_MOVABLE, "fixed")
_SERVO_TOP = {"name", "title", "baud", "base", "tip", "joints", "poses", "gripper", "mapping", "collision", "world"}
_SERVO_JOINT = {"servos", "limits", "max_velocity"}


@dataclass(frozen=True)
class UrdfJoint:
    """One ``<joint>`` as read: metres and radians; ``lower``/``upper``/``velocity`` None when absent."""

    name: str
    type: str
    parent: str
    child: str
    xyz: tuple[float, float, float]
    rpy: tuple[float, float, float]
    axis: tuple[float, float, float]
    lower: float | None
    upper: float | None
    velocity: float | None


@dataclass(frozen=True)
class UrdfModel:
    """The links and joints of a URDF: ``joints`` by name, ``parent_joint`` by child link name."""

    path: Path
    name: str
    links: tuple[str, ...]
    joints: dict[str, UrdfJoint]
    parent_joint: dict[str, UrdfJoint]
    #: each link's ``<collision>`` elements (see :mod:`retarget.arm.urdf_collision`)
    collisions: dict[str, tuple[UrdfCollision, ...]] = field(default_factory=dict)

    def error(self, message: str, key: str | None = None, value: Any = None) -> ConfigError:
        if value is None:
            return ConfigError(message, path=self.path, key=key)
        return ConfigError(message, path=self.path, key=key, value=value)


def _floats(text: str, n: int, where: str, model_path: Path) -> tuple[float, ...]:
    """The ``n`` finite numbers of an attribute's ``text``, else a ConfigError naming ``where``."""
    try:
        values = tuple(float(v) for v in text.split())
    except ValueError:
        values = ()
    if len(values) != n or not all(math.isfinite(v) for v in values):
        raise ConfigError(f"expected {n} numbers", path=model_path, key=where, value=text)
    return values


def _vec3(
    text: str | None, default: tuple[float, float, float], where: str, model_path: Path
) -> tuple[float, float, float]:
    """Three numbers from an attribute's ``text``, ``default`` when the attribute is absent."""
    if text is None:
        return default
    x, y, z = _floats(text, 3, where, model_path)
    return (x, y, z)


def _scalar(text: str | None, where: str, model_path: Path) -> float | None:
    """One number from an attribute's ``text``, None when the attribute is absent."""
    return None if text is None else _floats(text, 1, where, model_path)[0]


def _link(el: ET.Element, role: str, key: str, links: set[str], model_path: Path) -> str:
    """The link named by the ``<parent>`` or ``<child>`` (``role``) of the joint ``el``: present and defined."""
    tag = el.find(role)
    link = tag.get("link") if tag is not None else None
    if not link:
        raise ConfigError(f"missing <{role} link=...>", path=model_path, key=f"{key}.{role}")
    if link not in links:
        raise ConfigError(f"{role} link {link!r} is not defined", path=model_path, key=f"{key}.{role}", value=link)
    return link


def parse_urdf(path: str | PathLike[str]) -> UrdfModel:
    """Read the links and joints of a URDF file; checks names, links, parents and cycles."""
    path = Path(path)
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as exc:
        line = exc.position[0] if exc.position else None
        raise ConfigError(f"invalid URDF XML: {exc}", path=path, key=f"line {line}" if line else None) from exc
    except OSError as exc:
        raise ConfigError(f"cannot read: {exc.strerror or exc}", path=path) from exc
    if root.tag != "robot":
        raise ConfigError("not a URDF: the root element must be <robot>", path=path, value=root.tag)
    links = []
    for el in root.findall("link"):
        name = el.get("name")
        if not name:
            raise ConfigError("a <link> without a name", path=path, key="link")
        links.append(name)
    link_set = set(links)
    joints: dict[str, UrdfJoint] = {}
    parent_joint: dict[str, UrdfJoint] = {}
    for el in root.findall("joint"):
        name = el.get("name")
        if not name:
            raise ConfigError("a <joint> without a name", path=path, key="joint")
        key = f"joint[{name}]"
        if name in joints:
            raise ConfigError("duplicate joint name", path=path, key=key)
        parent = _link(el, "parent", key, link_set, path)
        child = _link(el, "child", key, link_set, path)
        origin = el.find("origin")
        xyz = _vec3(origin.get("xyz") if origin is not None else None, (0.0, 0.0, 0.0), f"{key}.origin.xyz", path)
        rpy = _vec3(origin.get("rpy") if origin is not None else None, (0.0, 0.0, 0.0), f"{key}.origin.rpy", path)
        axis_el = el.find("axis")
        axis = _vec3(axis_el.get("xyz") if axis_el is not None else None, (1.0, 0.0, 0.0), f"{key}.axis", path)
        limit = el.find("limit")
        lower: float | None = None
        upper: float | None = None
        velocity: float | None = None
        if limit is not None:
            lower = _scalar(limit.get("lower"), f"{key}.limit.lower", path)
            upper = _scalar(limit.get("upper"), f"{key}.limit.upper", path)
            velocity = _scalar(limit.get("velocity"), f"{key}.limit.velocity", path)
        joint = UrdfJoint(name, el.get("type", ""), parent, child, xyz, rpy, axis, lower, upper, velocity)
        if child in parent_joint:
            other = parent_joint[child].name
            raise ConfigError(f"link {child!r} is the child of two joints ({other}, {name})", path=path, key=key)
        joints[name] = joint
        parent_joint[child] = joint
    collisions = read_collisions(root, path)
    model = UrdfModel(path, root.get("name", path.stem), tuple(links), joints, parent_joint, collisions)
    _check_cycles(model)
    return model


def _check_cycles(model: UrdfModel) -> None:
    done: set[str] = set()
    for start in model.links:
        trail: list[str] = []
        link = start
        while link in model.parent_joint and link not in done:
            if link in trail:
                loop = trail[trail.index(link) :] + [link]
                raise model.error(f"the joints form a cycle: {' -> '.join(loop)}", key=f"link[{link}]")
            trail.append(link)
            link = model.parent_joint[link].parent
        done.update(trail)


def find_chain(model: UrdfModel, base: str | None = None, tip: str | None = None) -> list[UrdfJoint]:
    """The joints from ``base`` to ``tip``, base first; auto-detects the ends when unambiguous."""
    children: dict[str, list[str]] = {}
    for j in model.joints.values():
        children.setdefault(j.parent, []).append(j.child)
    if base is None:
        roots = [link for link in model.links if link not in model.parent_joint]
        if len(roots) != 1:
            raise model.error(f"cannot tell the base link: roots {', '.join(roots)}; name one", key="base")
        base = roots[0]
    elif base not in model.links:
        raise model.error(f"no link named {base!r}; links: {', '.join(model.links)}", key="base", value=base)
    if tip is None:
        leaves, stack = [], [base]
        while stack:
            link = stack.pop()
            below = children.get(link, [])
            if not below:
                leaves.append(link)
            stack.extend(below)
        if len(leaves) != 1:
            raise model.error(f"cannot tell the tip link: leaves {', '.join(sorted(leaves))}; name one", key="tip")
        tip = leaves[0]
    elif tip not in model.links:
        raise model.error(f"no link named {tip!r}; links: {', '.join(model.links)}", key="tip", value=tip)
    chain: list[UrdfJoint] = []
    link = tip
    while link != base:
        joint = model.parent_joint.get(link)
        if joint is None:
            raise model.error(f"tip link {tip!r} is not below base link {base!r}", key="tip", value=tip)
        chain.append(joint)
        link = joint.parent
    chain.reverse()
    for j in chain:
        if j.type not in _SUPPORTED:
            raise model.error(
                f"unsupported joint type on the chain (only {', '.join(_SUPPORTED)})", key=f"joint[{j.name}].type",
                value=j.type,
            )  # fmt: skip
    if not any(j.type in _MOVABLE for j in chain):
        raise model.error(f"no revolute or continuous joint between {base!r} and {tip!r}", key="tip", value=tip)
    return chain


def servo_file(urdf_path: Path) -> Path:
    """The servo file of a URDF: ``<stem>.servos.toml`` beside it."""
    return urdf_path.with_name(f"{urdf_path.stem}.servos.toml")


def load_urdf_arm(
    path: str | PathLike[str],
    *,
    base: str | None = None,
    tip: str | None = None,
    servos: str | PathLike[str] | None = None,
) -> Arm:
    """Build an :class:`~retarget.arm.Arm` from a URDF chain and its servo file (default :func:`servo_file`)."""
    path = Path(path)
    model = parse_urdf(path)
    spath = Path(servos) if servos is not None else servo_file(path)
    if not spath.is_file():
        raise ConfigError(f"servo file not found: {spath} (see retarget.arm.urdf for its format)", path=path)
    reader = ArmFileReader(spath)
    data = reader.table(read_toml(spath), "", _SERVO_TOP, ("joints",))
    base = base if base is not None else (reader.string(data["base"], "base") if "base" in data else None)
    tip = tip if tip is not None else (reader.string(data["tip"], "tip") if "tip" in data else None)
    chain = find_chain(model, base, tip)
    entries = reader.table(data["joints"], "joints", [j.name for j in chain if j.type in _MOVABLE])

    joints: list[Joint] = []
    pending = np.eye(4)
    frames: list[tuple[str, int, np.ndarray]] = [(chain[0].parent, 0, np.eye(4))]  # link, frame, link -> frame
    for uj in chain:
        if any(abs(v) > MAX_LENGTH for v in uj.xyz):
            raise model.error(
                f"expected an origin within +-{MAX_LENGTH:g} m", key=f"joint[{uj.name}].origin.xyz", value=uj.xyz
            )
        T = pending @ transform(uj.xyz, uj.rpy)
        if uj.type == "fixed":
            pending = T
            frames.append((uj.child, len(joints), T))
            continue
        pending = np.eye(4)
        frames.append((uj.child, len(joints) + 1, np.eye(4)))
        key = f"joints.{uj.name}"
        if uj.name not in entries:
            raise reader.error("missing the servo table of this chain joint", key)
        entry = reader.table(entries[uj.name], key, _SERVO_JOINT, ("servos",))
        if "limits" in entry:
            lower, upper = reader.limits(entry["limits"], f"{key}.limits")
        elif uj.type == "continuous":
            lower, upper = -math.pi, math.pi
        else:
            if uj.lower is None or uj.upper is None:
                raise model.error("revolute joint without <limit lower upper>", key=f"joint[{uj.name}].limit")
            if uj.lower >= uj.upper:
                raise model.error(
                    "lower limit must be below upper limit", key=f"joint[{uj.name}].limit", value=(uj.lower, uj.upper)
                )
            if max(-uj.lower, uj.upper) > math.radians(MAX_ANGLE):
                raise model.error(
                    f"expected limits within +-{math.radians(MAX_ANGLE):g} rad ({MAX_ANGLE:g} deg)",
                    key=f"joint[{uj.name}].limit",
                    value=(uj.lower, uj.upper),
                )
            lower, upper = uj.lower, uj.upper
        if "max_velocity" in entry:
            velocity = reader.velocity(entry["max_velocity"], f"{key}.max_velocity")
        elif uj.velocity is not None and uj.velocity > 0:
            velocity = uj.velocity
            if not math.radians(MIN_VELOCITY) <= velocity <= math.radians(MAX_VELOCITY):
                raise model.error(
                    f"expected a velocity from {math.radians(MIN_VELOCITY):.4g} to {math.radians(MAX_VELOCITY):.4g}"
                    f" rad/s ({MIN_VELOCITY:g} to {MAX_VELOCITY:g} deg/s); or set max_velocity (deg/s) in {spath.name}",
                    key=f"joint[{uj.name}].limit.velocity",
                    value=velocity,
                )
        else:
            raise reader.error("the URDF gives no velocity for this joint: set max_velocity (deg/s)", key)
        norm = math.hypot(*uj.axis)  # no overflow for huge components
        if not 1e-9 <= norm < math.inf:
            raise model.error("joint axis has zero length", key=f"joint[{uj.name}].axis", value=uj.axis)
        joints.append(
            Joint(
                name=uj.name,
                origin_xyz=tuple(T[:3, 3].tolist()),
                origin_rpy=matrix_rpy(T[:3, :3]),
                axis=(uj.axis[0] / norm, uj.axis[1] / norm, uj.axis[2] / norm),
                lower=lower,
                upper=upper,
                max_velocity=velocity,
                servos=reader.servos(entry["servos"], f"{key}.servos"),
            )
        )
    joints_t = tuple(joints)
    if "poses" in data:
        home, rest = reader.poses(data["poses"], joints_t)
    else:
        home = rest = tuple(min(max(0.0, j.lower), j.upper) for j in joints_t)
    name = reader.string(data.get("name", model.name), "name")
    baud = reader.baud(data.get("baud", DEFAULT_BAUD))
    gripper = reader.gripper(data["gripper"]) if "gripper" in data else None
    ends = [j.origin_xyz for j in joints_t] + [tuple(pending[:3, 3].tolist())]
    geometry = _geometry(reader, model, data.get("collision", {}), frames, joints_t, ends)
    return Arm(
        name=name,
        title=reader.string(data.get("title", name), "title"),
        joints=joints_t,
        tool_xyz=tuple(pending[:3, 3].tolist()),
        tool_rpy=matrix_rpy(pending[:3, :3]),
        home=np.array(home, dtype=np.float64),
        rest=np.array(rest, dtype=np.float64),
        baud=baud,
        gripper=gripper,
        mapping=reader.mapping(data.get("mapping", {})),
        source=path,
        geometry=geometry,
        world=read_world(reader, data.get("world", {})),
    )


def _geometry(
    reader: ArmFileReader,
    model: UrdfModel,
    table: object,
    frames: list[tuple[str, int, np.ndarray]],
    joints: tuple[Joint, ...],
    ends: list[tuple[float, float, float]],
) -> Geometry:
    """The chain's shapes from the URDF (:mod:`retarget.arm.urdf_collision`) and the servo file's ``[collision]``
    table: ``radius`` (metres, for meshes and bare links), ``allowed``, ``nest`` and more ``links``."""
    t = reader.table(table, "collision", (*COLLISION_KEYS, "radius"))
    radius = reader.number(t["radius"], "collision.radius") if "radius" in t else DEFAULT_RADIUS
    if not 0 < radius <= 1.0:
        raise reader.error("expected a radius from 0 to 1 m", "collision.radius", radius)
    try:
        shapes, touching = chain_shapes(frames, model.collisions, ends, radius)
    except ConfigError as exc:
        raise model.error(f"collision shape: {exc.message}", key=exc.key, value=exc.value) from exc
    geometry = read_collision(reader, t, joints, extra_keys=("radius",), required=(), more=shapes)
    return replace(geometry, allowed=(*touching, *geometry.allowed))
