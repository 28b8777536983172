"""A rig's look-ahead plan kept clear of each arm's world, as one arm's is (:mod:`~retarget.control.keepclear`).

:class:`RigWorld` gives :func:`~retarget.control.keepclear.keep_clear` what it measures, over the plant's joint
vector: every arm's pairs against its own world (its table, its keep-out zones, in its base frame), each less what
its clearance exceeds the least one by, so that one clearance holds for all.  The arms against each other are left to
the rig's goal check (:mod:`~retarget.rig.check`).  Math only.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import numpy.typing as npt

from retarget.collision import CollisionModel
from retarget.control.keepclear import MARGIN
from retarget.ik.bound import State, shared_bound

__all__ = ["RigWorld"]

Array = npt.NDArray[np.float64]


class RigWorld:
    """The arms' world pairs over a rig's plant: ``models`` by arm name, ``parts`` each arm's ``(name, joints)``
    (its slice of the plant's joint vector).

    >>> import retarget
    >>> from retarget.rig import load_rig
    >>> from retarget.rig.plant import RigPlant
    >>> rig = load_rig("wx250s-pair")
    >>> plant = RigPlant.of(rig)
    >>> world = RigWorld({a.name: CollisionModel.for_arm(a.arm) for a in rig.arms}, list(zip(rig.names, plant.slices)))
    >>> home = np.concatenate([a.arm.home for a in rig.arms])[None]
    >>> world.world_distances(home).shape[0], bool(world.world_distances(home).min() > world.clearance)
    (1, True)
    """

    def __init__(self, models: Mapping[str, CollisionModel], parts: Sequence[tuple[str, slice]]):
        self.models, self.parts = models, list(parts)
        self.clearance = min(float(models[name].clearance) for name, _ in self.parts)  #: metres, the least

    def world_distances(self, q: Array) -> Array:
        """``(n_poses, n_pairs)`` metres of the plant's poses ``q`` ``(n_poses, plant n_joints)`` rad, each arm's
        world pairs less its clearance's excess over :attr:`clearance`."""
        return np.concatenate([self.models[name].world_distances(q[:, part]) - self._excess(name)
                               for name, part in self.parts], axis=1)  # fmt: skip

    def pose_lows(
        self, q: Array, notes: Mapping[str, Sequence[State]], index: Mapping[str, npt.NDArray[np.intp]]
    ) -> Array:
        """``(n,)`` metres: each plant pose's lower bound (the least over the arms, less their clearance's excess),
        from each arm's notes of its IK pass (:meth:`~retarget.ik.bound.ClearanceBound.pose_lows`)."""
        lows = np.full(len(q), np.inf)
        for name, part in self.parts:
            model = self.models[name]
            own = shared_bound(model).pose_lows(q[:, part], notes[name], index[name][: len(q)], MARGIN)
            lows = np.minimum(lows, own - self._excess(name))
        return lows

    def _excess(self, name: str) -> float:
        return float(self.models[name].clearance) - self.clearance
