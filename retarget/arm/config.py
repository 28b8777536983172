"""Load arm descriptions: bundled TOML files, user TOML files and URDF + servo TOML.

``load_arm("wx250s")`` resolves a bare name to the bundled ``config/arms/wx250s.toml``
(installed: ``retarget/_config/arms``; source checkout: ``<repo>/config/arms``).
``load_arm("my_arm.toml")`` reads a user file; ``load_arm("robot.urdf", base=..., tip=...)``
imports a URDF chain with its servo file beside it (see :mod:`retarget.arm.urdf`).

TOML schema (every angle in the file is in DEGREES, lengths in metres; the loaded
:class:`~retarget.arm.Arm` holds radians)::

    name = "wx250s"                   # required, the arm's short name
    title = "WidowX-250 6DOF"         # optional, human name
    baud = 1_000_000                  # optional, bus baud rate (default 1 Mbps)

    [tool]                            # the tool point in the last joint's child frame
    link = "ee_gripper_link"          # optional, documentary: the URDF link it stands for
    xyz = [0.093575, 0.0, 0.0]        # metres
    rpy = [0.0, 0.0, 0.0]             # optional, degrees (URDF roll-pitch-yaw)

    [poses]
    home = [0, 0, 0, 0, 0, 0]         # required, degrees, one per joint, inside the limits
    rest = [0, -103.1, 88.8, 0, 45.8, 0]  # optional (default: home), the "sleep" pose
    calibration = [0, 0, 0, 0, 0, 0]  # optional (default: home), the reference pose of `retarget calibrate`

    requires_calibration = false      # optional: true = a real port needs a `retarget calibrate` file first
    calibrate_directions = false      # optional: true = `retarget calibrate` also finds each servo's direction

    [[joints]]                        # one table per joint, base to tip
    name = "waist"                    # required, unique
    type = "revolute"                 # optional, the only type
    xyz = [0.0, 0.0, 0.072]           # required, origin parent -> joint frame, metres
    rpy = [0.0, 0.0, 0.0]             # optional, degrees
    axis = [0, 0, 1]                  # required, in the joint frame, any non-zero length
    limits = [-180, 180]              # required, [lower, upper] degrees, lower < upper
    max_velocity = 180                # required, degrees per second, > 0
    max_acceleration = 2500           # optional, degrees per second^2 (default 2500: 180 deg/s in 72 ms)
    calibration_hint = "upper arm vertical"   # optional: how to set it for the calibration pose
    servos = [                        # required, primary first, then shadows
        { id = 2, model = "XM430-W350" },
        { id = 3, model = "XM430-W350", direction = -1 },   # direction +1/-1, offset ticks
    ]

    [gripper]                         # optional: driven on its own, outside IK
    name = "gripper"                  # optional
    servo = { id = 9, model = "XL430-W250" }
    limits = [-21.7, 72.7]            # required, degrees of the servo shaft
    closed = "lower"                  # optional: which limit is closed (default "lower")
    current_limit = 650               # optional, mA: current-based position mode (5) with this limit
    pwm_limit = 28.2                  # optional, % of full duty: the PWM Limit (caps the output in every mode)

    [mapping]                         # optional, any keys: read by retarget.mapping.config

    [collision]                       # optional: link shapes and allowed pairs (retarget.arm.geometry)
    allowed = [["gripper", "upper_arm"]]
    [[collision.links]]
    name = "upper_arm"
    frame = "shoulder"                # "base" or the joint whose child frame carries the shape
    capsule = { a = [0, 0, 0.04], b = [0.05, 0, 0.25], radius = 0.03 }   # or box (base only), sphere

    [world]                           # optional: table = true, keep_out = [{ box = {...} }, { sphere = {...} }]

A servo table has ``id`` (0-252, unique over the arm), ``model`` (one of
``retarget.arm.SERVO_MODELS``), ``direction`` (+1 normal, -1 reverse; default +1) and
``offset`` (zero offset in ticks, -2048..2048, default 0: 0 rad = 2048 + offset ticks).

Every number has a physical range, so that an arm file this reader accepts also
runs (``MAX_LENGTH``, ``MAX_ANGLE``, ``MIN_VELOCITY``/``MAX_VELOCITY``,
``SUPPORTED_BAUDS``):

- lengths (``xyz`` of joints and tool): each coordinate within +-10 m;
- angles (``rpy``, ``limits``, gripper ``limits``, poses): within +-360 degrees;
- ``max_velocity``: 0.1 to 1000 deg/s (the fastest supported servo, the XL330-M288, turns
  at 618 deg/s without load);
- ``max_acceleration``: 1 to 100000 deg/s^2; default 2500 (``retarget.arm.model.DEFAULT_MAX_ACCELERATION``,
  where its source is given);
- ``baud``: one the servos and dynamixel-sdk support: 9600, 57600, 115200, 1, 2, 3
  or 4 Mbps (``retarget.arm.model.SUPPORTED_BAUDS``; not 4.5 Mbps, which the SDK
  refuses and the XL330-M288 lacks);
- ``axis``: any finite non-zero vector (its length is computed without overflow).

Every problem is a :class:`~retarget.errors.ConfigError` naming the file, the key
path (``joints[2].limits``) and the bad value: unknown keys, missing keys, wrong
types, unknown servo models, ``lower >= upper``, duplicate servo IDs, a zero axis,
a pose outside the limits, a number outside its range, TOML syntax errors (with the line).
"""

from __future__ import annotations

import math
import re
import tomllib
from collections.abc import Iterable, Mapping
from os import PathLike
from pathlib import Path
from typing import Any, TypeGuard

import numpy as np

from retarget.arm.geometry import read_collision, read_world
from retarget.arm.model import (
    DEFAULT_MAX_ACCELERATION,
    MAX_CURRENT_LIMIT_MA,
    SERVO_MODELS,
    SUPPORTED_BAUDS,
    Arm,
    Gripper,
    Joint,
    JointType,
    Servo,
)
from retarget.errors import ConfigError

_ACCEL_DEG = math.degrees(DEFAULT_MAX_ACCELERATION)  #: deg/s^2, a joint's max_acceleration when unset

__all__ = ["URDF_SUFFIXES", "ArmFileReader", "arm_dirs", "is_urdf", "list_arms", "read_toml", "resolve_arm"]

#: Suffixes that make ``load_arm`` treat its argument as a path: a TOML arm file, or a URDF.
_TOML_SUFFIXES = (".toml",)
URDF_SUFFIXES = (".urdf", ".xml")

_TOP_KEYS = {"name", "title", "baud", "tool", "poses", "joints", "gripper", "mapping", "collision", "world"} | {
    "requires_calibration",
    "calibrate_directions",
}
_JOINT_KEYS = {"name", "type", "xyz", "rpy", "axis", "limits", "max_velocity", "servos", "calibration_hint"} | {
    "max_acceleration"
}
_SERVO_KEYS = {"id", "model", "direction", "offset"}
_GRIPPER_KEYS = {"name", "servo", "limits", "current_limit", "pwm_limit", "closed"}
_TOOL_KEYS = {"link", "xyz", "rpy"}
_POSE_KEYS = {"home", "rest", "calibration"}
_MISSING = object()

#: The physical ranges of an arm file's numbers (see the module notes).
MAX_LENGTH = 10.0  #: metres, each coordinate of an ``xyz``
MAX_ANGLE = 360.0  #: degrees, every angle (rpy, limits, poses)
MIN_VELOCITY, MAX_VELOCITY = 0.1, 1000.0  #: deg/s, ``max_velocity``
MIN_ACCELERATION, MAX_ACCELERATION = 1.0, 100_000.0  #: deg/s^2, ``max_acceleration``
DEFAULT_BAUD = 1_000_000


def arm_dirs() -> list[Path]:
    """The folders searched for bundled arms, in order: the installed copy, then the source checkout."""
    package = Path(__file__).resolve().parents[1]  # the retarget package
    return [package / "_config" / "arms", package.parent / "config" / "arms"]


def list_arms() -> list[str]:
    """Names of the bundled arms (the file stems), sorted."""
    names: set[str] = set()
    for folder in arm_dirs():
        if folder.is_dir():
            names.update(p.stem for p in folder.glob("*.toml"))
    return sorted(names)


def _looks_like_path(name: str | PathLike[str]) -> bool:
    text = str(name)
    return isinstance(name, PathLike) or "/" in text or "\\" in text or text.endswith(_TOML_SUFFIXES + URDF_SUFFIXES)


def is_urdf(path: str | PathLike[str]) -> bool:
    """True when ``path`` names a URDF file (by its suffix), which ``load_arm`` imports with its servo file."""
    return Path(path).suffix.lower() in URDF_SUFFIXES


def resolve_arm(name_or_path: str | PathLike[str]) -> Path:
    """The file of an arm: a path as given, or a bare name looked up in :func:`arm_dirs`."""
    if _looks_like_path(name_or_path):
        path = Path(name_or_path)
        if not path.is_file():
            raise ConfigError("arm description not found", path=path)
        return path
    name = str(name_or_path)
    for folder in arm_dirs():
        candidate = folder / f"{name}.toml"
        if candidate.is_file():
            return candidate
    known = ", ".join(list_arms()) or "none found"
    raise ConfigError(f"unknown arm {name!r}; known arms: {known} (or give a .toml or .urdf path)", key="arm")


def read_toml(path: Path) -> dict[str, Any]:
    """Parse a TOML file; syntax errors become a ConfigError with the line."""
    try:
        with open(path, "rb") as f:
            return tomllib.load(f)
    except tomllib.TOMLDecodeError as exc:
        m = re.search(r"\(at line (\d+), column (\d+)\)", str(exc))
        where = f"line {m.group(1)}" if m else None
        raise ConfigError(f"invalid TOML: {exc}", path=path, key=where) from exc
    except OSError as exc:
        raise ConfigError(f"cannot read: {exc.strerror or exc}", path=path) from exc


def _is_number(v: object) -> TypeGuard[int | float]:
    """A finite int or float (an int compared exactly: ``math.isfinite`` overflows on a huge TOML integer)."""
    if isinstance(v, bool):
        return False
    if isinstance(v, int):
        return -_FLOAT_MAX <= v <= _FLOAT_MAX
    return isinstance(v, float) and math.isfinite(v)


_FLOAT_MAX = 1.7976931348623157e308


class ArmFileReader:
    """Validating readers for the pieces of an arm file; every error names ``path`` and the key path.

    Also used by :mod:`retarget.arm.urdf` for its servo file.
    """

    def __init__(self, path: Path):
        self.path = path
        self.seen_ids: dict[int, str] = {}

    # -- primitives -----------------------------------------------------------------------------------------------
    def error(self, message: str, key: str, value: object = _MISSING) -> ConfigError:
        if value is _MISSING:
            return ConfigError(message, path=self.path, key=key)
        return ConfigError(message, path=self.path, key=key, value=value)

    def table(self, value: object, key: str, allowed: Iterable[str], required: Iterable[str] = ()) -> Mapping[str, Any]:
        if not isinstance(value, Mapping):
            raise self.error("expected a table", key, value)
        allowed = set(allowed)
        for k in value:
            if k not in allowed:
                raise self.error(f"unknown key {k!r}; expected one of {', '.join(sorted(allowed))}", _join(key, k))
        for k in required:
            if k not in value:
                raise self.error("missing required key", _join(key, k))
        return value

    def number(self, value: object, key: str, *, positive: bool = False) -> float:
        if not _is_number(value):
            raise self.error("expected a finite number", key, value)
        if positive and value <= 0:
            raise self.error("expected a number > 0", key, value)
        return float(value)

    def velocity(self, value: object, key: str) -> float:
        """A ``max_velocity`` in deg/s, ``MIN_VELOCITY..MAX_VELOCITY``, as rad/s."""
        deg = self.number(value, key, positive=True)
        if not MIN_VELOCITY <= deg <= MAX_VELOCITY:
            raise self.error(f"expected a velocity from {MIN_VELOCITY:g} to {MAX_VELOCITY:g} deg/s", key, value)
        return math.radians(deg)

    def acceleration(self, value: object, key: str) -> float:
        """A ``max_acceleration`` in deg/s^2, ``MIN_ACCELERATION..MAX_ACCELERATION``, as rad/s^2."""
        deg = self.number(value, key, positive=True)
        if not MIN_ACCELERATION <= deg <= MAX_ACCELERATION:
            message = f"expected an acceleration from {MIN_ACCELERATION:g} to {MAX_ACCELERATION:g} deg/s^2"
            raise self.error(message, key, value)
        return math.radians(deg)

    def baud(self, value: object, key: str = "baud") -> int:
        """A bus baud rate the servos support (``SUPPORTED_BAUDS``)."""
        if not isinstance(value, int) or isinstance(value, bool):
            raise self.error("expected an integer", key, value)
        if value not in SUPPORTED_BAUDS:
            rates = ", ".join(str(b) for b in SUPPORTED_BAUDS)
            raise self.error(f"expected a baud rate the servos and dynamixel-sdk support: {rates}", key, value)
        return value

    def integer(self, value: object, key: str, lo: int, hi: int) -> int:
        if not isinstance(value, int) or isinstance(value, bool):
            raise self.error("expected an integer", key, value)
        if not lo <= value <= hi:
            raise self.error(f"expected an integer in {lo}..{hi}", key, value)
        return value

    def string(self, value: object, key: str) -> str:
        if not isinstance(value, str) or not value:
            raise self.error("expected a non-empty string", key, value)
        return value

    def _numbers(self, value: object, key: str, n: int) -> list[int | float]:
        """``value`` itself when it is a list of ``n`` finite numbers (as written: ints stay ints)."""
        if not isinstance(value, list) or len(value) != n or not all(_is_number(v) for v in value):
            raise self.error(f"expected a list of {n} numbers", key, value)
        return value

    def vector(
        self, value: object, key: str, n: int = 3, *, bound: float | None = None, unit: str = ""
    ) -> tuple[float, ...]:
        """``n`` finite numbers, each within ``+-bound`` when given."""
        numbers = self._numbers(value, key, n)
        if bound is not None and not all(abs(v) <= bound for v in numbers):
            raise self.error(f"expected numbers from {-bound:g} to {bound:g}{unit}", key, value)
        return tuple(float(v) for v in numbers)

    def xyz(self, value: object, key: str) -> tuple[float, float, float]:
        """A point or offset: a list of 3 numbers (metres, each within ``MAX_LENGTH``)."""
        x, y, z = self.vector(value, key, bound=MAX_LENGTH, unit=" m")
        return (x, y, z)

    def degrees3(self, value: object, key: str) -> tuple[float, float, float]:
        x, y, z = self.vector(value, key, bound=MAX_ANGLE, unit=" deg")
        return (math.radians(x), math.radians(y), math.radians(z))

    def axis(self, value: object, key: str) -> tuple[float, float, float]:
        x, y, z = self.vector(value, key)
        norm = math.hypot(x, y, z)  # no overflow for huge components, no underflow to 0 for tiny ones
        if not 1e-9 <= norm < math.inf:
            raise self.error("joint axis has zero length", key, value)
        return (x / norm, y / norm, z / norm)

    def limits(self, value: object, key: str) -> tuple[float, float]:
        lo, hi = self.vector(value, key, 2, bound=MAX_ANGLE, unit=" deg")
        if lo >= hi:
            raise self.error("lower limit must be below upper limit", key, value)
        return math.radians(lo), math.radians(hi)

    # -- pieces ---------------------------------------------------------------------------------------------------
    def servo(self, value: object, key: str) -> Servo:
        t = self.table(value, key, _SERVO_KEYS, ("id", "model"))
        sid = self.integer(t["id"], f"{key}.id", 0, 252)
        model = t["model"]
        if model not in SERVO_MODELS:
            raise self.error(f"unknown servo model; known models: {', '.join(SERVO_MODELS)}", f"{key}.model", model)
        direction = t.get("direction", 1)
        if direction not in (1, -1) or isinstance(direction, bool):
            raise self.error("direction must be 1 (normal) or -1 (reverse)", f"{key}.direction", direction)
        offset = self.integer(t.get("offset", 0), f"{key}.offset", -2048, 2048)
        if sid in self.seen_ids:
            raise self.error(f"duplicate servo ID (also {self.seen_ids[sid]})", f"{key}.id", sid)
        self.seen_ids[sid] = f"{key}.id"
        return Servo(id=sid, model=model, direction=int(direction), offset=offset)

    def servos(self, value: object, key: str) -> tuple[Servo, ...]:
        if not isinstance(value, list) or not value:
            raise self.error("expected a non-empty list of servo tables", key, value)
        return tuple(self.servo(v, f"{key}[{i}]") for i, v in enumerate(value))

    def gripper(self, value: object, key: str = "gripper") -> Gripper:
        t = self.table(value, key, _GRIPPER_KEYS, ("servo", "limits"))
        name = self.string(t.get("name", "gripper"), f"{key}.name")
        servo = self.servo(t["servo"], f"{key}.servo")
        lo, hi = self.limits(t["limits"], f"{key}.limits")
        current = None
        if "current_limit" in t:
            current = self.number(t["current_limit"], f"{key}.current_limit", positive=True)
            top = MAX_CURRENT_LIMIT_MA[servo.model]
            if top is None:
                message = f"{servo.model} has no current sensing: use pwm_limit"
                raise self.error(message, f"{key}.current_limit", current)
            if current > top:
                raise self.error(f"expected at most {top:.0f} mA for {servo.model}", f"{key}.current_limit", current)
        pwm = self.number(t["pwm_limit"], f"{key}.pwm_limit", positive=True) if "pwm_limit" in t else None
        if pwm is not None and pwm > 100.0:
            raise self.error("expected a percentage of full duty, 0 < pwm_limit <= 100", f"{key}.pwm_limit", pwm)
        closed = self.string(t.get("closed", "lower"), f"{key}.closed")
        if closed not in ("lower", "upper"):
            raise self.error('expected "lower" or "upper"', f"{key}.closed", closed)
        return Gripper(name, servo, lo, hi, current_limit=current, pwm_limit=pwm, closed=closed)

    def poses(
        self, value: object, joints: tuple[Joint, ...], key: str = "poses"
    ) -> tuple[tuple[float, ...], tuple[float, ...]]:
        t = self.table(value, key, _POSE_KEYS, ("home",))
        home = self.pose(t["home"], f"{key}.home", joints)
        rest = self.pose(t["rest"], f"{key}.rest", joints) if "rest" in t else home
        return home, rest

    def calibration_pose(self, value: object, joints: tuple[Joint, ...], key: str = "poses") -> tuple[float, ...]:
        """``[poses] calibration`` (default: home), the reference pose of ``retarget calibrate``."""
        t = self.table(value, key, _POSE_KEYS, ("home",))
        return self.pose(t.get("calibration", t["home"]), f"{key}.calibration", joints)

    def flag(self, value: object, key: str) -> bool:
        if not isinstance(value, bool):
            raise self.error("expected true or false", key, value)
        return value

    def pose(self, value: object, key: str, joints: tuple[Joint, ...]) -> tuple[float, ...]:
        raw = self._numbers(value, key, len(joints))
        pose = tuple(math.radians(float(v)) for v in raw)
        for i, (a, j) in enumerate(zip(pose, joints, strict=True)):
            if not j.lower - 1e-9 <= a <= j.upper + 1e-9:
                raise self.error(
                    f"outside the limits of joint {j.name!r} "
                    f"[{math.degrees(j.lower):g}, {math.degrees(j.upper):g}] deg",
                    f"{key}[{i}]",
                    raw[i],
                )
        return tuple(min(max(a, j.lower), j.upper) for a, j in zip(pose, joints, strict=True))

    def mapping(self, value: object, key: str = "mapping") -> dict[str, Any]:
        if not isinstance(value, Mapping):
            raise self.error("expected a table", key, value)
        return dict(value)

    def joint(self, value: object, key: str) -> Joint:
        t = self.table(value, key, _JOINT_KEYS, ("name", "xyz", "axis", "limits", "max_velocity", "servos"))
        name = self.string(t["name"], f"{key}.name")
        kind = t.get("type", "revolute")
        if kind != JointType.REVOLUTE.value:
            raise self.error("only 'revolute' joints are supported", f"{key}.type", kind)
        lo, hi = self.limits(t["limits"], f"{key}.limits")
        return Joint(
            name=name,
            origin_xyz=self.xyz(t["xyz"], f"{key}.xyz"),
            origin_rpy=self.degrees3(t.get("rpy", [0.0, 0.0, 0.0]), f"{key}.rpy"),
            axis=self.axis(t["axis"], f"{key}.axis"),
            lower=lo,
            upper=hi,
            max_velocity=self.velocity(t["max_velocity"], f"{key}.max_velocity"),
            max_acceleration=self.acceleration(t.get("max_acceleration", _ACCEL_DEG), f"{key}.max_acceleration"),
            servos=self.servos(t["servos"], f"{key}.servos"),
            calibration_hint=self.string(t["calibration_hint"], f"{key}.calibration_hint")
            if "calibration_hint" in t
            else "",
        )

    def arm(self, data: Mapping[str, Any]) -> Arm:
        """A whole arm file (the schema in the module docstring)."""
        t = self.table(data, "", _TOP_KEYS, ("name", "joints", "poses"))
        name = self.string(t["name"], "name")
        title = self.string(t.get("title", name), "title")
        baud = self.baud(t.get("baud", DEFAULT_BAUD))
        raw_joints = t["joints"]
        if not isinstance(raw_joints, list) or not raw_joints:
            raise self.error("expected at least one [[joints]] table", "joints", raw_joints)
        joints = tuple(self.joint(v, f"joints[{i}]") for i, v in enumerate(raw_joints))
        names: dict[str, int] = {}
        for i, j in enumerate(joints):
            if j.name in names:
                raise self.error(f"duplicate joint name (also joints[{names[j.name]}])", f"joints[{i}].name", j.name)
            names[j.name] = i
        tool = self.table(t.get("tool", {}), "tool", _TOOL_KEYS)
        if "link" in tool:
            self.string(tool["link"], "tool.link")
        tool_xyz = self.xyz(tool.get("xyz", [0.0, 0.0, 0.0]), "tool.xyz")
        tool_rpy = self.degrees3(tool.get("rpy", [0.0, 0.0, 0.0]), "tool.rpy")
        home, rest = self.poses(t["poses"], joints)
        gripper = self.gripper(t["gripper"]) if "gripper" in t else None
        return Arm(
            name=name,
            title=title,
            joints=joints,
            tool_xyz=tool_xyz,
            tool_rpy=tool_rpy,
            home=np.array(home, dtype=np.float64),
            rest=np.array(rest, dtype=np.float64),
            baud=baud,
            gripper=gripper,
            mapping=self.mapping(t.get("mapping", {})),
            source=self.path,
            geometry=read_collision(self, t["collision"], joints) if "collision" in t else None,
            world=read_world(self, t.get("world", {})),
            calibration_pose=np.array(self.calibration_pose(t["poses"], joints), dtype=np.float64),
            requires_calibration=self.flag(t.get("requires_calibration", False), "requires_calibration"),
            calibrate_directions=self.flag(t.get("calibrate_directions", False), "calibrate_directions"),
        )


def _join(key: str, sub: str) -> str:
    return f"{key}.{sub}" if key else sub
