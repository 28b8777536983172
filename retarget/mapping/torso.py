"""Body frames from torso points, per frame and vectorised: the math under :mod:`retarget.mapping.body`.

- from the shoulders and hips: :func:`body_frames_masked` (flags the degenerate frames), :func:`body_frames`
  (raises for them);
- from the spine and hips, for frames the shoulders do not frame: :func:`torso_joint` (the joint carrying
  the shoulders), :func:`shoulder_offsets` (the shoulders in its frame) and :func:`spine_frames`.

Points in any units, BVH world; frames are ``(3, 3)`` columns forward, left, up as BVH-world unit vectors.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

__all__ = [
    "body_frames",
    "body_frames_masked",
    "shoulder_offsets",
    "spine_frames",
    "torso_joint",
]

#: a shoulder line shorter than this fraction of the torso's part across it (hips to the shoulders' midpoint,
#: made orthogonal to the shoulder line), or the other way round, gives no body frame
DEGENERATE = 1e-6


def body_frames_masked(
    hips: np.ndarray, left_shoulder: np.ndarray, right_shoulder: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Torso frames ``(n, 3, 3)`` and which of them are sound, ``(n,)`` bool, from points ``(n, 3)``.

    Points in any units, BVH world.  Columns are forward, left, up as BVH-world unit vectors: left
    along the shoulder line, up from the hips to the shoulders' midpoint (made orthogonal), forward =
    left x up.  A frame is unsound (``False``, its matrix NaN) when the shoulders coincide, the hips sit
    on their midpoint, or the shoulder line runs along the spine (the shoulder line and the torso's part
    across it within a factor :data:`DEGENERATE` of each other), or a point is not finite.  Never raises
    for a degenerate frame: :func:`body_frames` is the strict form.

    >>> hips = np.zeros((2, 3))
    >>> frames, ok = body_frames_masked(hips, [[1.0, 5, 0], [0, 5, 0]], [[-1.0, 5, 0], [0, 5, 0]])
    >>> frames[0].tolist(), ok.tolist()  # facing +z, left +x, up +y; the second frame's shoulders coincide
    ([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]], [True, False])
    """
    left = np.asarray(left_shoulder, dtype=np.float64) - right_shoulder
    up = 0.5 * (np.asarray(left_shoulder, dtype=np.float64) + right_shoulder) - hips
    with np.errstate(divide="ignore", invalid="ignore"):  # degenerate frames divide by 0: flagged below
        n_left = np.linalg.norm(left, axis=-1, keepdims=True)
        left /= n_left
        fwd = np.cross(left, up)
        n_fwd = np.linalg.norm(fwd, axis=-1, keepdims=True)  # the torso across the shoulder line
        fwd /= n_fwd
        good: np.ndarray = ((n_fwd > DEGENERATE * n_left) & (n_left > DEGENERATE * n_fwd))[..., 0]
    up = np.cross(fwd, left)
    frames = np.stack([fwd, left, up], axis=-1)
    if not good.all():
        frames[~good] = np.nan
    return frames, good


def body_frames(hips: np.ndarray, left_shoulder: np.ndarray, right_shoulder: np.ndarray) -> np.ndarray:
    """Torso frames ``(n, 3, 3)`` from points ``(n, 3)`` (any units, BVH world).

    Columns are forward, left, up as BVH-world unit vectors: left along the
    shoulder line, up from the hips to the shoulders' midpoint (made orthogonal),
    forward = left x up.  ``frames[i].T @ v`` expresses a world vector in the body frame.
    ``ValueError`` when a frame is degenerate (:func:`body_frames_masked` flags them instead).
    """
    frames, ok = body_frames_masked(hips, left_shoulder, right_shoulder)
    if not ok.all():
        left = np.asarray(left_shoulder, dtype=np.float64) - right_shoulder
        up = 0.5 * (np.asarray(left_shoulder, dtype=np.float64) + right_shoulder) - hips
        n_left, n_up = np.linalg.norm(left, axis=-1), np.linalg.norm(up, axis=-1)
        what = "torso (shoulder line parallel to the spine)"
        if np.any((n_left <= DEGENERATE * n_up)[~ok]):
            what = "shoulder line"
        elif np.any((n_up <= DEGENERATE * n_left)[~ok]):
            what = "torso (the hips on the shoulders' midpoint)"
        raise ValueError(f"Expected a non-degenerate {what}, got a zero-length vector")
    return frames


def torso_joint(parents: np.ndarray, shoulders: Sequence[int]) -> int:
    """The joint at the top of the spine that carries the shoulders: a joint index of ``parents`` ``(n_joints,)``.

    For two shoulder joints, their lowest common ancestor; for one, its nearest ancestor that branches
    (the chest, which also carries the neck or the other arm), else the root.

    >>> parents = np.array([-1, 0, 1, 2, 1, 4])  # hips, chest, clavicle, shoulder, other clavicle, shoulder
    >>> torso_joint(parents, [3, 5]), torso_joint(parents, [3]), torso_joint(parents[:4], [3])  # one arm: the root
    (1, 1, 0)
    """
    parents = np.asarray(parents, dtype=np.intp)
    if len(shoulders) >= 2:
        above = set()
        j = int(parents[shoulders[0]])
        while j >= 0:
            above.add(j)
            j = int(parents[j])
        j = int(parents[shoulders[1]])
        while j >= 0 and j not in above:
            j = int(parents[j])
        if j >= 0:
            return j
    n_children = np.bincount(parents[parents >= 0], minlength=len(parents))
    j = int(parents[shoulders[0]])
    if j < 0:  # the shoulder is the root
        return int(shoulders[0])
    while n_children[j] < 2 and parents[j] >= 0:
        j = int(parents[j])
    return j


def _local(rotations: np.ndarray, origin: np.ndarray, points: np.ndarray) -> np.ndarray:
    """``rotations^T @ (points - origin)``: world points ``(n, 3)`` in frames ``(n, 3, 3)`` at ``origin`` ``(n, 3)``."""
    out: np.ndarray = np.einsum("nji,nj->ni", rotations, points - origin)
    return out


def shoulder_offsets(
    torso_position: np.ndarray,
    torso_rotation: np.ndarray,
    shoulder: np.ndarray,
    *,
    side: str,
    spine_axis: np.ndarray | Sequence[float] = (0.0, 1.0, 0.0),
    other_shoulder: np.ndarray | None = None,
    good: np.ndarray | None = None,
) -> np.ndarray:
    """``(2, 3)`` the left and right shoulders' offsets from the torso joint, in its frame (file units).

    ``torso_position``, ``shoulder`` (of ``side``) and ``other_shoulder``: ``(n, 3)`` file units, BVH
    world; ``torso_rotation`` ``(n, 3, 3)`` the torso joint's frame -> world (the rotations of the
    chain from the root up to the joint carrying the shoulders, :func:`torso_joint`).

    With ``other_shoulder`` and some ``good`` ``(n,)`` frames (where both shoulders gave a body frame):
    each shoulder's mean offset over those frames.  Otherwise (a one-armed rig, or no good frame) the
    ``side`` shoulder's mean offset over every frame, and for the other shoulder the same turned half a
    turn about ``spine_axis`` ``(3,)``, the spine's direction in the torso joint's frame (in the rest
    pose, where every frame is the world's: from the root up to the torso joint, or the BVH up axis).
    Both rows are equal when nothing separates the shoulders.

    >>> R = np.eye(3)[None]
    >>> shoulder_offsets([[0.0, 50, 0]], R, [[18.0, 60, 0]], side="left").tolist()
    [[18.0, 10.0, 0.0], [-18.0, 10.0, 0.0]]
    """
    R = np.asarray(torso_rotation, dtype=np.float64)
    origin = np.asarray(torso_position, dtype=np.float64)
    own = _local(R, origin, np.asarray(shoulder, dtype=np.float64))
    if other_shoulder is not None and good is not None and np.any(good):
        use = np.asarray(good, dtype=bool)
        mine = own[use].mean(axis=0)
        theirs = _local(R, origin, np.asarray(other_shoulder, dtype=np.float64))[use].mean(axis=0)
    else:
        mine = own.mean(axis=0)
        axis = np.asarray(spine_axis, dtype=np.float64)
        axis = axis / float(np.linalg.norm(axis))
        theirs = 2.0 * float(mine @ axis) * axis - mine
    return np.stack([mine, theirs] if side == "left" else [theirs, mine])


def spine_frames(
    hips: np.ndarray, torso_position: np.ndarray, torso_rotation: np.ndarray, offsets: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Body frames from the spine and hips: :func:`body_frames_masked` of shoulders carried by the torso joint.

    ``hips``, ``torso_position`` ``(n, 3)`` file units, BVH world; ``torso_rotation`` ``(n, 3, 3)``
    the torso joint's frame -> world; ``offsets`` ``(2, 3)`` the left and right shoulders in the torso
    joint's frame (:func:`shoulder_offsets`).  Each frame's shoulders are the torso joint's position
    plus the offsets turned by its rotation, so the frames match the shoulder-based ones exactly while
    the clavicles are still, and within a few degrees otherwise.  Returns ``(frames (n, 3, 3), ok (n,)
    bool)`` as :func:`body_frames_masked`.

    >>> turn = np.array([[0.0, 0, 1], [0, 1, 0], [-1, 0, 0]])  # the torso turned 90 degrees about +y
    >>> R = np.stack([np.eye(3), turn])
    >>> hips, chest = np.zeros((2, 3)), np.tile([0.0, 50, 0], (2, 1))
    >>> frames, ok = spine_frames(hips, chest, R, np.array([[18.0, 10, 0], [-18.0, 10, 0]]))
    >>> frames[:, :, 1].round(6).tolist(), ok.tolist()  # the body's left follows the torso
    ([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0]], [True, True])
    """
    R = np.asarray(torso_rotation, dtype=np.float64)
    origin = np.asarray(torso_position, dtype=np.float64)
    carried = origin[:, None, :] + np.einsum("nij,sj->nsi", R, np.asarray(offsets, dtype=np.float64))
    return body_frames_masked(hips, carried[:, 0], carried[:, 1])
