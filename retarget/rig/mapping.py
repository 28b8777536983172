"""Both human arms onto a rig's arms in one world frame, keeping the relation between the two hands.

One arm alone maps its wrist relative to its own shoulder (:mod:`retarget.mapping.targets`).  On a rig that
would lose what the two hands do to each other: hands that meet in the clip would each land at their own
arm's origin.  So a rig maps every hand relative to the **middle of the two shoulders**, in **one body
frame** and with **one scale** for both arms, onto one point of the world:

    world target = origin + scale x basis(body frame^T (wrist - mid-shoulders))

``scale = arm_scale x (the shortest arm's reach) / (the human arm length, both sides' median)``, and ``origin``
(where the middle of the shoulders lands) is the mean of the arms' own default origins, in the world.  Each
hand's world target then goes into its own arm's base frame, where that arm's workspace clamps it as on one
arm.  Hands that meet in the clip meet in front of the rig; hands held apart stay apart, by ``scale`` times
their distance (exactly, wherever neither target is clamped).

Arrays: BVH file units in; targets ``(n_frames, 3)`` float64 metres, each arm's base frame (``Targets``), or
the world (``RigTargets.world``).  Math only.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from retarget.bvh.motion import Motion
from retarget.errors import BvhError, ConfigError
from retarget.mapping.body import mapping_frames
from retarget.mapping.config import MappingConfig
from retarget.mapping.targets import Targets, map_points
from retarget.mapping.workspace import Workspace, arm_geometry, default_origin
from retarget.rig.spec import Rig

if TYPE_CHECKING:
    from retarget.collision import CollisionModel

__all__ = ["RigTargets", "rig_targets"]


@dataclass(frozen=True)
class RigTargets:
    """Per-frame targets of one clip on a rig: ``arms`` maps each rig arm's name to its
    :class:`~retarget.mapping.targets.Targets` (base frame, clamped into its workspace); ``world`` maps it to the
    unclamped targets ``(n_frames, 3)`` metres in the world; ``scale`` metres per file unit, shared."""

    arms: dict[str, Targets]
    world: dict[str, npt.NDArray[np.float64]]
    scale: float
    origin: npt.NDArray[np.float64]  #: ``(3,)`` metres, world: where the middle of the shoulders lands


def rig_targets(
    motion: Motion,
    rig: Rig,
    config: MappingConfig | None = None,
    *,
    collision: dict[str, CollisionModel] | None = None,
) -> RigTargets:
    """Targets for every frame of ``motion`` on every arm of ``rig`` (see the module docstring).

    ``config``: the mapping shared by the arms (its ``side`` is replaced by each arm's); default the first
    arm's ``[mapping]`` table.  Position only: a ``config.orientation_weight > 0`` is a ConfigError.
    ``collision``: per arm name, a model whose blocked zones that arm's targets are pushed out of.

    Raises :class:`~retarget.errors.BvhError` (the clip's path) when the clip lacks an arm the rig needs or
    has no frames.

    >>> from retarget.bvh.parse import DEMO_CLIP, load_bvh
    >>> from retarget.rig import load_rig
    >>> targets = rig_targets(load_bvh(DEMO_CLIP), load_rig("wx250s-pair"))
    >>> sorted(targets.arms), targets.arms["left"].positions.shape
    (['left', 'right'], (630, 3))
    """
    first = rig.arms[0].arm
    if config is None:
        config = MappingConfig.from_table(first.mapping, path=first.source)
    if config.orientation_weight > 0:
        raise ConfigError("Expected 0 for a rig (rigs follow positions only)", key="mapping.orientation_weight",
                          value=config.orientation_weight)  # fmt: skip
    if motion.n_frames == 0:
        raise BvhError(
            "Expected at least one frame of motion, got Frames: 0 (the clip has no frames)", path=motion.path
        )
    sides = {a.side.value for a in rig.arms} | {"left", "right"}
    chains = {side: motion.arm_points(side) for side in sorted(sides)}
    points = {side: np.asarray(c.points, dtype=np.float64) for side, c in chains.items()}  # (n, 3, 3) each
    middle = 0.5 * (points["left"][:, 0] + points["right"][:, 0])
    human = _human_arm_length(motion, points)
    frames = mapping_frames(motion, chains[rig.arms[0].side.value], config.forward, config.up)
    geometries = [arm_geometry(a.arm) for a in rig.arms]
    scale = config.arm_scale * min(g.reach for g in geometries) / human
    origins = [a.placement.to_world(default_origin(config, g)) for a, g in zip(rig.arms, geometries, strict=True)]
    origin = np.mean(origins, axis=0)
    arms, world = {}, {}
    for rig_arm in rig.arms:
        wrist = points[rig_arm.side.value][:, 2]
        world[rig_arm.name] = map_points(middle, wrist, frames, scale=scale, origin=origin)
        own = replace(config, side=rig_arm.side)
        model = None if collision is None else collision.get(rig_arm.name)
        arms[rig_arm.name] = Targets.from_raw(
            rig_arm.placement.to_base(world[rig_arm.name]),
            frame_time=float(motion.frame_time),
            workspace=Workspace.for_arm(rig_arm.arm, own).with_blocked(model),
            config=own,
            scale=scale,
        )
    return RigTargets(arms=arms, world=world, scale=float(scale), origin=origin)


def _human_arm_length(motion: Motion, points: dict[str, npt.NDArray[np.float64]]) -> float:
    """The human arm length (file units): the median over frames and both sides of upper arm + forearm."""
    lengths = [
        np.linalg.norm(p[:, 1] - p[:, 0], axis=-1) + np.linalg.norm(p[:, 2] - p[:, 1], axis=-1) for p in points.values()
    ]
    human = float(np.median(np.concatenate(lengths)))
    if not (np.isfinite(human) and human > 0):
        raise BvhError(
            f"Expected arms of positive length, got {human:g} (median upper arm + forearm)", path=motion.path
        )
    return human
