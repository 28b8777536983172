"""BVH motion capture in: parse, Euler maths, vectorised FK, and the arm chain of any skeleton.

- :mod:`~retarget.bvh.parse`: :func:`load_bvh` / :func:`parse_bvh`, the header and the frame block;
- :mod:`~retarget.bvh.numbers`: the fast number reader behind the frame block;
- :mod:`~retarget.bvh.rotations`: Euler angles to rotation matrices, in any channel order;
- :mod:`~retarget.bvh.fk`: forward kinematics of every frame at once;
- :mod:`~retarget.bvh.motion`: :class:`Motion`, a parsed clip and its joint positions;
- :mod:`~retarget.bvh.skeleton`: the shoulder > elbow > wrist detection's entry points, :func:`find_arm` and
  :func:`search_arm`;
- :mod:`~retarget.bvh.chains`: what the detection returns, :class:`ArmJoints`, :class:`ArmSearch`, :class:`Rejected`;
- :mod:`~retarget.bvh.names`: the naming tables, a joint name's side and role, detection by names;
- :mod:`~retarget.bvh.structure`: the structure fallback and why a limb is not an arm;
- :mod:`~retarget.bvh.proportions`: :func:`height_from_bones` and the arm bone-length checks;
- :mod:`~retarget.bvh.units`: :func:`guess_units`, the length unit from the skeleton's size;
- :mod:`~retarget.bvh.tree`: walking the joint hierarchy.
"""

from retarget.bvh.chains import ArmJoints, ArmSearch, Rejected
from retarget.bvh.fk import Pose, forward_kinematics
from retarget.bvh.motion import ArmChain, ChannelLayout, EndSite, Motion
from retarget.bvh.parse import DEMO_CLIP, load_bvh, parse_bvh
from retarget.bvh.proportions import check_arm_lengths, height_from_bones
from retarget.bvh.skeleton import find_arm, search_arm
from retarget.bvh.units import UnitsGuess, guess_units

__all__ = [
    "DEMO_CLIP",
    "ArmChain",
    "ArmJoints",
    "ArmSearch",
    "ChannelLayout",
    "EndSite",
    "Motion",
    "Pose",
    "Rejected",
    "UnitsGuess",
    "check_arm_lengths",
    "find_arm",
    "forward_kinematics",
    "guess_units",
    "height_from_bones",
    "load_bvh",
    "parse_bvh",
    "search_arm",
]
