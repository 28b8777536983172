"""Human arm motion -> tool-point targets of a robot arm, vectorized over frames.

The mapping is position based and built from five parts, each configurable in
the ``[mapping]`` table of an arm description and by CLI flags
(:class:`~retarget.mapping.config.MappingConfig`, in :mod:`retarget.mapping.config`):

1. the human **wrist relative to the shoulder** of the chosen side;
2. expressed in a **body frame** built from the torso (hips, the midpoint of
   both shoulders, the shoulder line), so walking or turning does not move the
   arm.  Its axes are forward, left and up; ``forward="+z"`` etc. replaces it
   by a fixed frame of the BVH world instead.  Where the shoulders give no
   frame (they coincide, or the rig has one arm) the body frame comes from the
   spine and hips instead (:func:`spine_frames`), and a frame neither gives
   holds the previous good one (:func:`clip_body_frames`);
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

import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from retarget.arm.kinematics import axis_angle_matrix, rpy_matrix
from retarget.arm.model import Arm
from retarget.bvh.motion import ArmChain, Motion
from retarget.errors import BvhError, ConfigError
from retarget.mapping.config import Axis, MappingConfig

__all__ = [
    "ArmGeometry",
    "BodyFrames",
    "Targets",
    "Workspace",
    "arm_geometry",
    "body_frames",
    "body_frames_masked",
    "clip_body_frames",
    "default_origin",
    "fixed_frame",
    "hold_good_frames",
    "ik_weights",
    "map_points",
    "retarget_targets",
    "shoulder_offsets",
    "spine_frames",
    "torso_joint",
]

log = logging.getLogger(__name__)


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


#: a shoulder line shorter than this fraction of the torso's part across it (hips to the shoulders' midpoint,
#: made orthogonal to the shoulder line), or the other way round, gives no body frame
DEGENERATE = 1e-6

#: :attr:`BodyFrames.source` codes: where each frame's body frame came from
FROM_SHOULDERS, FROM_SPINE, HELD = 0, 1, 2


def body_frames_masked(
    hips: np.ndarray, left_shoulder: np.ndarray, right_shoulder: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Torso frames ``(n, 3, 3)`` and which of them are sound, ``(n,)`` bool, from points ``(n, 3)``.

    Points in any units, BVH world.  Columns are forward, left, up as BVH-world unit vectors: left
    along the shoulder line, up from the hips to the shoulders' midpoint (made orthogonal), forward =
    left x up.  A frame is unsound (``False``, its matrix NaN) when the shoulders coincide, the hips sit
    on their midpoint, or the shoulder line runs along the spine (the shoulder line and the torso's part
    across it within a factor :data:`DEGENERATE` of each other), or a point is not finite.  Never raises
    for a degenerate frame: :func:`body_frames` is the strict form.

    >>> hips = np.zeros((2, 3))
    >>> frames, ok = body_frames_masked(hips, [[1.0, 5, 0], [0, 5, 0]], [[-1.0, 5, 0], [0, 5, 0]])
    >>> frames[0].tolist(), ok.tolist()  # facing +z, left +x, up +y; the second frame's shoulders coincide
    ([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]], [True, False])
    """
    left = np.asarray(left_shoulder, dtype=np.float64) - right_shoulder
    up = 0.5 * (np.asarray(left_shoulder, dtype=np.float64) + right_shoulder) - hips
    with np.errstate(divide="ignore", invalid="ignore"):  # degenerate frames divide by 0: flagged below
        n_left = np.linalg.norm(left, axis=-1, keepdims=True)
        left /= n_left
        fwd = np.cross(left, up)
        n_fwd = np.linalg.norm(fwd, axis=-1, keepdims=True)  # the torso across the shoulder line
        fwd /= n_fwd
        good: np.ndarray = ((n_fwd > DEGENERATE * n_left) & (n_left > DEGENERATE * n_fwd))[..., 0]
    up = np.cross(fwd, left)
    frames = np.stack([fwd, left, up], axis=-1)
    if not good.all():
        frames[~good] = np.nan
    return frames, good


def body_frames(hips: np.ndarray, left_shoulder: np.ndarray, right_shoulder: np.ndarray) -> np.ndarray:
    """Torso frames ``(n, 3, 3)`` from points ``(n, 3)`` (any units, BVH world).

    Columns are forward, left, up as BVH-world unit vectors: left along the
    shoulder line, up from the hips to the shoulders' midpoint (made orthogonal),
    forward = left x up.  ``frames[i].T @ v`` expresses a world vector in the body frame.
    ``ValueError`` when a frame is degenerate (:func:`body_frames_masked` flags them instead).
    """
    frames, ok = body_frames_masked(hips, left_shoulder, right_shoulder)
    if not ok.all():
        left = np.asarray(left_shoulder, dtype=np.float64) - right_shoulder
        up = 0.5 * (np.asarray(left_shoulder, dtype=np.float64) + right_shoulder) - hips
        n_left, n_up = np.linalg.norm(left, axis=-1), np.linalg.norm(up, axis=-1)
        what = "torso (shoulder line parallel to the spine)"
        if np.any((n_left <= DEGENERATE * n_up)[~ok]):
            what = "shoulder line"
        elif np.any((n_up <= DEGENERATE * n_left)[~ok]):
            what = "torso (the hips on the shoulders' midpoint)"
        raise ValueError(f"Expected a non-degenerate {what}, got a zero-length vector")
    return frames


def torso_joint(parents: np.ndarray, shoulders: Sequence[int]) -> int:
    """The joint at the top of the spine that carries the shoulders: a joint index of ``parents`` ``(n_joints,)``.

    For two shoulder joints, their lowest common ancestor; for one, its nearest ancestor that branches
    (the chest, which also carries the neck or the other arm), else the root.

    >>> parents = np.array([-1, 0, 1, 2, 1, 4])  # hips, chest, clavicle, shoulder, other clavicle, shoulder
    >>> torso_joint(parents, [3, 5]), torso_joint(parents, [3]), torso_joint(parents[:4], [3])  # one arm: the root
    (1, 1, 0)
    """
    parents = np.asarray(parents, dtype=np.intp)
    if len(shoulders) >= 2:
        above = set()
        j = int(parents[shoulders[0]])
        while j >= 0:
            above.add(j)
            j = int(parents[j])
        j = int(parents[shoulders[1]])
        while j >= 0 and j not in above:
            j = int(parents[j])
        if j >= 0:
            return j
    n_children = np.bincount(parents[parents >= 0], minlength=len(parents))
    j = int(parents[shoulders[0]])
    if j < 0:  # the shoulder is the root
        return int(shoulders[0])
    while n_children[j] < 2 and parents[j] >= 0:
        j = int(parents[j])
    return j


def _local(rotations: np.ndarray, origin: np.ndarray, points: np.ndarray) -> np.ndarray:
    """``rotations^T @ (points - origin)``: world points ``(n, 3)`` in frames ``(n, 3, 3)`` at ``origin`` ``(n, 3)``."""
    out: np.ndarray = np.einsum("nji,nj->ni", rotations, points - origin)
    return out


def shoulder_offsets(
    torso_position: np.ndarray,
    torso_rotation: np.ndarray,
    shoulder: np.ndarray,
    *,
    side: str,
    spine_axis: np.ndarray | Sequence[float] = (0.0, 1.0, 0.0),
    other_shoulder: np.ndarray | None = None,
    good: np.ndarray | None = None,
) -> np.ndarray:
    """``(2, 3)`` the left and right shoulders' offsets from the torso joint, in its frame (file units).

    ``torso_position``, ``shoulder`` (of ``side``) and ``other_shoulder``: ``(n, 3)`` file units, BVH
    world; ``torso_rotation`` ``(n, 3, 3)`` the torso joint's frame -> world (the rotations of the
    chain from the root up to the joint carrying the shoulders, :func:`torso_joint`).

    With ``other_shoulder`` and some ``good`` ``(n,)`` frames (where both shoulders gave a body frame):
    each shoulder's mean offset over those frames.  Otherwise (a one-armed rig, or no good frame) the
    ``side`` shoulder's mean offset over every frame, and for the other shoulder the same turned half a
    turn about ``spine_axis`` ``(3,)``, the spine's direction in the torso joint's frame (in the rest
    pose, where every frame is the world's: from the root up to the torso joint, or the BVH up axis).
    Both rows are equal when nothing separates the shoulders.

    >>> R = np.eye(3)[None]
    >>> shoulder_offsets([[0.0, 50, 0]], R, [[18.0, 60, 0]], side="left").tolist()
    [[18.0, 10.0, 0.0], [-18.0, 10.0, 0.0]]
    """
    R = np.asarray(torso_rotation, dtype=np.float64)
    origin = np.asarray(torso_position, dtype=np.float64)
    own = _local(R, origin, np.asarray(shoulder, dtype=np.float64))
    if other_shoulder is not None and good is not None and np.any(good):
        use = np.asarray(good, dtype=bool)
        mine = own[use].mean(axis=0)
        theirs = _local(R, origin, np.asarray(other_shoulder, dtype=np.float64))[use].mean(axis=0)
    else:
        mine = own.mean(axis=0)
        axis = np.asarray(spine_axis, dtype=np.float64)
        axis = axis / float(np.linalg.norm(axis))
        theirs = 2.0 * float(mine @ axis) * axis - mine
    return np.stack([mine, theirs] if side == "left" else [theirs, mine])


def spine_frames(
    hips: np.ndarray, torso_position: np.ndarray, torso_rotation: np.ndarray, offsets: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Body frames from the spine and hips: :func:`body_frames_masked` of shoulders carried by the torso joint.

    ``hips``, ``torso_position`` ``(n, 3)`` file units, BVH world; ``torso_rotation`` ``(n, 3, 3)``
    the torso joint's frame -> world; ``offsets`` ``(2, 3)`` the left and right shoulders in the torso
    joint's frame (:func:`shoulder_offsets`).  Each frame's shoulders are the torso joint's position
    plus the offsets turned by its rotation, so the frames match the shoulder-based ones exactly while
    the clavicles are still, and within a few degrees otherwise.  Returns ``(frames (n, 3, 3), ok (n,)
    bool)`` as :func:`body_frames_masked`.

    >>> turn = np.array([[0.0, 0, 1], [0, 1, 0], [-1, 0, 0]])  # the torso turned 90 degrees about +y
    >>> R = np.stack([np.eye(3), turn])
    >>> hips, chest = np.zeros((2, 3)), np.tile([0.0, 50, 0], (2, 1))
    >>> frames, ok = spine_frames(hips, chest, R, np.array([[18.0, 10, 0], [-18.0, 10, 0]]))
    >>> frames[:, :, 1].round(6).tolist(), ok.tolist()  # the body's left follows the torso
    ([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0]], [True, True])
    """
    R = np.asarray(torso_rotation, dtype=np.float64)
    origin = np.asarray(torso_position, dtype=np.float64)
    carried = origin[:, None, :] + np.einsum("nij,sj->nsi", R, np.asarray(offsets, dtype=np.float64))
    return body_frames_masked(hips, carried[:, 0], carried[:, 1])


def hold_good_frames(values: np.ndarray, good: np.ndarray) -> np.ndarray:
    """``values`` ``(n, ...)`` with each row where ``good`` ``(n,)`` is False replaced by the previous good row.

    Rows before the first good one take the first good one.  ``ValueError`` when no row is good.

    >>> hold_good_frames(np.arange(5.0), np.array([False, True, False, False, True])).tolist()
    [1.0, 1.0, 1.0, 1.0, 4.0]
    """
    good = np.asarray(good, dtype=bool)
    if not good.any():
        raise ValueError("Expected at least one good frame, got none")
    index = np.where(good, np.arange(good.size), -1)
    np.maximum.accumulate(index, out=index)
    index[index < 0] = int(np.argmax(good))
    held: np.ndarray = np.asarray(values)[index]
    return held


@dataclass(frozen=True)
class BodyFrames:
    """The body frame of every frame of a clip, and where each came from (:func:`clip_body_frames`)."""

    frames: np.ndarray  #: ``(n_frames, 3, 3)`` columns forward, left, up: BVH-world unit vectors
    #: ``(n_frames,)`` int8: :data:`FROM_SHOULDERS`, :data:`FROM_SPINE` or :data:`HELD` (the previous good frame)
    source: np.ndarray
    torso: str | None = None  #: the torso joint of the spine fallback; None when the shoulders framed every frame

    def count(self, source: int) -> int:
        """How many frames came from ``source``."""
        return int(np.count_nonzero(self.source == source))


def _other_shoulder(motion: Motion, chain: ArmChain) -> tuple[ArmChain | None, str]:
    """The other arm's chain when the clip has a usable one, else None and why not (for the log line)."""
    other = "left" if chain.side == "right" else "right"
    try:
        found = motion.arm_points(other)
    except BvhError:  # its message is for when that arm drives the robot
        return None, f"no {other} arm was found"
    mine = {chain.indices[0], chain.indices[1]}
    if found.indices[0] in mine or found.indices[1] in mine:
        return None, f"the {other} arm found, {' > '.join(found.names)}, shares the {chain.side} arm's joints"
    a, b = chain.indices[0], found.indices[0]
    if torso_joint(motion.parents, [a, b]) in (a, b):
        return None, f"the {other} shoulder {found.names[0]} and the {chain.side} one are on one branch"
    return found, ""


def clip_body_frames(motion: Motion, chain: ArmChain, *, up: Axis = Axis.PY) -> BodyFrames:
    """The body frame of every frame of ``motion``, given the arm ``chain`` that drives the robot.

    Per frame, vectorised: from the shoulders (both arms' shoulder joints and the root, as
    :func:`body_frames`); where they give none (they coincide, as in exporters that write all-zero
    channels, or the other arm is missing: a one-armed rig) from the spine and hips
    (:func:`spine_frames`, with ``up`` the BVH up axis); where neither does, the previous good frame
    (:func:`hold_good_frames`).  Logs one line when a fallback was used (a warning for degenerate
    frames, info for a one-armed rig).  Raises :class:`~retarget.errors.BvhError` (the clip's path)
    when no frame at all gives a body frame.

    >>> from retarget.bvh.parse import DEMO_CLIP, load_bvh
    >>> motion = load_bvh(DEMO_CLIP)
    >>> body = clip_body_frames(motion, motion.arm_points("right"))
    >>> body.frames.shape, body.count(FROM_SHOULDERS), body.torso
    ((630, 3, 3), 630, None)
    """
    positions = motion.positions()
    parents = np.asarray(motion.parents)
    root = int(np.flatnonzero(parents < 0)[0])
    hips = positions[:, root]
    n = motion.n_frames
    shoulder = np.asarray(chain.points[:, 0], dtype=np.float64)
    other, why = _other_shoulder(motion, chain)
    if other is not None:
        theirs = np.asarray(other.points[:, 0], dtype=np.float64)
        left, right = (shoulder, theirs) if chain.side == "left" else (theirs, shoulder)
        frames, ok = body_frames_masked(hips, left, right)
        if ok.all():
            return BodyFrames(frames, np.full(n, FROM_SHOULDERS, dtype=np.int8))
        shoulders = [chain.indices[0], other.indices[0]]
    else:
        frames, ok = np.full((n, 3, 3), np.nan), np.zeros(n, dtype=bool)
        theirs = None
        shoulders = [chain.indices[0]]
    t = torso_joint(parents, shoulders)
    rotations, _ = motion.global_transforms()
    rest = motion.rest_positions()
    axis = rest[t] - rest[root]
    if not np.linalg.norm(axis) > 0:  # the shoulders hang from the root
        axis = up.vector
    offsets = shoulder_offsets(
        positions[:, t], rotations[:, t], shoulder, side=chain.side, spine_axis=axis, other_shoulder=theirs, good=ok
    )
    spine, spine_ok = spine_frames(hips, positions[:, t], rotations[:, t], offsets)
    mirrored = f"the {chain.side} shoulder (mirrored for the other)"
    carried = f"both shoulders as in the {int(ok.sum())} good frames" if ok.any() else f"{mirrored} as in the clip"
    if not spine_ok.any():  # nothing in the clip separates the shoulders (they sit on the spine): the rest pose
        both = len(shoulders) == 2
        offsets = shoulder_offsets(
            rest[t][None],
            np.eye(3)[None],
            rest[shoulders[0]][None],
            side=chain.side,
            spine_axis=axis,
            other_shoulder=rest[shoulders[1]][None] if both else None,
            good=np.ones(1, dtype=bool),
        )
        spine, spine_ok = spine_frames(hips, positions[:, t], rotations[:, t], offsets)
        carried = f"{'both shoulders' if both else mirrored} as in the rest pose"
    usable = ok | spine_ok
    torso = motion.joint_names[t]
    if not usable.any():
        names = f"shoulder {chain.names[0]}" if other is None else f"shoulders {chain.names[0]} and {other.names[0]}"
        raise BvhError(
            f"Expected a torso for the body frame in at least one of the {n} frames, got none: the {names} and "
            f"the spine ({torso}) coincide or line up in every frame and in the rest pose; a fixed forward axis "
            "(the mapping's forward) needs no torso",
            path=motion.path,
        )
    source = np.where(ok, FROM_SHOULDERS, np.where(spine_ok, FROM_SPINE, HELD)).astype(np.int8)
    frames = hold_good_frames(np.where(ok[:, None, None], frames, spine), usable)
    body = BodyFrames(frames, source, torso)
    where = motion.path.name if motion.path else "the clip"
    held = f"; {body.count(HELD)} hold the previous good frame" if body.count(HELD) else ""
    if other is None:
        log.info("%s: body frame from the spine, %s carrying %s, since %s%s", where, torso, carried, why, held)
    else:
        log.warning(
            "%s: the shoulders %s and %s coincide or line up with the spine in %d of %d frames: "
            "%d framed from the spine, %s carrying %s%s",
            where, chain.names[0], other.names[0], n - body.count(FROM_SHOULDERS), n, body.count(FROM_SPINE), torso,
            carried, held,
        )  # fmt: skip
    return body


def fixed_frame(forward: Axis, up: Axis) -> np.ndarray:
    """``(3, 3)`` columns forward, left, up for a fixed BVH forward and up axis."""
    f, u = forward.vector, up.vector
    if abs(float(f @ u)) > 0.5:
        raise ConfigError(
            f"Expected a forward axis perpendicular to up ({up.value})", key="mapping.forward", value=forward.value
        )
    return np.stack([f, np.cross(u, f), u], axis=-1)


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

    With ``config.forward`` AUTO the body frames come from :func:`clip_body_frames`: from both
    shoulders, else (one arm, or shoulders that coincide) from the spine and hips, else the previous
    good frame, with one log line saying which fallback was used.

    Raises :class:`~retarget.errors.BvhError` (a ``ValueError``; naming the clip's path) for a clip
    that cannot drive the arm: no frames (``Frames: 0``), no arm chain for ``config.side``, an arm of
    zero length, or no frame giving a body frame; :class:`~retarget.errors.ConfigError` for a bad
    ``[mapping]`` table.

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
    if motion.n_frames == 0:
        raise BvhError(
            "Expected at least one frame of motion, got Frames: 0 (the clip has no frames)", path=motion.path
        )
    side = config.side.value
    chain = motion.arm_points(side)
    pts = np.asarray(chain.points, dtype=np.float64)  # (n, 3, 3) shoulder, elbow, wrist
    shoulder, elbow, wrist = pts[:, 0], pts[:, 1], pts[:, 2]
    human = float(np.median(np.linalg.norm(elbow - shoulder, axis=-1) + np.linalg.norm(wrist - elbow, axis=-1)))
    if not (math.isfinite(human) and human > 0):
        raise BvhError(
            f"Expected a {side} arm of positive length, got {human:g} (median upper arm + forearm) for "
            f"{' > '.join(chain.names)}",
            path=motion.path,
        )
    hand = _hand_alignment(motion, chain, config) if config.orientation_weight > 0 else None
    if config.forward is Axis.AUTO:
        frames = clip_body_frames(motion, chain, up=config.up).frames
    else:
        frames = fixed_frame(config.forward, config.up)

    geometry = arm_geometry(arm)
    scale = config.arm_scale * geometry.reach / human
    origin = np.asarray(config.origin, dtype=np.float64) if config.origin else default_origin(config, geometry)
    basis = geometry.basis(config.robot_forward)
    raw = map_points(shoulder, wrist, frames, scale=scale, origin=origin, basis=basis)
    rotations = None
    if hand is not None:  # tool orientations in the body frame, then in the base frame
        rotations = basis @ np.einsum("...ji,...jk,kl->...il", frames, hand[0], hand[1])
    return Targets.from_raw(
        raw,
        frame_time=float(motion.frame_time),
        workspace=Workspace.for_arm(arm, config),
        config=config,
        rotations=rotations,
        scale=scale,
    )


def _hand_alignment(motion: Motion, chain: ArmChain, config: MappingConfig) -> tuple[np.ndarray, np.ndarray]:
    """The hand joint's global rotations ``(n, 3, 3)`` (hand local -> BVH world) and the tool's axes in it ``(3, 3)``.

    Tool x = the hand bone (the first child of the wrist joint away from it in the first frame, else the
    forearm direction), tool z = the BVH up axis seen from the hand in the rest pose (rest rotations are
    identity).  An End Site wrist has no rotation of its own: the forearm's is used.
    """
    rotations, positions = motion.global_transforms()
    w = chain.indices[1] if chain.wrist_is_end_site else chain.indices[2]
    R = rotations[:, w]  # (n, 3, 3) hand local -> world
    bones = [positions[0, c] - positions[0, w] for c in motion.children(w)]
    bones.append(np.asarray(chain.points[0, 2] - chain.points[0, 1], dtype=np.float64))  # the forearm
    bone = next((b for b in bones if np.linalg.norm(b) > 0), None)
    if bone is None:
        raise BvhError(
            f"Expected a hand bone or forearm of positive length in the first frame to follow the hand's "
            f"orientation, got none for {' > '.join(chain.names)}",
            path=motion.path,
        )
    x = R[0].T @ bone
    x /= np.linalg.norm(x)
    z = config.up.vector - (config.up.vector @ x) * x
    if np.linalg.norm(z) < 1e-6:
        z = np.cross(x, [1.0, 0.0, 0.0]) if abs(x[0]) < 0.9 else np.cross(x, [0.0, 0.0, 1.0])
    z /= np.linalg.norm(z)
    return R, np.stack([x, np.cross(z, x), z], axis=-1)  # tool -> hand local
