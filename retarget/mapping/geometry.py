"""Human arm motion -> tool-point targets of a robot arm, vectorized over frames.

The mapping is position based and built from five parts, each configurable in
the ``[mapping]`` table of an arm description and by CLI flags
(:class:`~retarget.mapping.config.MappingConfig`, in :mod:`retarget.mapping.config`):

1. the human **wrist relative to the shoulder** of the chosen side;
2. expressed in a **body frame** built from the torso (hips, the midpoint of
   both shoulders, the shoulder line), so walking or turning does not move the
   arm.  Its axes are forward, left and up; ``forward="+z"`` etc. replaces it
   by a fixed frame of the BVH world instead;
3. **scaled** by ``arm_scale`` x the robot's reach over the human arm length
   measured from the clip (median shoulder-elbow + elbow-wrist), so BVH units
   (cm, m, inches) do not matter;
4. **rotated** into the robot base frame (x forward, y left, z up; the body
   frame's forward/left/up map onto them, which also turns BVH Y-up into
   robot Z-up);
5. **offset** to ``origin``, a point of the workspace in the base frame where
   the human shoulder lands (default: in front of and above the robot's
   shoulder joint, so a hanging arm maps in front of the robot, not into the
   base).

Targets outside the :class:`Workspace` (a shell ``min_reach..max_reach``
around the robot's shoulder pivot, above ``floor``) are pulled to the nearest
reachable point and counted in ``Targets.clamped``.

Optionally (``orientation_weight > 0``) the hand's orientation becomes a tool
orientation: tool x along the hand bone, tool z the body's up in the rest pose.

Units: BVH file units in, metres and radians out.  This module is math only
(it imports neither drivers, sim nor serial).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from retarget.arm.kinematics import axis_angle_matrix, rpy_matrix
from retarget.arm.model import Arm
from retarget.bvh.motion import Motion
from retarget.errors import ConfigError
from retarget.mapping.config import Axis, MappingConfig

__all__ = [
    "ArmGeometry",
    "Targets",
    "Workspace",
    "arm_geometry",
    "body_frames",
    "default_origin",
    "fixed_frame",
    "ik_weights",
    "map_points",
    "retarget_targets",
]


# ----------------------------------------------------------------------------------------------- arm geometry


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


#: default IK weight of a roll joint (its axis runs through the tool point, so it barely moves it)
ROLL_WEIGHT = 1e-3
#: default IK weight of the wrist joints beyond the elbow (keeps the wrist from churning)
WRIST_WEIGHT = 0.3


def ik_weights(arm: Arm, config: MappingConfig) -> np.ndarray:
    """Per-joint CCD weights ``(n_joints,)`` in ``(0, 1]`` for following this mapping's targets.

    Position only (``orientation_weight == 0``), a 6-DOF arm is redundant and CCD's
    exact per-joint steps make the redundant joints churn (a roll joint near a
    singularity swings by radians for a millimetre).  So by default a *roll* joint
    (its axis within 25 degrees of the line from its pivot to the tool, at home) gets
    ``ROLL_WEIGHT`` (it stays put) and joints after the third get ``WRIST_WEIGHT``;
    with an orientation target every joint gets 1.  ``config.joint_weights``
    overrides them by joint name, or gives all of them.
    """
    n = arm.n_joints
    weights = np.ones(n)
    if config.orientation_weight == 0:
        _, points = arm.fk(arm.home)
        tool = points[-1]
        rotations = _joint_rotations(arm, arm.home)
        for i in range(n):
            axis = rotations[i] @ np.asarray(arm.joints[i].axis, dtype=np.float64)
            lever = tool - points[i]
            length = np.linalg.norm(lever)
            if length > 1e-9 and abs(axis @ lever) / (np.linalg.norm(axis) * length) > math.cos(math.radians(25)):
                weights[i] = ROLL_WEIGHT
            elif i >= 3:
                weights[i] = WRIST_WEIGHT
    given = config.joint_weights
    if given:
        if isinstance(given[0], tuple):
            names = arm.joint_names
            for name, w in given:
                if name not in names:
                    raise ConfigError(
                        f"unknown joint; expected one of {', '.join(names)}",
                        path=arm.source,
                        key=f"mapping.joint_weights.{name}",
                    )
                weights[names.index(name)] = w
        else:
            if len(given) != n:
                raise ConfigError(
                    f"Expected {n} joint weights", path=arm.source, key="mapping.joint_weights", value=list(given)
                )
            weights = np.asarray(given, dtype=np.float64)
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
    """The reachable region targets are pulled into: ``r_min <= |p - center| <= r_max`` and ``z >= floor``."""

    center: np.ndarray  #: ``(3,)`` metres, base frame (the shoulder pivot)
    r_min: float
    r_max: float
    floor: float

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
        above the original point, pulled into the ring the shell cuts out of the floor.
        """
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
        return np.where(moved[..., None], d + self.center, p), moved

    def clamp_point(self, x: float, y: float, z: float) -> tuple[float, float, float, bool]:
        """:meth:`clamp` of one point in plain floats (~20x faster than numpy for a single point)."""
        cx, cy, cz = (float(v) for v in self.center)
        dx, dy, dz = x - cx, y - cy, z - cz
        r = math.sqrt(dx * dx + dy * dy + dz * dz)
        if self.r_min <= r <= self.r_max and z >= self.floor:
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
        return dx + cx, dy + cy, dz + cz, True


# ----------------------------------------------------------------------------------------------- the mapping


def body_frames(hips: np.ndarray, left_shoulder: np.ndarray, right_shoulder: np.ndarray) -> np.ndarray:
    """Torso frames ``(n, 3, 3)`` from points ``(n, 3)`` (any units, BVH world).

    Columns are forward, left, up as BVH-world unit vectors: left along the
    shoulder line, up from the hips to the shoulders' midpoint (made orthogonal),
    forward = left x up.  ``frames[i].T @ v`` expresses a world vector in the body frame.
    """
    left = np.asarray(left_shoulder, dtype=np.float64) - right_shoulder
    left /= _norm(left, "shoulder line")
    up = 0.5 * (np.asarray(left_shoulder) + right_shoulder) - hips
    fwd = np.cross(left, up)
    fwd /= _norm(fwd, "torso (shoulder line parallel to the spine)")
    up = np.cross(fwd, left)
    return np.stack([fwd, left, up], axis=-1)


def fixed_frame(forward: Axis, up: Axis) -> np.ndarray:
    """``(3, 3)`` columns forward, left, up for a fixed BVH forward and up axis."""
    f, u = forward.vector, up.vector
    if abs(float(f @ u)) > 0.5:
        raise ConfigError(
            f"Expected a forward axis perpendicular to up ({up.value})", key="mapping.forward", value=forward.value
        )
    return np.stack([f, np.cross(u, f), u], axis=-1)


def _norm(v: np.ndarray, what: str) -> np.ndarray:
    n: np.ndarray = np.linalg.norm(v, axis=-1, keepdims=True)
    if np.any(n < 1e-12):
        raise ValueError(f"Expected a non-degenerate {what}, got a zero-length vector")
    return n


def map_points(
    shoulder: np.ndarray,
    wrist: np.ndarray,
    frames: np.ndarray,
    *,
    scale: float,
    origin: np.ndarray,
    basis: np.ndarray | None = None,
) -> np.ndarray:
    """Wrist relative to shoulder, in body ``frames``, scaled, turned and offset: ``(n, 3)`` metres, base frame.

    ``shoulder``/``wrist`` ``(n, 3)`` file units, BVH world; ``frames`` ``(n, 3, 3)`` or ``(3, 3)``
    (columns forward, left, up); ``scale`` metres per file unit; ``origin`` ``(3,)`` metres;
    ``basis`` ``(3, 3)`` the robot's forward, left, up in its base frame (default identity: x, y, z).
    """
    rel = np.asarray(wrist, dtype=np.float64) - shoulder
    local = np.einsum("...ji,...j->...i", frames, rel)  # frames^T @ rel: (forward, left, up)
    if basis is not None:
        local = local @ np.asarray(basis).T
    targets: np.ndarray = local * scale + origin
    return targets


@dataclass(frozen=True)
class Targets:
    """Per-frame tool targets of one clip on one arm."""

    positions: np.ndarray  #: ``(n_frames, 3)`` metres, base frame, inside the workspace
    raw: np.ndarray  #: ``(n_frames, 3)`` metres, before the workspace clamp
    clamped: np.ndarray  #: ``(n_frames,)`` bool, the frame's target was pulled into the workspace
    rotations: np.ndarray | None  #: ``(n_frames, 3, 3)`` tool orientations in the base frame, or None
    frame_time: float  #: seconds between frames
    workspace: Workspace
    config: MappingConfig
    scale: float  #: metres per BVH file unit

    @classmethod
    def from_raw(
        cls,
        raw: np.ndarray,
        *,
        frame_time: float,
        workspace: Workspace,
        config: MappingConfig | None = None,
        rotations: np.ndarray | None = None,
        scale: float = 1.0,
    ) -> Targets:
        """Targets from tool points ``raw`` ``(n_frames, 3)`` metres (base frame), clamped into ``workspace``."""
        raw = np.asarray(raw, dtype=np.float64)
        if raw.ndim != 2 or raw.shape[1] != 3 or raw.shape[0] < 1:
            raise ValueError(f"Expected raw targets of shape (n_frames, 3), got {raw.shape}")
        if not (np.isfinite(frame_time) and frame_time > 0):
            raise ValueError(f"Expected a frame time > 0 s, got {frame_time}")
        positions, clamped = workspace.clamp(raw)
        return cls(
            positions=positions,
            raw=raw,
            clamped=clamped,
            rotations=rotations,
            frame_time=float(frame_time),
            workspace=workspace,
            config=config or MappingConfig(),
            scale=scale,
        )

    @property
    def n_frames(self) -> int:
        return int(self.positions.shape[0])

    @property
    def n_clamped(self) -> int:
        return int(np.count_nonzero(self.clamped))

    def sample(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
        """Targets at clip ``times`` ``(n,)`` seconds by linear interpolation of the raw targets, then clamped.

        Returns ``(positions (n, 3) metres, rotations (n, 3, 3) or None, clamped (n,) bool)``.
        Times outside the clip hold the first/last frame.
        """
        t = np.asarray(times, dtype=np.float64) / self.frame_time
        n = self.n_frames
        if n == 1:
            i0 = np.zeros(t.shape, dtype=np.intp)
            w = np.zeros(t.shape)
        else:
            t = np.clip(t, 0.0, n - 1)
            i0 = np.minimum(np.floor(t).astype(np.intp), n - 2)
            w = t - i0
        i1 = np.minimum(i0 + 1, n - 1)
        raw = self.raw[i0] * (1.0 - w)[:, None] + self.raw[i1] * w[:, None]
        positions, clamped = self.workspace.clamp(raw)
        rotations = None
        if self.rotations is not None:
            rotations = _orthonormalize(
                self.rotations[i0] * (1.0 - w)[:, None, None] + self.rotations[i1] * w[:, None, None]
            )
        return positions, rotations, clamped

    def at(self, time: float) -> tuple[np.ndarray, bool]:
        """The position target ``(3,)`` metres at one clip ``time`` and whether it was clamped (plain floats).

        Same values as :meth:`sample` (without rotations), for a single time.
        """
        n = self.n_frames
        f = min(max(time / self.frame_time, 0.0), n - 1.0)
        i0 = min(int(f), max(n - 2, 0))
        w = f - i0 if n > 1 else 0.0
        a, b = self.raw[i0].tolist(), self.raw[min(i0 + 1, n - 1)].tolist()
        u = 1.0 - w
        x, y, z, moved = self.workspace.clamp_point(a[0] * u + b[0] * w, a[1] * u + b[1] * w, a[2] * u + b[2] * w)
        return np.array((x, y, z)), moved


def _orthonormalize(m: np.ndarray) -> np.ndarray:
    """Nearest rotations ``(n, 3, 3)`` by Gram-Schmidt on the x and z columns."""
    x = m[..., :, 0] / np.linalg.norm(m[..., :, 0], axis=-1, keepdims=True)
    z = m[..., :, 2] - np.sum(m[..., :, 2] * x, axis=-1, keepdims=True) * x
    z /= np.linalg.norm(z, axis=-1, keepdims=True)
    return np.stack([x, np.cross(z, x), z], axis=-1)


def retarget_targets(motion: Motion, arm: Arm, config: MappingConfig | None = None) -> Targets:
    """Tool-point targets for every frame of ``motion`` on ``arm``: the steps in the module docstring.

    ``motion``: the clip, in any length unit (the scale comes from its own arm length).  ``arm``: the
    robot.  ``config``: the mapping; default ``MappingConfig.from_table(arm.mapping, path=arm.source)``,
    the arm file's ``[mapping]`` table.

    Returns :class:`Targets`: ``positions`` ``(n_frames, 3)`` float64 metres in the arm's base frame,
    inside the :class:`Workspace`; ``raw`` the same before the workspace clamp; ``clamped``
    ``(n_frames,)`` bool; ``rotations`` ``(n_frames, 3, 3)`` tool orientations in the base frame when
    ``config.orientation_weight > 0``, else None; ``frame_time`` seconds; ``scale`` metres per file unit.

    Raises :class:`~retarget.errors.BvhError` when the clip has no arm chain for ``config.side`` or
    for the other side (the torso frame needs both shoulders), :class:`~retarget.errors.ConfigError`
    for a bad ``[mapping]`` table, and ``ValueError`` for a degenerate clip (a zero-length arm or torso).

    >>> from retarget.arm.load import load_arm
    >>> from retarget.bvh.parse import DEMO_CLIP, load_bvh
    >>> targets = retarget_targets(load_bvh(DEMO_CLIP), load_arm("wx250s"))
    >>> targets.positions.shape, targets.n_clamped, targets.frame_time, targets.rotations is None
    ((630, 3), 0, 0.0166667, True)
    >>> bool(targets.workspace.clamp(targets.positions)[1].any())  # every target already inside the workspace
    False
    """
    if config is None:
        config = MappingConfig.from_table(arm.mapping, path=arm.source)
    side = config.side.value
    chain = motion.arm_points(side)
    pts = np.asarray(chain.points, dtype=np.float64)  # (n, 3, 3) shoulder, elbow, wrist
    shoulder, elbow, wrist = pts[:, 0], pts[:, 1], pts[:, 2]
    other = "left" if side == "right" else "right"
    opposite = np.asarray(motion.arm_points(other).points, dtype=np.float64)[:, 0]
    left_sh, right_sh = (shoulder, opposite) if side == "left" else (opposite, shoulder)

    if config.forward is Axis.AUTO:
        all_positions = motion.positions()
        root = int(np.flatnonzero(np.asarray(motion.parents) < 0)[0])
        frames = body_frames(all_positions[:, root], left_sh, right_sh)
    else:
        frames = fixed_frame(config.forward, config.up)

    human = np.median(np.linalg.norm(elbow - shoulder, axis=-1) + np.linalg.norm(wrist - elbow, axis=-1))
    if not np.isfinite(human) or human <= 0:
        raise ValueError(f"Expected a human arm of positive length, got {human}")
    geometry = arm_geometry(arm)
    scale = config.arm_scale * geometry.reach / float(human)
    origin = np.asarray(config.origin, dtype=np.float64) if config.origin else default_origin(config, geometry)
    basis = geometry.basis(config.robot_forward)
    raw = map_points(shoulder, wrist, frames, scale=scale, origin=origin, basis=basis)
    rotations = None
    if config.orientation_weight > 0:
        rotations = basis @ _hand_rotations(motion, chain.names, frames, config)
    return Targets.from_raw(
        raw,
        frame_time=float(motion.frame_time),
        workspace=Workspace.for_arm(arm, config),
        config=config,
        rotations=rotations,
        scale=scale,
    )


def _hand_rotations(motion: Motion, names: tuple[str, ...], frames: np.ndarray, config: MappingConfig) -> np.ndarray:
    """Tool orientations ``(n, 3, 3)`` in the body frame (forward, left, up) from the hand joint's global rotation.

    Tool x = the hand bone (the wrist's first child, else the forearm direction),
    tool z = the BVH up axis seen from the hand in the rest pose (rest rotations are identity).
    """
    rotations, positions = motion.global_transforms()
    joint_names = list(motion.joint_names)
    wrist_name = names[2]
    if wrist_name not in joint_names:  # an End Site wrist has no rotation of its own: use the forearm's
        wrist_name = names[1]
    w = joint_names.index(wrist_name)
    R = rotations[:, w]  # (n, 3, 3) hand local -> world
    children = np.flatnonzero(np.asarray(motion.parents) == w)
    if children.size:
        bone = positions[0, children[0]] - positions[0, w]
    else:
        bone = positions[0, w] - positions[0, joint_names.index(names[1])]
    x = R[0].T @ bone
    x /= np.linalg.norm(x)
    z = config.up.vector - (config.up.vector @ x) * x
    if np.linalg.norm(z) < 1e-6:
        z = np.cross(x, [1.0, 0.0, 0.0]) if abs(x[0]) < 0.9 else np.cross(x, [0.0, 0.0, 1.0])
    z /= np.linalg.norm(z)
    align = np.stack([x, np.cross(z, x), z], axis=-1)  # tool -> hand local
    tool: np.ndarray = np.einsum("...ji,...jk,kl->...il", frames, R, align)
    return tool
