"""``Motion``: a parsed BVH clip, with forward kinematics for all frames at once.

Frames and units: positions are in the file's units (usually centimetres) in
the BVH world frame (usually Y up).  Angles inside are radians; the raw
``channels`` keep the file's degrees.

FK convention: a joint's local transform is its translation (OFFSET, or its
position channels in place of the OFFSET components they name) followed by
its rotation channels composed in listed order as intrinsic rotations
(``Zrotation Xrotation Yrotation`` -> ``Rz @ Rx @ Ry``)::

    R_world[j] = R_world[parent] @ R_local[j]
    p_world[j] = p_world[parent] + R_world[parent] @ t_local[j]

FK (:mod:`retarget.bvh.fk`) runs vectorised over blocks of ~170 frames, one
depth level of the skeleton per step; results are computed on first use,
cached, and returned read-only.

Example::

    motion = load_bvh("clip.bvh")
    motion.positions()            # (n_frames, n_joints, 3)
    arm = motion.arm_points("right")
    arm.points[:, 2]              # (n_frames, 3) wrist, file units
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

import retarget.bvh.chains as chains
import retarget.bvh.proportions as proportions
import retarget.bvh.skeleton as skeleton
import retarget.bvh.units as units
from retarget.bvh.fk import Pose, forward_kinematics
from retarget.errors import BvhError

log = logging.getLogger(__name__)

#: ``guess_units`` measures the skeleton's extent on at most this many frames, evenly spaced.
UNITS_SAMPLE_FRAMES = 64


@dataclass(frozen=True)
class ChannelLayout:
    """The CHANNELS of one joint: canonical names (``"Zrotation"``, ...) and the first column in ``Motion.channels``."""

    names: tuple[str, ...]
    first_column: int

    @property
    def rotation_order(self) -> str:
        """Axis letters of the rotation channels in file order, e.g. ``"ZXY"`` (``""`` if none)."""
        return "".join(n[0] for n in self.names if n.endswith("rotation"))

    @property
    def position_axes(self) -> str:
        """Axis letters of the position channels in file order, e.g. ``"XYZ"`` (``""`` if none)."""
        return "".join(n[0] for n in self.names if n.endswith("position"))

    def columns(self, kind: str) -> list[int]:
        """Columns in ``Motion.channels`` of the ``"rotation"`` or ``"position"`` channels, in file order."""
        return [self.first_column + i for i, n in enumerate(self.names) if n.endswith(kind)]


@dataclass(frozen=True)
class EndSite:
    """An End Site: the joint it hangs from and its OFFSET (file units) in that joint's frame."""

    parent: int
    offset: tuple[float, float, float]


@dataclass(frozen=True)
class ArmChain:
    """Shoulder (glenohumeral), elbow and wrist of one arm over a clip.

    ``points``: ``(n_frames, 3, 3)`` float64, file units, BVH world frame;
    ``points[:, 0]`` shoulder, ``[:, 1]`` elbow, ``[:, 2]`` wrist.
    ``names``: the joints used; an End Site wrist is named ``"forearm.L/End Site"``.
    ``indices``: joint indices of shoulder and elbow, and of the wrist joint
    (or, when ``wrist_is_end_site``, the index into ``Motion.end_sites``).
    ``rest_points``: ``(3, 3)`` the same three points in the rest pose (OFFSETs alone).
    ``bone_lengths``: median upper-arm and forearm lengths.
    ``detail``: how the chain was found; ``rejected``: the other candidates and why
    they were not chosen; ``warnings``: unusual bone lengths (see
    :func:`~retarget.bvh.proportions.check_arm_lengths`).
    """

    side: str
    names: tuple[str, str, str]
    indices: tuple[int, int, int]
    wrist_is_end_site: bool
    points: np.ndarray = field(repr=False, compare=False)
    method: str = "names"  #: how the joints were chosen: "names", "structure" or "explicit"
    rest_points: np.ndarray | None = field(default=None, repr=False, compare=False)
    rejected: tuple[chains.Rejected, ...] = field(default=(), repr=False, compare=False)
    detail: str = field(default="", repr=False, compare=False)
    warnings: tuple[str, ...] = field(default=(), repr=False, compare=False)

    @property
    def lengths_from(self) -> str:
        """Where :attr:`bone_lengths` come from: ``"frames"``, or ``"rest pose"`` for a clip without frames."""
        return "rest pose" if self.points.shape[0] == 0 and self.rest_points is not None else "frames"

    @property
    def bone_lengths(self) -> tuple[float, float]:
        """Median upper-arm and forearm lengths over the clip (file units); the rest pose's without frames."""
        pts = self.points if self.lengths_from == "frames" else np.asarray(self.rest_points)[None]
        upper = np.linalg.norm(pts[:, 1] - pts[:, 0], axis=-1)
        fore = np.linalg.norm(pts[:, 2] - pts[:, 1], axis=-1)
        if upper.size == 0:
            return 0.0, 0.0
        return float(np.median(upper)), float(np.median(fore))


def _readonly(a: np.ndarray) -> np.ndarray:
    a.flags.writeable = False
    return a


class Motion:
    """A BVH clip: skeleton, raw channels and cached FK.

    Read one with :func:`~retarget.bvh.parse.load_bvh` or :func:`~retarget.bvh.parse.parse_bvh`.  The
    constructor checks the shapes (``ValueError``); the arrays are kept read-only.  FK results
    (:meth:`positions`, :meth:`end_site_positions`, :meth:`global_transforms`, :meth:`arm_points`) are
    computed for all frames on first use, cached, and returned read-only.

    Attributes:
        joint_names: ROOT and JOINT names in file order (End Sites excluded).
        parents: ``(n_joints,)`` int, parent joint index, -1 for a root.
        offsets: ``(n_joints, 3)`` float64 OFFSETs, file units.
        layout: per joint, its :class:`ChannelLayout`.
        end_sites: the End Sites, in file order.
        channels: ``(n_frames, n_channels)`` float64, raw values in file order (degrees, file units).
        frame_time: seconds per frame.
        path: the file read, or None.

    >>> from retarget.bvh.parse import DEMO_CLIP, load_bvh
    >>> motion = load_bvh(DEMO_CLIP)
    >>> motion.n_joints, motion.n_frames, round(motion.fps), round(motion.duration, 2)
    (21, 630, 60, 10.5)
    >>> motion.joint_names[:3], motion.guess_units().unit
    (('Hips', 'Spine', 'Spine1'), 'cm')
    """

    def __init__(
        self,
        *,
        joint_names: tuple[str, ...],
        parents: np.ndarray,
        offsets: np.ndarray,
        layout: tuple[ChannelLayout, ...],
        end_sites: tuple[EndSite, ...],
        channels: np.ndarray,
        frame_time: float,
        path: Path | None = None,
    ):
        n = len(joint_names)
        parents = np.asarray(parents, dtype=np.intp)
        offsets = np.asarray(offsets, dtype=np.float64).reshape(n, 3)
        channels = np.asarray(channels, dtype=np.float64)
        if parents.shape != (n,) or len(layout) != n:
            raise ValueError(f"Expected {n} parents and layouts, got {parents.shape} and {len(layout)}")
        if any(p >= j for j, p in enumerate(parents)):
            raise ValueError("Expected every parent index to come before its child")
        n_channels = sum(len(c.names) for c in layout)
        if channels.ndim != 2 or channels.shape[1] != n_channels:
            raise ValueError(f"Expected channels of shape (n_frames, {n_channels}), got {channels.shape}")
        if not (frame_time > 0):
            raise ValueError(f"Expected a positive frame time, got {frame_time}")
        self.joint_names = tuple(joint_names)
        self.parents = _readonly(parents)
        self.offsets = _readonly(offsets)
        self.layout = tuple(layout)
        self.end_sites = tuple(end_sites)
        self.channels = _readonly(channels)
        self.frame_time = float(frame_time)
        self.path = path
        self._cached_pose: Pose | None = None
        #: joint positions of a few joints and their ancestors (:meth:`joint_positions`): (joints, positions)
        self._cached_chains: list[tuple[list[int], np.ndarray]] = []
        self._cached_lengths: np.ndarray | None = None
        self._cached_height: float | None = None

    # ------------------------------------------------------------------------------------------ info
    @property
    def n_frames(self) -> int:
        return int(self.channels.shape[0])

    @property
    def n_joints(self) -> int:
        return len(self.joint_names)

    @property
    def fps(self) -> float:
        """Frames per second, ``1 / frame_time``."""
        return 1.0 / self.frame_time

    @property
    def duration(self) -> float:
        """Seconds of playback, ``n_frames * frame_time``."""
        return self.n_frames * self.frame_time

    @property
    def rotation_orders(self) -> tuple[str, ...]:
        """Per joint, its rotation channel axes in file order (``"ZXY"``; ``""`` if none)."""
        return tuple(c.rotation_order for c in self.layout)

    def joint_index(self, name: str) -> int:
        """Index of the joint called ``name`` (exact match); ``KeyError`` listing nothing else if absent."""
        try:
            return self.joint_names.index(name)
        except ValueError:
            raise KeyError(f"Expected a joint name of this clip, got {name!r}") from None

    def children(self, index: int) -> list[int]:
        """Joint indices whose parent is ``index``."""
        return [int(c) for c in np.flatnonzero(self.parents == index)]

    def rest_positions(self) -> np.ndarray:
        """``(n_joints, 3)`` joint positions from OFFSETs alone (no channels), file units."""
        out = np.zeros((self.n_joints, 3))
        for j, p in enumerate(self.parents):
            out[j] = self.offsets[j] + (out[p] if p >= 0 else 0.0)
        return out

    def rest_end_site_positions(self) -> np.ndarray:
        """``(n_end_sites, 3)`` End Site positions from OFFSETs alone, file units."""
        rest = self.rest_positions()
        return np.array([rest[e.parent] + np.asarray(e.offset) for e in self.end_sites]).reshape(-1, 3)

    def bone_lengths(self) -> np.ndarray:
        """``(n_joints,)`` float64 each joint's distance from its parent, file units; 0 for a root.

        A joint with position channels measures the median over the frames of its
        translation (the OFFSET with the channels in place of the components they
        name); the others, and every joint of a clip without frames, the OFFSET's
        length.  Computed once, read-only.

        >>> from retarget.bvh.parse import DEMO_CLIP, load_bvh
        >>> motion = load_bvh(DEMO_CLIP)
        >>> lengths = motion.bone_lengths()
        >>> lengths.shape, float(lengths[motion.joint_index("RightForeArm")])  # upper arm, cm
        ((21,), 29.0)
        >>> round(motion.skeleton_height()), motion.guess_units().basis   # the rest pose is upright: 169 cm
        (174, 'rest pose')
        """
        if self._cached_lengths is None:
            lengths = np.linalg.norm(self.offsets, axis=1)
            for j, lay in enumerate(self.layout):
                columns = lay.columns("position")
                if columns and self.parents[j] >= 0 and self.n_frames:
                    t = np.repeat(self.offsets[j][None], self.n_frames, axis=0)
                    for axis, column in zip(lay.position_axes, columns, strict=True):
                        t[:, "XYZ".index(axis)] = self.channels[:, column]
                    lengths[j] = float(np.median(np.linalg.norm(t, axis=1)))
            lengths[self.parents < 0] = 0.0
            self._cached_lengths = _readonly(lengths)
        return self._cached_lengths

    def skeleton_height(self) -> float:
        """The standing height from :meth:`bone_lengths`, file units; pose-independent.

        See :func:`~retarget.bvh.proportions.height_from_bones`; the arm checks and :meth:`guess_units`
        measure against it.
        """
        if self._cached_height is None:
            self._cached_height = proportions.height_from_bones(
                self.parents,
                self.bone_lengths(),
                [e.parent for e in self.end_sites],
                [float(np.linalg.norm(e.offset)) for e in self.end_sites],
            )
        return self._cached_height

    def guess_units(self) -> units.UnitsGuess:
        """The length unit suggested by the skeleton's height (see :func:`retarget.bvh.units.guess_units`).

        The height is the rest pose's extent when that agrees with :meth:`skeleton_height` (an upright rest
        pose), else the median extent over up to 64 evenly spaced frames when that agrees, else
        :meth:`skeleton_height` itself; ``basis`` says which.
        """
        rest = np.vstack([self.rest_positions(), self.rest_end_site_positions()])
        return units.guess_units(rest, bone_height=self.skeleton_height(), frames=self._sampled_points())

    def _sampled_points(self) -> np.ndarray:
        """``(k, n_joints + n_end_sites, 3)`` joints and End Sites on at most 64 evenly spaced frames."""
        if self.n_frames == 0:
            return np.zeros((0, self.n_joints + len(self.end_sites), 3))
        k = min(self.n_frames, UNITS_SAMPLE_FRAMES)
        frames = np.unique(np.linspace(0, self.n_frames - 1, k).round().astype(np.intp))
        pose = self._cached_pose
        if pose is not None and pose.end_sites is not None:
            return np.concatenate([pose.positions[frames], pose.end_sites[frames]], axis=1)
        sampled = forward_kinematics(
            self.parents,
            self.offsets,
            [lay.names for lay in self.layout],
            [lay.first_column for lay in self.layout],
            self.channels[frames],
            [e.parent for e in self.end_sites],
            [e.offset for e in self.end_sites],
            end_sites=True,
        )
        if sampled.end_sites is None:
            raise AssertionError("unreachable: end_sites=True computes the End Sites")
        return np.concatenate([sampled.positions, sampled.end_sites], axis=1)

    def __repr__(self) -> str:
        src = f" {self.path.name!r}" if self.path else ""
        return f"<Motion{src}: {self.n_joints} joints, {self.n_frames} frames at {self.fps:.4g} fps>"

    # -------------------------------------------------------------------------------------------- FK
    def positions(self) -> np.ndarray:
        """``(n_frames, n_joints, 3)`` float64 global joint positions, file units, BVH world frame.

        Joint ``j`` is ``joint_names[j]``.  Computed for all frames on the first call (see the module
        notes for the convention), then cached; the array is read-only.

        >>> from retarget.bvh.parse import DEMO_CLIP, load_bvh
        >>> motion = load_bvh(DEMO_CLIP)
        >>> p = motion.positions()
        >>> p.shape, p.flags.writeable
        ((630, 21, 3), False)
        >>> p[0, motion.joint_index("Head")].round(1).tolist()  # frame 0, centimetres, Y up
        [0.4, 153.0, 0.7]
        """
        return self._pose().positions

    def joint_positions(self, indices: Sequence[int]) -> np.ndarray:
        """``(n_frames, len(indices), 3)`` float64 global positions of the joints ``indices``, file units, BVH world
        frame: the same values as those columns of :meth:`positions`.  Before the whole FK has run, only these
        joints and their ancestors go through it (an arm chain is ~8 of a full-body skeleton's 20-60 joints), and
        that is cached; read-only.

        >>> from retarget.bvh.parse import DEMO_CLIP, load_bvh
        >>> motion = load_bvh(DEMO_CLIP)
        >>> arm = [motion.joint_index(name) for name in ("RightArm", "RightForeArm", "RightHand")]
        >>> bool((motion.joint_positions(arm) == motion.positions()[:, arm]).all())
        True
        """
        wanted = [int(i) for i in indices]
        if any(not 0 <= i < self.n_joints for i in wanted):
            raise ValueError(f"Expected joint indices in 0..{self.n_joints - 1}, got {wanted}")
        if self._cached_pose is not None:
            return _readonly(self._cached_pose.positions[:, wanted])
        for joints, positions in self._cached_chains:
            column = {j: k for k, j in enumerate(joints)}
            if all(i in column for i in wanted):
                return _readonly(positions[:, [column[i] for i in wanted]])
        joints = self._with_ancestors(wanted)
        column = {j: k for k, j in enumerate(joints)}
        parents = [column[int(self.parents[j])] if self.parents[j] >= 0 else -1 for j in joints]
        positions = forward_kinematics(
            np.array(parents, dtype=np.intp),
            self.offsets[joints],
            [self.layout[j].names for j in joints],
            [self.layout[j].first_column for j in joints],
            self.channels,
            end_sites=False,
        ).positions
        self._cached_chains.append((joints, _readonly(positions)))
        return _readonly(positions[:, [column[i] for i in wanted]])

    def _with_ancestors(self, indices: Sequence[int]) -> list[int]:
        """``indices`` and every ancestor of them, in file order (parents first)."""
        found: set[int] = set()
        for j in indices:
            while j >= 0 and j not in found:
                found.add(j)
                j = int(self.parents[j])
        return sorted(found)

    def global_transforms(self) -> tuple[np.ndarray, np.ndarray]:
        """``(rotations (n_frames, n_joints, 3, 3), positions (n_frames, n_joints, 3))``: joint frame -> world."""
        pose = self._pose(rotations=True)
        if pose.rotations is None:
            raise AssertionError("unreachable: _pose(rotations=True) computes the rotations")
        return pose.rotations, pose.positions

    def end_site_positions(self) -> np.ndarray:
        """``(n_frames, n_end_sites, 3)`` float64 global End Site positions, file units."""
        sites = self._pose(end_sites=True).end_sites
        if sites is None:
            raise AssertionError("unreachable: _pose(end_sites=True) computes the End Sites")
        return sites

    def _pose(self, *, rotations: bool = False, end_sites: bool = False) -> Pose:
        """The cached FK results, computed (again, with more in it) only when something asked for is missing."""
        pose = self._cached_pose
        if pose is None or (rotations and pose.rotations is None) or (end_sites and pose.end_sites is None):
            new = forward_kinematics(
                self.parents,
                self.offsets,
                [lay.names for lay in self.layout],
                [lay.first_column for lay in self.layout],
                self.channels,
                [e.parent for e in self.end_sites],
                [e.offset for e in self.end_sites],
                rotations=rotations,
                end_sites=end_sites or rotations,
            )
            old = pose or new  # keep the arrays already handed out
            pose = Pose(
                positions=old.positions,
                end_sites=old.end_sites if old.end_sites is not None else new.end_sites,
                rotations=old.rotations if old.rotations is not None else new.rotations,
            )
            for array in (pose.positions, pose.end_sites, pose.rotations):
                if array is not None:
                    _readonly(array)
            self._cached_pose = pose
        return pose

    # -------------------------------------------------------------------------------------- arms
    def arm_search(self, side: str, *, names: tuple[str, str, str] | None = None) -> chains.ArmSearch:
        """What arm detection finds for ``side``, and rejects, without raising for a missing chain.

        See :func:`retarget.bvh.skeleton.search_arm`; the plausibility checks measure against
        :meth:`skeleton_height`.  Bad explicit ``names`` raise as in :meth:`arm_points`.
        """
        return skeleton.search_arm(
            side,
            joint_names=self.joint_names,
            parents=self.parents,
            offsets=self.offsets,
            end_site_parents=tuple(e.parent for e in self.end_sites),
            end_site_offsets=tuple(e.offset for e in self.end_sites),
            names=names,
            path=self.path,
            height=self.skeleton_height(),
        )

    def arm_points(self, side: str, *, names: tuple[str, str, str] | None = None) -> ArmChain:
        """Shoulder, elbow and wrist of the ``"left"`` or ``"right"`` arm for every frame.

        Detection by joint names (CMU, Mixamo, Collar/Shoulder/Elbow/Wrist,
        Rigify, MakeHuman, Poser/DAZ, OptiTrack, any prefix), else by skeleton
        structure; see :mod:`retarget.bvh.skeleton`.  ``names`` overrides
        detection with three joint names (the wrist may be ``"<joint>/End Site"``).

        Returns an :class:`ArmChain`: ``points`` ``(n_frames, 3, 3)`` float64, file
        units, BVH world frame (``[:, 0]`` shoulder, ``[:, 1]`` elbow, ``[:, 2]``
        wrist; read-only), ``rest_points`` ``(3, 3)``, the joints' ``names`` and
        ``indices``, how they were found (``method``, ``detail``), the candidates not
        chosen (``rejected``) and ``warnings``.
        Raises ``ValueError`` for a bad side or not three ``names``, and
        :class:`~retarget.errors.BvhError` (naming the file) when no arm chain
        (or more than one) is found, a given name does not exist, or the chain's
        upper arm or forearm (median over the frames; the rest pose's without
        frames) is under 2 % or over 75 % of :meth:`skeleton_height`.  Outside
        6-40 % it logs a warning, also kept in ``warnings``.

        >>> from retarget.bvh.parse import DEMO_CLIP, load_bvh
        >>> motion = load_bvh(DEMO_CLIP)
        >>> arm = motion.arm_points("right")
        >>> arm.names, arm.method
        (('RightArm', 'RightForeArm', 'RightHand'), 'names')
        >>> arm.points.shape, arm.bone_lengths  # (n_frames, 3, 3); upper arm and forearm, cm
        ((630, 3, 3), (29.0, 25.0))
        >>> motion.arm_points("up")
        Traceback (most recent call last):
        ...
        ValueError: Expected side 'left' or 'right', got 'up'
        """
        search = self.arm_search(side, names=names)
        found = search.found
        if found is None:
            raise BvhError(search.error, path=self.path)
        if found.method == "structure":
            log.info("%s arm found by structure: %s", side, " > ".join(found.names))
        points = np.empty((self.n_frames, 3, 3))
        rest = self.rest_positions()
        if found.wrist_is_end_site:
            points[:, :2] = self.joint_positions(found.indices[:2])
            points[:, 2] = self.end_site_positions()[:, found.indices[2]]
            rest_wrist = self.rest_end_site_positions()[found.indices[2]]
        else:
            points[:] = self.joint_positions(found.indices)
            rest_wrist = rest[found.indices[2]]
        chain = ArmChain(
            side=found.side,
            names=found.names,
            indices=found.indices,
            wrist_is_end_site=found.wrist_is_end_site,
            points=_readonly(points),
            method=found.method,
            rest_points=_readonly(np.array([rest[found.indices[0]], rest[found.indices[1]], rest_wrist])),
            rejected=found.rejected,
            detail=found.detail,
        )
        upper, fore = chain.bone_lengths
        n = self.n_frames
        measured = f"median over {n} frame{'s' if n != 1 else ''}" if n else "in the rest pose (no frames)"
        warning = proportions.check_arm_lengths(
            found, upper, fore, self.skeleton_height(), measured=measured, path=self.path
        )
        if warning is None:
            return chain
        log.warning("%s: %s", self.path or "<bvh>", warning)
        return replace(chain, warnings=(warning,))

    # ---------------------------------------------------------------------------------- transforms
    def scaled(self, factor: float) -> Motion:
        """A copy with every length (OFFSETs, End Sites, position channels) multiplied by ``factor``."""
        factor = float(factor)
        if not (np.isfinite(factor) and factor > 0):
            raise ValueError(f"Expected a positive finite scale factor, got {factor}")
        channels = self.channels.copy()
        for lay in self.layout:
            channels[:, lay.columns("position")] *= factor
        return Motion(
            joint_names=self.joint_names,
            parents=self.parents.copy(),
            offsets=self.offsets * factor,
            layout=self.layout,
            end_sites=tuple(EndSite(e.parent, _scaled(e.offset, factor)) for e in self.end_sites),
            channels=channels,
            frame_time=self.frame_time,
            path=self.path,
        )


def _scaled(offset: tuple[float, float, float], factor: float) -> tuple[float, float, float]:
    x, y, z = offset
    return (x * factor, y * factor, z * factor)
