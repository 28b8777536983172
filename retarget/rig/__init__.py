"""Rigs: several arms in one world frame (bimanual replay and teleop build on this).

:func:`load_rig` reads a rig file (bundled under ``config/rigs/``: ``aloha``, ``wx250s-pair``); a
:class:`Rig` holds :class:`RigArm` entries, each an :class:`~retarget.arm.model.Arm` with its base's
:class:`Placement` in the world, its port and the human side that drives it.
"""

from retarget.rig.spec import Placement, Rig, RigArm, list_rigs, load_rig, rig_dirs

__all__ = ["Placement", "Rig", "RigArm", "list_rigs", "load_rig", "rig_dirs"]
