"""What the views draw, as plain numpy: the human skeleton, its placement next to or onto the robot, the
workspace and the robot's links.  No drawing library here, so all of it is testable without the viz extra.

Frames and units: the skeleton stays in BVH file units and the BVH world frame; a per-frame affine
:attr:`Scene.human_linear` / :attr:`Scene.human_offset` places it in the display frame, which is the robot's
base frame (metres, z up).  Two layouts (:class:`Layout`): ``SIDE`` stands the human next to the robot at the
mapping's scale (so the human arm is as long as the robot arm it drives), facing the robot's forward;
``OVERLAY`` puts the human into the robot's frame exactly as the mapping does (the chosen shoulder on the
mapping's origin, the body frame turned onto the robot's forward/left/up), so the human wrist lands on the
raw target.

    scene = Scene.for_clip(motion, arm, targets, layout=Layout.SIDE)
    pts = scene.human_points(frame)        # (n_points, 3) metres, display frame
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

import numpy as np

from retarget.arm.model import Arm
from retarget.bvh.motion import ArmChain, Motion
from retarget.collision import CollisionModel
from retarget.errors import BvhError
from retarget.mapping import Targets, Workspace, arm_geometry, default_origin
from retarget.mapping.body import mapping_frames

__all__ = [
    "Layout",
    "LinkShapes",
    "Scene",
    "Skeleton",
    "capsule_poses",
    "frame_index",
    "project",
    "robot_points",
    "workspace_strips",
]


class Layout(enum.Enum):
    SIDE = "side"  #: the human stands beside the robot, same scale
    OVERLAY = "overlay"  #: the human in the robot's frame, shoulder on the mapping's origin


@dataclass(frozen=True)
class Skeleton:
    """The bones of a clip: its points are the joints (file order) then the End Sites (file order)."""

    names: tuple[str, ...]  #: one per point; End Sites as ``"<parent>/End Site"``
    bones: np.ndarray  #: ``(n_bones, 2)`` int, point indices (parent, child)
    chain: tuple[int, int, int]  #: point indices of the driving arm's shoulder, elbow, wrist

    @classmethod
    def of(cls, motion: Motion, chain: ArmChain) -> Skeleton:
        n = motion.n_joints
        names = [*motion.joint_names, *(f"{motion.joint_names[e.parent]}/End Site" for e in motion.end_sites)]
        bones = [(int(p), j) for j, p in enumerate(motion.parents) if p >= 0]
        bones += [(e.parent, n + i) for i, e in enumerate(motion.end_sites)]
        s, e, w = chain.indices
        return cls(
            tuple(names), np.array(bones, dtype=np.intp).reshape(-1, 2), (s, e, n + w if chain.wrist_is_end_site else w)
        )


def skeleton_points(motion: Motion) -> np.ndarray:
    """``(n_frames, n_joints + n_end_sites, 3)`` float64, file units, BVH world: joints then End Sites."""
    return np.concatenate([motion.positions(), motion.end_site_positions()], axis=1)


def frame_index(clip_time: np.ndarray | float, frame_time: float, n_frames: int) -> np.ndarray:
    """The clip frame shown at ``clip_time`` seconds (nearest frame, within the clip): int array like the input."""
    return np.clip(np.rint(np.asarray(clip_time, dtype=np.float64) / frame_time), 0, n_frames - 1).astype(np.intp)


@dataclass(frozen=True)
class LinkShapes:
    """The arm file's link geometry as drawn: its capsules posed by the collision model (the same numbers the
    collision checks use), and its boxes on the base frame (static).  Boxes on moving links are not drawn."""

    model: CollisionModel
    names: tuple[str, ...]  #: one per capsule, in the order of :meth:`capsules`
    radii: np.ndarray  #: ``(n_capsules,)`` metres
    base_boxes: tuple[tuple[str, np.ndarray, np.ndarray], ...]  #: (name, centre ``(3,)``, half size ``(3,)``), metres

    @classmethod
    def of(cls, arm: Arm) -> LinkShapes | None:
        """The shapes of ``arm``, or None when its file has no link geometry (``[collision]``)."""
        if arm.geometry is None:
            return None
        from retarget.collision import Box, Capsule

        links = arm.geometry.links
        model = CollisionModel.for_arm(arm)
        boxes = tuple((link.name, np.asarray(link.shape.center, dtype=np.float64),
                       np.asarray(link.shape.half_size, dtype=np.float64))
                      for link in links if isinstance(link.shape, Box) and link.frame == 0)  # fmt: skip
        names = tuple(link.name for link in links if isinstance(link.shape, Capsule))
        return cls(model, names, model.capsules(arm.home)[1], boxes)

    def capsules(self, q: np.ndarray) -> np.ndarray:
        """``(n, n_capsules, 2, 3)`` metres, base frame: each capsule's end points for the poses ``q``
        ``(n, n_joints)`` radians."""
        q = np.asarray(q, dtype=np.float64).reshape(-1, self.model.arm.n_joints)
        if q.shape[0] == 0:
            return np.zeros((0, len(self.names), 2, 3))
        ends: np.ndarray = self.model.capsules(q)[0]
        return ends


def capsule_poses(ends: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Capsules given by their end points ``(m, 2, 3)`` as Rerun draws them (from the origin along +z, then
    rotated and moved): lengths ``(m,)``, quaternions ``(m, 4)`` (x, y, z, w) turning +z onto ``b - a``, and
    translations ``(m, 3)`` (= ``a``).

    >>> lengths, quats, at = capsule_poses(np.array([[[0.0, 0, 0], [0, 2.0, 0]], [[1.0, 1, 1], [1, 1, 0]]]))
    >>> lengths.tolist(), quats.round(4).tolist()
    ([2.0, 1.0], [[-0.7071, 0.0, 0.0, 0.7071], [1.0, 0.0, 0.0, 0.0]])
    """
    a = ends[:, 0]
    d = ends[:, 1] - a
    lengths = np.linalg.norm(d, axis=-1)
    u = np.divide(d, lengths[:, None], out=np.tile([0.0, 0.0, 1.0], (len(d), 1)), where=lengths[:, None] > 1e-12)
    # the half-way quaternion from z to u: (z x u, 1 + z.u), normalised; u = -z: half a turn about x
    quats = np.stack([-u[:, 1], u[:, 0], np.zeros(len(u)), 1.0 + u[:, 2]], axis=-1)
    flip = quats[:, 3] < 1e-9
    quats[flip] = [1.0, 0.0, 0.0, 0.0]
    quats /= np.linalg.norm(quats, axis=-1, keepdims=True)
    return lengths, quats, a


@dataclass(frozen=True)
class Scene:
    """Everything static about one view: the arm, its workspace, and (for a clip) the human and its placement."""

    arm: Arm
    workspace: Workspace
    layout: Layout = Layout.SIDE
    motion: Motion | None = None
    targets: Targets | None = None
    skeleton: Skeleton | None = None
    points: np.ndarray | None = None  #: ``(n_frames, n_points, 3)`` file units, BVH world
    body: np.ndarray | None = None  #: ``(n_frames, 3, 3)`` torso frames, columns forward, left, up (BVH world)
    torso: np.ndarray | None = None  #: ``(n_frames, 3)`` file units: the body frame's origin (mid-shoulders)
    human_linear: np.ndarray | None = None  #: ``(n_frames, 3, 3)`` BVH world -> display, incl. the scale
    human_offset: np.ndarray | None = None  #: ``(n_frames, 3)`` metres, display frame
    links: LinkShapes | None = None  #: the arm's link geometry; None when the arm file has none

    @classmethod
    def for_arm(cls, arm: Arm, workspace: Workspace | None = None) -> Scene:
        """A scene of the arm alone (teleop): its workspace with the arm file's mapping table."""
        return cls(arm=arm, workspace=workspace or Workspace.for_arm(arm), links=LinkShapes.of(arm))

    @classmethod
    def for_clip(cls, motion: Motion, arm: Arm, targets: Targets, *, layout: Layout = Layout.SIDE) -> Scene:
        """The scene of ``motion`` mapped onto ``arm`` as ``targets`` (from ``retarget_targets``)."""
        config = targets.config
        chain = motion.arm_points(config.side.value)
        body = np.broadcast_to(mapping_frames(motion, chain, config.forward, config.up), (motion.n_frames, 3, 3))
        torso = _torso_origin(motion, chain)
        geometry = arm_geometry(arm)
        basis = geometry.basis(config.robot_forward)
        s = targets.scale
        n = motion.n_frames
        points = skeleton_points(motion)
        if layout is Layout.OVERLAY:  # as map_points: basis @ body^T @ (p - shoulder) * s + origin
            origin = np.asarray(config.origin, dtype=np.float64) if config.origin else default_origin(config, geometry)
            linear = s * np.einsum("ij,fkj->fik", basis, body)
            offset = origin - np.einsum("fij,fj->fi", linear, chain.points[:, 0])
        else:
            linear, offset = _beside(points, body[0], config.up.vector, basis, s, geometry.reach)
            linear, offset = np.broadcast_to(linear, (n, 3, 3)), np.broadcast_to(offset, (n, 3))
        return cls(
            arm=arm,
            workspace=targets.workspace,
            layout=layout,
            motion=motion,
            targets=targets,
            skeleton=Skeleton.of(motion, chain),
            points=points,
            body=np.asarray(body),
            torso=torso,
            human_linear=np.asarray(linear),
            human_offset=np.asarray(offset),
            links=LinkShapes.of(arm),
        )

    def human_points(self, frame: int) -> np.ndarray:
        """``(n_points, 3)`` metres, display frame: the skeleton's points at clip frame ``frame``."""
        if self.points is None or self.human_linear is None or self.human_offset is None:
            raise ValueError("Expected a scene of a clip, got one of an arm alone")
        placed: np.ndarray = self.points[frame] @ self.human_linear[frame].T + self.human_offset[frame]
        return placed

    def torso_axes(self, frame: int, length: float) -> tuple[np.ndarray, np.ndarray]:
        """The body frame at ``frame`` in the display frame: origin ``(3,)`` and axes ``(3, 3)`` (rows forward,
        left, up), each ``length`` metres."""
        if self.torso is None or self.body is None or self.human_linear is None or self.human_offset is None:
            raise ValueError("Expected a scene of a clip, got one of an arm alone")
        origin = self.human_linear[frame] @ self.torso[frame] + self.human_offset[frame]
        axes = (self.human_linear[frame] @ self.body[frame]).T
        return origin, axes / np.linalg.norm(axes, axis=1, keepdims=True) * length

    def raw_targets(self, clip_time: np.ndarray) -> np.ndarray | None:
        """``(n, 3)`` metres, base frame: the targets before the workspace clamp at ``clip_time`` ``(n,)`` s
        (linear in time between frames, as :meth:`~retarget.mapping.Targets.sample`); None without a clip."""
        if self.targets is None:
            return None
        raw = self.targets.raw
        frames = np.arange(raw.shape[0]) * self.targets.frame_time
        t = np.asarray(clip_time, dtype=np.float64)
        return np.stack([np.interp(t, frames, raw[:, i]) for i in range(3)], axis=-1)


def _torso_origin(motion: Motion, chain: ArmChain) -> np.ndarray:
    """``(n_frames, 3)``: the midpoint of both shoulders, or the driving shoulder for a one-armed rig."""
    other = "left" if chain.side == "right" else "right"
    try:
        other_points = motion.arm_points(other).points
    except BvhError:
        return np.asarray(chain.points[:, 0], dtype=np.float64)
    return np.asarray((chain.points[:, 0] + other_points[:, 0]) / 2, dtype=np.float64)


def _beside(
    points: np.ndarray, body0: np.ndarray, up: np.ndarray, basis: np.ndarray, scale: float, reach: float
) -> tuple[np.ndarray, np.ndarray]:
    """The fixed placement of the SIDE layout: BVH up -> z, the first frame's facing -> the robot's forward,
    scaled, the clip's lowest point on z = 0, the start's root beside the robot (1.3 reach to its right)."""
    forward = body0[:, 0] - (body0[:, 0] @ up) * up
    norm = float(np.linalg.norm(forward))
    forward = forward / norm if norm > 1e-9 else np.cross(up, [1.0, 0.0, 0.0] if abs(up[0]) < 0.9 else [0, 0, 1.0])
    frame = np.stack([forward, np.cross(up, forward), up], axis=-1)  # BVH columns forward, left, up
    linear = scale * basis @ frame.T
    placed = points.reshape(-1, 3) @ linear.T
    root = points[0, 0] @ linear.T
    side = -basis[:, 1] * 1.3 * reach  # on the robot's right: left of it seen from the front
    offset = np.array([-root[0], -root[1], -float(placed[:, 2].min())]) + side
    return linear, offset


def robot_points(arm: Arm, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """FK of joint angles ``q`` ``(n, n_joints)`` rad: joint origins then the tool point ``(n, n_joints + 1, 3)``
    metres and the tool frames ``(n, 4, 4)``, base frame."""
    q = np.asarray(q, dtype=np.float64).reshape(-1, arm.n_joints)
    poses = [arm.fk(row) for row in q]
    if not poses:
        return np.zeros((0, arm.n_joints + 1, 3)), np.zeros((0, 4, 4))
    return np.stack([p for _, p in poses]), np.stack([t for t, _ in poses])


def workspace_strips(ws: Workspace, *, segments: int = 72) -> list[np.ndarray]:
    """Wireframe of the workspace: the outer shell's three great circles above the floor and the floor's circle,
    each an ``(m, 3)`` polyline, metres, base frame."""
    a = np.linspace(0.0, 2 * math.pi, segments + 1)
    c, s, z0 = np.cos(a), np.sin(a), np.zeros_like(a)
    strips: list[np.ndarray] = []
    for circle in (np.stack([c, s, z0], -1), np.stack([c, z0, s], -1), np.stack([z0, c, s], -1)):
        pts = ws.center + ws.r_max * circle
        strips += _split_below(pts, ws.floor)
    dz = ws.floor - ws.center[2]
    if abs(dz) < ws.r_max:
        r = math.sqrt(ws.r_max**2 - dz**2)
        strips.append(np.stack([ws.center[0] + r * c, ws.center[1] + r * s, np.full_like(a, ws.floor)], -1))
    return strips


def _split_below(pts: np.ndarray, floor: float) -> list[np.ndarray]:
    """The runs of a polyline ``(m, 3)`` at or above z = ``floor``."""
    keep = pts[:, 2] >= floor - 1e-9
    runs, start = [], None
    for i, k in enumerate([*keep, False]):
        if k and start is None:
            start = i
        elif not k and start is not None:
            if i - start >= 2:
                runs.append(pts[start:i])
            start = None
    return runs


def project(points: np.ndarray, *, azimuth: float = -60.0, elevation: float = 20.0) -> np.ndarray:
    """Orthographic view of ``points`` ``(..., 3)`` (z up) from ``azimuth``/``elevation`` degrees: ``(..., 2)``
    (right, up) in the same units.  Azimuth 0 looks along -x (from the front of a robot facing +x).

    >>> project(np.array([0.0, 0.0, 1.0])).round(3).tolist()
    [0.0, 0.94]
    """
    az, el = math.radians(azimuth), math.radians(elevation)
    right = np.array([-math.sin(az), math.cos(az), 0.0])
    toward = np.array([math.cos(az) * math.cos(el), math.sin(az) * math.cos(el), math.sin(el)])
    up = np.cross(toward, right)
    stacked: np.ndarray = np.stack([points @ right, points @ up], axis=-1)
    return stacked
