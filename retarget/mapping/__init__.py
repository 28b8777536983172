"""Human to arm: the wrist relative to the shoulder, in a torso body frame, scaled into the arm's workspace.

- :mod:`~retarget.mapping.config`: :class:`MappingConfig` (the ``[mapping]`` table), :class:`Side`, :class:`Axis`;
- :mod:`~retarget.mapping.geometry`: body frames (from the shoulders, else the spine and hips, else the
  previous good frame: :func:`clip_body_frames`), the arm's shoulder pivot and reach, its workspace,
  :func:`retarget_targets` (a clip on an arm: :class:`Targets`) and the IK weights that follow them.
"""

from retarget.mapping.config import Axis, MappingConfig, Side
from retarget.mapping.geometry import (
    ArmGeometry,
    BodyFrames,
    Targets,
    Workspace,
    arm_geometry,
    body_frames,
    body_frames_masked,
    clip_body_frames,
    default_origin,
    fixed_frame,
    hold_good_frames,
    ik_weights,
    map_points,
    retarget_targets,
    spine_frames,
    torso_joint,
)

__all__ = [
    "ArmGeometry",
    "Axis",
    "BodyFrames",
    "MappingConfig",
    "Side",
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
    "spine_frames",
    "torso_joint",
]
