"""The arm's side of the mapping: where its shoulder is, how far it reaches, where targets may go, IK weights.

- :class:`ArmGeometry` (:func:`arm_geometry`): the shoulder pivot, the reach and the home pose's forward
  direction of an :class:`~retarget.arm.model.Arm`, from one FK call; :func:`default_origin`, where the
  human shoulder lands by default;
- :class:`Workspace`: the shell around the pivot, above the floor, that targets are pulled into
  (:meth:`Workspace.clamp`, vectorised, and :meth:`Workspace.clamp_point` for one point); with a collision
  model (``blocked``), targets are also pushed out of its blocked zones (below the table, inside a keep-out
  zone or the base: ``CollisionModel.push_out``);
- :func:`ik_weights`: per-joint CCD weights for following the mapping's targets (:data:`ROLL_WEIGHT`,
  :data:`WRIST_WEIGHT`).

Metres and radians, the arm's base frame.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np

from retarget.arm.kinematics import axis_angle_matrix, rpy_matrix
from retarget.arm.model import Arm
from retarget.errors import ConfigError
from retarget.mapping.config import Axis, MappingConfig

if TYPE_CHECKING:
    from retarget.collision import CollisionModel

__all__ = [
    "ArmGeometry",
    "Workspace",
    "arm_geometry",
    "default_origin",
    "ik_weights",
]


@dataclass(frozen=True)
class ArmGeometry:
    """Where the arm's shoulder pivot is and how far its tool point reaches from it (base frame, metres)."""

    pivot: np.ndarray  #: ``(3,)`` the first joint whose axis differs from the base joint's (the shoulder)
    reach: float  #: sum of the link lengths from the pivot to the tool point
    #: ``(3,)`` unit, horizontal: where the arm points at its home pose (+x for most arms, -x for the Koch URDF)
    forward: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0]))

    def basis(self, robot_forward: Axis = Axis.AUTO) -> np.ndarray:
        """``(3, 3)`` columns: the robot's forward, left and up (z) in its base frame.

        ``robot_forward`` AUTO uses :attr:`forward`; ``+x``/``-x``/``+y``/``-y`` override it.
        """
        f = self.forward if robot_forward is Axis.AUTO else robot_forward.vector
        up = np.array([0.0, 0.0, 1.0])
        return np.stack([f, np.cross(up, f), up], axis=-1)


def default_origin(config: MappingConfig, geometry: ArmGeometry) -> np.ndarray:
    """``(3,)`` metres, base frame: where the shoulder lands when ``config.origin`` is None.

    0.3 reach in front of and 0.38 reach above the shoulder pivot: with the default ``arm_scale`` the
    human arm's sphere then fits inside the workspace shell, and a hanging arm lands just above the
    floor in front of the robot.
    """
    ahead: np.ndarray = geometry.basis(config.robot_forward) @ np.array([0.3, 0.0, 0.38])
    return geometry.pivot + geometry.reach * ahead


def arm_geometry(arm: Arm) -> ArmGeometry:
    """The shoulder pivot and reach of ``arm``, from one FK call.

    Distances between consecutive joint origins are constant in a serial chain,
    so their sum from the pivot to the tool point bounds the reach whatever the pose.
    """
    _, points = arm.fk(arm.home)  # (n_joints + 1, 3): joint origins then the tool point
    axes = [np.asarray(j.axis, dtype=np.float64) for j in arm.joints]
    k = 0
    for i in range(1, arm.n_joints):
        if abs(float(np.dot(axes[i], axes[0]))) < 0.99 * np.linalg.norm(axes[i]) * np.linalg.norm(axes[0]):
            k = i
            break
    segments = np.diff(points[k:], axis=0)
    ahead = points[-1, :2] - points[0, :2]  # the tool seen from the base joint, horizontally
    norm = float(np.linalg.norm(ahead))
    forward = np.array([ahead[0] / norm, ahead[1] / norm, 0.0]) if norm > 1e-6 else np.array([1.0, 0.0, 0.0])
    axis = int(np.argmax(np.abs(forward[:2])))
    if abs(forward[axis]) > math.cos(math.radians(10)):  # a lateral link offset, not a turned base: snap
        forward = np.zeros(3)
        forward[axis] = math.copysign(1.0, ahead[axis])
    return ArmGeometry(
        pivot=np.array(points[k], dtype=np.float64),
        reach=float(np.linalg.norm(segments, axis=1).sum()),
        forward=forward,
    )


#: default IK weight of a roll joint in position-only mode: 0, the joint is locked and keeps its value
ROLL_WEIGHT = 0.0
#: default IK weight of the other joints (the wrist included: the IK's DLS steps share a move among the joints in
#: proportion to their weights, and a stiff wrist made the shoulder swing near a folded elbow)
WRIST_WEIGHT = 1.0
#: a joint is a *roll* when the tool point, at home, lies closer than this fraction of the reach to its axis
ROLL_LEVER = 0.1


def ik_weights(arm: Arm, config: MappingConfig) -> np.ndarray:
    """Per-joint CCD weights ``(n_joints,)`` in ``[0, 1]`` for following this mapping's targets.

    Position only (``orientation_weight == 0``), a 6-DOF arm is redundant and a roll joint cannot help a point
    target: its axis runs (nearly) through the tool point, so it would spin by radians for a millimetre.  So by
    default a *roll* joint (at home, the tool point within ``ROLL_LEVER`` x the reach of its axis: forearm_roll and
    wrist_rotate on the wx250s and vx300s, 0 mm from it; the Koch's wrist_roll, 16 mm, 0.06 reach; every other
    joint of the bundled arms is 0.2 reach or more away) gets ``ROLL_WEIGHT`` = 0: the IK locks it and it keeps
    its value (at least three joints stay free).  The others get ``WRIST_WEIGHT`` = 1.  With an orientation
    target every joint gets 1.  ``config.joint_weights`` overrides them by joint name, or gives all of them.

    >>> import retarget
    >>> from retarget.mapping.config import MappingConfig
    >>> ik_weights(retarget.load_arm("wx250s"), MappingConfig()).tolist()
    [1.0, 1.0, 1.0, 0.0, 1.0, 0.0]
    """
    n = arm.n_joints
    weights = _default_weights(arm) if config.orientation_weight == 0 else np.ones(n)
    given = config.joint_weights
    if not given:
        return weights
    if isinstance(given[0], tuple):
        return _named_weights(arm, given, weights)
    if len(given) != n:
        raise ConfigError(
            f"Expected {n} joint weights", path=arm.source, key="mapping.joint_weights", value=list(given)
        )
    return np.asarray(given, dtype=np.float64)


def _default_weights(arm: Arm) -> np.ndarray:
    """Position-only weights ``(n_joints,)``: :data:`ROLL_WEIGHT` on roll joints, :data:`WRIST_WEIGHT` on the rest."""
    n = arm.n_joints
    _, points = arm.fk(arm.home)
    tool = points[-1]
    reach = arm_geometry(arm).reach
    rotations = _joint_rotations(arm, arm.home)
    rolls = []
    for i in range(n):
        axis = rotations[i] @ np.asarray(arm.joints[i].axis, dtype=np.float64)
        axis /= np.linalg.norm(axis)
        lever = tool - points[i]
        if np.linalg.norm(lever - axis * float(axis @ lever)) < ROLL_LEVER * reach:  # the tool's distance to the axis
            rolls.append(i)
    weights = np.full(n, WRIST_WEIGHT)
    if n - len(rolls) >= 3:  # a point target needs three free joints
        weights[rolls] = ROLL_WEIGHT
    return weights


def _named_weights(arm: Arm, given: tuple[tuple[str, float], ...], weights: np.ndarray) -> np.ndarray:
    """``weights`` with the joints named in ``given`` set to theirs; ``ConfigError`` for an unknown name."""
    names = arm.joint_names
    for name, w in given:
        if name not in names:
            raise ConfigError(
                f"unknown joint; expected one of {', '.join(names)}",
                path=arm.source,
                key=f"mapping.joint_weights.{name}",
            )
        weights[names.index(name)] = w
    return weights


def _joint_rotations(arm: Arm, q: np.ndarray) -> list[np.ndarray]:
    """Base-frame rotation of each joint's child frame at ``q``, before its own rotation (so ``R @ axis`` is world)."""
    R = np.eye(3)
    out = []
    for joint, angle in zip(arm.joints, q, strict=True):
        R = R @ rpy_matrix(joint.origin_rpy)
        out.append(R.copy())
        R = R @ axis_angle_matrix(np.asarray(joint.axis, dtype=np.float64) / np.linalg.norm(joint.axis), angle)
    return out


@dataclass(frozen=True)
class Workspace:
    """The reachable region targets are pulled into: ``r_min <= |p - center| <= r_max`` and ``z >= floor``, and
    out of ``blocked``'s zones (its clearance away from the table, the keep-out zones and the base)."""

    center: np.ndarray  #: ``(3,)`` metres, base frame (the shoulder pivot)
    r_min: float
    r_max: float
    floor: float
    blocked: CollisionModel | None = field(default=None, compare=False)  #: None: no blocked zones

    def with_blocked(self, model: CollisionModel | None) -> Workspace:
        """This workspace with ``model``'s blocked zones (None: none)."""
        return replace(self, blocked=model)

    def push(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``points`` ``(..., 3)`` metres pushed out of the blocked zones: ``(points (..., 3), pushed (...) bool)``;
        unchanged without a model.  Every point's margin (its signed distance to the zones) in one vectorised
        query; only the blocked ones are pushed, one by one."""
        p = np.array(points, dtype=np.float64)
        pushed = np.zeros(p.shape[:-1], dtype=bool)
        model = self.blocked
        if model is None:
            return p, pushed
        flat, flags = p.reshape(-1, 3), pushed.reshape(-1)
        for i in np.flatnonzero(model.point_margins(flat) < model.clearance).tolist():
            flat[i] = model.push_out(flat[i])
            flags[i] = True
        return p, pushed

    @classmethod
    def for_arm(cls, arm: Arm, config: MappingConfig | None = None) -> Workspace:
        """The workspace of ``arm`` with the reach fractions and floor of ``config``."""
        config = config or MappingConfig()
        g = arm_geometry(arm)
        return cls(
            center=g.pivot, r_min=config.min_reach * g.reach, r_max=config.max_reach * g.reach, floor=config.floor
        )

    def clamp(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pull ``points`` ``(..., 3)`` metres to the nearest point of the workspace.

        Returns ``(clamped (..., 3), moved (...) bool)``.  Radially onto the shell;
        a point that would end below the floor goes onto the floor instead, straight
        above the original point, pulled into the ring the shell cuts out of the floor;
        then out of the blocked zones (:meth:`push`).
        """
        out, moved, _ = self.clamp_and_push(points)
        return out, moved

    def clamp_and_push(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`clamp`, and which of the points were pushed out of a blocked zone: ``(clamped (..., 3), moved
        (...) bool, pushed (...) bool)`` (``pushed`` all False without :attr:`blocked`)."""
        p = np.array(points, dtype=np.float64)
        if p.shape[-1:] != (3,):
            raise ValueError(f"Expected points of shape (..., 3), got {p.shape}")
        d = p - self.center
        r = np.linalg.norm(d, axis=-1)
        safe = np.where(r > 1e-12, r, 1.0)
        radius = np.clip(r, self.r_min, self.r_max)
        fwd = np.zeros(3)
        fwd[0] = 1.0
        d = np.where((r > 1e-12)[..., None], d / safe[..., None], fwd) * radius[..., None]
        low = d[..., 2] + self.center[2] < self.floor
        if np.any(low):  # onto the floor, below the original point, inside the annulus the shell cuts out of it
            dz = self.floor - self.center[2]
            h = p[..., :2] - self.center[:2]
            hn = np.linalg.norm(h, axis=-1)
            hdir = np.where((hn > 1e-12)[..., None], h / np.where(hn > 1e-12, hn, 1.0)[..., None], fwd[:2])
            lo = math.sqrt(max(self.r_min**2 - dz**2, 0.0))
            hi = math.sqrt(max(self.r_max**2 - dz**2, 0.0))
            hn2 = np.clip(hn, lo, hi)
            d[..., :2] = np.where(low[..., None], hdir * hn2[..., None], d[..., :2])
            d[..., 2] = np.where(low, dz, d[..., 2])
        moved = (r < self.r_min) | (r > self.r_max) | low
        out = np.where(moved[..., None], d + self.center, p)
        pushed = np.zeros(moved.shape, dtype=bool)
        if self.blocked is not None:
            out, pushed = self.push(out)
        return out, moved | pushed, pushed

    def clamp_point(self, x: float, y: float, z: float) -> tuple[float, float, float, bool]:
        """:meth:`clamp` of one point in plain floats (~20x faster than numpy for a single point)."""
        cx, cy, cz = (float(v) for v in self.center)
        dx, dy, dz = x - cx, y - cy, z - cz
        r = math.sqrt(dx * dx + dy * dy + dz * dz)
        if self.r_min <= r <= self.r_max and z >= self.floor:
            if self.blocked is not None and self.blocked.point_blocked((x, y, z)):
                px, py, pz = self.blocked.push_out((x, y, z)).tolist()
                return px, py, pz, True
            return x, y, z, False
        radius = min(max(r, self.r_min), self.r_max)
        if r > 1e-12:
            k = radius / r
            dx, dy, dz = dx * k, dy * k, dz * k
        else:
            dx, dy, dz = radius, 0.0, 0.0
        if dz + cz < self.floor:
            fz = self.floor - cz
            hx, hy = x - cx, y - cy
            hn = math.hypot(hx, hy)
            ux, uy = (hx / hn, hy / hn) if hn > 1e-12 else (1.0, 0.0)
            lo = math.sqrt(max(self.r_min**2 - fz**2, 0.0))
            hi = math.sqrt(max(self.r_max**2 - fz**2, 0.0))
            hn = min(max(hn, lo), hi)
            dx, dy, dz = ux * hn, uy * hn, fz
        x, y, z = dx + cx, dy + cy, dz + cz
        if self.blocked is not None and self.blocked.point_blocked((x, y, z)):
            x, y, z = self.blocked.push_out((x, y, z)).tolist()
        return x, y, z, True
