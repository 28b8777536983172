"""The clearance between the arms of a rig: every shape of one arm against every shape of another, in the world.

Each arm's own collisions (itself, the table, keep-outs) stay with its
:class:`~retarget.collision.CollisionModel`; this module adds what only a rig has: arm against arm.  Each arm's
shapes are its arm file's ``[collision]`` links (or capsules between the joint origins, as
:func:`~retarget.collision.fallback_geometry` builds them, when it has none).  Capsules are measured exactly
(segment to segment, less both radii); a box (a base, a shoulder block, a gripper) is taken as its bounding
sphere, a capsule of zero length, so its clearance is never overstated.

Arrays: poses ``(n_joints,)`` or ``(n_poses, n_joints)`` float64 radians per arm; clearances metres, signed
(negative: overlapping).  Math only.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from retarget.arm.kinematics import Chain
from retarget.collision import DEFAULT_CLEARANCE, Box, Capsule, fallback_geometry
from retarget.collision.distance import segment_segment
from retarget.rig.spec import Rig, RigArm

__all__ = ["ArmShapes", "RigClearance"]

Array = npt.NDArray[np.float64]


@dataclass(frozen=True)
class ArmShapes:
    """One arm's shapes as capsules on its frames: ``frames`` ``(m,)`` frame index (0 the base), ``ends``
    ``(m, 2, 3)`` metres in that frame, ``radii`` ``(m,)`` metres, ``names`` ``(m,)`` the links'."""

    frames: npt.NDArray[np.intp]
    ends: Array
    radii: Array
    names: tuple[str, ...]

    @classmethod
    def of(cls, rig_arm: RigArm) -> ArmShapes:
        """The shapes of a rig arm's arm (its geometry, or the fallback capsules)."""
        arm = rig_arm.arm
        geometry = arm.geometry if arm.geometry is not None else fallback_geometry(arm)
        frames, ends, radii, names = [], [], [], []
        for link in geometry.links:
            shape = link.shape
            if isinstance(shape, Capsule):
                ends.append((shape.a, shape.b))
                radii.append(shape.radius)
            elif isinstance(shape, Box):  # its bounding sphere
                ends.append((shape.center, shape.center))
                radii.append(float(np.linalg.norm(shape.half_size)))
            else:  # pragma: no cover - the geometry holds capsules and boxes only
                raise TypeError(f"Expected a Capsule or a Box, got {type(shape).__name__}")
            frames.append(link.frame)
            names.append(link.name)
        return cls(np.array(frames, dtype=np.intp), np.array(ends, dtype=np.float64), np.array(radii), tuple(names))

    def world(self, rig_arm: RigArm, Q: Array) -> Array:
        """The capsules' end points ``(n_poses, m, 2, 3)`` metres, world, of poses ``Q`` ``(n_poses, n_joints)``."""
        if Q.shape[0] == 1:  # one pose: the frames one joint at a time (a batch of one costs 10x more)
            frames = _frames_one(rig_arm.arm.chain, Q[0])[None, self.frames]
        else:
            frames = rig_arm.arm.chain.frames_batch(Q)[:, self.frames]  # (N, m, 4, 4) base frame
        local = np.einsum("nmij,mej->nmei", frames[..., :3, :3], self.ends) + frames[..., None, :3, 3]
        T = rig_arm.placement.matrix
        out: Array = local @ T[:3, :3].T + T[:3, 3]
        return out


def _frames_one(chain: Chain, q: Array) -> Array:
    """Every link frame ``(n_joints + 1, 4, 4)`` of one pose ``q`` (rad), base frame first: ``Chain.frames_batch``
    of one pose, without its batch overhead."""
    frames = np.empty((chain.n + 1, 4, 4))
    frames[0] = T = np.eye(4)
    rot = np.eye(4)
    for i, angle in enumerate(q.tolist()):
        x, y, z = chain.axes[i].tolist()
        c, s = math.cos(angle), math.sin(angle)
        t = 1.0 - c
        rot[:3, :3] = (
            (t * x * x + c, t * x * y - s * z, t * x * z + s * y),
            (t * x * y + s * z, t * y * y + c, t * y * z - s * x),
            (t * x * z - s * y, t * y * z + s * x, t * z * z + c),
        )
        frames[i + 1] = T = T @ chain.origins[i] @ rot
    return frames


class RigClearance:
    """Arm-against-arm clearances of a rig (see the module docstring), ``clearance`` metres required.

    >>> from retarget.rig import load_rig
    >>> rig = load_rig("wx250s-pair")
    >>> check = RigClearance(rig)
    >>> homes = {a.name: a.arm.home for a in rig.arms}
    >>> check.is_clear(homes), round(float(check.min_clearance(homes)), 3)
    (True, 0.38)
    """

    def __init__(self, rig: Rig, *, clearance: float = DEFAULT_CLEARANCE):
        self.rig = rig
        self.clearance = float(clearance)
        self.shapes = {a.name: ArmShapes.of(a) for a in rig.arms}
        names: list[str] = []
        self._pairs: list[tuple[RigArm, RigArm]] = []
        for i, a in enumerate(rig.arms):
            for b in rig.arms[i + 1 :]:
                self._pairs.append((a, b))
                names += [
                    f"{a.name}:{u}/{b.name}:{v}" for u in self.shapes[a.name].names for v in self.shapes[b.name].names
                ]
        self.pair_names: tuple[str, ...] = tuple(names)  #: ``"left:upper_arm/right:gripper"``, as distances' columns

    def distances(self, poses: Mapping[str, npt.ArrayLike]) -> Array:
        """Every arm-arm shape pair's signed clearance, metres: ``(n_pairs,)`` for one pose per arm, or
        ``(n_poses, n_pairs)`` for ``(n_poses, n_joints)`` arrays; ``poses`` maps each rig arm's name to its pose."""
        Q = {name: np.asarray(poses[name], dtype=np.float64) for name in self.rig.names}
        one = all(q.ndim == 1 for q in Q.values())
        parts = []
        for a, b in self._pairs:
            sa, sb = self.shapes[a.name], self.shapes[b.name]
            ea = sa.world(a, np.atleast_2d(Q[a.name]))[:, :, None]  # (N, ma, 1, 2, 3)
            eb = sb.world(b, np.atleast_2d(Q[b.name]))[:, None, :]  # (N, 1, mb, 2, 3)
            ea, eb = np.broadcast_arrays(ea, eb)
            gap = segment_segment(ea[..., 0, :], ea[..., 1, :], eb[..., 0, :], eb[..., 1, :])
            parts.append((gap - sa.radii[:, None] - sb.radii[None, :]).reshape(gap.shape[0], -1))
        out: Array = np.concatenate(parts, axis=1)
        return out[0] if one else out

    def min_clearance(self, poses: Mapping[str, npt.ArrayLike]) -> Array:
        """The least arm-arm clearance, metres: a 0-d array for one pose per arm, ``(n_poses,)`` for many.

        One pose per arm measures exactly only the pairs that can be the nearest: a pair's clearance is at least
        its bounding spheres' and at most its two capsules' midpoints', so a pair whose lower bound exceeds the
        least upper bound is skipped."""
        Q = {name: np.asarray(poses[name], dtype=np.float64) for name in self.rig.names}
        if any(q.ndim != 1 for q in Q.values()):
            out: Array = self.distances(poses).min(axis=-1)
            return out
        best = math.inf
        for a, b in self._pairs:
            sa, sb = self.shapes[a.name], self.shapes[b.name]
            ea, eb = sa.world(a, Q[a.name][None])[0], sb.world(b, Q[b.name][None])[0]  # (m, 2, 3)
            ca, cb = ea.mean(axis=1), eb.mean(axis=1)
            half_a = 0.5 * np.linalg.norm(ea[:, 1] - ea[:, 0], axis=-1)
            half_b = 0.5 * np.linalg.norm(eb[:, 1] - eb[:, 0], axis=-1)
            centres = np.linalg.norm(ca[:, None] - cb[None], axis=-1) - sa.radii[:, None] - sb.radii[None]
            upper = float(centres.min())
            near = np.nonzero(centres - half_a[:, None] - half_b[None] <= min(upper, best))
            if near[0].size:
                i, j = near
                gap = segment_segment(ea[i, 0], ea[i, 1], eb[j, 0], eb[j, 1]) - sa.radii[i] - sb.radii[j]
                best = min(best, float(gap.min()))
        return np.asarray(best)

    def is_clear(self, poses: Mapping[str, npt.ArrayLike]) -> bool:
        """Whether one pose per arm keeps every arm-arm pair at least :attr:`clearance` apart."""
        return bool(np.all(self.min_clearance(poses) >= self.clearance))

    def worst_pair(self, poses: Mapping[str, npt.ArrayLike]) -> tuple[str, float]:
        """The nearest arm-arm pair of one pose per arm, and its clearance (metres)."""
        d = self.distances(poses)
        k = int(np.argmin(d))
        return self.pair_names[k], float(d[k])
