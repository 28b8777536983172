"""Forward kinematics of a BVH skeleton over all frames at once.

The work is laid out for numpy: joints are visited level by level (all
joints at one depth together) and 3x3 rotations are stored entry-major,
``(3, 3, k, n_frames)``, so each level is one elementwise composition of its
local rotations and one ``einsum`` with its parents' rotations, on long
contiguous rows, instead of tens of thousands of tiny 3x3 matmuls.  Only the
previous level's world rotations are kept, all of them only when asked for.

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


@dataclass(frozen=True)
class Pose:
    """FK results in file order.

    ``positions``: ``(n_frames, n_joints, 3)``; ``end_sites``: ``(n_frames,
    n_end_sites, 3)``; ``rotations``: ``(n_frames, n_joints, 3, 3)`` joint
    frame -> world; each None when not asked for.
    """

    positions: np.ndarray
    end_sites: np.ndarray | None
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
    end_sites: bool = True,
) -> Pose:
    """Global positions (and rotations) of every joint and End Site for every frame.

    ``parents`` ``(J,)`` (parent before child, -1 for roots); ``offsets``
    ``(J, 3)``; per joint its canonical channel names and first column in
    ``channels`` ``(n_frames, n_channels)`` (degrees, file units).

    World rotations are computed only for joints that need one: those with
    child joints, with End Sites (when ``end_sites``), or all (when
    ``rotations``).  Without ``end_sites``, ``Pose.end_sites`` is None.
    """
    parents = np.asarray(parents, dtype=np.intp)
    nj, n = len(parents), channels.shape[0]
    order, level_bounds = _breadth_first(parents)
    columns = channels.T  # (C, n) view
    positions = np.empty((n, nj, 3))
    all_rot = np.empty((n, nj, 3, 3)) if rotations else None
    site_parents = np.asarray(end_site_parents, dtype=np.intp) if end_sites else np.zeros(0, dtype=np.intp)
    site_offsets = np.asarray(end_site_offsets, dtype=np.float64).reshape(-1, 3)
    sites = np.empty((n, site_parents.size, 3)) if end_sites else None
    needs_rotation = np.ones(nj, dtype=bool) if rotations else np.zeros(nj, dtype=bool)
    needs_rotation[parents[parents >= 0]] = True
    needs_rotation[site_parents] = True
    slot = np.zeros(nj, dtype=np.intp)  # a joint's row in its level's rotation rows
    prev_rot = prev_pos = np.zeros(0)
    for a, b in level_bounds:
        joints = order[a:b]
        turning = joints[needs_rotation[joints]]
        slot[turning] = np.arange(turning.size)
        trans = _translations(joints, offsets, channel_names, first_columns, columns)  # (3, k, 1 or n)
        local = _local_rotations(turning, channel_names, first_columns, columns)  # (3, 3, k', n)
        if parents[joints[0]] < 0:  # the roots, alone in the first level
            pos = np.broadcast_to(trans, (3, b - a, n))
            world = local
        else:
            rows = slot[parents[joints]]
            single = bool(np.all(rows == rows[0]))
            pick = slice(int(rows[0]), int(rows[0]) + 1) if single else rows
            # p = p_parent + R_parent @ t;  R = R_parent @ R_local  (3x3 over the leading axes, rows broadcast)
            pos = np.einsum("ij...,j...->i...", prev_rot[:, :, pick], trans) + prev_pos[:, pick]
            if turning.size < joints.size and not single:
                pick = slot[parents[turning]]
            world = np.einsum("ij...,jl...->il...", prev_rot[:, :, pick], local)
        for i in range(3):
            positions[:, joints, i] = pos[i].T
            if all_rot is not None:
                for c in range(3):
                    all_rot[:, joints, i, c] = world[i, c].T
        if sites is not None:
            for e in np.flatnonzero(np.isin(site_parents, joints)):
                r, row = slot[site_parents[e]], int(np.flatnonzero(joints == site_parents[e])[0])
                sites[:, e, :] = (pos[:, row] + np.einsum("ijn,j->in", world[:, :, r], site_offsets[e])).T
        prev_rot, prev_pos = world, pos[:, needs_rotation[joints]]
    return Pose(positions=positions, end_sites=sites, rotations=all_rot)


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
    joints: np.ndarray, channel_names: Sequence[Sequence[str]], first_columns: Sequence[int], columns: np.ndarray
) -> np.ndarray:
    """``(3, 3, k, n)`` local rotations of ``joints``."""
    k, n = len(joints), columns.shape[1]
    out = np.empty((3, 3, k, n))
    orders: dict[str, list[int]] = {}
    cols: list[list[int]] = []
    for r, j in enumerate(joints):
        names = channel_names[j]
        picked = [i for i, name in enumerate(names) if name.endswith("rotation")]
        orders.setdefault("".join(names[i][0] for i in picked), []).append(r)
        cols.append([first_columns[j] + i for i in picked])
    for axes_text, rows in orders.items():
        where = slice(None) if len(rows) == k else np.array(rows)
        if not axes_text:
            out[:, :, where] = np.eye(3)[:, :, None, None]
            continue
        angles = np.radians(columns[np.array([cols[r] for r in rows]).T])  # (m, k, n)
        entries = compose_entries([AXIS_INDEX[a] for a in axes_text], np.cos(angles), np.sin(angles))
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
