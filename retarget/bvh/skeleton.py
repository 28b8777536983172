"""Find the shoulder -> elbow -> wrist chain of an arm in a BVH skeleton: the entry points.

:func:`find_arm` (raises when there is no single chain), :func:`search_arm` (says why instead) and
:func:`arm_candidates` combine the ways a chain is found, in this order:

1. explicitly, by three joint names the caller gives;
2. by joint names alone (:mod:`~retarget.bvh.names`: the naming conventions, sides and roles); detection by
   names wins whenever it finds a chain;
3. by skeleton structure (:mod:`~retarget.bvh.structure`), but only for a plausible limb, measured against the
   skeleton's height from its bone lengths (:mod:`~retarget.bvh.proportions`).

What they return is in :mod:`~retarget.bvh.chains`: :class:`~retarget.bvh.chains.ArmJoints`, and for a search
:class:`~retarget.bvh.chains.ArmSearch` with the candidates not chosen as :class:`~retarget.bvh.chains.Rejected`.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from os import PathLike

import numpy as np

import retarget.bvh.tree as tree
from retarget.bvh.chains import ArmJoints, ArmSearch
from retarget.bvh.names import END_SITE_SUFFIX, check_side, name_chains, name_hint, search_by_names
from retarget.bvh.proportions import height_from_bones
from retarget.bvh.structure import search_by_structure
from retarget.errors import BvhError

log = logging.getLogger(__name__)


def find_arm(
    side: str,
    *,
    joint_names: Sequence[str],
    parents: np.ndarray,
    offsets: np.ndarray,
    end_site_parents: Sequence[int] = (),
    end_site_offsets: Sequence[Sequence[float]] = (),
    names: Sequence[str] | None = None,
    path: str | PathLike[str] | None = None,
    height: float | None = None,
) -> ArmJoints:
    """The arm chain of ``side`` (``"left"``/``"right"``): by ``names`` if given, else by name, else by structure.

    ``offsets`` ``(n_joints, 3)`` and ``end_site_offsets`` in file units; ``height``: the skeleton's height in
    file units for the plausibility checks (default: :func:`~retarget.bvh.proportions.height_from_bones` of
    the OFFSETs).
    Raises ``ValueError`` for a bad side, :class:`BvhError` (with ``path``)
    when an explicit name does not exist, when no chain is found (the message
    lists the candidates and why each was rejected), or when several chains
    tie (the message lists them).
    """
    search = search_arm(
        side,
        joint_names=joint_names,
        parents=parents,
        offsets=offsets,
        end_site_parents=end_site_parents,
        end_site_offsets=end_site_offsets,
        names=names,
        path=path,
        height=height,
    )
    if search.found is None:
        raise BvhError(search.error, path=path)
    if search.found.method == "structure":
        log.info("%s arm found by structure: %s", side, " > ".join(search.found.names))
    return search.found


def search_arm(
    side: str,
    *,
    joint_names: Sequence[str],
    parents: np.ndarray,
    offsets: np.ndarray,
    end_site_parents: Sequence[int] = (),
    end_site_offsets: Sequence[Sequence[float]] = (),
    names: Sequence[str] | None = None,
    path: str | PathLike[str] | None = None,
    height: float | None = None,
) -> ArmSearch:
    """Like :func:`find_arm`, but a missing or tied chain is an :class:`ArmSearch` with ``found`` None.

    Bad explicit ``names`` still raise (``ValueError``, :class:`BvhError`).
    """
    check_side(side)
    parents = np.asarray(parents, dtype=np.intp)
    offsets = np.asarray(offsets, dtype=np.float64).reshape(len(joint_names), 3)
    if names is not None:
        chain = _explicit(side, names, joint_names, parents, end_site_parents, path)
        return ArmSearch(side, chain, (), chain.detail)
    by_names = search_by_names(side, joint_names, parents, end_site_parents)
    if by_names is not None:
        return by_names
    if height is None:
        lengths = np.linalg.norm(offsets, axis=1)
        site_lengths = [float(np.linalg.norm(np.asarray(o, dtype=np.float64))) for o in end_site_offsets]
        height = height_from_bones(parents, lengths, end_site_parents, site_lengths)
    hint = name_hint(side, joint_names)
    return search_by_structure(side, joint_names, parents, offsets, end_site_parents, end_site_offsets, height, hint)


def arm_candidates(
    side: str, *, joint_names: Sequence[str], parents: np.ndarray, end_site_parents: Sequence[int] = ()
) -> list[tuple[tuple[int, int], ArmJoints]]:
    """Name-based chains of ``side``, best first, each with its rank ``(penalty, links)``."""
    check_side(side)
    return name_chains(side, joint_names, np.asarray(parents, dtype=np.intp), end_site_parents)[0]


def _explicit(
    side: str,
    names: Sequence[str],
    joint_names: Sequence[str],
    parents: np.ndarray,
    end_site_parents: Sequence[int],
    path: str | PathLike[str] | None,
) -> ArmJoints:
    """The chain ``names`` gives (shoulder, elbow, wrist; the wrist may be ``"<joint>/End Site"``), checked to exist
    and to run down the hierarchy."""
    if len(names) != 3:
        raise ValueError(f"Expected 3 joint names (shoulder, elbow, wrist), got {len(names)}")
    index = {n: i for i, n in enumerate(joint_names)}
    roles = ("shoulder", "elbow", "wrist")
    found: list[int] = []
    wrist_is_site = False
    for role, name in zip(roles, names, strict=True):
        if role == "wrist" and name.endswith(END_SITE_SUFFIX) and name[: -len(END_SITE_SUFFIX)] in index:
            owner = index[name[: -len(END_SITE_SUFFIX)]]
            sites = [k for k, p in enumerate(end_site_parents) if p == owner]
            if not sites:
                raise BvhError(f"Expected an End Site below joint {owner!r} for the {side} wrist, got none", path=path)
            found.append(sites[0])
            wrist_is_site = True
            continue
        if name not in index:
            raise BvhError(f"Expected a joint named {name!r} for the {side} {role}, got no such joint", path=path)
        found.append(index[name])
    elbow_ok = tree.depth_below(parents, found[1], found[0], len(joint_names))
    wrist_joint = end_site_parents[found[2]] if wrist_is_site else found[2]
    wrist_ok = (
        wrist_is_site and wrist_joint == found[1] or tree.depth_below(parents, wrist_joint, found[1], len(parents))
    )
    if not elbow_ok or not wrist_ok:
        raise BvhError(
            f"Expected {names[0]!r} > {names[1]!r} > {names[2]!r} to run down the hierarchy, got joints on other "
            "branches",
            path=path,
        )
    return ArmJoints(
        side,
        (names[0], names[1], names[2]),
        (found[0], found[1], found[2]),
        wrist_is_site,
        "explicit",
        detail="named explicitly",
    )
