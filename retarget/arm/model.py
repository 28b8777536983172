"""Arm descriptions: joints, limits, servos, tool point and poses.

An :class:`Arm` is a serial chain of revolute joints from the base frame to a
tool point.  Angles are radians and lengths metres everywhere in code; the
TOML files under ``config/arms/`` hold angles in degrees (see
``retarget.arm.config``; URDF import in ``retarget.arm.urdf``).  Instances are
frozen: build them with ``retarget.load_arm``.

    arm = retarget.load_arm("wx250s")
    T, points = arm.fk(arm.home)    # (4, 4) tool pose, (n_joints + 1, 3) joint origins + tool, metres
    arm.lower, arm.upper            # (n_joints,) radians
"""

from __future__ import annotations

import enum
import math
from collections.abc import Hashable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from retarget.arm.kinematics import Chain
from retarget.collision.shapes import Geometry, World

#: Servo models the arm descriptions may name; ``drivers.control_table`` holds their registers.
SERVO_MODELS: tuple[str, ...] = ("XL430-W250", "XM430-W350", "XL330-M288", "XM540-W270")
#: the highest gripper ``current_limit`` (mA) each model takes: its Current Limit register's maximum x its current
#: unit (e-Manual; tests/drivers check it against drivers.control_table); None: no current sensing (XL430)
MAX_CURRENT_LIMIT_MA: dict[str, float | None] = {
    "XL430-W250": None,
    "XM430-W350": 1193 * 2.69,
    "XL330-M288": 1750 * 1.0,
    "XM540-W270": 2047 * 2.69,
}

#: The bus baud rates (bps) the servos support, by their Baud Rate (8) register value 0..7: ROBOTIS e-Manual,
#: X series control table, Baud Rate (8) (``docs/en/dxl/x/xl430-w250.md`` and siblings; summarised in
#: ``shared/reference/dynamixel.md`` section 3).  Kept here, not imported from ``drivers`` (the arm layer knows
#: nothing above it); a test checks it equals ``drivers.control_table.BAUD_RATES``.
SERVO_BAUDS: tuple[int, ...] = (9600, 57600, 115200, 1_000_000, 2_000_000, 3_000_000, 4_000_000, 4_500_000)
#: The baud rates an arm file may ask for: :data:`SERVO_BAUDS` without 4.5 Mbps, which dynamixel-sdk's
#: ``PortHandler.setBaudRate`` refuses (its list stops at 4 Mbps) and the XL330-M288 lacks (Baud Rate 0..6).
SUPPORTED_BAUDS: tuple[int, ...] = tuple(b for b in SERVO_BAUDS if b <= 4_000_000)

Vec3 = tuple[float, float, float]


class JointType(enum.Enum):
    REVOLUTE = "revolute"


@dataclass(frozen=True)
class Servo:
    """One Dynamixel servo driving a joint (or the gripper).

    ``direction`` is +1 for the servo's normal direction and -1 for reverse
    (Drive Mode bit 0).  ``offset`` is the zero offset in ticks: the joint's
    0 rad sits at ``2048 + offset`` ticks.
    """

    id: int
    model: str
    direction: int = 1
    offset: int = 0


#: rad/s^2 (2500 deg/s^2 = 43.6 rad/s^2), a joint's acceleration limit when its arm file sets none: 180 deg/s
#: reached in 72 ms.  Chosen by measurement (``bench/bench_smooth.py``, issue 14): it is 10x below the peak the
#: velocity-only loop commanded on motion_dance (442.8 rad/s^2 on wx250s), the issue's target; Interbotix's xs_sdk
#: default ramp (``modes.yaml``: ``profile_type: time``, 300 ms ramps of a 2000 ms move: 600 deg/s^2 at 180 deg/s)
#: is a point-to-point setting: at 600 the loop trailed motion_dance by p95 170 mm.  The servo's own Profile
#: Acceleration (the e-Manual's 214.577 rev/min^2 units) is set from it: ``drivers.servo_plan.servo_acceleration``.
DEFAULT_MAX_ACCELERATION = math.radians(2500.0)


@dataclass(frozen=True)
class Joint:
    """A revolute joint: origin (parent -> child frame), axis in the child frame, limits, servos.

    ``servos[0]`` is the primary servo; any further ones are shadows driven
    with the same goal in the same sync write (mirrored by their direction).
    """

    name: str
    origin_xyz: Vec3
    origin_rpy: Vec3
    axis: Vec3
    lower: float  #: rad
    upper: float  #: rad
    max_velocity: float  #: rad/s
    servos: tuple[Servo, ...]
    type: JointType = JointType.REVOLUTE
    #: how to set this joint for the calibration pose, shown by ``retarget calibrate`` (``calibration_hint``)
    calibration_hint: str = ""
    #: rad/s^2, the loop's acceleration limit (``max_acceleration`` in the arm file, deg/s^2)
    max_acceleration: float = DEFAULT_MAX_ACCELERATION


@dataclass(frozen=True)
class Gripper:
    """The gripper servo, driven on its own, outside IK.  Limits in radians of the servo shaft."""

    name: str
    servo: Servo
    lower: float
    upper: float
    #: mA: run it in current-based position mode (Operating Mode 5) with this Current Limit and Goal Current;
    #: None: plain position mode (models without current sensing, XL430)
    current_limit: float | None = None
    #: percent of full duty: the PWM Limit, which caps the motor's output in every mode; None: the factory's
    pwm_limit: float | None = None
    #: which limit is closed: "lower" or "upper"
    closed: str = "lower"

    def angle(self, closure: float) -> float:
        """Shaft angle (rad) of ``closure`` 0 (open) .. 1 (closed), clipped to 0..1.

        >>> Gripper("g", Servo(9, "XM430-W350"), -1.0, 1.0, closed="upper").angle(0.75)
        0.5
        """
        c = min(max(float(closure), 0.0), 1.0)
        open_, shut = (self.lower, self.upper) if self.closed == "upper" else (self.upper, self.lower)
        return open_ + c * (shut - open_)

    def closure(self, angle: float) -> float:
        """The inverse of :meth:`angle`: 0 (open) .. 1 (closed) of shaft angle ``angle`` (rad), not clipped."""
        open_, shut = (self.lower, self.upper) if self.closed == "upper" else (self.upper, self.lower)
        return (float(angle) - open_) / (shut - open_)


@dataclass(frozen=True)
class Arm:
    """A serial arm of revolute joints, base to tool point: radians and metres, frozen.

    Load one with :func:`~retarget.arm.load.load_arm`.  ``joints`` run base to tip; ``tool_xyz``/
    ``tool_rpy`` place the tool point in the last joint's child frame (metres, radians); ``home`` and
    ``rest`` are ``(n_joints,)`` float64 radians, read-only (the constructor converts any sequence of
    floats and raises ``ValueError`` for a wrong length, as for a joint with ``lower >= upper``).
    ``lower``/``upper``/``max_velocity`` give the limits as ``(n_joints,)`` float64 (radians, rad/s).

    >>> from retarget.arm.load import load_arm
    >>> arm = load_arm("wx250s")
    >>> arm.n_joints, arm.home.flags.writeable, arm.within_limits(arm.rest)
    (6, False, True)
    >>> arm.lower.shape, arm.servo_ids[:3]
    ((6,), (1, 2, 3))
    """

    name: str
    joints: tuple[Joint, ...]
    tool_xyz: Vec3  #: tool point in the last joint's child frame, metres
    tool_rpy: Vec3
    #: ``(n_joints,) float64`` home pose, radians (read-only; converted from any sequence of floats at run time)
    home: np.ndarray = field(compare=False)
    #: ``(n_joints,) float64`` rest ("sleep") pose, radians (read-only; converted like ``home``)
    rest: np.ndarray = field(compare=False)
    baud: int = 1_000_000
    gripper: Gripper | None = None
    #: the raw ``[mapping]`` table, read and validated by retarget.mapping.config
    mapping: Mapping[str, Any] = field(default_factory=dict)
    source: Path | None = None  #: the file it was loaded from
    title: str = ""  #: human name, e.g. "WidowX-250 6DOF"
    #: the link shapes and allowed pairs (``[collision]``), None for an arm without any
    geometry: Geometry | None = None
    #: the world the arm works in (``[world]``): the table plane and keep-out zones
    world: World = field(default_factory=World)
    #: ``(n_joints,) float64`` radians, the reference pose of ``retarget calibrate`` (``[poses] calibration``;
    #: read-only; default the home pose)
    calibration_pose: np.ndarray | None = field(default=None, compare=False)
    #: the arm must be calibrated before it drives real servos (``requires_calibration``: a hand-built arm)
    requires_calibration: bool = False
    #: the calibration also finds each servo's direction (``calibrate_directions``: servos mounted either way)
    calibrate_directions: bool = False
    #: private per-instance cache (precomputed kinematic chain, IK solvers by their knobs); not part of equality
    _cache: dict[Hashable, Any] = field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        n = len(self.joints)
        if self.calibration_pose is None:
            object.__setattr__(self, "calibration_pose", self.home)
        for name in ("home", "rest", "calibration_pose"):
            pose = np.array(getattr(self, name), dtype=np.float64)
            if pose.shape != (n,):
                raise ValueError(f"Expected a {name} pose of {n} angles, got shape {pose.shape}")
            pose.flags.writeable = False
            object.__setattr__(self, name, pose)
        for j in self.joints:
            if not j.lower < j.upper:
                raise ValueError(f"Expected lower < upper for joint {j.name!r}, got {j.lower} and {j.upper}")

    @property
    def n_joints(self) -> int:
        return len(self.joints)

    @property
    def joint_names(self) -> tuple[str, ...]:
        return tuple(j.name for j in self.joints)

    @property
    def lower(self) -> np.ndarray:
        """``(n_joints,) float64`` lower limits, radians."""
        return np.array([j.lower for j in self.joints], dtype=np.float64)

    @property
    def upper(self) -> np.ndarray:
        """``(n_joints,) float64`` upper limits, radians."""
        return np.array([j.upper for j in self.joints], dtype=np.float64)

    @property
    def max_velocity(self) -> np.ndarray:
        """``(n_joints,) float64`` rad/s."""
        return np.array([j.max_velocity for j in self.joints], dtype=np.float64)

    @property
    def max_acceleration(self) -> np.ndarray:
        """``(n_joints,) float64`` rad/s^2."""
        return np.array([j.max_acceleration for j in self.joints], dtype=np.float64)

    @property
    def home_pose(self) -> tuple[float, ...]:
        """The home pose as a tuple of radians: an old name of :attr:`home`, kept for now."""
        return tuple(self.home.tolist())

    @property
    def rest_pose(self) -> tuple[float, ...]:
        """The rest pose as a tuple of radians: an old name of :attr:`rest`, kept for now."""
        return tuple(self.rest.tolist())

    @property
    def servo_ids(self) -> tuple[int, ...]:
        """Every servo ID of the arm: joints (primary and shadows) then the gripper."""
        ids = [s.id for j in self.joints for s in j.servos]
        if self.gripper is not None:
            ids.append(self.gripper.servo.id)
        return tuple(ids)

    @property
    def chain(self) -> Chain:
        """The precomputed kinematic chain (constant transforms), built once per arm."""
        chain = self._cache.get("chain")
        if chain is None:
            chain = self._cache["chain"] = Chain(
                origins=[(j.origin_xyz, j.origin_rpy) for j in self.joints],
                axes=[j.axis for j in self.joints],
                tool=(self.tool_xyz, self.tool_rpy),
                lower=self.lower,
                upper=self.upper,
            )
        return chain

    def fk(self, q: np.ndarray | Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
        """Forward kinematics of joint angles ``q`` ``(n_joints,)`` radians (the limits are not enforced).

        Returns ``(T_tool, points)``: ``T_tool`` ``(4, 4)`` float64, the homogeneous pose of the
        tool point in the base frame (metres), and ``points`` ``(n_joints + 1, 3)`` float64, every
        joint origin base to tip then the tool point, base frame, metres (for drawing).  Raises
        ``ValueError`` when ``q`` is not ``(n_joints,)``; many poses at once:
        :func:`retarget.arm.kinematics.fk_batch`.

        >>> from retarget.arm.load import load_arm
        >>> arm = load_arm("wx250s")
        >>> T, points = arm.fk(arm.home)
        >>> T[:3, 3].round(4).tolist()  # the tool point at home, metres
        [0.4583, 0.0, 0.3607]
        >>> points.shape
        (7, 3)
        """
        return self.chain.fk(q)

    def clip(self, q: np.ndarray) -> np.ndarray:
        """``q`` clipped to the joint limits, ``(..., n_joints)`` radians."""
        clipped: np.ndarray = np.clip(q, self.lower, self.upper)
        return clipped

    def within_limits(self, q: np.ndarray, *, atol: float = 0.0) -> bool:
        """True when every angle of ``q`` ``(..., n_joints)`` lies inside the limits (plus ``atol`` rad)."""
        q = np.asarray(q, dtype=np.float64)
        return bool(np.all(q >= self.lower - atol) and np.all(q <= self.upper + atol))
