"""The structure fallback: the arm chain of a skeleton whose joint names name none, and why other limbs are not arms.

When no chain is named, the structure decides, but only for a plausible limb.  Every child of a joint with two
or more children starts a candidate limb; along its main chain (into the child with the longest reach, twist and
roll bones and zero-length bones skipped) the upper arm is the longest bone and the forearm the bone after it
(the bone before it when that one is over 1.25 times longer: then the longest bone was the forearm).  A
candidate is rejected, with the reason kept, when

- its joints' names say another side, or a leg, finger or head/face bone (``UpLeg``, ``Index1``, ``Tongue``);
- its upper arm or forearm is outside :data:`~retarget.bvh.proportions.ARM_BONE_RANGE` of the skeleton's height
  (see :func:`~retarget.bvh.proportions.height_from_bones`), or one is more than 2.5 times the other;
- it is not on the requested side: by its names, and by the rest pose (the mean x of its shoulder, elbow and
  wrist is off the joint it branches from by more than a quarter of its upper arm and forearm: a T, A or even
  I pose, not a leg under the hip; BVH faces +Z with Y up, so +X is the character's left); names and rest pose
  must agree when both tell;
- nothing mirrors it on the other side (a limb within a factor 1.5 of its bone lengths), unless its names say
  arm (``Arm_L_01``): a lone hand's fingers are not a pair of arms;
- it branches off the spine below another plausible limb of its side (legs branch off the hips, below the
  chest; the arms themselves may branch off different spine joints).

Among the candidates left, those with arm-like names (``Arm_L_01 > Arm_L_02 > Arm_L_03``) come first, then the
one branching off deepest in the hierarchy; a tie is an error.  With none left, the error lists the candidates
and why each was rejected.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

import retarget.bvh.tree as tree
from retarget.bvh.chains import ArmJoints, ArmSearch, Rejected
from retarget.bvh.names import END_SITE_SUFFIX, SIDES, is_twist, name_side, not_arm_kind, role_of, squash
from retarget.bvh.proportions import ARM_BONE_RANGE, ARM_RATIO_RANGE, percent


@dataclass(eq=False)
class _Limb:
    """One structure candidate: the limb from ``first`` (a child of ``branch``) and its shoulder, elbow, wrist."""

    branch: int
    names: tuple[str, str, str]
    indices: tuple[int, int, int]
    wrist_is_site: bool
    upper: float
    fore: float
    points: np.ndarray  # (3, 3) rest positions of shoulder, elbow, wrist
    joints: list[int]  # the limb's joints from its first down to the wrist (or the wrist's owner)
    names_side: str | None = None
    rest_side: str | None = None
    side: str | None = None
    arm_named: bool = False
    reasons: list[str] = field(default_factory=list)  # names and proportions: not an arm at all
    side_reason: str = ""  # why it is not this side's arm


def search_by_structure(
    side: str,
    joint_names: Sequence[str],
    parents: np.ndarray,
    offsets: np.ndarray,
    end_site_parents: Sequence[int],
    end_site_offsets: Sequence[Sequence[float]],
    height: float,
    hint: str,
) -> ArmSearch:
    """The ``side`` arm by skeleton structure, or why none: ``found`` None with ``error`` listing the candidates.

    ``offsets`` and ``end_site_offsets`` and ``height`` (the skeleton's, for the bone-length checks) in file
    units; ``hint`` says what the names told, for ``detail`` and the error.
    """
    rest = tree.rest_positions(parents, offsets)
    limbs = _candidates(joint_names, parents, rest, end_site_parents, end_site_offsets)
    for limb in limbs:
        _judge(limb, joint_names, rest, height)
    plausible = [m for m in limbs if not m.reasons and m.side in SIDES]
    _rule_out_unmirrored(plausible)
    paired = [m for m in plausible if not m.side_reason]
    _rule_out_lower(paired, joint_names, parents)
    chosen = _choose(side, paired, joint_names, parents)
    return _outcome(side, limbs, paired, chosen, joint_names, hint)


def _candidates(
    joint_names: Sequence[str],
    parents: np.ndarray,
    rest: np.ndarray,
    end_site_parents: Sequence[int],
    end_site_offsets: Sequence[Sequence[float]],
) -> list[_Limb]:
    """A limb from every child of a joint with two or more children; a chain reached from several branches counts
    once, from the branch nearest to it."""
    children = tree.children(parents)
    reach = tree.reach(children, rest)
    sites: dict[int, np.ndarray] = {}  # the first End Site of a joint: its index and position
    site_index: dict[int, int] = {}
    for k, p in enumerate(end_site_parents):
        if int(p) not in site_index:
            site_index[int(p)] = k
            sites[int(p)] = rest[int(p)] + np.asarray(end_site_offsets[k], dtype=np.float64)
    by_chain: dict[tuple[int, int, int, bool], _Limb] = {}
    for b in range(len(joint_names)):
        if len(children[b]) < 2:
            continue
        for c in children[b]:
            limb = _limb(b, c, joint_names, children, rest, reach, site_index, sites)
            key = (*limb.indices, limb.wrist_is_site) if limb else None
            if (
                limb
                and key
                and (key not in by_chain or tree.depth(parents, b) > tree.depth(parents, by_chain[key].branch))
            ):
                by_chain[key] = limb  # the same chain from further down: keep the branch nearest to it
    return list(by_chain.values())


def _limb(
    branch: int,
    first: int,
    joint_names: Sequence[str],
    children: list[list[int]],
    rest: np.ndarray,
    reach: np.ndarray,
    site_index: dict[int, int],
    sites: dict[int, np.ndarray],
) -> _Limb | None:
    """The candidate chain of the limb from ``first``, or None when it has fewer than two bones."""
    main = [first]  # always into the child with the longest reach
    while children[main[-1]]:
        j = main[-1]
        main.append(max(children[j], key=lambda c: float(np.linalg.norm(rest[c] - rest[j])) + reach[c]))
    # points: (joint index, or End Site index, is End Site, position); the branch joint first
    points: list[tuple[int, bool, np.ndarray]] = [(branch, False, rest[branch])]
    points += [(j, False, rest[j]) for j in main if not is_twist(joint_names[j])]
    if main[-1] in site_index:
        points.append((site_index[main[-1]], True, sites[main[-1]]))
    kept = [points[0]]
    for p in points[1:]:
        if np.linalg.norm(p[2] - kept[-1][2]) > 0:  # a zero-length bone: keep the joint above it
            kept.append(p)
    if len(kept) < 4:
        return None
    bones = [float(np.linalg.norm(kept[i + 1][2] - kept[i][2])) for i in range(len(kept) - 1)]
    k = max(range(1, len(bones)), key=lambda i: bones[i])  # bone i: kept[i] to kept[i + 1]; not from the branch
    # the longest bone is the upper arm, unless the bone before it is much longer than the one after it
    after_is_fore = k + 1 < len(bones) and not (k >= 2 and bones[k - 1] > 1.25 * bones[k + 1])
    i = k if after_is_fore else max(k - 1, 1)
    s, e, w = kept[i], kept[i + 1], kept[i + 2]
    owner = main[-1] if w[1] else w[0]
    return _Limb(
        branch=branch,
        names=(
            joint_names[s[0]],
            joint_names[e[0]],
            joint_names[owner] + END_SITE_SUFFIX if w[1] else joint_names[w[0]],
        ),
        indices=(s[0], e[0], w[0]),
        wrist_is_site=w[1],
        upper=bones[i],
        fore=bones[i + 1],
        points=np.array([s[2], e[2], w[2]]),
        joints=main[: main.index(owner) + 1],
    )


def _judge(limb: _Limb, joint_names: Sequence[str], rest: np.ndarray, height: float) -> None:
    """Fill in the limb's side (by names and rest pose) and the reasons that rule it out as an arm."""
    votes = {"left": 0, "right": 0}
    kinds: list[str] = []
    for j in limb.joints:
        s, rest_name = name_side(joint_names[j])
        if s:
            votes[s] += 1
        kind = not_arm_kind(joint_names[j])
        if kind and kind not in kinds:
            kinds.append(kind)
        if role_of(rest_name)[0] is not None or "arm" in squash(rest_name):
            limb.arm_named = True
    if votes["left"] != votes["right"]:
        limb.names_side = max(votes, key=votes.__getitem__)
    limb.reasons += [f"its names say {kind}" for kind in kinds]
    limb.arm_named = limb.arm_named and not kinds
    lo, hi = ARM_BONE_RANGE
    if not all(lo * height <= b <= hi * height for b in (limb.upper, limb.fore)):
        limb.reasons.append(
            f"bones {limb.upper:.3g} and {limb.fore:.3g} units, {percent(limb.upper, height)} and "
            f"{percent(limb.fore, height)} of the skeleton's height ({height:.4g} units); an arm's are "
            f"{lo * 100:.0f}-{hi * 100:.0f} %"
        )
    elif not ARM_RATIO_RANGE[0] <= limb.upper / limb.fore <= ARM_RATIO_RANGE[1]:
        limb.reasons.append(f"upper arm {limb.upper:.3g} and forearm {limb.fore:.3g} units are too unequal")
    dx = float(limb.points[:, 0].mean() - rest[limb.branch][0])  # BVH: Y up, facing +Z, so +X is the left
    if dx > 0.25 * (limb.upper + limb.fore):
        limb.rest_side = "left"
    elif dx < -0.25 * (limb.upper + limb.fore):
        limb.rest_side = "right"
    if limb.names_side and limb.rest_side and limb.names_side != limb.rest_side:
        limb.side_reason = f"its names say {limb.names_side} but the rest pose puts it on the {limb.rest_side}"
        return
    limb.side = limb.names_side or limb.rest_side


def _rule_out_unmirrored(plausible: list[_Limb]) -> None:
    """A pair of arms: each has a mirror image on the other side, unless its names say arm."""
    for limb in plausible:
        mirrored = any(
            m.side != limb.side and _within(m.upper, limb.upper, 1.5) and _within(m.fore, limb.fore, 1.5)
            for m in plausible
        )
        if not mirrored and not limb.arm_named:
            limb.side_reason = f"no limb mirrors it on the {'right' if limb.side == 'left' else 'left'}"


def _rule_out_lower(paired: list[_Limb], joint_names: Sequence[str], parents: np.ndarray) -> None:
    """Near the top of the spine: no plausible limb on its side branches off further up."""
    n = len(joint_names)
    for limb in paired:
        above = [
            m
            for m in paired
            if m.side == limb.side and m.branch != limb.branch and tree.depth_below(parents, m.branch, limb.branch, n)
        ]
        if above:
            limb.side_reason = (
                f"branches off {joint_names[limb.branch]}, below {' > '.join(above[0].names)} "
                f"off {joint_names[above[0].branch]}"
            )


def _choose(side: str, paired: list[_Limb], joint_names: Sequence[str], parents: np.ndarray) -> list[_Limb]:
    """The best limbs of ``side`` (one, or a tie): named like an arm first, then branching off deepest."""
    chosen = [m for m in paired if not m.side_reason and m.side == side]
    named = [m for m in chosen if m.arm_named]
    for m in chosen:
        if named and not m.arm_named:
            m.side_reason = f"its names do not say arm, while those of {' > '.join(named[0].names)} do"
    chosen = named or chosen
    if chosen:
        deepest = max(tree.depth(parents, m.branch) for m in chosen)
        for m in chosen:
            if tree.depth(parents, m.branch) < deepest:
                m.side_reason = f"branches off {joint_names[m.branch]}, higher up the hierarchy than another"
        chosen = [m for m in chosen if tree.depth(parents, m.branch) == deepest]
    return chosen


def _outcome(
    side: str, limbs: list[_Limb], paired: list[_Limb], chosen: list[_Limb], joint_names: Sequence[str], hint: str
) -> ArmSearch:
    """The search's result: the one chosen limb, or the error for a tie or for none, with the others and why."""
    others = [m for m in limbs if len(chosen) != 1 or m is not chosen[0]]
    others.sort(key=lambda m: (len(m.reasons) + (m.side != side), -(m.upper + m.fore)))
    listed = tuple(Rejected(m.names, _why(m, side)) for m in others)
    if len(chosen) == 1:
        return _found(side, chosen[0], paired, listed, joint_names, hint)
    if chosen:
        ties = "; ".join(" > ".join(m.names) for m in chosen)
        error = (
            f"Expected one {side} arm chain, found {len(chosen)} equally plausible by skeleton structure: {ties}; "
            "name the joints explicitly"
        )
        return ArmSearch(side, None, listed, f"{hint}; {len(chosen)} limbs equally plausible by structure", error)
    shown = "; ".join(str(r) for r in listed[:6]) + (f"; and {len(listed) - 6} more" if len(listed) > 6 else "")
    structure = f"candidates: {shown}" if listed else "no limb of two or more bones"
    error = (
        f"Expected a {side} arm chain (shoulder, elbow, wrist), found none by joint names ({hint}) or skeleton "
        f"structure ({structure}); name the joints explicitly"
    )
    return ArmSearch(side, None, listed, f"{hint}; no plausible limb by structure", error)


def _found(
    side: str,
    limb: _Limb,
    paired: list[_Limb],
    listed: tuple[Rejected, ...],
    joint_names: Sequence[str],
    hint: str,
) -> ArmSearch:
    """The search's result when one limb was chosen: its chain, and in ``detail`` its branch and mirror image."""
    detail = f"{hint}; by structure: the {side} limb off {joint_names[limb.branch]}"
    mirror = [m for m in paired if m.side not in (side, None) and not m.side_reason]
    if mirror:
        detail += f", mirrored by {' > '.join(mirror[0].names)}"
    if limb.arm_named:
        detail += ", named like an arm"
    found = ArmJoints(side, limb.names, limb.indices, limb.wrist_is_site, "structure", listed, detail)
    return ArmSearch(side, found, listed, detail)


def _why(m: _Limb, side: str) -> str:
    """Why the limb ``m`` is not the ``side`` arm."""
    if m.reasons:
        return "; ".join(m.reasons)
    if m.side is not None and m.side != side:
        return f"on the {m.side} {'by its names' if m.names_side else 'in the rest pose'}"
    if m.side_reason:
        return m.side_reason
    return "tied" if m.side == side else "neither its names nor the rest pose put it on a side"


def _within(a: float, b: float, factor: float) -> bool:
    return a > 0 and b > 0 and max(a / b, b / a) <= factor
