"""Rigs: several arms in one world frame (bimanual replay and teleop build on this).

:func:`load_rig` reads a rig file (bundled under ``config/rigs/``: ``aloha``, ``wx250s-pair``); a
:class:`Rig` holds :class:`RigArm` entries, each an :class:`~retarget.arm.model.Arm` with its base's
:class:`Placement` in the world, its port and the human side that drives it.  Bimanual teleop: two-arm
messages (:mod:`~retarget.rig.messages`) on a :class:`RigInput`, one follower per arm (:func:`run_rig_teleop`).
"""

from retarget.rig.bus import RigBus
from retarget.rig.inputs import RigInput, RigStdinSource, RigUdpSource
from retarget.rig.mapping import RigTargets, rig_targets
from retarget.rig.messages import RigGate, parse_rig_message
from retarget.rig.plant import RigPlant
from retarget.rig.replay import RigReplay
from retarget.rig.spec import Placement, Rig, RigArm, list_rigs, load_rig, rig_dirs
from retarget.rig.summary import RigSummary
from retarget.rig.teleop import RigTeleopResult, rig_followers, run_rig_teleop

__all__ = [
    "Placement",
    "Rig",
    "RigArm",
    "RigBus",
    "RigGate",
    "RigInput",
    "RigPlant",
    "RigReplay",
    "RigStdinSource",
    "RigSummary",
    "RigTargets",
    "RigTeleopResult",
    "RigUdpSource",
    "list_rigs",
    "load_rig",
    "parse_rig_message",
    "rig_dirs",
    "rig_followers",
    "rig_targets",
    "run_rig_teleop",
]
