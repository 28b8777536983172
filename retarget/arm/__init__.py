"""The arm model: joints, limits, servos and poses, read from TOML or imported from a URDF, and its kinematics.

- :mod:`~retarget.arm.load`: :func:`load_arm`, the one entry point: a bundled name, a TOML file or a URDF;
- :mod:`~retarget.arm.model`: :class:`Arm`, :class:`Joint`, :class:`Servo`, :class:`Gripper` (frozen specs);
- :mod:`~retarget.arm.config`: the TOML arm files (schema and validating reader) and the bundled arms;
- :mod:`~retarget.arm.urdf`: URDF import of one chain, with its servo file;
- :mod:`~retarget.arm.kinematics`: forward kinematics, one pose or a batch, and the rotation helpers.
"""

from retarget.arm.config import URDF_SUFFIXES, ArmFileReader, arm_dirs, is_urdf, list_arms, read_toml, resolve_arm
from retarget.arm.kinematics import Chain, axis_angle_matrix, fk, fk_batch, matrix_rpy, rpy_matrix, transform
from retarget.arm.load import load_arm
from retarget.arm.model import SERVO_MODELS, Arm, Gripper, Joint, JointType, Servo
from retarget.arm.urdf import UrdfJoint, UrdfModel, find_chain, load_urdf_arm, parse_urdf, servo_file

__all__ = [
    "SERVO_MODELS",
    "URDF_SUFFIXES",
    "Arm",
    "ArmFileReader",
    "Chain",
    "Gripper",
    "Joint",
    "JointType",
    "Servo",
    "UrdfJoint",
    "UrdfModel",
    "arm_dirs",
    "axis_angle_matrix",
    "find_chain",
    "fk",
    "fk_batch",
    "is_urdf",
    "list_arms",
    "load_arm",
    "load_urdf_arm",
    "matrix_rpy",
    "parse_urdf",
    "read_toml",
    "resolve_arm",
    "rpy_matrix",
    "servo_file",
    "transform",
]
