"""``CollisionModel``: the signed clearance of every pair of an arm's links and its world, for one pose or many.

Built once per arm (:meth:`CollisionModel.for_arm`), it precomputes the pairs and the buffers of its one-pose
path (:mod:`~retarget.collision.fast`); a batch of poses runs the link frames' forward kinematics and every
pair's distance in a few vectorised numpy operations.

Pairs, in this order (``pair_names``):

1. capsule/capsule: every two links that are not neighbours on the chain (links on the same body, or on two
   bodies with no link between them, are joined by a joint and may touch) and not listed as allowed; two
   capsules one joint apart that touch at the zero pose are neighbours too, unless that joint swings them by
   more than the clearance (an elbow folds the forearm onto the upper arm): those are checked, with the depth
   the joint's own range needs (see ``CollisionModel._folding``), so a fold past the range is caught;
2. capsule/base box: each moving link against each box on the base frame, unless neighbours or allowed;
3. ``<link>/table``: each moving link against the table plane z = 0 (when the world has the table);
4. ``<link>/keep_out[i]``: each moving link against each keep-out zone.

How many, and what a check costs: with ``c`` capsules, ``b`` boxes, ``s`` moving shapes and ``k`` keep-out
zones, at most ``c (c - 1) / 2`` capsule pairs (about ``n_links^2 / 2``, minus neighbours and allowed pairs),
plus ``c b`` capsule/box pairs, plus ``s (1 + k)`` world pairs: wx250s and vx300s have 42-43 (with ``k`` = 0),
+16 per keep-out zone.  :meth:`~CollisionModel.is_clear` and :meth:`~CollisionModel.min_clearance` of one pose
run a fixed ~40 numpy calls whatever the count (forward kinematics, every pair's bounding-box gap, the table),
then measure exactly, in plain floats, only the pairs whose bound is within reach (of the clearance, or of the
least clearance so far): about 1 us per capsule pair, 5 us per box pair, a handful per pose.  Measured
(bench/bench_collision.py, thread CPU time, wx250s, typical poses; 0 / 2 / 8 keep-outs): ``is_clear`` 29 / 30
/ 31 us, ``min_clearance`` 48 / 48 / 52 us; :meth:`~CollisionModel.distances` (every pair exact, ~80 calls on
arrays that grow with the pairs) 125 / 138 / 156 us.

An arm without link geometry (``arm.geometry is None``) is checked against the world only, with a capsule of
:data:`FALLBACK_RADIUS` between each two joint origins (and to the tool point), except the first (the turntable
on the base, whose capsule starts at the base's mounting plane).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from retarget.arm.kinematics import rpy_matrix
from retarget.collision.distance import point_box, point_segment, segment_box, segment_segment
from retarget.collision.fast import OnePose
from retarget.collision.points import TargetPoints
from retarget.collision.shapes import (
    BASE_FRAME,
    DEFAULT_CLEARANCE,
    TABLE,
    Box,
    Capsule,
    Geometry,
    LinkShape,
    Sphere,
    World,
)
from retarget.errors import ConfigError

if TYPE_CHECKING:
    from retarget.arm.model import Arm

__all__ = ["FALLBACK_RADIUS", "CollisionModel", "SegmentCheck", "fallback_geometry"]

#: :meth:`CollisionModel.segment_clear` checks moves of up to this many samples pose by pose (the one-pose path
#: costs less than a sample of the batch path), longer ones in batches.
_ONE_BY_ONE = 64

#: Radius of the capsules between joint origins for an arm without geometry, metres (an XM430 is 28.5 mm wide).
FALLBACK_RADIUS = 0.02


@dataclass(frozen=True)
class SegmentCheck:
    """The result of :meth:`CollisionModel.segment_clear`: ``blocked_at`` is the fraction (0..1) along the
    joint-space segment of the first sample closer than the clearance, None when ``clear``."""

    clear: bool
    min_clearance: float  #: metres, the smallest pair clearance over every sample
    blocked_at: float | None
    samples: int


def fallback_geometry(arm: Arm, radius: float = FALLBACK_RADIUS) -> Geometry:
    """Capsules between each two joint origins and to the tool point, named after the joints (world checks)."""
    links = []
    joints = arm.joints
    for i, joint in enumerate(joints):
        end = joints[i + 1].origin_xyz if i + 1 < len(joints) else arm.tool_xyz
        links.append(LinkShape(joint.name, i + 1, Capsule((0.0, 0.0, 0.0), end, radius)))
    return Geometry(tuple(links), source="fallback: capsules between the joint origins")


def _neighbours(links: Sequence[LinkShape], gap: np.ndarray | None = None) -> set[tuple[int, int]]:
    """Index pairs of links on the same body, or on consecutive bodies (frames with geometry) of the chain whose
    shapes meet at the zero pose (``gap[i, j]`` < 0: they touch at their joint); other pairs are checked."""
    bodies = sorted({link.frame for link in links})
    rank = {frame: k for k, frame in enumerate(bodies)}
    out = set()
    for i, li in enumerate(links):
        for j in range(i + 1, len(links)):
            step = abs(rank[li.frame] - rank[links[j].frame])
            if step == 0 or (step == 1 and (gap is None or gap[i, j] < 0)):
                out.add((i, j))
    return out


class CollisionModel(TargetPoints):
    """Clearances of an arm against itself and its world (metres, base frame; poses in radians).

    >>> from retarget.arm.load import load_arm
    >>> model = CollisionModel.for_arm(load_arm("wx250s"))
    >>> model.is_clear(model.arm.home), model.clearance
    (True, 0.01)
    >>> name, value = model.worst_pair(model.arm.home)
    >>> model.point_blocked([0.3, 0.0, -0.05]), model.push_out([0.3, 0.0, -0.05]).round(3).tolist()
    (True, [0.3, 0.0, 0.01])
    """

    def __init__(self, arm: Arm, geometry: Geometry, world: World, clearance: float, *, self_pairs: bool = True):
        if not (math.isfinite(clearance) and clearance >= 0):
            raise ConfigError("Expected a clearance >= 0 in metres", key="clearance", value=clearance)
        n = arm.n_joints
        for link in geometry.links:
            if link.frame > n:
                raise ConfigError(f"Expected a frame index 0..{n}", key=f"links.{link.name}.frame", value=link.frame)
        self.arm = arm
        self.geometry = geometry
        self.world = world
        self.clearance = float(clearance)
        self._kinematics(arm)
        self._shapes(geometry)
        # each joint's envelopes depend on the arm and its shapes only: two models of one arm (a rig's two arms of
        # one file share their Arm) measure them once
        shared = arm._cache.get("joint_envelopes")
        if shared is None or shared[0] is not geometry:
            shared = arm._cache["joint_envelopes"] = (geometry, {})
        self._envelopes: dict[tuple[int, int, int], tuple[float, float]] = shared[1]
        self._pairs(geometry, world, self_pairs)
        self._motion_bounds(arm)
        self._one = OnePose(self)
        self._last_end: tuple[bytes, float] = (b"", math.inf)  # the last short segment's end pose, its clearance

    @classmethod
    def for_arm(cls, arm: Arm, *, world: World | None = None, clearance: float = DEFAULT_CLEARANCE) -> CollisionModel:
        """The model of ``arm``: its geometry (or capsules between the joint origins, world pairs only, when it
        has none) against ``world`` (None: the arm file's ``[world]``), with ``clearance`` metres."""
        world = arm.world if world is None else world
        if arm.geometry is None:
            return cls(arm, fallback_geometry(arm), world, clearance, self_pairs=False)
        return cls(arm, arm.geometry, world, clearance)

    # -- construction -------------------------------------------------------------------------------------------
    def _kinematics(self, arm: Arm) -> None:
        self._n = arm.n_joints
        self._rot0 = np.stack([rpy_matrix(j.origin_rpy) for j in arm.joints])  # (n, 3, 3)
        self._trans0 = np.array([j.origin_xyz for j in arm.joints], dtype=np.float64)  # (n, 3)
        axes = np.array([j.axis for j in arm.joints], dtype=np.float64).reshape(-1, 3)
        x, y, z = axes.T
        zero = np.zeros_like(x)
        self._K = np.stack([zero, -z, y, z, zero, -x, -y, x, zero], axis=1).reshape(-1, 3, 3)  # cross-product
        self._K2 = self._K @ self._K

    def _shapes(self, geometry: Geometry) -> None:
        caps = [(i, link, link.shape) for i, link in enumerate(geometry.links) if isinstance(link.shape, Capsule)]
        boxes = [(i, link, link.shape) for i, link in enumerate(geometry.links) if isinstance(link.shape, Box)]
        self._cap_ids = [i for i, _, _ in caps]
        self._box_ids = [i for i, _, _ in boxes]
        self._cap_frame = np.array([link.frame for _, link, _ in caps], dtype=np.intp)
        self._cap_local = np.array([(c.a, c.b) for _, _, c in caps], dtype=np.float64).reshape(-1, 2, 3)
        self._cap_r = np.array([c.radius for _, _, c in caps], dtype=np.float64)
        self._box_frame = np.array([link.frame for _, link, _ in boxes], dtype=np.intp)
        self._box_c = np.array([b.center for _, _, b in boxes], dtype=np.float64).reshape(-1, 3)
        self._box_h = np.array([b.half_size for _, _, b in boxes], dtype=np.float64).reshape(-1, 3)
        signs = np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).reshape(3, 8).T  # (8, 3)
        self._box_corners = self._box_c[:, None, :] + signs[None] * self._box_h[:, None, :]  # (n_boxes, 8, 3)

    def _zero_pose_gaps(self, geometry: Geometry) -> np.ndarray:
        """``(n_links, n_links)`` distances between capsule links at the zero pose (boxes: -1, always neighbours)."""
        n = len(geometry.links)
        gaps = -np.ones((n, n))
        rots, origins = self._frames(np.zeros((1, self._n)))
        f = self._cap_frame
        ends = np.einsum("ckl,cel->cek", rots[0, f], self._cap_local) + origins[0, f][:, None, :]
        u, v = np.meshgrid(np.arange(len(f)), np.arange(len(f)), indexing="ij")  # every two capsules, one call
        d = segment_segment(ends[u, 0], ends[u, 1], ends[v, 0], ends[v, 1]) - self._cap_r[u] - self._cap_r[v]
        ids = np.array(self._cap_ids, dtype=np.intp)
        gaps[np.ix_(ids, ids)] = d - self.clearance
        return gaps

    def _joint_envelope(self, u: int, v: int, joint: int) -> tuple[float, float]:
        """The least and greatest distance (metres) of capsules ``u`` and ``v`` (capsule indices) on the two sides
        of ``joint`` (``u`` on its parent frame, ``v`` on its child frame) over that joint's whole range (every 0.5
        degree; no other joint moves one against the other), in the parent frame."""
        known = self._envelopes.get((u, v, joint))
        if known is not None:
            return known
        lo, hi = float(self.arm.lower[joint]), float(self.arm.upper[joint])
        q = np.linspace(lo, hi, max(2, math.ceil((hi - lo) / math.radians(0.5)) + 1))
        spin = np.eye(3) + np.sin(q)[:, None, None] * self._K[joint] + (1 - np.cos(q))[:, None, None] * self._K2[joint]
        R = self._rot0[joint] @ spin  # (m, 3, 3): the child frame in the parent's
        a, b = self._cap_local[u]
        ends = np.einsum("mkl,el->mek", R, self._cap_local[v]) + self._trans0[joint]
        d = segment_segment(a, b, ends[:, 0], ends[:, 1]) - self._cap_r[u] - self._cap_r[v]
        envelope = self._envelopes[(u, v, joint)] = (float(d.min()), float(d.max()))
        return envelope

    def _folding(self, links: Sequence[LinkShape], near: set[tuple[int, int]]) -> dict[tuple[int, int], float]:
        """Neighbouring capsules one joint apart that meet at the zero pose but that the joint swings by more than
        the clearance (it folds one onto the other, as an elbow), and the nest depth they are checked with: what
        the joint's own range brings them to, plus 1 mm, so no pose within the joint's limits is blocked by them
        (a configured ``nest`` depth, if larger, wins).  A fold past the range (the forearm through the upper
        arm) is caught.  Pairs that the joint hardly moves (a roll, or shapes overlapping at the joint itself)
        stay unchecked neighbours."""
        cap_index = {link_id: k for k, link_id in enumerate(self._cap_ids)}
        out = {}
        for i, j in sorted(near):
            fi, fj = sorted((links[i].frame, links[j].frame))
            if fi == BASE_FRAME or fj != fi + 1 or i not in cap_index or j not in cap_index:
                continue
            lower, upper = (i, j) if links[i].frame == fi else (j, i)
            reach, widest = self._joint_envelope(cap_index[lower], cap_index[upper], fi)
            if widest - reach <= self.clearance:
                continue
            depth = max(self.geometry.nest_depth(links[i].name, links[j].name), self.clearance - reach + 1e-3)
            out[(i, j)] = max(depth, 0.0)
        return out

    def _pairs(self, geometry: Geometry, world: World, self_pairs: bool) -> None:
        links = geometry.links
        near = _neighbours(links, self._zero_pose_gaps(geometry) if self_pairs else None)
        folding = self._folding(links, near) if self_pairs else {}
        if folding:  # the model's geometry lists the depths it checks these pairs with
            names = {
                (min(links[i].name, links[j].name), max(links[i].name, links[j].name)): d
                for (i, j), d in folding.items()
            }
            kept = tuple(n for n in geometry.nest if (n[0], n[1]) not in names)
            geometry = replace(geometry, nest=kept + tuple((a, b, d) for (a, b), d in names.items()))
            self.geometry = geometry
        allowed = set(geometry.allowed)
        cap_index = {link_id: k for k, link_id in enumerate(self._cap_ids)}
        box_index = {link_id: k for k, link_id in enumerate(self._box_ids)}
        cc: list[tuple[int, int]] = []
        cb: list[tuple[int, int]] = []
        cc_nest: list[float] = []
        cb_nest: list[float] = []
        cc_names: list[str] = []
        cb_names: list[str] = []
        for i in range(len(links)):
            for j in range(i + 1, len(links)):
                li, lj = links[i], links[j]
                fixed = li.frame == BASE_FRAME and lj.frame == BASE_FRAME
                pair = (min(li.name, lj.name), max(li.name, lj.name))
                if not self_pairs or fixed or ((i, j) in near and (i, j) not in folding) or pair in allowed:
                    continue
                depth = folding.get((i, j), geometry.nest_depth(li.name, lj.name))
                if i in cap_index and j in cap_index:
                    cc.append((cap_index[i], cap_index[j]))
                    cc_nest.append(depth)
                    cc_names.append(f"{lj.name}/{li.name}")
                elif i in cap_index or j in cap_index:
                    cap, box = (i, j) if i in cap_index else (j, i)
                    cb.append((cap_index[cap], box_index[box]))
                    cb_nest.append(depth)
                    cb_names.append(f"{links[cap].name}/{links[box].name}")
                else:
                    raise ConfigError(
                        "two boxes that are not neighbours on the chain: list them as allowed or make one a capsule",
                        key="collision.allowed", value=[li.name, lj.name],
                    )  # fmt: skip
        self._cc = np.array(cc, dtype=np.intp).reshape(-1, 2)
        self._cb = np.array(cb, dtype=np.intp).reshape(-1, 2)
        self._cc_r = self._cap_r[self._cc[:, 0]] + self._cap_r[self._cc[:, 1]] - np.array(cc_nest).reshape(-1)
        self._cb_r = self._cap_r[self._cb[:, 0]] - np.array(cb_nest).reshape(-1)  # radius, minus any nest depth
        self._cb_fixed = bool(np.all(self._box_frame[self._cb[:, 1]] == BASE_FRAME)) if len(cb) else True
        self._world_pairs(links, world, first_moving=self_pairs)
        self.pair_names: tuple[str, ...] = (*cc_names, *cb_names, *self._world_names)

    def _world_pairs(self, links: Sequence[LinkShape], world: World, *, first_moving: bool = True) -> None:
        """Each moving shape against the table and each keep-out zone (without ``first_moving``: not the shapes
        on frame 1, which for the fallback capsules is the turntable sitting on the base)."""
        skip = BASE_FRAME if first_moving else 1
        self._mcap = np.flatnonzero((self._cap_frame != BASE_FRAME) & (self._cap_frame != skip))
        self._mbox = np.flatnonzero(self._box_frame != BASE_FRAME)
        cap_names = [links[self._cap_ids[k]].name for k in self._mcap]
        box_names = [links[self._box_ids[k]].name for k in self._mbox]
        shapes = [*cap_names, *box_names]
        names = [f"{n}/{TABLE}" for n in shapes] if world.table else []
        zone = world.zone_names()
        sph = [(i, z) for i, z in enumerate(world.keep_out) if isinstance(z, Sphere)]
        kbx = [(i, z) for i, z in enumerate(world.keep_out) if isinstance(z, Box)]
        spheres, kboxes = [i for i, _ in sph], [i for i, _ in kbx]
        self._sph_c = np.array([z.center for _, z in sph], dtype=np.float64).reshape(-1, 3)
        self._sph_r = np.array([z.radius for _, z in sph], dtype=np.float64)
        self._kb_c = np.array([z.center for _, z in kbx], dtype=np.float64).reshape(-1, 3)
        self._kb_h = np.array([z.half_size for _, z in kbx], dtype=np.float64).reshape(-1, 3)
        names += [f"{n}/{zone[i]}" for i in spheres for n in shapes]
        names += [f"{n}/{zone[i]}" for i in kboxes for n in shapes]
        self._world_names = names

    def _motion_bounds(self, arm: Arm) -> None:
        """``(n_joints,)`` metres per radian: how far any point of the geometry downstream of joint j can move
        per radian of joint j (its distance from the joint's origin, bounded along the chain)."""
        hops = np.linalg.norm(self._trans0, axis=1)  # joint k's origin in frame k (frame k = child of joint k-1)
        reach = [
            *zip(
                self._cap_frame.tolist(),
                np.linalg.norm(self._cap_local, axis=2).max(axis=1, initial=0) + self._cap_r,
                strict=True,
            ),
            *zip(
                self._box_frame.tolist(), np.linalg.norm(self._box_corners, axis=2).max(axis=1, initial=0), strict=True
            ),
        ]
        bounds = np.zeros(self._n)
        for frame, extent in reach:
            for j in range(frame):  # joints 0..frame-1 move a shape on frame `frame`
                bounds[j] = max(bounds[j], float(hops[j + 1 : frame].sum() + extent))
        self.motion_per_radian = bounds

    # -- kinematics ---------------------------------------------------------------------------------------------
    def _frames(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Rotations ``(N, n + 1, 3, 3)`` and origins ``(N, n + 1, 3)`` of every frame, base frame first."""
        N = q.shape[0]
        rots = np.empty((N, self._n + 1, 3, 3))
        origins = np.empty((N, self._n + 1, 3))
        R = np.broadcast_to(np.eye(3), (N, 3, 3))
        p = np.zeros((N, 3))
        rots[:, 0], origins[:, 0] = R, p
        spin = np.eye(3) + np.sin(q)[..., None, None] * self._K + (1 - np.cos(q))[..., None, None] * self._K2
        for i in range(self._n):
            p = p + R @ self._trans0[i]
            R = R @ self._rot0[i] @ spin[:, i]
            rots[:, i + 1], origins[:, i + 1] = R, p
        return rots, origins

    def _poses(self, q: np.ndarray | Sequence[float]) -> np.ndarray:
        Q = np.asarray(q, dtype=np.float64)
        if Q.ndim not in (1, 2) or Q.shape[-1] != self._n:
            raise ValueError(f"Expected q of shape ({self._n},) or (n_poses, {self._n}), got {Q.shape}")
        return Q.reshape(-1, self._n)

    def capsules(self, q: np.ndarray | Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
        """Capsule end points ``(n_capsules, 2, 3)`` (or ``(n_poses, n_capsules, 2, 3)``; base frame, metres) for
        pose(s) ``q`` radians, and their radii ``(n_capsules,)``, in the order of ``geometry.links`` minus boxes."""
        rots, origins = self._frames(self._poses(q))
        f = self._cap_frame
        ends = np.einsum("nckl,cel->ncek", rots[:, f], self._cap_local) + origins[:, f][:, :, None, :]
        return (ends[0] if np.ndim(q) == 1 else ends), self._cap_r

    # -- queries ------------------------------------------------------------------------------------------------
    def _one_pose(self, q: np.ndarray | Sequence[float]) -> np.ndarray | None:
        """``q`` as a ``(n_joints,)`` float array when it is one pose, else None."""
        Q = np.asarray(q, dtype=np.float64)
        return Q if Q.shape == (self._n,) else None

    def distances(self, q: np.ndarray | Sequence[float]) -> np.ndarray:
        """Signed clearance of every pair, metres (negative: penetrating): ``q`` ``(n_joints,)`` radians ->
        ``(n_pairs,)``; ``(n_poses, n_joints)`` -> ``(n_poses, n_pairs)``; pairs as :attr:`pair_names`.

        Every pair is measured exactly (no bounds, unlike :meth:`is_clear` and :meth:`min_clearance`).  A segment
        inside a box has no single depth: its value is negative, a lower bound of its deepest point's (one pose
        and a batch may give different negative values for it; never different signs)."""
        one = self._one_pose(q)
        if one is not None:
            out: np.ndarray = self._one.values(one)[self._one.perm]
            return out
        Q = self._poses(q)
        out = self._distances(Q)
        return out[0] if np.ndim(q) == 1 else out

    def pair_bounds(self, q: np.ndarray | Sequence[float], reach: float) -> np.ndarray:
        """Lower bounds of every pair's signed clearance for one pose ``q`` ``(n_joints,)`` radians, metres
        ``(n_pairs,)`` as :attr:`pair_names`: exact (as :meth:`distances`) for each pair that may be closer than
        ``reach`` metres, at least ``reach`` for the others; so the min is exact when below ``reach``.

        >>> import retarget
        >>> model = CollisionModel.for_arm(retarget.load_arm("wx250s"))
        >>> home = model.arm.home
        >>> bool((model.pair_bounds(home, 0.04) <= model.distances(home) + 1e-12).all())
        True
        """
        one = self._one_pose(q)
        if one is None:
            raise ValueError(f"Expected one pose of {self._n} joint angles, got shape {np.shape(q)}")
        out: np.ndarray = self._one.bounds(one, float(reach))[self._one.perm]
        return out

    def world_distances(self, q: np.ndarray | Sequence[float]) -> np.ndarray:
        """Signed clearance of every pair against the world (the table, the keep-out zones), metres: ``q``
        ``(n_poses, n_joints)`` radians -> ``(n_poses, n_world_pairs)``, exactly as :meth:`distances` measures those
        pairs (a fraction of its work: the arm's pairs with itself are left out).

        >>> import retarget
        >>> model = CollisionModel.for_arm(retarget.load_arm("wx250s"))
        >>> d = model.world_distances(np.stack([model.arm.home, model.arm.rest]))
        >>> d.shape[0], bool(d.min() >= model.clearance)
        (2, True)
        """
        Q = self._poses(q)
        rots, origins, a, b = self._ends(Q)
        parts = self._world_distances(a, b, rots, origins)
        return np.concatenate(parts, axis=1) if parts else np.zeros((len(Q), 0))

    def _ends(self, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`_frames` of poses ``Q`` ``(N, n)``, and the capsules' end points ``a``, ``b`` ``(N, n_caps, 3)``."""
        rots, origins = self._frames(Q)
        f = self._cap_frame
        ends = np.einsum("nckl,cel->ncek", rots[:, f], self._cap_local) + origins[:, f][:, :, None, :]
        return rots, origins, ends[:, :, 0], ends[:, :, 1]

    def _distances(self, Q: np.ndarray) -> np.ndarray:
        rots, origins, a, b = self._ends(Q)  # a, b: (N, n_caps, 3)
        i, j = self._cc[:, 0], self._cc[:, 1]
        parts = [segment_segment(a[:, i], b[:, i], a[:, j], b[:, j]) - self._cc_r]
        if len(self._cb):
            c, k = self._cb[:, 0], self._cb[:, 1]
            if self._cb_fixed:  # boxes on the base frame only: no transform
                parts.append(segment_box(a[:, c], b[:, c], self._box_c[k], self._box_h[k]) - self._cb_r)
            else:
                Rb, ob = rots[:, self._box_frame[k]], origins[:, self._box_frame[k]]  # (N, m, 3, 3), (N, m, 3)
                la = np.einsum("nmji,nmj->nmi", Rb, a[:, c] - ob)
                lb = np.einsum("nmji,nmj->nmi", Rb, b[:, c] - ob)
                parts.append(segment_box(la, lb, self._box_c[k], self._box_h[k]) - self._cb_r)
        parts += self._world_distances(a, b, rots, origins)
        return np.concatenate(parts, axis=1)

    def _world_distances(self, a: np.ndarray, b: np.ndarray, rots: np.ndarray, origins: np.ndarray) -> list[np.ndarray]:
        mc, mb = self._mcap, self._mbox
        r = self._cap_r[mc]
        am, bm = a[:, mc], b[:, mc]
        parts = []
        if mb.size:
            Rb, ob = rots[:, self._box_frame[mb]], origins[:, self._box_frame[mb]]
        if self.world.table:
            parts.append(np.minimum(am[..., 2], bm[..., 2]) - r)
            if mb.size:
                z = np.einsum("nmj,mkj->nmk", Rb[:, :, 2, :], self._box_corners[mb]) + ob[..., 2:3]
                parts.append(z.min(axis=2))
        for c, rad in zip(self._sph_c, self._sph_r, strict=True):
            parts.append(point_segment(c, am, bm) - r - rad)
            if mb.size:
                local = np.einsum("nmji,nmj->nmi", Rb, c - ob)
                parts.append(point_box(local, self._box_c[mb], self._box_h[mb]) - rad)
        for c, h in zip(self._kb_c, self._kb_h, strict=True):
            parts.append(segment_box(am, bm, c, h) - r)
            if mb.size:  # a moving box against a keep-out box: its bounding sphere (conservative)
                centre = np.einsum("nmij,mj->nmi", Rb, self._box_c[mb]) + ob
                parts.append(point_box(centre, c, h) - np.linalg.norm(self._box_h[mb], axis=1))
        return parts

    def min_clearance(self, q: np.ndarray | Sequence[float]) -> float:
        """The smallest signed clearance over every pair for one pose ``(n_joints,)`` radians, metres
        (inf when the model has no pairs): exactly ``distances(q).min()``, though only the pairs whose lower bound
        is below the least clearance found so far are measured."""
        one = self._one_pose(q)
        if one is not None:
            return self._one.least(one)
        d = self.distances(q)
        return float(d.min()) if d.size else math.inf

    def is_clear(self, q: np.ndarray | Sequence[float]) -> bool:
        """True when every pair keeps at least the clearance in pose ``q`` ``(n_joints,)`` radians (exactly
        ``min_clearance(q) >= clearance``; only the pairs whose lower bound is below the clearance are measured)."""
        one = self._one_pose(q)
        if one is None:
            return self.min_clearance(q) >= self.clearance
        return self._one.clear(one, self.clearance)

    def worst_pair(self, q: np.ndarray | Sequence[float]) -> tuple[str, float]:
        """The pair with the smallest clearance in pose ``q`` and that clearance (metres)."""
        d = self.distances(q)
        if not d.size:
            return "", math.inf
        k = int(np.argmin(d))
        return self.pair_names[k], float(d[k])

    def samples_for(self, q0: np.ndarray | Sequence[float], q1: np.ndarray | Sequence[float]) -> int:
        """How many poses :meth:`segment_clear` checks from ``q0`` to ``q1`` (both ends included): enough that
        no point of the geometry moves more than half the clearance (at least 0.5 mm) between two samples."""
        dq = np.abs(np.asarray(q1, dtype=np.float64) - np.asarray(q0, dtype=np.float64))
        travel = float(dq @ self.motion_per_radian)
        step = 0.5 * max(self.clearance, 1e-3)
        return max(2, math.ceil(travel / step) + 1)

    def segment_clear(self, q0: np.ndarray | Sequence[float], q1: np.ndarray | Sequence[float]) -> SegmentCheck:
        """Check the straight joint-space move ``q0`` -> ``q1`` (radians), sampled by :meth:`samples_for`.

        Between two samples no two shapes approach by more than the clearance, so a move whose samples all
        keep the clearance never penetrates.
        """
        start, end = self._poses(q0)[0], self._poses(q1)[0]
        n = self.samples_for(start, end)
        if n <= _ONE_BY_ONE:
            return self._short_segment(start, end, n)
        frac = np.linspace(0.0, 1.0, n)
        worst = np.full(n, math.inf)
        for lo in range(0, n, 4096):  # bounded memory for very long moves
            chunk = frac[lo : lo + 4096]
            d = self._distances(start + chunk[:, None] * (end - start))
            if d.shape[1]:
                worst[lo : lo + len(chunk)] = d.min(axis=1)
        bad = np.flatnonzero(worst < self.clearance)
        blocked = float(frac[bad[0]]) if bad.size else None
        return SegmentCheck(blocked is None, float(worst.min()), blocked, n)

    def _short_segment(self, start: np.ndarray, end: np.ndarray, n: int) -> SegmentCheck:
        """:meth:`segment_clear` of ``n`` samples pose by pose (the one-pose path); the start pose's clearance is
        the previous call's end pose's when that ended there (a tick's move starts where the last one ended)."""
        step = (end - start) / (n - 1)
        key = start.tobytes()
        worst = [self._last_end[1] if key == self._last_end[0] else self._one.least(start)]
        for k in range(1, n - 1):
            worst.append(self._one.least(start + k * step))
        worst.append(self._one.least(end))
        self._last_end = (end.tobytes(), worst[-1])
        blocked = next((k / (n - 1) for k, w in enumerate(worst) if w < self.clearance), None)
        return SegmentCheck(blocked is None, min(worst), blocked, n)
