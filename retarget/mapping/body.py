"""The body frame of every frame of a clip: where the mapping's "forward, left, up" comes from.

:func:`clip_body_frames` frames each frame from both shoulders, else from the spine and hips, else holds
the previous good frame (:func:`hold_good_frames`), and says which in :class:`BodyFrames` (codes
:data:`FROM_SHOULDERS`, :data:`FROM_SPINE`, :data:`HELD`) and one log line.  :func:`fixed_frame` is the
frame of a fixed BVH forward axis instead.  The per-frame math is in :mod:`retarget.mapping.torso`.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from retarget.bvh.motion import ArmChain, Motion
from retarget.errors import BvhError, ConfigError
from retarget.mapping.config import Axis
from retarget.mapping.torso import body_frames_masked, shoulder_offsets, spine_frames, torso_joint

__all__ = [
    "BodyFrames",
    "clip_body_frames",
    "fixed_frame",
    "mapping_frames",
    "hold_good_frames",
]

log = logging.getLogger(__name__)

#: :attr:`BodyFrames.source` codes: where each frame's body frame came from
FROM_SHOULDERS, FROM_SPINE, HELD = 0, 1, 2


def fixed_frame(forward: Axis, up: Axis) -> np.ndarray:
    """``(3, 3)`` columns forward, left, up for a fixed BVH forward and up axis."""
    f, u = forward.vector, up.vector
    if abs(float(f @ u)) > 0.5:
        raise ConfigError(
            f"Expected a forward axis perpendicular to up ({up.value})", key="mapping.forward", value=forward.value
        )
    return np.stack([f, np.cross(u, f), u], axis=-1)


def mapping_frames(motion: Motion, chain: ArmChain, forward: Axis, up: Axis) -> np.ndarray:
    """The body frames a mapping uses: with ``forward`` AUTO, each frame's own (:func:`clip_body_frames`,
    ``(n_frames, 3, 3)``); else the one fixed frame of that BVH axis (:func:`fixed_frame`, ``(3, 3)``).

    >>> from retarget.bvh.parse import DEMO_CLIP, load_bvh
    >>> motion = load_bvh(DEMO_CLIP)
    >>> mapping_frames(motion, motion.arm_points("right"), Axis.AUTO, Axis.PY).shape
    (630, 3, 3)
    >>> mapping_frames(motion, motion.arm_points("right"), Axis.PZ, Axis.PY).shape
    (3, 3)
    """
    if forward is Axis.AUTO:
        return clip_body_frames(motion, chain, up=up).frames
    return fixed_frame(forward, up)


def hold_good_frames(values: np.ndarray, good: np.ndarray) -> np.ndarray:
    """``values`` ``(n, ...)`` with each row where ``good`` ``(n,)`` is False replaced by the previous good row.

    Rows before the first good one take the first good one.  ``ValueError`` when no row is good.

    >>> hold_good_frames(np.arange(5.0), np.array([False, True, False, False, True])).tolist()
    [1.0, 1.0, 1.0, 1.0, 4.0]
    """
    good = np.asarray(good, dtype=bool)
    if not good.any():
        raise ValueError("Expected at least one good frame, got none")
    index = np.where(good, np.arange(good.size), -1)
    np.maximum.accumulate(index, out=index)
    index[index < 0] = int(np.argmax(good))
    held: np.ndarray = np.asarray(values)[index]
    return held


@dataclass(frozen=True)
class BodyFrames:
    """The body frame of every frame of a clip, and where each came from (:func:`clip_body_frames`)."""

    frames: np.ndarray  #: ``(n_frames, 3, 3)`` columns forward, left, up: BVH-world unit vectors
    #: ``(n_frames,)`` int8: :data:`FROM_SHOULDERS`, :data:`FROM_SPINE` or :data:`HELD` (the previous good frame)
    source: np.ndarray
    torso: str | None = None  #: the torso joint of the spine fallback; None when the shoulders framed every frame

    def count(self, source: int) -> int:
        """How many frames came from ``source``."""
        return int(np.count_nonzero(self.source == source))


def clip_body_frames(motion: Motion, chain: ArmChain, *, up: Axis = Axis.PY) -> BodyFrames:
    """The body frame of every frame of ``motion``, given the arm ``chain`` that drives the robot.

    Per frame, vectorised: from the shoulders (both arms' shoulder joints and the root, as
    :func:`~retarget.mapping.torso.body_frames`); where they give none (they coincide, as in exporters
    that write all-zero channels, or the other arm is missing: a one-armed rig) from the spine and hips
    (:func:`~retarget.mapping.torso.spine_frames`, with ``up`` the BVH up axis); where neither does, the
    previous good frame (:func:`hold_good_frames`).  Logs one line when a fallback was used (a warning
    for degenerate frames, info for a one-armed rig).  Raises :class:`~retarget.errors.BvhError` (the clip's path)
    when no frame at all gives a body frame.

    >>> from retarget.bvh.parse import DEMO_CLIP, load_bvh
    >>> motion = load_bvh(DEMO_CLIP)
    >>> body = clip_body_frames(motion, motion.arm_points("right"))
    >>> body.frames.shape, body.count(FROM_SHOULDERS), body.torso
    ((630, 3, 3), 630, None)
    """
    root = int(np.flatnonzero(np.asarray(motion.parents) < 0)[0])
    hips = motion.joint_positions([root])[:, 0]
    other, why = _other_shoulder(motion, chain)
    shoulders = _shoulder_frames(hips, chain, other, motion.n_frames)
    if other is not None and shoulders.ok.all():
        return BodyFrames(shoulders.frames, np.full(motion.n_frames, FROM_SHOULDERS, dtype=np.int8))
    spine = _spine_of(motion, root, shoulders.joints, up)
    frames, spine_ok, carried = _spine_fallback(motion, chain, hips, spine, shoulders)
    ok = shoulders.ok
    usable = ok | spine_ok
    torso = motion.joint_names[spine.joint]
    if not usable.any():
        raise _no_torso_error(motion, chain, other, torso)
    source = np.where(ok, FROM_SHOULDERS, np.where(spine_ok, FROM_SPINE, HELD)).astype(np.int8)
    body = BodyFrames(hold_good_frames(np.where(ok[:, None, None], shoulders.frames, frames), usable), source, torso)
    _log_fallback(motion, chain, other, why, body, carried)
    return body


def _other_shoulder(motion: Motion, chain: ArmChain) -> tuple[ArmChain | None, str]:
    """The other arm's chain when the clip has a usable one, else None and why not (for the log line)."""
    other = "left" if chain.side == "right" else "right"
    try:
        found = motion.arm_points(other)
    except BvhError:  # its message is for when that arm drives the robot
        return None, f"no {other} arm was found"
    mine = {chain.indices[0], chain.indices[1]}
    if found.indices[0] in mine or found.indices[1] in mine:
        return None, f"the {other} arm found, {' > '.join(found.names)}, shares the {chain.side} arm's joints"
    a, b = chain.indices[0], found.indices[0]
    if torso_joint(motion.parents, [a, b]) in (a, b):
        return None, f"the {other} shoulder {found.names[0]} and the {chain.side} one are on one branch"
    return found, ""


@dataclass(frozen=True)
class _Shoulders:
    """What both shoulders give over a clip: the first step of :func:`clip_body_frames`."""

    frames: np.ndarray  #: ``(n, 3, 3)`` body frames, NaN where not ``ok``
    ok: np.ndarray  #: ``(n,)`` bool, the shoulders gave a sound body frame
    mine: np.ndarray  #: ``(n, 3)`` the driving arm's shoulder, file units, BVH world
    theirs: np.ndarray | None  #: ``(n, 3)`` the other shoulder; None for a one-armed rig
    joints: list[int]  #: the shoulder joints, the driving arm's first


def _shoulder_frames(hips: np.ndarray, chain: ArmChain, other: ArmChain | None, n: int) -> _Shoulders:
    """Body frames from both shoulders and the ``hips`` ``(n, 3)``; none (all flagged) without an ``other`` arm."""
    shoulder = np.asarray(chain.points[:, 0], dtype=np.float64)
    if other is None:
        return _Shoulders(np.full((n, 3, 3), np.nan), np.zeros(n, dtype=bool), shoulder, None, [chain.indices[0]])
    theirs = np.asarray(other.points[:, 0], dtype=np.float64)
    left, right = (shoulder, theirs) if chain.side == "left" else (theirs, shoulder)
    frames, ok = body_frames_masked(hips, left, right)
    return _Shoulders(frames, ok, shoulder, theirs, [chain.indices[0], other.indices[0]])


@dataclass(frozen=True)
class _Spine:
    """The joint carrying the shoulders (:func:`~retarget.mapping.torso.torso_joint`) over a clip."""

    joint: int  #: its joint index
    position: np.ndarray  #: ``(n, 3)`` file units, BVH world
    rotation: np.ndarray  #: ``(n, 3, 3)`` its frame -> world
    axis: np.ndarray  #: ``(3,)`` the spine's direction in its frame (rest pose: root to it, else the BVH up axis)


def _spine_of(motion: Motion, root: int, shoulders: list[int], up: Axis) -> _Spine:
    """The torso joint carrying the ``shoulders`` joints, its path over the clip and the spine's direction."""
    t = torso_joint(np.asarray(motion.parents), shoulders)
    rotations, positions = motion.global_transforms()
    rest = motion.rest_positions()
    axis = rest[t] - rest[root]
    if not np.linalg.norm(axis) > 0:  # the shoulders hang from the root
        axis = up.vector
    return _Spine(t, positions[:, t], rotations[:, t], axis)


def _spine_fallback(
    motion: Motion, chain: ArmChain, hips: np.ndarray, spine: _Spine, shoulders: _Shoulders
) -> tuple[np.ndarray, np.ndarray, str]:
    """Body frames from the spine and hips: ``(frames (n, 3, 3), ok (n,))`` and what carries the shoulders.

    The shoulders sit at their offsets from the torso joint in the good frames (else the driving one's,
    mirrored: :func:`~retarget.mapping.torso.shoulder_offsets`); when that gives no frame at all (the
    shoulders sit on the spine throughout the clip), at their offsets in the rest pose.  The third item
    says which, for the log line.
    """
    offsets = shoulder_offsets(
        spine.position,
        spine.rotation,
        shoulders.mine,
        side=chain.side,
        spine_axis=spine.axis,
        other_shoulder=shoulders.theirs,
        good=shoulders.ok,
    )
    frames, ok = spine_frames(hips, spine.position, spine.rotation, offsets)
    mirrored = f"the {chain.side} shoulder (mirrored for the other)"
    if ok.any():
        good = shoulders.ok
        carried = (
            f"both shoulders as in the {int(good.sum())} good frames" if good.any() else f"{mirrored} as in the clip"
        )
        return frames, ok, carried
    rest = motion.rest_positions()  # nothing in the clip separates the shoulders (they sit on the spine)
    joints = shoulders.joints
    both = len(joints) == 2
    offsets = shoulder_offsets(
        rest[spine.joint][None],
        np.eye(3)[None],
        rest[joints[0]][None],
        side=chain.side,
        spine_axis=spine.axis,
        other_shoulder=rest[joints[1]][None] if both else None,
        good=np.ones(1, dtype=bool),
    )
    frames, ok = spine_frames(hips, spine.position, spine.rotation, offsets)
    return frames, ok, f"{'both shoulders' if both else mirrored} as in the rest pose"


def _no_torso_error(motion: Motion, chain: ArmChain, other: ArmChain | None, torso: str) -> BvhError:
    """The error for a clip where no frame, nor the rest pose, gives a body frame."""
    names = f"shoulder {chain.names[0]}" if other is None else f"shoulders {chain.names[0]} and {other.names[0]}"
    return BvhError(
        f"Expected a torso for the body frame in at least one of the {motion.n_frames} frames, got none: the "
        f"{names} and the spine ({torso}) coincide or line up in every frame and in the rest pose; a fixed "
        "forward axis (the mapping's forward) needs no torso",
        path=motion.path,
    )


def _log_fallback(
    motion: Motion, chain: ArmChain, other: ArmChain | None, why: str, body: BodyFrames, carried: str
) -> None:
    """The one log line of a clip framed (in part) from the spine: info for a one-armed rig, else a warning."""
    n = motion.n_frames
    where = motion.path.name if motion.path else "the clip"
    held = f"; {body.count(HELD)} hold the previous good frame" if body.count(HELD) else ""
    if other is None:
        log.info("%s: body frame from the spine, %s carrying %s, since %s%s", where, body.torso, carried, why, held)
    else:
        log.warning(
            "%s: the shoulders %s and %s coincide or line up with the spine in %d of %d frames: "
            "%d framed from the spine, %s carrying %s%s",
            where, chain.names[0], other.names[0], n - body.count(FROM_SHOULDERS), n, body.count(FROM_SPINE),
            body.torso, carried, held,
        )  # fmt: skip
