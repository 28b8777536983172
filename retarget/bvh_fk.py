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

    Only one depth level of world rotations is kept at a time (as nine
    ``(k, n_frames)`` rows), unless ``rotations`` asks for all of them; and
    only for joints that need one: those with child joints, with End Sites
    (when ``end_sites``), or all (when ``rotations``).  Without
    ``end_sites``, ``Pose.end_sites`` is None.
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
    prev_rot: list[list[np.ndarray]] = []
    prev_pos: list[np.ndarray] = []
    for a, b in level_bounds:
        joints = order[a:b]
        k = b - a
        turning = joints[needs_rotation[joints]]
        slot[turning] = np.arange(turning.size)
        trans = _translations(joints, offsets, channel_names, first_columns, columns)  # (3, k, 1 or n)
        local = _local_rotations(turning, channel_names, first_columns, columns) if turning.size else None
        if parents[joints[0]] < 0:  # the roots, alone in the first level
            pos = [np.broadcast_to(trans[i], (k, n)).copy() for i in range(3)]
            world = [[_rows(local[i][c], turning.size, n) for c in range(3)] for i in range(3)] if local else []
        else:
            prot, ppos = _parent_rows(prev_rot, prev_pos, slot[parents[joints]])
            pos = [_rows(_dot3(prot[i], [trans[0], trans[1], trans[2]]) + ppos[i], k, n) for i in range(3)]
            world = []
            if local:
                if turning.size < k:
                    prot, _ = _parent_rows(prev_rot, prev_pos, slot[parents[turning]])
                world = [
                    [_rows(_dot3(prot[i], [local[0][c], local[1][c], local[2][c]]), turning.size, n) for c in range(3)]
                    for i in range(3)
                ]
        for i in range(3):
            positions[:, joints, i] = pos[i].T
            if all_rot is not None:
                for c in range(3):
                    all_rot[:, joints, i, c] = world[i][c].T
        if sites is not None:
            for e in np.flatnonzero(np.isin(site_parents, joints)):
                r, p, off = slot[site_parents[e]], pos, site_offsets[e]
                row = int(np.flatnonzero(joints == site_parents[e])[0])
                for i in range(3):
                    sites[:, e, i] = (
                        p[i][row] + world[i][0][r] * off[0] + world[i][1][r] * off[1] + world[i][2][r] * off[2]
                    )
        prev_rot, prev_pos = world, [pos[i][needs_rotation[joints]] for i in range(3)]
    return Pose(positions=positions, end_sites=sites, rotations=all_rot)


def _parent_rows(prev_rot: list, prev_pos: list, rows: np.ndarray) -> tuple[list, list]:
    """The parents' rotation and position rows (a broadcastable single row when all share one parent)."""
    pick = slice(int(rows[0]), int(rows[0]) + 1) if np.all(rows == rows[0]) else rows
    return [[prev_rot[i][c][pick] for c in range(3)] for i in range(3)], [prev_pos[i][pick] for i in range(3)]


def _dot3(row: list, col: list) -> np.ndarray:
    """``row[0]*col[0] + row[1]*col[1] + row[2]*col[2]`` with ``None`` as 0 and ``1.0`` as 1 folded away."""
    total = None
    for x, y in zip(row, col, strict=True):
        if x is None or y is None:
            continue
        term = y if isinstance(x, float) and x == 1.0 else x if isinstance(y, float) and y == 1.0 else x * y
        total = term if total is None else total + term
    return total  # type: ignore[return-value]


def _rows(entry, k: int, n: int) -> np.ndarray:
    """An entry (None, 1.0, or an array broadcastable to ``(k, n)``) as a ``(k, n)`` array."""
    if entry is None:
        return np.zeros((k, n))
    if isinstance(entry, float):
        return np.full((k, n), entry)
    if entry.shape != (k, n):
        return np.broadcast_to(entry, (k, n)).copy()
    return entry


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
) -> list[list]:
    """Local rotations of ``joints`` as a 3x3 nested list of ``(k, n)`` rows (or ``None``/``1.0`` when constant)."""
    k, n = len(joints), columns.shape[1]
    orders = []
    cols = []
    for j in joints:
        names = channel_names[j]
        picked = [i for i, name in enumerate(names) if name.endswith("rotation")]
        orders.append("".join(names[i][0] for i in picked))
        cols.append([first_columns[j] + i for i in picked])
    if len(set(orders)) == 1:
        return _compose(orders[0], np.array(cols).reshape(k, -1), columns)
    out = [[np.empty((k, n)) for _ in range(3)] for _ in range(3)]
    for axes_text in set(orders):
        rows = [r for r, o in enumerate(orders) if o == axes_text]
        part = _compose(axes_text, np.array([cols[r] for r in rows]).reshape(len(rows), -1), columns)
        for i in range(3):
            for c in range(3):
                e = part[i][c]
                out[i][c][rows] = 0.0 if e is None else e
    return out


def _compose(axes_text: str, cols: np.ndarray, columns: np.ndarray) -> list[list]:
    """Entries of the rotations of channel columns ``cols`` ``(k, m)`` in order ``axes_text``."""
    if not axes_text:
        return [[1.0 if i == c else None for c in range(3)] for i in range(3)]
    angles = np.radians(columns[cols.T])  # (m, k, n)
    return compose_entries([AXIS_INDEX[a] for a in axes_text], np.cos(angles), np.sin(angles))


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
