"""Forward kinematics of a BVH skeleton over all frames at once.

The work is laid out for numpy: joints are visited level by level (all
joints at one depth together, as a contiguous slice in breadth-first order)
and 3x3 rotations are stored entry-major, ``(3, 3, n_joints, n_frames)``, so
each step is a few dozen elementwise operations on long contiguous rows
instead of tens of thousands of tiny 3x3 matmuls.

Convention (see :mod:`retarget.motion`): ``R_world[j] = R_world[parent] @
R_local[j]``, ``p_world[j] = p_world[parent] + R_world[parent] @ t_local[j]``,
with ``t_local`` the OFFSET or the position channels in its place, and
``R_local`` the rotation channels composed in listed order (intrinsic).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from retarget.rotations import AXIS_INDEX, compose_entries

#: Elements per vector step when building local rotations (keeps temporaries small and in cache).
_STEP_ELEMENTS = 12_000


@dataclass(frozen=True)
class Pose:
    """FK results in file order.

    ``positions``: ``(n_frames, n_joints, 3)``; ``end_sites``: ``(n_frames,
    n_end_sites, 3)``; ``rotations``: ``(n_frames, n_joints, 3, 3)`` joint
    frame -> world, or None when not asked for.
    """

    positions: np.ndarray
    end_sites: np.ndarray
    rotations: np.ndarray | None


def forward_kinematics(
    parents: np.ndarray,
    offsets: np.ndarray,
    channel_names: Sequence[Sequence[str]],
    first_columns: Sequence[int],
    channels: np.ndarray,
    end_site_parents: Sequence[int] = (),
    end_site_offsets: Sequence[Sequence[float]] = (),
    *,
    rotations: bool = False,
) -> Pose:
    """Global positions (and rotations) of every joint and End Site for every frame.

    ``parents`` ``(J,)`` (parent before child, -1 for roots); ``offsets``
    ``(J, 3)``; per joint its canonical channel names and first column in
    ``channels`` ``(n_frames, n_channels)`` (degrees, file units).
    """
    parents = np.asarray(parents, dtype=np.intp)
    nj, n = len(parents), channels.shape[0]
    order, level_bounds = _breadth_first(parents)
    rank = np.empty(nj, dtype=np.intp)
    rank[order] = np.arange(nj)
    columns = np.ascontiguousarray(channels.T)  # (C, n)

    local = _local_rotations(order, channel_names, first_columns, columns)
    world = np.empty((3, 3, nj, n))
    pos = np.empty((3, nj, n))
    tmp = np.empty((nj, n))
    for a, b in level_bounds:
        joints = order[a:b]
        trans = _translations(joints, offsets, channel_names, first_columns, columns)  # (3, k, 1 or n)
        if parents[joints[0]] < 0:  # roots come first, alone in their level
            world[:, :, a:b] = local[:, :, a:b]
            pos[:, a:b] = trans
            continue
        pr = rank[parents[joints]]
        if np.all(pr == pr[0]):
            parent_rot, parent_pos = world[:, :, pr[0] : pr[0] + 1], pos[:, pr[0] : pr[0] + 1]
        else:
            parent_rot, parent_pos = world[:, :, pr], pos[:, pr]
        t = tmp[: b - a]
        for i in range(3):
            for c in range(3):
                dst = world[i, c, a:b]
                np.multiply(parent_rot[i, 0], local[0, c, a:b], out=dst)
                np.multiply(parent_rot[i, 1], local[1, c, a:b], out=t)
                dst += t
                np.multiply(parent_rot[i, 2], local[2, c, a:b], out=t)
                dst += t
            dst = pos[i, a:b]
            np.multiply(parent_rot[i, 0], trans[0], out=dst)
            np.multiply(parent_rot[i, 1], trans[1], out=t)
            dst += t
            np.multiply(parent_rot[i, 2], trans[2], out=t)
            dst += t
            dst += parent_pos[i]

    positions = np.ascontiguousarray(pos[:, rank].transpose(2, 1, 0))
    sites = np.empty((n, len(end_site_parents), 3))
    for k, (p, off) in enumerate(zip(end_site_parents, end_site_offsets, strict=True)):
        r = rank[p]
        for i in range(3):
            sites[:, k, i] = pos[i, r] + world[i, 0, r] * off[0] + world[i, 1, r] * off[1] + world[i, 2, r] * off[2]
    rot = world[:, :, rank].transpose(3, 2, 0, 1) if rotations else None
    return Pose(positions=positions, end_sites=sites, rotations=rot)


def _breadth_first(parents: np.ndarray) -> tuple[np.ndarray, list[tuple[int, int]]]:
    """Joint indices in breadth-first order (roots first) and the ``[a, b)`` slice of each depth in it."""
    depth = np.zeros(len(parents), dtype=np.intp)
    for j, p in enumerate(parents):
        depth[j] = depth[p] + 1 if p >= 0 else 0
    order = np.argsort(depth, kind="stable")
    counts = np.bincount(depth) if len(depth) else np.zeros(0, dtype=np.intp)
    stops = np.cumsum(counts)
    return order, [(int(s - c), int(s)) for s, c in zip(stops, counts, strict=True) if c]


def _local_rotations(
    order: np.ndarray, channel_names: Sequence[Sequence[str]], first_columns: Sequence[int], columns: np.ndarray
) -> np.ndarray:
    """``(3, 3, J, n)`` local rotations, joints in ``order``."""
    nj, n = len(order), columns.shape[1]
    out = np.empty((3, 3, nj, n))
    groups: dict[str, list[int]] = {}  # rotation order -> positions in `order`
    rot_cols: list[list[int]] = []
    for pos, j in enumerate(order):
        names = channel_names[j]
        cols = [first_columns[j] + i for i, name in enumerate(names) if name.endswith("rotation")]
        rot_cols.append(cols)
        groups.setdefault("".join(names[i - first_columns[j]][0] for i in cols), []).append(pos)
    step = max(1, _STEP_ELEMENTS // max(n, 1))
    for axes_text, members in groups.items():
        axes = [AXIS_INDEX[a] for a in axes_text]
        for s in range(0, len(members), step):
            part = members[s : s + step]
            contiguous = part[-1] - part[0] == len(part) - 1
            where = slice(part[0], part[-1] + 1) if contiguous else np.array(part)
            if not axes:
                out[:, :, where] = np.eye(3)[:, :, None, None]
                continue
            cols = np.array([rot_cols[p] for p in part])  # (k, m)
            angles = np.radians(columns[cols.T])  # (m, k, n)
            entries = compose_entries(axes, np.cos(angles), np.sin(angles))
            for i in range(3):
                for c in range(3):
                    e = entries[i][c]
                    out[i, c, where] = 0.0 if e is None else e
    return out


def _translations(
    joints: np.ndarray,
    offsets: np.ndarray,
    channel_names: Sequence[Sequence[str]],
    first_columns: Sequence[int],
    columns: np.ndarray,
) -> np.ndarray:
    """``(3, k, 1)`` OFFSETs of ``joints``, or ``(3, k, n)`` when some have position channels."""
    off = np.asarray(offsets, dtype=np.float64)[joints].T[:, :, None]  # (3, k, 1)
    moving = [
        (slot, first_columns[j] + i, name)
        for slot, j in enumerate(joints)
        for i, name in enumerate(channel_names[j])
        if name.endswith("position")
    ]
    if not moving:
        return off
    out = np.repeat(off, columns.shape[1], axis=2)
    for slot, col, name in moving:
        out[AXIS_INDEX[name[0]], slot] = columns[col]
    return out
