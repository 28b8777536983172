"""A rig's arms as one plant for the tick loop: their joint vectors concatenated in rig order.

The tick loop (:func:`~retarget.control.loop.run_ticks`) steps one joint vector within its limits, checks it and
writes it in one bus call.  A rig runs the same loop on a :class:`RigPlant`: the limits, speeds, accelerations,
home and rest poses of every arm, one after the other in ``rig.names`` order, with joint names prefixed by the
arm's (``"left/waist"``).  Each tick thus steps, checks and writes both arms at once, and one shutdown ends both.

Arrays: ``(n_joints,)`` float64 radians (rad/s, rad/s^2), every arm's joints in rig order.  Math only.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from retarget.rig.spec import Rig

__all__ = ["RigPlant"]

Array = npt.NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class RigPlant:
    """Every arm of ``rig`` as one joint vector (see the module docstring).

    >>> from retarget.rig import load_rig
    >>> plant = RigPlant.of(load_rig("wx250s-pair"))
    >>> plant.n_joints, plant.joint_names[0], plant.joint_names[6]
    (12, 'left/waist', 'right/waist')
    >>> sorted(plant.split(plant.home))
    ['left', 'right']
    """

    rig: Rig
    slices: tuple[slice, ...]  #: each arm's joints in the plant's vector, in rig order
    joint_names: tuple[str, ...]  #: ``"<arm>/<joint>"``
    lower: Array  #: rad
    upper: Array  #: rad
    max_velocity: Array  #: rad/s
    max_acceleration: Array  #: rad/s^2
    home: Array  #: rad
    rest: Array  #: rad

    @classmethod
    def of(cls, rig: Rig) -> RigPlant:
        """The plant of ``rig``'s arms, in rig order."""
        slices, start = [], 0
        for a in rig.arms:
            slices.append(slice(start, start + a.arm.n_joints))
            start += a.arm.n_joints
        arms = [a.arm for a in rig.arms]
        return cls(
            rig=rig,
            slices=tuple(slices),
            joint_names=tuple(f"{a.name}/{j}" for a in rig.arms for j in a.arm.joint_names),
            lower=np.concatenate([arm.lower for arm in arms]),
            upper=np.concatenate([arm.upper for arm in arms]),
            max_velocity=np.concatenate([arm.max_velocity for arm in arms]),
            max_acceleration=np.concatenate([arm.max_acceleration for arm in arms]),
            home=np.concatenate([arm.home for arm in arms]),
            rest=np.concatenate([arm.rest for arm in arms]),
        )

    @property
    def name(self) -> str:
        return self.rig.name

    @property
    def n_joints(self) -> int:
        return len(self.joint_names)

    def split(self, q: npt.ArrayLike) -> dict[str, Array]:
        """Each arm's part of ``q`` (``(..., n_joints)``), by arm name: ``(..., arm n_joints)`` views."""
        q = np.asarray(q, dtype=np.float64)
        if q.shape[-1] != self.n_joints:
            raise ValueError(f"Expected poses of {self.n_joints} joints, got shape {q.shape}")
        return {a.name: q[..., s] for a, s in zip(self.rig.arms, self.slices, strict=True)}

    def join(self, parts: Mapping[str, npt.ArrayLike]) -> Array:
        """The plant's vector ``(..., n_joints)`` from each arm's part, by arm name (every arm needed)."""
        missing = [name for name in self.rig.names if name not in parts]
        if missing:
            raise ValueError(f"Expected a pose for every arm of the rig, got none for {', '.join(missing)}")
        out: Array = np.concatenate([np.asarray(parts[name], dtype=np.float64) for name in self.rig.names], axis=-1)
        return out
