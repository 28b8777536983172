"""Walking a joint hierarchy given as a ``parents`` array (``-1`` for the root, parents before children).

Each joint's children, its depth, how far one joint lies below another, the joints between them, the rest
pose from the OFFSETs and each joint's reach down to a leaf: the tree walks that arm detection by names
(:mod:`~retarget.bvh.names`) and by structure (:mod:`~retarget.bvh.structure`) share.
"""

from __future__ import annotations

import numpy as np


def children(parents: np.ndarray) -> list[list[int]]:
    """Per joint, the indices of its children in order."""
    out: list[list[int]] = [[] for _ in range(len(parents))]
    for j, p in enumerate(parents):
        if p >= 0:
            out[int(p)].append(j)
    return out


def depth(parents: np.ndarray, j: int) -> int:
    """Number of links from the root down to joint ``j``."""
    d = 0
    while parents[j] >= 0:
        j = int(parents[j])
        d += 1
    return d


def depth_below(parents: np.ndarray, child: int, ancestor: int, limit: int) -> int | None:
    """Number of links from ``ancestor`` down to ``child`` (at most ``limit``), else None."""
    d, j = 0, child
    while j >= 0 and d <= limit:
        if j == ancestor:
            return d
        j = int(parents[j])
        d += 1
    return None


def path_between(parents: np.ndarray, child: int, ancestor: int) -> list[int]:
    """The joints strictly between ``child`` and its ``ancestor``, from the child up."""
    out, j = [], int(parents[child])
    while j >= 0 and j != ancestor:
        out.append(j)
        j = int(parents[j])
    return out


def rest_positions(parents: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """``(n_joints, 3)`` joint positions from the OFFSETs alone (file units)."""
    rest = np.zeros((len(parents), 3))
    for j in range(len(parents)):
        rest[j] = np.asarray(offsets[j], dtype=np.float64) + (rest[parents[j]] if parents[j] >= 0 else 0.0)
    return rest


def reach(children: list[list[int]], rest: np.ndarray) -> np.ndarray:
    """Per joint, the longest path down to a leaf joint (rest pose, file units)."""
    out = np.zeros(len(children))
    for j in range(len(children) - 1, -1, -1):  # parents come before children
        out[j] = max((float(np.linalg.norm(rest[c] - rest[j])) + out[c] for c in children[j]), default=0.0)
    return out
