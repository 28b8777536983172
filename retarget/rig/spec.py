"""A rig: two (or more) arms placed in one world frame, each with its port and the human side that drives it.

A rig file (TOML, bundled under ``config/rigs/`` or given as a path)::

    [rig]
    name = "wx250s-pair"            # optional; the file's stem by default

    [[arms]]
    name = "left"                   # a unique name: telemetry columns and flags use it (letters, digits, _ -)
    arm = "wx250s"                  # a bundled arm, or a .toml / .urdf path (relative to this file)
    xyz = [0.0, 0.3, 0.0]           # metres: the arm's base origin in the world
    rpy = [0.0, 0.0, 0.0]           # degrees: the base's orientation (URDF roll-pitch-yaw)
    port = "sim://wx250s"           # optional; sim://<arm> by default
    side = "left"                   # the human arm that drives it

The world frame: z up, the table at z = 0 under bases mounted on it, x forward (away from the operator).
Units: metres and radians inside; the file's angles are degrees.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, replace
from os import PathLike
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from retarget.arm.config import read_toml
from retarget.arm.kinematics import transform
from retarget.arm.load import load_arm
from retarget.arm.model import Arm
from retarget.errors import ConfigError
from retarget.mapping.config import Side

__all__ = ["Placement", "Rig", "RigArm", "list_rigs", "load_rig", "rig_dirs"]

_RIG_KEYS = {"name"}
_ARM_KEYS = {"name", "arm", "xyz", "rpy", "port", "side"}
_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_-]{0,31}$")
MAX_OFFSET = 10.0  #: metres, each coordinate of a base's ``xyz``


@dataclass(frozen=True)
class Placement:
    """Where an arm's base frame sits in the world: ``xyz`` ``(3,)`` metres, ``rpy`` ``(3,)`` radians
    (URDF roll-pitch-yaw, fixed axes).

    >>> p = Placement((0.0, 0.3, 0.0), (0.0, 0.0, math.pi / 2))
    >>> p.to_world([[0.1, 0.0, 0.2]]).round(6).tolist()
    [[0.0, 0.4, 0.2]]
    """

    xyz: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)

    @property
    def matrix(self) -> npt.NDArray[np.float64]:
        """``(4, 4)`` float64: world from base (a point in the base frame, metres, to the world)."""
        return transform(self.xyz, self.rpy)

    def to_world(self, points: npt.ArrayLike) -> npt.NDArray[np.float64]:
        """Points ``(..., 3)`` metres in the base frame to the world frame ``(..., 3)``."""
        T = self.matrix
        out: npt.NDArray[np.float64] = np.asarray(points, dtype=np.float64) @ T[:3, :3].T + T[:3, 3]
        return out

    def to_base(self, points: npt.ArrayLike) -> npt.NDArray[np.float64]:
        """Points ``(..., 3)`` metres in the world frame to the base frame ``(..., 3)``."""
        T = self.matrix
        out: npt.NDArray[np.float64] = (np.asarray(points, dtype=np.float64) - T[:3, 3]) @ T[:3, :3]
        return out


@dataclass(frozen=True)
class RigArm:
    """One arm of a rig: its ``name`` in the rig, the :class:`~retarget.arm.model.Arm`, its base's
    :class:`Placement` in the world, its ``port`` (a serial device or ``sim://``/``tcp://`` URL) and the human
    ``side`` that drives it."""

    name: str
    arm: Arm
    placement: Placement
    port: str
    side: Side

    def tool_point(self, q: npt.ArrayLike) -> npt.NDArray[np.float64]:
        """The tool point ``(3,)`` metres, world frame, of joint angles ``q`` ``(n_joints,)`` rad."""
        T, _ = self.arm.fk(np.asarray(q, dtype=np.float64))
        return self.placement.to_world(T[:3, 3])


@dataclass(frozen=True)
class Rig:
    """Arms in one world frame (see the module docstring); ``path`` is the rig file (None: built in code).

    >>> rig = load_rig("wx250s-pair")
    >>> rig.name, rig.names, [a.side.value for a in rig.arms]
    ('wx250s-pair', ('left', 'right'), ['left', 'right'])
    >>> round(float(np.linalg.norm(rig["left"].tool_point(rig["left"].arm.home)
    ...                             - rig["right"].tool_point(rig["right"].arm.home))), 3)
    0.6
    """

    name: str
    arms: tuple[RigArm, ...]
    path: Path | None = None

    @property
    def names(self) -> tuple[str, ...]:
        """The arms' names, in file order."""
        return tuple(a.name for a in self.arms)

    def __getitem__(self, name: str) -> RigArm:
        for a in self.arms:
            if a.name == name:
                return a
        raise ConfigError(f"Expected one of the rig's arms {', '.join(self.names)}", key="rig.arm", value=name)

    def with_ports(self, ports: Mapping[str, str]) -> Rig:
        """The rig with some arms' ports replaced: ``{arm name: port}`` (an unknown name is a ConfigError).

        >>> load_rig("wx250s-pair").with_ports({"right": "/dev/ttyUSB1"})["right"].port
        '/dev/ttyUSB1'
        """
        for name in ports:
            self[name]  # noqa: B018 - raises on an unknown arm
        arms = tuple(replace(a, port=ports.get(a.name, a.port)) for a in self.arms)
        return replace(self, arms=arms)


def rig_dirs() -> list[Path]:
    """The folders searched for bundled rigs, in order: the installed copy, then the source checkout."""
    package = Path(__file__).resolve().parents[1]
    return [package / "_config" / "rigs", package.parent / "config" / "rigs"]


def list_rigs() -> list[str]:
    """Names of the bundled rigs (the file stems), sorted."""
    return sorted({p.stem for d in rig_dirs() if d.is_dir() for p in d.glob("*.toml")})


def _resolve(name_or_path: str | PathLike[str]) -> Path:
    text = str(name_or_path)
    if isinstance(name_or_path, PathLike) or "/" in text or "\\" in text or text.endswith(".toml"):
        path = Path(name_or_path)
        if not path.is_file():
            raise ConfigError("rig file not found", path=path)
        return path
    for folder in rig_dirs():
        if (candidate := folder / f"{text}.toml").is_file():
            return candidate
    known = ", ".join(list_rigs()) or "none found"
    raise ConfigError(f"unknown rig {text!r}; known rigs: {known} (or give a .toml path)", key="rig")


def load_rig(name_or_path: str | PathLike[str]) -> Rig:
    """Load a rig by bundled name or TOML path (the schema in the module docstring).

    Raises :class:`~retarget.errors.ConfigError` naming the file, the key path (``arms[1].xyz``) and the bad
    value: an unknown rig, unreadable TOML, an unknown or missing key, a bad number, a duplicate arm name or
    side, an arm file that does not load (its own error, with the rig's key path in front).

    >>> rig = load_rig("aloha")
    >>> [(a.name, a.arm.name, a.placement.xyz) for a in rig.arms]
    [('left', 'vx300s', (0.0, 0.3, 0.0)), ('right', 'vx300s', (0.0, -0.3, 0.0))]
    >>> load_rig("no_such_rig")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    retarget.errors.ConfigError: rig: unknown rig 'no_such_rig'; known rigs: ...
    """
    path = _resolve(name_or_path)
    data = read_toml(path)
    unknown = set(data) - {"rig", "arms"}
    if unknown:
        raise ConfigError("Expected only the tables [rig] and [[arms]]", path=path, key=sorted(unknown)[0])
    head = _table(data.get("rig", {}), "rig", _RIG_KEYS, path)
    name = _string(head.get("name", path.stem), "rig.name", path)
    entries = data.get("arms")
    if not isinstance(entries, list) or len(entries) < 2:
        raise ConfigError("Expected two or more [[arms]] tables", path=path, key="arms")
    loaded: dict[str | Path, Arm] = {}  # an arm file named twice (aloha's two vx300s) is read once: specs are frozen
    arms = tuple(_rig_arm(entry, f"arms[{i}]", path, loaded) for i, entry in enumerate(entries))
    for field in ("name", "side"):
        values = [getattr(a, field) for a in arms]
        for i, v in enumerate(values):
            if v in values[:i]:
                shown = v.value if isinstance(v, Side) else v
                raise ConfigError(f"Expected a different {field} for each arm", path=path, key=f"arms[{i}].{field}",
                                  value=shown)  # fmt: skip
    return Rig(name, arms, path)


def _rig_arm(entry: object, key: str, path: Path, loaded: dict[str | Path, Arm]) -> RigArm:
    table = _table(entry, key, _ARM_KEYS, path, required=("name", "arm", "xyz", "side"))
    name = _string(table["name"], f"{key}.name", path)
    if not _NAME.match(name):
        raise ConfigError("Expected a name of letters, digits, _ and - (at most 32)", path=path, key=f"{key}.name",
                          value=name)  # fmt: skip
    arm = _arm(_string(table["arm"], f"{key}.arm", path), f"{key}.arm", path, loaded)
    xyz = _vector(table["xyz"], f"{key}.xyz", path, MAX_OFFSET)
    rpy = tuple(math.radians(v) for v in _vector(table.get("rpy", [0.0, 0.0, 0.0]), f"{key}.rpy", path, 360.0))
    port = _string(table.get("port", f"sim://{arm.name}"), f"{key}.port", path)
    side_text = _string(table["side"], f"{key}.side", path)
    try:
        side = Side(side_text)
    except ValueError:
        raise ConfigError("Expected 'left' or 'right'", path=path, key=f"{key}.side", value=side_text) from None
    return RigArm(name, arm, Placement(xyz, (rpy[0], rpy[1], rpy[2])), port, side)


def _arm(text: str, key: str, path: Path, loaded: dict[str | Path, Arm]) -> Arm:
    """The arm by bundled name, or by a path relative to the rig file (from ``loaded`` when read already)."""
    target: str | Path = text
    if "/" in text or "\\" in text or text.endswith((".toml", ".urdf", ".xml")):
        target = (path.parent / text).resolve()
    if target in loaded:
        return loaded[target]
    try:
        loaded[target] = load_arm(target)
        return loaded[target]
    except ConfigError as exc:
        if exc.path is None:  # a bare name that is not bundled: say where in the rig
            raise ConfigError(exc.message, path=path, key=key, value=text) from exc
        raise


def _table(value: object, key: str, allowed: set[str], path: Path, required: tuple[str, ...] = ()) -> dict[str, Any]:
    if not isinstance(value, dict):
        raise ConfigError("Expected a table", path=path, key=key, value=value)
    for k in value:
        if k not in allowed:
            raise ConfigError(f"Expected one of {', '.join(sorted(allowed))}", path=path, key=f"{key}.{k}")
    for k in required:
        if k not in value:
            raise ConfigError("Expected this key", path=path, key=f"{key}.{k}")
    return value


def _string(value: object, key: str, path: Path) -> str:
    if not isinstance(value, str) or not value:
        raise ConfigError("Expected a non-empty string", path=path, key=key, value=value)
    return value


def _vector(value: object, key: str, path: Path, bound: float) -> tuple[float, float, float]:
    numbers: list[float] = []
    if isinstance(value, list) and len(value) == 3:
        numbers = [float(v) for v in value if isinstance(v, int | float) and not isinstance(v, bool)]
    if len(numbers) != 3 or not all(math.isfinite(v) and abs(v) <= bound for v in numbers):
        raise ConfigError(f"Expected 3 numbers within +-{bound:g}", path=path, key=key, value=value)
    return (numbers[0], numbers[1], numbers[2])
