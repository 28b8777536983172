"""BVH motion capture in: parse, Euler maths, vectorised FK, and the arm chain of any skeleton.

- :mod:`~retarget.bvh.parse`: :func:`load_bvh` / :func:`parse_bvh`, the header and the frame block;
- :mod:`~retarget.bvh.numbers`: the fast number reader behind the frame block;
- :mod:`~retarget.bvh.rotations`: Euler angles to rotation matrices, in any channel order;
- :mod:`~retarget.bvh.fk`: forward kinematics of every frame at once;
- :mod:`~retarget.bvh.motion`: :class:`Motion`, a parsed clip and its joint positions;
- :mod:`~retarget.bvh.skeleton`: naming tables and the shoulder > elbow > wrist detection.
"""

from retarget.bvh.fk import Pose, forward_kinematics
from retarget.bvh.motion import ArmChain, ChannelLayout, EndSite, Motion
from retarget.bvh.parse import DEMO_CLIP, load_bvh, parse_bvh
from retarget.bvh.skeleton import ArmJoints, UnitsGuess, find_arm, guess_units

__all__ = [
    "DEMO_CLIP",
    "ArmChain",
    "ArmJoints",
    "ChannelLayout",
    "EndSite",
    "Motion",
    "Pose",
    "UnitsGuess",
    "find_arm",
    "forward_kinematics",
    "guess_units",
    "load_bvh",
    "parse_bvh",
]
