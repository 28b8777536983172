"""Forward kinematics of a BVH skeleton over all frames at once.

The work is laid out for numpy, with frames on the last (contiguous) axis:

* every 3x3 rotation is stored entry-major, ``(3, 3, k, frames)``, and
  positions coordinate-major, ``(3, n_joints, frames)``, so each numpy call
  works on long contiguous rows;
* frames go in blocks of ``BLOCK_ELEMENTS // n_rotating_joints`` (~170 for a
  31-joint body): a block's buffers are allocated once per call and its
  temporaries (~32 KB each) are recycled by the allocator, where
  whole-clip temporaries (megabytes each) would be page-faulted in afresh on
  every call, which costs more than the arithmetic;
* per block, the local rotations of all joints are built in one go: one
  :func:`~retarget.bvh.rotations.cos_sin_degrees` per group of joints sharing a
  rotation order (usually one group), then the Euler product entry by entry
  (:func:`~retarget.bvh.rotations.compose_entries`);
* joints are then visited level by level (all joints at one depth together):
  per level one ``einsum`` for positions and one for world rotations.

Only joints that need a world rotation get one: those with child joints, with
End Sites (when ``end_sites``), or all (when ``rotations``).  Rows are in
breadth-first order with, inside each level, the rotating joints first, so a
level's rows are one slice of each buffer; positions go back to file order
once per block.

Convention (see :mod:`retarget.bvh.motion`): ``R_world[j] = R_world[parent] @
R_local[j]``, ``p_world[j] = p_world[parent] + R_world[parent] @ t_local[j]``,
with ``t_local`` the OFFSET or the position channels in its place, and
``R_local`` the rotation channels composed in listed order (intrinsic).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TypeAlias

import numpy as np

from retarget.bvh.rotations import AXIS_INDEX, compose_entries, cos_sin_degrees


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


#: A group of joints sharing a rotation order: its axes (0-2), its rows among the rotating joints (a slice when
#: all of them) and its angle columns ``(m, k')`` in ``channels`` (one row per rotation channel).
_Group: TypeAlias = tuple[list[int], slice | np.ndarray, np.ndarray]

#: Rotating joints times frames per block (see the module notes).
BLOCK_ELEMENTS = 1 << 12


@dataclass(frozen=True)
class _Level:
    """The joints at one depth of the skeleton, rotating ones first, and where their inputs are."""

    joints: slice  #: their position rows
    rows: slice  #: rotation rows of the first ``n_turning`` of them
    n_turning: int
    parent_rows: slice | np.ndarray | None  #: parents' rotation rows (a 1-row slice broadcasts); None for roots
    parent_joints: slice | np.ndarray | None  #: parents' position rows, likewise
    offsets: np.ndarray  #: (3, k, 1) OFFSETs
    moving: tuple[tuple[int, int, int], ...]  #: position channels: (axis, slot in joints, column in channels)


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
    offsets = np.asarray(offsets, dtype=np.float64).reshape(-1, 3)
    nj, n = len(parents), channels.shape[0]
    site_parents = np.asarray(end_site_parents, dtype=np.intp) if end_sites else np.zeros(0, dtype=np.intp)
    site_offsets = np.asarray(end_site_offsets, dtype=np.float64).reshape(-1, 3)[: site_parents.size]
    needs_rotation = np.full(nj, rotations, dtype=bool)
    needs_rotation[parents[parents >= 0]] = True
    needs_rotation[site_parents] = True
    levels, order = _plan(parents, offsets, channel_names, first_columns, needs_rotation)
    turning = order[needs_rotation[order]]  # joint of each rotation row
    slot = np.empty(nj, dtype=np.intp)  # a joint's position row
    slot[order] = np.arange(nj)
    row = np.full(nj, -1, dtype=np.intp)  # a joint's rotation row
    row[turning] = np.arange(turning.size)
    groups = _rotation_groups(turning, channel_names, first_columns)
    in_file_order = slice(None) if (order == np.arange(nj)).all() else slot

    positions = np.empty((n, nj, 3))
    sites = np.empty((n, site_parents.size, 3)) if end_sites else None
    all_rot = np.empty((n, nj, 3, 3)) if rotations else None
    step = max(16, BLOCK_ELEMENTS // max(turning.size, 1))
    local = np.empty((3, 3, turning.size, min(step, n)))  # block buffers, reused: rows x frames of the block
    world = np.empty_like(local)
    pos = np.empty((3, nj, min(step, n)))
    for f0 in range(0, n, step):
        f1 = min(f0 + step, n)
        columns = channels[f0:f1].T  # (C, b) view
        b = f1 - f0
        _local_rotations(groups, columns, out=local[..., :b])
        _block(levels, local[..., :b], columns, world[..., :b], pos[..., :b])
        positions[f0:f1] = pos[:, in_file_order, :b].transpose(2, 1, 0)
        if sites is not None and site_parents.size:
            # p_site = p_parent + R_parent @ offset
            at = np.einsum("ij...,j...->i...", world[:, :, row[site_parents], :b], site_offsets.T[:, :, None])
            at += pos[:, slot[site_parents], :b]
            sites[f0:f1] = at.transpose(2, 1, 0)
        if all_rot is not None:  # every joint turns
            all_rot[f0:f1] = world[:, :, row, :b].transpose(3, 2, 0, 1)
    return Pose(positions=positions, end_sites=sites, rotations=all_rot)


def _block(levels: list[_Level], local: np.ndarray, columns: np.ndarray, world: np.ndarray, pos: np.ndarray) -> None:
    """World rotations ``(3, 3, K, b)`` and positions ``(3, J, b)`` of one block of frames, level by level, from
    the local rotations ``(3, 3, K, b)`` and the block's ``columns`` ``(C, b)``."""
    for level in levels:
        trans = level.offsets  # (3, k, 1), or (3, k, b) with position channels
        if level.moving:
            trans = np.repeat(trans, columns.shape[1], axis=2)
            for axis, slot, col in level.moving:
                trans[axis, slot] = columns[col]
        rows = level.rows
        if level.parent_rows is None:  # the roots
            pos[:, level.joints] = trans
            world[:, :, rows] = local[:, :, rows]
            continue
        parent_rot = world[:, :, level.parent_rows]  # (3, 3, k or 1, b)
        # p = p_parent + R_parent @ t;  R = R_parent @ R_local  (3x3 over the leading axes, rows broadcast)
        at = pos[:, level.joints]
        np.einsum("ij...,j...->i...", parent_rot, trans, out=at)
        at += pos[:, level.parent_joints]
        if level.n_turning:
            np.einsum(
                "ij...,jl...->il...", parent_rot[:, :, : level.n_turning], local[:, :, rows], out=world[:, :, rows]
            )


def _plan(
    parents: np.ndarray,
    offsets: np.ndarray,
    channel_names: Sequence[Sequence[str]],
    first_columns: Sequence[int],
    needs_rotation: np.ndarray,
) -> tuple[list[_Level], np.ndarray]:
    """The levels and the row order: breadth-first, roots first, in each level the rotating joints first, then
    file order.  Positions use this order for all joints, rotations for the rotating ones (a prefix per level).
    Returns the levels and ``order`` (joint index of each position row)."""
    parent_list = parents.tolist()
    turns = needs_rotation.tolist()
    depth: list[int] = []
    for p in parent_list:
        depth.append(depth[p] + 1 if p >= 0 else 0)
    by_level: list[list[int]] = [[] for _ in range(max(depth, default=-1) + 1)]
    for j in sorted(range(len(parent_list)), key=lambda j: (depth[j], not turns[j], j)):
        by_level[depth[j]].append(j)
    slot: dict[int, int] = {}  # joint -> position row
    row: dict[int, int] = {}  # joint -> rotation row
    for j in (j for level in by_level for j in level):
        slot[j] = len(slot)
        if turns[j]:
            row[j] = len(row)
    levels = []
    for joints in by_level:
        up = [parent_list[j] for j in joints]
        first = slot[joints[0]]
        n_turning = sum(turns[j] for j in joints)
        levels.append(
            _Level(
                joints=slice(first, first + len(joints)),
                rows=slice(row.get(joints[0], 0), row.get(joints[0], 0) + n_turning),
                n_turning=n_turning,
                parent_rows=None if up[0] < 0 else _index([row[p] for p in up]),
                parent_joints=None if up[0] < 0 else _index([slot[p] for p in up]),
                offsets=offsets[joints].T[:, :, None],
                moving=tuple(
                    (AXIS_INDEX[name[0]], k, first_columns[j] + i)
                    for k, j in enumerate(joints)
                    for i, name in enumerate(channel_names[j])
                    if name.endswith("position")
                ),
            )
        )
    return levels, np.array([j for level in by_level for j in level], dtype=np.intp)


def _index(rows: list[int]) -> slice | np.ndarray:
    """``rows`` as an index on one axis: a 1-row slice when all are the same row (it broadcasts), a slice when
    they are consecutive (a view), else an array (a copy)."""
    first = rows[0]
    if all(r == first for r in rows):
        return slice(first, first + 1)
    if rows == list(range(first, first + len(rows))):
        return slice(first, first + len(rows))
    return np.array(rows, dtype=np.intp)


def _rotation_groups(
    joints: np.ndarray, channel_names: Sequence[Sequence[str]], first_columns: Sequence[int]
) -> list[_Group]:
    """``joints`` grouped by rotation order: per group its axes, its rows in ``joints`` and its angle columns
    ``(m, k')`` (one row per rotation channel)."""
    groups: dict[str, tuple[list[int], list[list[int]]]] = {}
    for r, j in enumerate(joints):
        names = channel_names[j]
        picked = [i for i, name in enumerate(names) if name.endswith("rotation")]
        rows, cols = groups.setdefault("".join(names[i][0] for i in picked), ([], []))
        rows.append(r)
        cols.append([first_columns[j] + i for i in picked])
    return [
        (
            [AXIS_INDEX[a] for a in axes],
            slice(None) if len(rows) == len(joints) else np.array(rows),
            np.array(cols, dtype=np.intp).reshape(len(rows), len(axes)).T,
        )
        for axes, (rows, cols) in groups.items()
    ]


def _local_rotations(groups: list[_Group], columns: np.ndarray, *, out: np.ndarray) -> None:
    """Write into ``out`` ``(3, 3, k, b)`` the local rotations of the grouped joints from ``columns`` ``(C, b)``:
    one trigonometry pass and one Euler product per rotation order."""
    for axes, where, cols in groups:
        if not axes:
            out[:, :, where] = np.eye(3)[:, :, None, None]
            continue
        cos, sin = cos_sin_degrees(columns[cols])  # (m, k', b) each
        entries = compose_entries(axes, cos, sin)
        for i in range(3):
            for c in range(3):
                e = entries[i][c]
                out[i, c, where] = 0.0 if e is None else e
