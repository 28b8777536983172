"""Rigs: several arms in one world frame (bimanual replay and teleop build on this).

:func:`load_rig` reads a rig file (bundled under ``config/rigs/``: ``aloha``, ``wx250s-pair``); a
:class:`Rig` holds :class:`RigArm` entries, each an :class:`~retarget.arm.model.Arm` with its base's
:class:`Placement` in the world, its port and the human side that drives it.
"""

from retarget.rig.bus import RigBus
from retarget.rig.mapping import RigTargets, rig_targets
from retarget.rig.plant import RigPlant
from retarget.rig.replay import RigReplay
from retarget.rig.spec import Placement, Rig, RigArm, list_rigs, load_rig, rig_dirs
from retarget.rig.summary import RigSummary

__all__ = [
    "Placement",
    "Rig",
    "RigArm",
    "RigBus",
    "RigPlant",
    "RigReplay",
    "RigSummary",
    "RigTargets",
    "list_rigs",
    "load_rig",
    "rig_dirs",
    "rig_targets",
]
