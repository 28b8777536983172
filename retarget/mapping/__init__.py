"""Human to arm: the wrist relative to the shoulder, in a torso body frame, scaled into the arm's workspace.

- :mod:`~retarget.mapping.config`: :class:`MappingConfig` (the ``[mapping]`` table), :class:`Side`, :class:`Axis`;
- :mod:`~retarget.mapping.geometry`: body frames, the arm's shoulder pivot and reach, its workspace,
  :func:`retarget_targets` (a clip on an arm: :class:`Targets`) and the IK weights that follow them.
"""

from retarget.mapping.config import Axis, MappingConfig, Side
from retarget.mapping.geometry import (
    ArmGeometry,
    Targets,
    Workspace,
    arm_geometry,
    body_frames,
    default_origin,
    fixed_frame,
    ik_weights,
    map_points,
    retarget_targets,
)

__all__ = [
    "ArmGeometry",
    "Axis",
    "MappingConfig",
    "Side",
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
