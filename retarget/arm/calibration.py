"""Per-unit calibration of an arm: each servo's zero offset and direction, and the joint ranges measured by hand.

A bundled arm file is right for a factory arm; a hand-built Koch or OpenMANIPULATOR-X, or a WidowX with a replaced
servo, has its own zero and direction per servo.  ``retarget calibrate`` measures them and saves a
:class:`Calibration` per arm instance; :func:`apply_calibration` returns the arm with them::

    cal = load_calibration(default_calibration_path("koch"))
    arm = apply_calibration(load_arm("koch"), cal)    # a new Arm: servo offsets/directions, narrowed limits

The file (TOML, angles in degrees as in the arm files; written by :func:`save_calibration`)::

    arm = "koch"                      # the arm file's name: applying it to another arm is an error
    name = "koch"                     # this instance's name (the file's stem by default)
    date = "2026-11-24T17:40:00+00:00"
    [[servos]]                        # one per joint servo (shadows too), base to tip
    id = 1
    joint = "shoulder_pan"
    offset = 37                       # pulses: the joint's 0 rad sits at 2048 + offset
    direction = -1                    # +1 normal, -1 reverse (Drive Mode bit 0)
    firmware = 46                     # Firmware Version (6) at calibration time (optional)
    [joints.shoulder_pan]             # optional, per joint
    measured = [-120.5, 118.0]        # the range seen while turning it by hand, degrees
    limits = [-120.5, 118.0]          # the narrowed limits to use (inside the arm file's), degrees

Every problem is a :class:`~retarget.errors.ConfigError` naming the file and the key path.

>>> from retarget.arm.load import load_arm
>>> arm = load_arm("koch")
>>> cal = Calibration(arm="koch", name="lab", date="2026-11-24",
...                   servos=tuple(ServoCalibration(s.id, j.name, 100, -1) for j in arm.joints for s in j.servos))
>>> calibrated = apply_calibration(arm, cal)
>>> calibrated.joints[0].servos[0]
Servo(id=1, model='XL430-W250', direction=-1, offset=100)
"""

from __future__ import annotations

import dataclasses
import json
import logging
import math
import os
import re
import sys
import tempfile
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from retarget.arm.config import ArmFileReader, read_toml
from retarget.arm.model import Arm, Joint, Servo
from retarget.errors import ConfigError

__all__ = [
    "Calibration",
    "JointCalibration",
    "ServoCalibration",
    "apply_calibration",
    "calibration_dir",
    "default_calibration_path",
    "load_calibration",
    "save_calibration",
]

log = logging.getLogger(__name__)

_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$")
_TOP_KEYS = {"arm", "name", "date", "servos", "joints"}
_SERVO_KEYS = {"id", "joint", "offset", "direction", "firmware", "model"}
_JOINT_KEYS = {"measured", "limits"}


@dataclass(frozen=True)
class ServoCalibration:
    """One servo's zero ``offset`` (pulses: 0 rad = 2048 + offset) and ``direction`` (+1/-1) on its ``joint``."""

    id: int
    joint: str
    offset: int
    direction: int = 1
    firmware: int | None = None  #: Firmware Version (6) when calibrated


@dataclass(frozen=True)
class JointCalibration:
    """A joint's range seen by hand (``measured``) and the limits to use (``limits``), radians, or None."""

    name: str
    measured: tuple[float, float] | None = None
    limits: tuple[float, float] | None = None


@dataclass(frozen=True)
class Calibration:
    """The calibration of one arm instance: servo offsets and directions, joint ranges, when it was made."""

    arm: str  #: the arm file's ``name``
    name: str  #: this instance's name (the file's stem by default)
    date: str  #: ISO 8601
    servos: tuple[ServoCalibration, ...]
    joints: tuple[JointCalibration, ...] = ()
    source: Path | None = None  #: the file it was loaded from

    def servo(self, dxl_id: int) -> ServoCalibration | None:
        return next((s for s in self.servos if s.id == dxl_id), None)

    def joint(self, name: str) -> JointCalibration | None:
        return next((j for j in self.joints if j.name == name), None)


def check_name(name: str, key: str = "name") -> str:
    """``name`` when it is a calibration name (letters, digits, ``_.-``, at most 64), else ConfigError."""
    if not _NAME.match(name):
        raise ConfigError("Expected a name of letters, digits, '_', '.', '-' (at most 64)", key=key, value=name)
    return name


def calibration_dir() -> Path:
    """The folder of saved calibrations: ``$XDG_CONFIG_HOME/retarget/calibration`` (``~/.config`` by default) on
    Linux, ``~/Library/Application Support/retarget/calibration`` on macOS, ``%APPDATA%\\retarget\\calibration``
    on Windows."""
    if sys.platform == "win32":
        base = Path(os.environ.get("APPDATA") or Path.home() / "AppData" / "Roaming")
    elif sys.platform == "darwin":
        base = Path.home() / "Library" / "Application Support"
    else:
        base = Path(os.environ.get("XDG_CONFIG_HOME") or Path.home() / ".config")
    return base / "retarget" / "calibration"


def default_calibration_path(name: str) -> Path:
    """Where the calibration of the arm instance ``name`` is saved by default: ``<calibration_dir()>/<name>.toml``.

    >>> default_calibration_path("koch").name
    'koch.toml'
    """
    return calibration_dir() / f"{check_name(name)}.toml"


# ---------------------------------------------------------------------------------------------------- reading


def load_calibration(path: str | os.PathLike[str]) -> Calibration:
    """Read a calibration file (the schema in the module docstring); ConfigError naming the file and key."""
    path = Path(path)
    if not path.is_file():
        raise ConfigError("calibration file not found", path=path)
    return _read(ArmFileReader(path), read_toml(path))


def _read(r: ArmFileReader, data: Mapping[str, Any]) -> Calibration:
    t = r.table(data, "", _TOP_KEYS, ("arm", "name", "date", "servos"))
    arm, name, date = r.string(t["arm"], "arm"), r.string(t["name"], "name"), r.string(t["date"], "date")
    if not _NAME.match(name):
        raise r.error("Expected a name of letters, digits, '_', '.', '-' (at most 64)", "name", name)
    raw = t["servos"]
    if not isinstance(raw, list) or not raw:
        raise r.error("expected a non-empty list of [[servos]] tables", "servos", raw)
    servos = []
    seen: set[int] = set()
    for i, v in enumerate(raw):
        key = f"servos[{i}]"
        s = r.table(v, key, _SERVO_KEYS, ("id", "joint", "offset"))
        sid = r.integer(s["id"], f"{key}.id", 0, 252)
        if sid in seen:
            raise r.error("duplicate servo ID", f"{key}.id", sid)
        seen.add(sid)
        direction = s.get("direction", 1)
        if direction not in (1, -1) or isinstance(direction, bool):
            raise r.error("direction must be 1 (normal) or -1 (reverse)", f"{key}.direction", direction)
        firmware = r.integer(s["firmware"], f"{key}.firmware", 0, 255) if "firmware" in s else None
        offset = r.integer(s["offset"], f"{key}.offset", -2048, 2048)
        servos.append(ServoCalibration(sid, r.string(s["joint"], f"{key}.joint"), offset, int(direction), firmware))
    joints_raw = t.get("joints", {})
    if not isinstance(joints_raw, Mapping):
        raise r.error("expected a table of joint tables", "joints", joints_raw)
    joints = []
    for jname, v in joints_raw.items():
        key = f"joints.{jname}"
        j = r.table(v, key, _JOINT_KEYS)
        measured = r.limits(j["measured"], f"{key}.measured") if "measured" in j else None
        limits = r.limits(j["limits"], f"{key}.limits") if "limits" in j else None
        joints.append(JointCalibration(jname, measured, limits))
    return Calibration(arm, name, date, tuple(servos), tuple(joints), source=r.path)


# ---------------------------------------------------------------------------------------------------- writing


def _q(text: str) -> str:
    """A TOML basic string (JSON's escapes are TOML's)."""
    return json.dumps(text, ensure_ascii=False)


def _deg_pair(pair: tuple[float, float]) -> str:
    return f"[{math.degrees(pair[0]):.4f}, {math.degrees(pair[1]):.4f}]"


def dumps_calibration(cal: Calibration) -> str:
    """The TOML text of ``cal`` (what :func:`save_calibration` writes)."""
    lines = [
        "# retarget calibration of one arm instance (written by `retarget calibrate`; schema in",
        "# retarget/arm/calibration.py).  Offsets in pulses (0 rad = 2048 + offset), angles in degrees.",
        f"arm = {_q(cal.arm)}",
        f"name = {_q(cal.name)}",
        f"date = {_q(cal.date)}",
    ]
    for s in cal.servos:
        lines += ["", "[[servos]]", f"id = {s.id}", f"joint = {_q(s.joint)}", f"offset = {s.offset}"]
        lines.append(f"direction = {s.direction}")
        if s.firmware is not None:
            lines.append(f"firmware = {s.firmware}")
    for j in cal.joints:
        if j.measured is None and j.limits is None:
            continue
        lines += ["", f"[joints.{_q(j.name)}]"]
        if j.measured is not None:
            lines.append(f"measured = {_deg_pair(j.measured)}")
        if j.limits is not None:
            lines.append(f"limits = {_deg_pair(j.limits)}")
    return "\n".join(lines) + "\n"


def save_calibration(cal: Calibration, path: str | os.PathLike[str]) -> Path:
    """Write ``cal`` to ``path`` atomically (a temporary file in the same folder, then a rename): an interrupted
    save leaves the old file or none, never half of one.  Creates the folder.  Returns the path.

    >>> import tempfile, pathlib
    >>> cal = Calibration("koch", "lab", "2026-11-24", (ServoCalibration(1, "shoulder_pan", 12, -1, 46),))
    >>> with tempfile.TemporaryDirectory() as d:
    ...     load_calibration(save_calibration(cal, pathlib.Path(d) / "lab.toml")).servos
    (ServoCalibration(id=1, joint='shoulder_pan', offset=12, direction=-1, firmware=46),)
    """
    path = Path(path)
    text = dumps_calibration(cal)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


# ---------------------------------------------------------------------------------------------------- applying


def apply_calibration(arm: Arm, cal: Calibration) -> Arm:
    """A new :class:`Arm`: every servo's offset and direction from ``cal``, each joint's limits narrowed to
    ``cal``'s (never widened), the poses clipped into them.  ConfigError (naming ``cal``'s file and key) for a
    calibration of another arm, a servo of the arm it lacks or one the arm lacks, a joint it names wrongly."""
    where = cal.source

    def error(message: str, key: str, value: object = None) -> ConfigError:
        if value is None:
            return ConfigError(message, path=where, key=key)
        return ConfigError(message, path=where, key=key, value=value)

    if cal.arm != arm.name:
        raise error(f"Expected a calibration of arm {arm.name!r}, got one of {cal.arm!r}", "arm")
    by_id = {s.id: (i, s) for i, s in enumerate(cal.servos)}
    arm_ids = {s.id: j.name for j in arm.joints for s in j.servos}
    if arm.gripper is not None:
        arm_ids[arm.gripper.servo.id] = arm.gripper.name
    for i, s in enumerate(cal.servos):
        if s.id not in arm_ids:
            raise error(f"servo {s.id} is not a servo of arm {arm.name!r}", f"servos[{i}].id", s.id)
        if s.joint != arm_ids[s.id]:
            raise error(f"Expected servo {s.id} on joint {arm_ids[s.id]!r}", f"servos[{i}].joint", s.joint)
    names = set(arm.joint_names)
    for j in cal.joints:
        if j.name not in names:
            raise error(f"no joint {j.name!r} in arm {arm.name!r}", f"joints.{j.name}")

    def servo(s: Servo, joint: str) -> Servo:
        found = by_id.get(s.id)
        if found is None:
            raise error(f"no entry for servo {s.id} of joint {joint!r}: run retarget calibrate again", "servos")
        c = found[1]
        return dataclasses.replace(s, offset=c.offset, direction=c.direction)

    joints: list[Joint] = []
    for joint in arm.joints:
        lo, hi = joint.lower, joint.upper
        jc = cal.joint(joint.name)
        if jc is not None and jc.limits is not None:
            lo, hi = max(lo, jc.limits[0]), min(hi, jc.limits[1])
            if not lo < hi:
                raise error(f"limits outside the arm file's for joint {joint.name!r}", f"joints.{joint.name}.limits")
        joints.append(_joint(joint, lo, hi, tuple(servo(s, joint.name) for s in joint.servos)))
    gripper = arm.gripper
    if gripper is not None and gripper.servo.id in by_id:
        gripper = dataclasses.replace(gripper, servo=servo(gripper.servo, gripper.name))
    lower = np.array([j.lower for j in joints])
    upper = np.array([j.upper for j in joints])
    poses = {name: np.clip(getattr(arm, name), lower, upper) for name in ("home", "rest", "calibration_pose")}
    return dataclasses.replace(arm, joints=tuple(joints), gripper=gripper, **poses)


def _joint(j: Joint, lower: float, upper: float, servos: tuple[Servo, ...]) -> Joint:
    return dataclasses.replace(j, lower=lower, upper=upper, servos=servos)
