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

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from retarget.collision import DEFAULT_CLEARANCE, Box, Capsule, fallback_geometry
from retarget.collision.distance import segment_segment
from retarget.rig.spec import Rig, RigArm

__all__ = ["ArmShapes", "RigClearance"]

Array = npt.NDArray[np.float64]


@dataclass(frozen=True)
class ArmShapes:
    """One arm's shapes as capsules on its frames: ``frames`` ``(m,)`` frame index (0 the base), ``ends``
    ``(m, 2, 3)`` metres in that frame, ``radii`` ``(m,)`` metres, ``names`` ``(m,)`` the links'.

    ``motion`` ``(m, n_joints)`` metres per radian: how far any point of shape ``i``'s segment moves per radian of
    joint ``j`` (0 for a joint that does not move it).  Joint ``j`` turns the frames from ``j + 1`` on about an
    axis through frame ``j + 1``'s origin, so a point on frame ``f > j`` is at most the hops from frame ``j + 1``
    to frame ``f`` plus its own distance from frame ``f``'s origin from that axis.  Along a straight joint-space
    move ``dq`` (rad) a point of shape ``i`` travels at most ``motion[i] @ |dq|``, whatever the pose."""

    frames: npt.NDArray[np.intp]
    ends: Array
    radii: Array
    names: tuple[str, ...]
    motion: Array

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
        ends_array = np.array(ends, dtype=np.float64).reshape(-1, 2, 3)
        hops = np.linalg.norm(arm.chain.origins[:, :3, 3], axis=1)  # frame k+1's origin from frame k's
        extent = np.linalg.norm(ends_array, axis=2).max(axis=1, initial=0.0)  # a segment's farthest point: an end
        motion = np.zeros((len(frames), arm.chain.n))
        for i, frame in enumerate(frames):
            for j in range(frame):  # joints 0 .. frame-1 move a shape on frame ``frame``
                motion[i, j] = float(hops[j + 1 : frame].sum()) + extent[i]
        return cls(np.array(frames, dtype=np.intp), ends_array, np.array(radii), tuple(names), motion)

    def world(self, rig_arm: RigArm, Q: Array) -> Array:
        """The capsules' end points ``(n_poses, m, 2, 3)`` metres, world, of poses ``Q`` ``(n_poses, n_joints)``."""
        return _Placer([rig_arm], [self]).ends([np.asarray(Q, dtype=np.float64)])[0]


class _Placer:
    """Every arm's shapes placed in the world at once: the arms' chains side by side (a shorter chain padded with
    still joints), every joint's rotation in one go (Rodrigues), then the chain products with each arm's placement
    as their first factor, only as far as the last frame that carries a shape."""

    def __init__(self, rig_arms: list[RigArm], shapes: list[ArmShapes]):
        self.sizes = [s.frames.size for s in shapes]
        n = self.n = max(1, *(int(s.frames.max(initial=0)) for s in shapes))
        A = len(rig_arms)
        axes = np.zeros((A, n, 3))
        self._local = np.broadcast_to(np.eye(4), (A, n, 4, 4)).copy()  # a padded joint: no offset, no turn
        for k, a in enumerate(rig_arms):
            m = min(n, a.arm.chain.n)
            axes[k, :m], self._local[k, :m] = a.arm.chain.axes[:m], a.arm.chain.origins[:m]
        x, y, z = np.moveaxis(axes, -1, 0)
        zero = np.zeros_like(x)
        K = np.stack([zero, -z, y, z, zero, -x, -y, x, zero], axis=-1).reshape(A, n, 3, 3)
        self._rot0 = self._local[..., :3, :3].copy()
        self._K, self._K2 = self._rot0 @ K, self._rot0 @ K @ K  # R0 (I + sin K + (1 - cos) K^2), R0 folded in
        self._axes = axes  #: each joint's axis in its child frame (a turn about it leaves it where it is)
        self._base = np.stack([np.asarray(a.placement.matrix, dtype=np.float64) for a in rig_arms])
        self._arm = np.concatenate([np.full(s.frames.size, k, dtype=np.intp) for k, s in enumerate(shapes)])
        self._frame = np.concatenate([s.frames for s in shapes])
        self._ends = np.concatenate([s.ends for s in shapes])  # (m, 2, 3) in their frames
        #: the (shape, joint) pairs where the joint moves the shape (joint j < the shape's frame, within its arm):
        #: ``(k,)`` each, the shapes' and the joints' indices
        self.moved = np.nonzero(np.arange(n)[None, :] < self._frame[:, None])

    def frames(self, Q: list[Array]) -> Array:
        """Every arm's frames ``(N, n_arms, n + 1, 4, 4)``, world, of ``Q``: each arm's ``(N, n_joints)`` rad."""
        N, n = Q[0].shape[0], self.n
        q = np.zeros((N, len(Q), n))
        for k, qk in enumerate(Q):
            m = min(n, qk.shape[1])
            q[:, k, :m] = qk[:, :m]
        s, c = np.sin(q)[..., None, None], (1.0 - np.cos(q))[..., None, None]
        local = np.broadcast_to(self._local, (N, *self._local.shape)).copy()
        local[..., :3, :3] = self._rot0 + s * self._K + c * self._K2
        frames = np.empty((N, len(Q), n + 1, 4, 4))
        frames[:, :, 0] = T = self._base
        for i in range(n):
            frames[:, :, i + 1] = T = T @ local[:, :, i]
        return frames

    def ends(self, Q: list[Array], frames: Array | None = None) -> list[Array]:
        """Each arm's shapes' end points ``(N, m_arm, 2, 3)`` metres, world (of ``frames``, else of ``Q``)."""
        return np.split(self.all_ends(self.frames(Q) if frames is None else frames), np.cumsum(self.sizes)[:-1], axis=1)

    def all_ends(self, frames: Array) -> Array:
        """Every arm's shapes' end points ``(N, m, 2, 3)`` metres, world, of ``frames`` (arms in turn)."""
        F = frames[:, self._arm, self._frame]  # (N, m, 4, 4)
        out: Array = (F[:, :, None, :3, :3] @ self._ends[None, :, :, :, None])[..., 0] + F[:, :, None, :3, 3]
        return out

    def levers(self, frames: Array, ends: Array) -> Array:
        """``(..., k)`` metres: each shape's greatest distance from the axis of each joint that moves it (the pairs
        :attr:`moved`), of poses' ``frames`` ``(..., n_arms, n + 1, 4, 4)`` and ends ``(..., m, 2, 3)``, world (one
        pose, or many along the leading axes)."""
        shape, joint = self.moved
        R, origin = frames[..., 1:, :3, :3], frames[..., 1:, :3, 3]  # joint j's axis runs through frame j + 1's origin
        axis = (R @ self._axes[..., None])[..., 0]  # (..., n_arms, n, 3) unit, world
        arm = self._arm[shape]
        d = ends[..., shape, :, :] - origin[..., arm, joint, None, :]  # (..., k, 2, 3)
        along = np.einsum("...ek,...k->...e", d, axis[..., arm, joint, :])
        square = np.einsum("...ek,...ek->...e", d, d) - along * along
        out: Array = np.sqrt(np.maximum(square, 0.0)).max(axis=-1)
        return out


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
        self._placer = _Placer(list(rig.arms), list(self.shapes.values()))
        first = dict(
            zip(rig.names, np.cumsum([0] + [len(s.names) for s in self.shapes.values()])[:-1].tolist(), strict=True)
        )
        names: list[str] = []
        left: list[int] = []
        right: list[int] = []
        for i, a in enumerate(rig.arms):
            for b in rig.arms[i + 1 :]:
                sa, sb = self.shapes[a.name], self.shapes[b.name]
                for u, name_u in enumerate(sa.names):
                    for v, name_v in enumerate(sb.names):
                        names.append(f"{a.name}:{name_u}/{b.name}:{name_v}")
                        left.append(first[a.name] + u)
                        right.append(first[b.name] + v)
        self.pair_names: tuple[str, ...] = tuple(names)  #: ``"left:upper_arm/right:gripper"``, as distances' columns
        #: each pair's two shapes ``(n_pairs,)``, indices into every arm's shapes in rig order (:attr:`shapes`)
        self.pair_shapes = (np.array(left, dtype=np.intp), np.array(right, dtype=np.intp))
        radii = np.concatenate([s.radii for s in self.shapes.values()])
        self._pair_radii = radii[self.pair_shapes[0]] + radii[self.pair_shapes[1]]
        #: where each arm's joints are in the rig's joint vector (every arm's in rig order) and its shapes' rows
        self.joint_slices = tuple(
            slice(start, start + a.arm.chain.n)
            for a, start in zip(rig.arms, np.cumsum([0] + [a.arm.chain.n for a in rig.arms]).tolist(), strict=False)
        )
        n_rig, m = sum(a.arm.chain.n for a in rig.arms), radii.size
        #: ``(n_shapes, n_rig_joints)`` metres per radian: each shape's :attr:`ArmShapes.motion` on its arm's joints
        self.motion = np.zeros((m, n_rig))
        row = 0
        for shapes, joints in zip(self.shapes.values(), self.joint_slices, strict=True):
            self.motion[row : row + shapes.frames.size, joints] = shapes.motion
            row += shapes.frames.size
        # where each lever (a shape, a joint that moves it) goes in an (n_shapes, n_rig_joints) matrix
        shape, joint = self._placer.moved
        self._lever_at = (shape, np.array([s.start for s in self.joint_slices])[self._placer._arm[shape]] + joint)

    def _poses(self, poses: Mapping[str, npt.ArrayLike]) -> tuple[list[Array], bool]:
        """Each arm's poses ``(N, n_joints)`` in rig order, and whether one pose per arm was given."""
        Q = [np.asarray(poses[name], dtype=np.float64) for name in self.rig.names]
        one = all(q.ndim == 1 for q in Q)
        return [np.atleast_2d(q) for q in Q], one

    def distances(self, poses: Mapping[str, npt.ArrayLike], *, pairs: npt.NDArray[np.intp] | None = None) -> Array:
        """Every arm-arm shape pair's signed clearance, metres: ``(n_pairs,)`` for one pose per arm, or
        ``(n_poses, n_pairs)`` for ``(n_poses, n_joints)`` arrays; ``poses`` maps each rig arm's name to its pose.
        ``pairs``: only these pairs (indices into :attr:`pair_names`), their columns in that order (each the same
        figure as among all pairs)."""
        Q, one = self._poses(poses)
        ends = self.ends(Q)
        if pairs is None:
            out = self._pair_gaps(ends)
        else:
            rows = np.arange(len(ends))[:, None]
            out = self.pair_gaps(ends, rows, np.asarray(pairs, dtype=np.intp)[None, :])
        return out[0] if one else out

    def ends(self, Q: list[Array]) -> Array:
        """Every arm's shapes' end points ``(n_poses, n_shapes, 2, 3)`` metres, world (shapes in rig order, as
        :attr:`pair_shapes` counts them), of each arm's poses ``Q`` ``(n_poses, n_joints)`` rad in rig order."""
        return self._placer.all_ends(self._placer.frames(Q))

    def pair_gaps(self, ends: Array, rows: npt.NDArray[np.intp], pairs: npt.NDArray[np.intp]) -> Array:
        """The signed clearances of pairs ``pairs`` at poses ``rows`` (index arrays of one shape, broadcast
        together) of world ``ends`` ``(n_poses, n_shapes, 2, 3)`` (:meth:`ends`): an array of their shape, metres
        (each the same figure as :meth:`distances` gives for that pose and pair)."""
        i, j = self.pair_shapes[0][pairs], self.pair_shapes[1][pairs]
        p1, q1, p2, q2 = ends[rows, i, 0], ends[rows, i, 1], ends[rows, j, 0], ends[rows, j, 1]
        out: Array = segment_segment(p1, q1, p2, q2) - self._pair_radii[pairs]
        return out

    def measure(self, poses: Mapping[str, npt.ArrayLike], *, every_pair: bool = True) -> tuple[Array, Array]:
        """Of one pose per arm: every pair's clearance ``(n_pairs,)`` (as :meth:`distances`) and every shape's lever
        ``(n_shapes, n_rig_joints)`` metres: its greatest distance from each joint's axis (0 for a joint that does
        not move it), joints in the rig's order (every arm's in turn, as :attr:`motion`'s columns); of
        ``(n_poses, n_joints)`` arrays, ``(n_poses, n_pairs)`` and ``(n_poses, n_shapes, n_rig_joints)``.
        ``every_pair=False``: each pose's least clearance (0-d, or ``(n_poses,)``) instead of every pair's: the least
        of :meth:`distances`, from only the pairs that may be the nearest (:meth:`_least`)."""
        Q, one = self._poses(poses)
        frames = self._placer.frames(Q)
        ends = self._placer.all_ends(frames)
        levers = np.zeros((len(ends), *self.motion.shape))
        levers[:, self._lever_at[0], self._lever_at[1]] = self._placer.levers(frames, ends)
        gaps = self._pair_gaps(ends) if every_pair else self._least(ends)
        return (gaps[0], levers[0]) if one else (gaps, levers)

    def _least(self, ends: Array) -> Array:
        """``(n_poses,)`` the least signed clearance of every arm's shapes' world ends ``(n_poses, m, 2, 3)``: the
        least of :meth:`_pair_gaps`, the same figure, measured only for the pairs that may be the nearest.

        Each capsule lies within its half length ``h`` of its middle ``c``, so a pair's clearance is at most
        ``U = |c_i - c_j| - r_i - r_j`` (the middles are on the segments) and at least ``U - h_i - h_j``: a pair
        whose least exceeds some pair's most (and a nanometre of rounding) is never the nearest."""
        i, j = self.pair_shapes
        middle = 0.5 * (ends[:, :, 0] + ends[:, :, 1])
        half = 0.5 * np.linalg.norm(ends[:, :, 1] - ends[:, :, 0], axis=-1)
        most = np.linalg.norm(middle[:, i] - middle[:, j], axis=-1) - self._pair_radii  # (n_poses, n_pairs)
        least = most - half[:, i] - half[:, j]
        rows, pairs = np.nonzero(~(least > most.min(axis=1, keepdims=True) + 1e-9))  # each pose's nearest among them
        out: Array = np.minimum.reduceat(self.pair_gaps(ends, rows, pairs), np.searchsorted(rows, np.arange(len(ends))))
        return out

    def _pair_gaps(self, ends: Array) -> Array:
        """``(n_poses, n_pairs)`` signed clearances of every arm's shapes' world ends ``(n_poses, m, 2, 3)``."""
        i, j = self.pair_shapes  # (each end gathered whole: arithmetic on contiguous arrays)
        out: Array = segment_segment(ends[:, i, 0], ends[:, i, 1], ends[:, j, 0], ends[:, j, 1]) - self._pair_radii
        return out

    def min_clearance(self, poses: Mapping[str, npt.ArrayLike]) -> Array:
        """The least arm-arm clearance, metres: a 0-d array for one pose per arm, ``(n_poses,)`` for many."""
        out: Array = self.distances(poses).min(axis=-1)
        return out

    def is_clear(self, poses: Mapping[str, npt.ArrayLike]) -> bool:
        """Whether one pose per arm keeps every arm-arm pair at least :attr:`clearance` apart."""
        return bool(np.all(self.min_clearance(poses) >= self.clearance))

    def worst_pair(self, poses: Mapping[str, npt.ArrayLike]) -> tuple[str, float]:
        """The nearest arm-arm pair of one pose per arm, and its clearance (metres)."""
        d = self.distances(poses)
        k = int(np.argmin(d))
        return self.pair_names[k], float(d[k])
