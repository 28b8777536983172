"""The mapping's configuration: the ``[mapping]`` table of an arm description, parsed and validated.

:class:`MappingConfig` says how human motion maps onto one arm (which human arm drives it, the body
and robot frames, scale, origin, workspace fractions, IK joint weights); :class:`Side` and
:class:`Axis` are its enums.  Build it with :meth:`MappingConfig.from_table` from the raw TOML table
(errors are ``ConfigError`` with the file path and ``mapping.<key>``), and apply CLI flags with
``overrides`` or :meth:`MappingConfig.with_overrides`.  The math that uses it is in the other modules of
:mod:`retarget.mapping` (body frames, the arm's workspace, the targets).

The ``[mapping]`` table of an arm file (every key optional; CLI flags override)::

    [mapping]
    side = "right"                # the human arm that drives the robot: left | right
    forward = "auto"              # body forward: auto (torso, per frame) | +z | -z | +x | -x
    up = "+y"                     # the BVH up axis
    robot_forward = "auto"        # the robot's forward in its base frame: auto (home pose) | +x | -x | +y | -y
    arm_scale = 0.4               # human arm length -> this fraction of the robot's reach
    origin = [0.2, 0.0, 0.36]     # metres, base frame, where the shoulder lands (default: from the reach)
    max_reach = 0.95              # workspace shell around the shoulder pivot, fractions of the reach
    min_reach = 0.2
    floor = 0.03                  # lowest target height, metres
    orientation_weight = 0.0      # > 0: follow the hand's orientation too
    joint_weights = { forearm_roll = 0.001 }   # IK weights by joint (or a list, one per joint)
    cutoff_hz = "auto"            # zero-phase low-pass of a clip's targets (no lag, -6 dB at the cutoff): "auto"
                                  # (from the clip's noise), Hz, or 0 = off

This module is math only (it imports neither drivers, sim nor serial).
"""

from __future__ import annotations

import enum
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields, replace
from os import PathLike
from typing import Any

import numpy as np

from retarget.errors import ConfigError
from retarget.mapping.filter import AUTO, DEFAULT_CUTOFF, Cutoff

__all__ = ["Axis", "MappingConfig", "Side"]


class Side(enum.Enum):
    LEFT = "left"
    RIGHT = "right"


class Axis(enum.Enum):
    """A signed axis of the BVH world, or ``AUTO`` (detect from the skeleton)."""

    AUTO = "auto"
    PX = "+x"
    NX = "-x"
    PY = "+y"
    NY = "-y"
    PZ = "+z"
    NZ = "-z"

    @property
    def vector(self) -> np.ndarray:
        """``(3,)`` unit vector; ``AUTO`` has none."""
        if self is Axis.AUTO:
            raise ValueError("Axis.AUTO has no vector")
        v = np.zeros(3)
        v["xyz".index(self.value[1])] = 1.0 if self.value[0] == "+" else -1.0
        return v


_FORWARD_CHOICES = ("auto", "+x", "-x", "+z", "-z", "+y", "-y")
_UP_CHOICES = ("+y", "-y", "+z", "-z", "+x", "-x")
_ROBOT_FORWARD_CHOICES = ("auto", "+x", "-x", "+y", "-y")


@dataclass(frozen=True, kw_only=True)
class MappingConfig:
    """How human motion maps onto one arm.  Build with :meth:`from_table`; all fields keyword-only.

    Lengths are metres in the robot base frame; fractions are of the robot's
    reach from its shoulder pivot (see :func:`arm_geometry`).
    """

    side: Side = Side.RIGHT  #: which human arm drives the robot
    forward: Axis = Axis.AUTO  #: body forward: AUTO = per frame from the torso; else a fixed BVH axis
    up: Axis = Axis.PY  #: BVH up axis, used with a fixed ``forward`` and for the hand orientation
    #: the robot's forward in its base frame: AUTO = where the arm points at home; or +x, -x, +y, -y
    robot_forward: Axis = Axis.AUTO
    arm_scale: float = 0.4  #: the human's full arm length maps to this fraction of the robot's reach
    #: where the shoulder lands; None = ``retarget.mapping.workspace.default_origin``
    origin: tuple[float, float, float] | None = None
    max_reach: float = 0.95  #: outer radius of the workspace shell, fraction of reach
    min_reach: float = 0.2  #: inner radius, fraction of reach
    floor: float = 0.03  #: lowest target z, metres above the base frame origin
    orientation_weight: float = 0.0  #: 0 = position only; > 0 also targets the tool orientation
    #: IK per-joint weights in (0, 1]: ``{joint: w}`` overriding the defaults (see :func:`ik_weights`), or all of them
    joint_weights: tuple[tuple[str, float], ...] | tuple[float, ...] | None = None
    #: Hz, the zero-phase low-pass of a clip's mapped targets before the workspace clamp (no lag, -6 dB at the
    #: cutoff; :func:`~retarget.mapping.filter.zero_phase`); 0 = unfiltered; ``"auto"``: chosen from the clip's
    #: noise (:func:`~retarget.mapping.cutoff.auto_cutoff`)
    cutoff_hz: Cutoff = DEFAULT_CUTOFF

    def __post_init__(self) -> None:
        for f in fields(self):
            _check(f.name, getattr(self, f.name), key=f"mapping.{f.name}", path=None)
        if self.min_reach >= self.max_reach:
            raise ConfigError(
                f"Expected min_reach < max_reach ({self.max_reach})", key="mapping.min_reach", value=self.min_reach
            )

    @classmethod
    def from_table(
        cls,
        table: Mapping[str, Any] | None,
        *,
        path: str | PathLike[str] | None = None,
        overrides: Mapping[str, Any] | None = None,
    ) -> MappingConfig:
        """Parse the raw ``[mapping]`` TOML table of an arm file, then apply ``overrides``.

        ``table``: the table as read (``Arm.mapping``; None or empty: every default).  ``path``: the
        arm file, named in errors.  ``overrides``: the same keys from CLI flags, applied after the
        table (``None`` values are skipped).  Values are taken as TOML and the CLI spell them:
        ``"left"``, ``"+z"`` or ``"z"``, numbers, ``origin`` as 3 numbers or ``"x,y,z"`` (metres,
        base frame), ``joint_weights`` as ``{joint = w}`` or one number per joint; the keys, units and
        defaults are in the module docstring.

        Returns the validated, frozen config.  Raises :class:`~retarget.errors.ConfigError` with
        ``key="mapping.<name>"`` and the file ``path`` for an unknown key, a bad value, or
        ``min_reach >= max_reach``.

        >>> config = MappingConfig.from_table({"side": "left", "forward": "z", "arm_scale": 0.5})
        >>> config.side, config.forward, config.arm_scale
        (<Side.LEFT: 'left'>, <Axis.PZ: '+z'>, 0.5)
        >>> MappingConfig.from_table({"side": "left"}, overrides={"side": "right", "floor": None}).side
        <Side.RIGHT: 'right'>
        >>> MappingConfig.from_table({"max_reach": 2}, path="arms/my_arm.toml")
        Traceback (most recent call last):
        ...
        retarget.errors.ConfigError: arms/my_arm.toml: mapping.max_reach: Expected a fraction in (0, 1] (got 2.0)
        """
        known = {f.name for f in fields(cls)}
        values: dict[str, Any] = {}
        for source, where in ((table or {}, path), (overrides or {}, None)):
            for name, raw in source.items():
                if raw is None and source is overrides:
                    continue
                if name not in known:
                    raise ConfigError(
                        f"unknown key; expected one of {', '.join(sorted(known))}", path=where, key=f"mapping.{name}"
                    )
                values[name] = _convert(name, raw, key=f"mapping.{name}", path=where)
        try:
            return cls(**values)
        except ConfigError as exc:
            if path is None or exc.path is not None:
                raise
            raise ConfigError(exc.message, path=path, key=exc.key, value=exc.value) from exc

    def with_overrides(self, **overrides: Any) -> MappingConfig:
        """A copy with the given fields replaced (``None`` values skipped), validated."""
        values = {k: _convert(k, v, key=f"mapping.{k}", path=None) for k, v in overrides.items() if v is not None}
        return replace(self, **values)


def _convert(name: str, raw: Any, *, key: str, path: str | PathLike[str] | None) -> Any:
    """A TOML/CLI value -> the field's type, or ConfigError."""
    try:
        if name == "side":
            return raw if isinstance(raw, Side) else Side(str(raw).lower())
        if name in ("forward", "up", "robot_forward"):
            if isinstance(raw, Axis):
                return raw
            text = str(raw).lower()
            if text in ("x", "y", "z"):
                text = "+" + text
            choices = {"forward": _FORWARD_CHOICES, "up": _UP_CHOICES, "robot_forward": _ROBOT_FORWARD_CHOICES}[name]
            if text not in choices:
                raise ValueError
            return Axis(text)
        if name == "joint_weights":
            items: tuple[tuple[str, float], ...] | tuple[float, ...]
            values: Sequence[float]
            if isinstance(raw, Mapping):
                items = tuple((str(k), float(v)) for k, v in raw.items())
                values = [v for _, v in items]
            else:
                items = values = tuple(float(v) for v in (raw.split(",") if isinstance(raw, str) else raw))
            if not values or not all(0 < v <= 1 for v in values):
                raise ValueError
            return items
        if name == "origin":
            if isinstance(raw, str):
                raw = raw.split(",")
            if isinstance(raw, bool) or len(raw) != 3:
                raise ValueError
            return tuple(float(v) for v in raw)
        if name == "cutoff_hz" and isinstance(raw, str) and raw.strip().lower() == AUTO:
            return AUTO
        if isinstance(raw, bool):
            raise ValueError
        return float(raw)
    except (TypeError, ValueError):
        raise ConfigError(f"Expected {_EXPECTED[name]}", path=path, key=key, value=raw) from None


CUTOFF_RANGE = (0.1, 100.0)  #: Hz, the zero-phase cutoffs accepted (besides 0: off)

_EXPECTED = {
    "side": "'left' or 'right'",
    "forward": "one of " + ", ".join(_FORWARD_CHOICES),
    "up": "one of " + ", ".join(_UP_CHOICES),
    "robot_forward": "one of " + ", ".join(_ROBOT_FORWARD_CHOICES),
    "arm_scale": "a number > 0",
    "origin": "three numbers x,y,z in metres",
    "max_reach": "a fraction in (0, 1]",
    "min_reach": "a fraction in [0, 1)",
    "floor": "a finite number of metres",
    "orientation_weight": "a number >= 0",
    "joint_weights": "weights in (0, 1]: a table {joint = w} or one number per joint",
    "cutoff_hz": f"'auto', a cutoff from {CUTOFF_RANGE[0]:g} to {CUTOFF_RANGE[1]:g} Hz, or 0 (no filter)",
}


def _check(name: str, value: Any, *, key: str, path: str | PathLike[str] | None) -> None:
    ok = True
    if name == "side":
        ok = isinstance(value, Side)
    elif name in ("forward", "up"):
        ok = isinstance(value, Axis) and (name == "forward" or value is not Axis.AUTO)
    elif name == "robot_forward":
        ok = isinstance(value, Axis) and value.value in _ROBOT_FORWARD_CHOICES
    elif name == "origin":
        ok = value is None or (len(value) == 3 and all(math.isfinite(v) for v in value))
    elif name == "joint_weights":
        ok = value is None or isinstance(value, tuple)
    elif name == "cutoff_hz" and value == AUTO:
        ok = True
    else:
        ok = isinstance(value, int | float) and math.isfinite(value)
        if ok and name == "arm_scale":
            ok = value > 0
        elif ok and name == "max_reach":
            ok = 0 < value <= 1
        elif ok and name == "min_reach":
            ok = 0 <= value < 1
        elif ok and name == "orientation_weight":
            ok = value >= 0
        elif ok and name == "cutoff_hz":
            ok = value == 0 or CUTOFF_RANGE[0] <= value <= CUTOFF_RANGE[1]
    if not ok:
        raise ConfigError(f"Expected {_EXPECTED[name]}", path=path, key=key, value=value)
