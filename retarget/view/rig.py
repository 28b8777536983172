"""What a rig's view draws, as plain numpy: every arm at its base pose in the rig's world frame, and the human
skeleton placed in that world exactly as the rig's mapping places it (:mod:`retarget.rig.mapping`), so each hand
lands on its own arm's raw target.  No drawing library here (the sheet and the Rerun log draw it).

Frames and units: each arm's own :class:`~retarget.view.scene.Scene` stays in its base frame (metres); its
:class:`~retarget.rig.spec.Placement` takes it to the world (metres, z up, the table at z = 0, x forward).  The
human's :class:`~retarget.view.scene.Scene` (layout OVERLAY) has the world as its display frame:
``world = origin + scale * body^T (p - mid-shoulders)``, per frame, as :func:`~retarget.rig.mapping.rig_targets`.

    scene = RigScene.for_clip(motion, rig, targets)
    links, tools = scene.arm_points("left", q)   # (n, n_joints + 1, 3) metres, world; (n, 4, 4) world from tool
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from retarget.arm.model import Arm
from retarget.bvh.motion import Motion
from retarget.control.loop import TickRecord
from retarget.control.tracking import at_velocity_limit
from retarget.mapping.body import mapping_frames
from retarget.mapping.config import Side
from retarget.rig.mapping import RigTargets
from retarget.rig.spec import Placement, Rig
from retarget.view.columns import TickColumns
from retarget.view.scene import Layout, LinkShapes, Scene, Skeleton, robot_points, skeleton_points

__all__ = ["RigArmScene", "RigScene", "arm_columns", "upper_body"]


@dataclass(frozen=True)
class RigArmScene:
    """One arm of the rig: its ``name``, the human ``side`` that drives it, its base ``placement`` in the world
    and its own ``scene`` (base frame: the arm, its workspace, its targets, its link shapes; no skeleton)."""

    name: str
    side: Side
    placement: Placement
    scene: Scene

    def to_world(self, points: np.ndarray) -> np.ndarray:
        """Points ``(..., 3)`` metres, this arm's base frame -> the world ``(..., 3)``."""
        return self.placement.to_world(points)


@dataclass(frozen=True)
class RigScene:
    """Everything static about a rig's view of a clip (see the module docstring).

    >>> from retarget.bvh.parse import DEMO_CLIP, load_bvh
    >>> from retarget.rig import load_rig, rig_targets
    >>> rig, motion = load_rig("wx250s-pair"), load_bvh(DEMO_CLIP)
    >>> scene = RigScene.for_clip(motion, rig, rig_targets(motion, rig))
    >>> [a.name for a in scene.arms], scene["right"].placement.xyz
    (['left', 'right'], (0.0, -0.3, 0.0))
    >>> links, tools = scene.arm_points("right", rig["right"].arm.home[None])
    >>> links[0, 0].round(3).tolist()   # the waist joint's origin, over the right base
    [0.0, -0.3, 0.072]
    """

    rig: Rig
    arms: tuple[RigArmScene, ...]
    human: Scene  #: the skeleton in the world (its display frame), layout OVERLAY
    chains: dict[str, tuple[int, int, int]]  #: per arm name: the skeleton points of its human shoulder, elbow, wrist
    upper: np.ndarray  #: ``(n_bones,)`` bool: the skeleton's bones above the hips (what the sheet draws)
    table: bool  #: the arms' collision world has the table at z = 0

    @classmethod
    def for_clip(cls, motion: Motion, rig: Rig, targets: RigTargets, *, table: bool = True) -> RigScene:
        """The scene of ``motion`` mapped onto ``rig`` as ``targets`` (from :func:`~retarget.rig.rig_targets`)."""
        arms = tuple(RigArmScene(a.name, a.side, a.placement, _arm_scene(a.arm, targets, a.name)) for a in rig.arms)
        first = targets.arms[rig.arms[0].name]
        config = first.config
        chains = {side: motion.arm_points(side) for side in ("left", "right")}
        body = np.broadcast_to(
            mapping_frames(motion, chains[rig.arms[0].side.value], config.forward, config.up), (motion.n_frames, 3, 3)
        )
        middle = 0.5 * (chains["left"].points[:, 0] + chains["right"].points[:, 0])  # (n_frames, 3) file units
        linear = targets.scale * np.transpose(body, (0, 2, 1))  # world from BVH: scale * body^T, per frame
        offset = targets.origin - np.einsum("fij,fj->fi", linear, middle)
        skeletons = {side: Skeleton.of(motion, chain) for side, chain in chains.items()}
        skeleton = skeletons[rig.arms[0].side.value]
        human = Scene(
            arm=rig.arms[0].arm,
            workspace=first.workspace,
            layout=Layout.OVERLAY,
            motion=motion,
            targets=first,
            skeleton=skeleton,
            points=skeleton_points(motion),
            body=np.asarray(body),
            torso=np.asarray(middle, dtype=np.float64),
            human_linear=linear,
            human_offset=offset,
        )
        chain_of = {a.name: skeletons[a.side.value].chain for a in rig.arms}
        return cls(rig, arms, human, chain_of, upper_body(motion, skeleton), table)

    def __getitem__(self, name: str) -> RigArmScene:
        for a in self.arms:
            if a.name == name:
                return a
        raise KeyError(name)

    def arm_points(self, name: str, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Arm ``name`` posed at ``q`` ``(n, n_joints)`` rad: its joint origins then tool point ``(n, n_joints + 1,
        3)`` metres, world, and its tool frames ``(n, 4, 4)`` (world from tool)."""
        a = self[name]
        points, tools = robot_points(a.scene.arm, q)
        return a.to_world(points), a.placement.matrix @ tools

    def capsules(self, name: str, q: np.ndarray) -> np.ndarray | None:
        """Arm ``name``'s link capsules at ``q`` ``(n, n_joints)`` rad: end points ``(n, n_capsules, 2, 3)``
        metres, world; None when its arm file has no link geometry."""
        a = self[name]
        return None if a.scene.links is None else a.to_world(a.scene.links.capsules(q))

    def raw_targets(self, name: str, clip_time: np.ndarray) -> np.ndarray:
        """Arm ``name``'s targets before its workspace clamp at ``clip_time`` ``(n,)`` s: ``(n, 3)`` metres, world."""
        a = self[name]
        raw = a.scene.raw_targets(clip_time)
        assert raw is not None  # every arm's scene has its targets
        return a.to_world(raw)


def _arm_scene(arm: Arm, targets: RigTargets, name: str) -> Scene:
    own = targets.arms[name]
    return Scene(arm=arm, workspace=own.workspace, layout=Layout.OVERLAY, targets=own, links=LinkShapes.of(arm))


def upper_body(motion: Motion, skeleton: Skeleton) -> np.ndarray:
    """``(n_bones,)`` bool: the bones of the branch from the root that holds the shoulders (spine, arms, neck,
    head) and the root's bone to it; the legs are left out (in a rig's world they hang below the table).

    >>> from retarget.bvh.parse import DEMO_CLIP, load_bvh
    >>> motion = load_bvh(DEMO_CLIP)
    >>> skeleton = Skeleton.of(motion, motion.arm_points("left"))
    >>> upper = upper_body(motion, skeleton)
    >>> names = [skeleton.names[b] for _, b in skeleton.bones[upper]]
    >>> "Spine" in names, "LeftUpLeg" in names, 0 < int(upper.sum()) < len(upper)
    (True, False, True)
    """
    parent = [*(int(p) for p in motion.parents), *(e.parent for e in motion.end_sites)]
    branch = skeleton.chain[0]
    while parent[branch] >= 0 and parent[parent[branch]] >= 0:  # climb to the root's child holding the shoulder
        branch = parent[branch]
    keep = np.zeros(len(parent), dtype=bool)
    for point in range(len(parent)):
        p = point
        while p >= 0 and p != branch:
            p = parent[p]
        keep[point] = p == branch
    if parent[branch] >= 0:
        keep[parent[branch]] = True  # the root, for its bone to the branch
    mask: np.ndarray = keep[skeleton.bones[:, 1]] & keep[skeleton.bones[:, 0]]
    return mask


def arm_columns(
    records: Sequence[TickRecord], split: Callable[[TickRecord, str], TickRecord], rig: Rig, *, rate: float
) -> dict[str, TickColumns]:
    """Each arm's :class:`~retarget.view.columns.TickColumns` (its target in its base frame, its joints, its IK),
    by arm name, from the rig's tick ``records`` (``rate`` ticks/s) and ``split(record, name)``
    (:meth:`~retarget.rig.replay.RigReplay.arm_record`).  ``velocity_limited`` is the arm's own
    (:func:`~retarget.control.tracking.at_velocity_limit` of its commanded joints, as its summary counts it), not
    the rig's limiter flag, which is one for every arm."""
    columns = {}
    for a in rig.arms:
        own = TickColumns.of([split(r, a.name) for r in records])
        limited = at_velocity_limit(own.q_cmd, rate=rate, max_velocity=a.arm.max_velocity)
        columns[a.name] = replace(own, velocity_limited=limited)
    return columns
