"""Human to arm: the wrist relative to the shoulder, in a torso body frame, scaled into the arm's workspace.

- :mod:`~retarget.mapping.config`: :class:`MappingConfig` (the ``[mapping]`` table), :class:`Side`, :class:`Axis`;
- :mod:`~retarget.mapping.torso`: body frames from torso points, per frame: from the shoulders and hips
  (:func:`body_frames`, :func:`body_frames_masked`), or from the spine and hips (:func:`torso_joint`,
  :func:`shoulder_offsets`, :func:`spine_frames`);
- :mod:`~retarget.mapping.body`: the body frame of every frame of a clip (from the shoulders, else the spine
  and hips, else the previous good frame: :func:`clip_body_frames`, :class:`BodyFrames`,
  :func:`hold_good_frames`), or a fixed one (:func:`fixed_frame`);
- :mod:`~retarget.mapping.workspace`: the arm's shoulder pivot and reach (:class:`ArmGeometry`,
  :func:`arm_geometry`, :func:`default_origin`), its :class:`Workspace` and the IK weights that follow
  the targets (:func:`ik_weights`);
- :mod:`~retarget.mapping.targets`: the mapping itself, :func:`map_points`, and :func:`retarget_targets`
  (a clip on an arm: :class:`Targets`).
"""

from retarget.mapping.body import BodyFrames, clip_body_frames, fixed_frame, hold_good_frames
from retarget.mapping.config import Axis, MappingConfig, Side
from retarget.mapping.targets import Targets, map_points, retarget_targets
from retarget.mapping.torso import body_frames, body_frames_masked, shoulder_offsets, spine_frames, torso_joint
from retarget.mapping.workspace import ArmGeometry, Workspace, arm_geometry, default_origin, ik_weights

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
    "shoulder_offsets",
    "spine_frames",
    "torso_joint",
]
