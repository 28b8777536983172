"""Find the shoulder -> elbow -> wrist chain of an arm in a BVH skeleton.

Detection by name first, for the conventions seen in the wild:

===================  ====================  ==============  ==================  ===============
convention           clavicle              upper arm       forearm             wrist
===================  ====================  ==============  ==================  ===============
CMU/LAFAN/Mixamo     LeftShoulder          LeftArm         LeftForeArm         LeftHand
Collar (mocapbank)   LeftCollar            LeftShoulder    LeftElbow           LeftWrist
short                lTorso_Clavicle       lShoulder       lElbow              lWrist
Blender/Rigify       shoulder.L            upper_arm.L     forearm.L           hand.L or End Site
MakeHuman            clavicle.L            upperarm01.L    lowerarm01.L        wrist.L
3ds Max Biped        Bip01 L Clavicle      Bip01 L UpperArm  Bip01 L Forearm   Bip01 L Hand
===================  ====================  ==============  ==================  ===============

Any prefix is ignored (``mixamorig:``, ``ns:``, ``DEF-``).  A name's side is
``Left``/``Right`` anywhere, a separated ``L``/``R`` (``.L``, ``_r``, ``" L "``),
or a leading ``l``/``r`` before a capital (``lShoulder``).  Among all
shoulder -> elbow -> wrist triples of one side linked down the hierarchy, the
one with the fewest numbered twist segments, then the shortest links, wins;
"LeftShoulder" is the upper arm only when nothing named like an arm sits
between it and the elbow.  A tie is an error listing the candidates.

When no name matches, the structure decides: the two longest limbs leaving
the chest (the deepest joint with three or more children) are the arms, and
along a limb the shoulder, elbow and wrist are the ends of the two
consecutive longest bones.
"""

from __future__ import annotations

import logging
import re
from collections.abc import Sequence
from dataclasses import dataclass
from os import PathLike

import numpy as np

from retarget.errors import BvhError

log = logging.getLogger(__name__)

SIDES: tuple[str, str] = ("left", "right")
END_SITE_SUFFIX = "/End Site"

_UPPER = ("upperarm", "uparm", "humerus", "arm")
_FORE = ("forearm", "lowerarm", "lowarm", "elbow", "radius", "ulna")
_HAND = ("hand", "wrist")
_CLAVICLE = ("clavicle", "collar")
_AMBIGUOUS = ("shoulder",)  # the clavicle in CMU naming, the upper arm in Collar naming

_SIDE_WORD = re.compile(r"left|right", re.IGNORECASE)
_SIDE_SEPARATED = re.compile(r"(?:^|(?<=[._\s-]))([LlRr])(?=$|[._\s-])")
_SIDE_LEADING = re.compile(r"^([lLrR])(?=[A-Z_])")
_SIDE_TRAILING = re.compile(r"(?<=[a-z])([LR])$")
_TRAILING_NUMBER = re.compile(r"(\d+)$")


@dataclass(frozen=True)
class ArmJoints:
    """Which joints make an arm: shoulder, elbow, wrist.

    ``indices`` are joint indices, except the wrist's when
    ``wrist_is_end_site``: then it indexes the End Sites.
    """

    side: str
    names: tuple[str, str, str]
    indices: tuple[int, int, int]
    wrist_is_end_site: bool
    method: str = "names"  #: "names", "structure" or "explicit"


def check_side(side: str) -> str:
    """``side`` if it is ``"left"`` or ``"right"``; ``ValueError`` otherwise."""
    if side not in SIDES:
        raise ValueError(f"Expected side 'left' or 'right', got {side!r}")
    return side


def base_name(name: str) -> str:
    """The name without a namespace (``mixamorig:LeftArm`` -> ``LeftArm``, ``a|b`` -> ``b``)."""
    return re.split(r"[:|]", name)[-1]


def name_side(name: str) -> tuple[str | None, str]:
    """``(side or None, the base name with the side marker removed)``."""
    base = base_name(name)
    m = _SIDE_WORD.search(base)
    if m:
        side = "left" if m.group(0).lower() == "left" else "right"
        return side, base[: m.start()] + " " + base[m.end() :]
    for pattern in (_SIDE_SEPARATED, _SIDE_LEADING, _SIDE_TRAILING):
        m = pattern.search(base)
        if m:
            side = "left" if m.group(1).lower() == "l" else "right"
            return side, base[: m.start(1)] + " " + base[m.end(1) :]
    low = base.lower()  # ASF-style lhumerus / rwrist
    if low[:1] in ("l", "r") and _role_of(low[1:])[0] is not None:
        return ("left" if low[0] == "l" else "right"), base[1:]
    return None, base


def _role_of(rest: str) -> tuple[str | None, int]:
    """Role (``upper``, ``fore``, ``hand``, ``clavicle``, ``shoulder``) of a side-less name and its penalty.

    Penalty 0 for no number or ``01``, 1 for another number 1 (``.001``);
    twist segments numbered 2 and up have no role.
    """
    text = re.sub(r"[^a-z0-9]", "", rest.lower())
    penalty = 0
    m = _TRAILING_NUMBER.search(text)
    if m:
        number = int(m.group(1))
        if number >= 2:
            return None, 0
        penalty = 0 if m.group(1) == "01" else 1
        text = text[: m.start()]
    for role, words in (
        ("fore", _FORE),
        ("upper", _UPPER),
        ("hand", _HAND),
        ("clavicle", _CLAVICLE),
        ("shoulder", _AMBIGUOUS),
    ):
        for word in words:
            if text.endswith(word):
                return role, penalty
    return None, 0


def joint_roles(joint_names: Sequence[str]) -> list[tuple[str | None, str | None, int]]:
    """Per joint ``(side, role, penalty)`` from its name alone."""
    out = []
    for name in joint_names:
        side, rest = name_side(name)
        role, penalty = _role_of(rest)
        out.append((side, role, penalty))
    return out


def _depth_below(parents: np.ndarray, child: int, ancestor: int, limit: int) -> int | None:
    """Number of links from ``ancestor`` down to ``child`` (at most ``limit``), else None."""
    d, j = 0, child
    while j >= 0 and d <= limit:
        if j == ancestor:
            return d
        j = int(parents[j])
        d += 1
    return None


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
) -> ArmJoints:
    """The arm chain of ``side`` (``"left"``/``"right"``): by ``names`` if given, else by name, else by structure.

    Raises ``ValueError`` for a bad side, :class:`BvhError` (with ``path``)
    when an explicit name does not exist, when no chain is found, or when
    several chains tie (the message lists them).
    """
    check_side(side)
    parents = np.asarray(parents, dtype=np.intp)
    if names is not None:
        return _explicit(side, names, joint_names, parents, end_site_parents, path)
    candidates = arm_candidates(side, joint_names=joint_names, parents=parents, end_site_parents=end_site_parents)
    if candidates:
        best = candidates[0][0]
        tied = [c for rank, c in candidates if rank == best]
        if len(tied) > 1:
            listed = "; ".join(" > ".join(c.names) for c in tied)
            raise BvhError(
                f"Expected one {side} arm chain, found {len(tied)} equally good: {listed}; name the joints explicitly",
                path=path,
            )
        return tied[0]
    found = _by_structure(side, joint_names, parents, offsets, end_site_parents, end_site_offsets)
    if found is None:
        raise BvhError(
            f"Expected a {side} arm chain (shoulder, elbow, wrist), found none by joint names or skeleton structure; "
            "name the joints explicitly",
            path=path,
        )
    log.info("%s arm found by structure: %s", side, " > ".join(found.names))
    return found


def arm_candidates(
    side: str, *, joint_names: Sequence[str], parents: np.ndarray, end_site_parents: Sequence[int] = ()
) -> list[tuple[tuple[int, int], ArmJoints]]:
    """Name-based chains of ``side``, best first, each with its rank ``(penalty, links)``."""
    check_side(side)
    parents = np.asarray(parents, dtype=np.intp)
    roles = joint_roles(joint_names)
    n = len(joint_names)
    children: list[list[int]] = [[] for _ in range(n)]
    for j, p in enumerate(parents):
        if p >= 0:
            children[p].append(j)
    sided = [j for j in range(n) if roles[j][0] == side]
    uppers = [j for j in sided if roles[j][1] in ("upper", "shoulder")]
    fores = [j for j in sided if roles[j][1] == "fore"]
    hands = [j for j in sided if roles[j][1] == "hand"]
    out: list[tuple[tuple[int, int], ArmJoints]] = []
    for u in uppers:
        for f in fores:
            d1 = _depth_below(parents, f, u, 3)
            if not d1:
                continue
            # "LeftShoulder" is the clavicle when an upper-arm-named joint sits between it and the elbow
            between = _path_between(parents, f, u)
            if roles[u][1] == "shoulder" and any(roles[k][1] == "upper" for k in between):
                continue
            wrists: list[tuple[int, int, int, bool, str]] = []  # (penalty, links, index, end_site, name)
            for h in hands:
                d2 = _depth_below(parents, h, f, 3)
                if d2:
                    wrists.append((roles[h][2], d2, h, False, joint_names[h]))
            if not wrists:
                sites = [k for k, p in enumerate(end_site_parents) if p == f]
                if sites:
                    wrists.append((0, 1, sites[0], True, joint_names[f] + END_SITE_SUFFIX))
                elif len(children[f]) == 1:
                    c = children[f][0]
                    wrists.append((1, 1, c, False, joint_names[c]))
            for wp, d2, w, is_site, wname in wrists:
                rank = (roles[u][2] + roles[f][2] + wp, d1 + d2)
                chain = ArmJoints(side, (joint_names[u], joint_names[f], wname), (u, f, w), is_site, "names")
                out.append((rank, chain))
    out.sort(key=lambda rc: rc[0])
    return out


def _path_between(parents: np.ndarray, child: int, ancestor: int) -> list[int]:
    out, j = [], int(parents[child])
    while j >= 0 and j != ancestor:
        out.append(j)
        j = int(parents[j])
    return out


def _explicit(
    side: str,
    names: Sequence[str],
    joint_names: Sequence[str],
    parents: np.ndarray,
    end_site_parents: Sequence[int],
    path: str | PathLike[str] | None,
) -> ArmJoints:
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
    elbow_ok = _depth_below(parents, found[1], found[0], len(joint_names))
    wrist_joint = end_site_parents[found[2]] if wrist_is_site else found[2]
    wrist_ok = wrist_is_site and wrist_joint == found[1] or _depth_below(parents, wrist_joint, found[1], len(parents))
    if not elbow_ok or not wrist_ok:
        raise BvhError(
            f"Expected {names[0]!r} > {names[1]!r} > {names[2]!r} to run down the hierarchy, got joints on other "
            "branches",
            path=path,
        )
    return ArmJoints(side, (names[0], names[1], names[2]), (found[0], found[1], found[2]), wrist_is_site, "explicit")


# ------------------------------------------------------------------------------------------ structure


def _by_structure(
    side: str,
    joint_names: Sequence[str],
    parents: np.ndarray,
    offsets: np.ndarray,
    end_site_parents: Sequence[int],
    end_site_offsets: Sequence[Sequence[float]],
) -> ArmJoints | None:
    n = len(joint_names)
    if n < 4:
        return None
    rest = np.zeros((n, 3))
    for j in range(n):
        rest[j] = np.asarray(offsets[j], dtype=np.float64) + (rest[parents[j]] if parents[j] >= 0 else 0.0)
    children: list[list[int]] = [[] for _ in range(n)]
    for j, p in enumerate(parents):
        if p >= 0:
            children[p].append(j)
    depth = np.zeros(n, dtype=int)
    for j in range(n):
        depth[j] = depth[parents[j]] + 1 if parents[j] >= 0 else 0
    branchy = [j for j in range(n) if len(children[j]) >= 3]  # the deepest is the chest (the root: upper body only)
    if not branchy:
        return None
    chest = max(branchy, key=lambda j: (depth[j], j))
    limbs = []
    for c in children[chest]:
        chain = _main_chain(c, children, rest)
        points = [rest[chest]] + [rest[k] for k in chain]
        length = float(sum(np.linalg.norm(np.diff(np.array(points), axis=0), axis=1)))
        limbs.append((length, c, chain))
    limbs.sort(key=lambda t: -t[0])
    arms = limbs[:2]
    sides = [_subtree_side(c, children, joint_names) for _, c, _ in arms]
    if sides[0] is None or sides[1] is None or sides[0] == sides[1]:
        # BVH convention: Y up, facing +Z, so the character's left is +X
        xs = [rest[c][0] for _, c, _ in arms]
        sides = ["left", "right"] if xs[0] >= xs[1] else ["right", "left"]
    _, _, chain = arms[sides.index(side)]
    # sites: treat the forearm's End Site as a final point of the chain
    tip = chain[-1]
    sites = [k for k, p in enumerate(end_site_parents) if p == tip]
    pts = [rest[k] for k in chain]
    if sites:
        pts.append(rest[tip] + np.asarray(end_site_offsets[sites[0]], dtype=np.float64))
    if len(pts) < 3:
        return None
    bones = np.linalg.norm(np.diff(np.array(pts), axis=0), axis=1)
    i = int(np.argmax(bones[:-1] + bones[1:]))
    idx = [i, i + 1, i + 2]
    is_site = bool(sites) and idx[2] == len(chain)
    names = [joint_names[chain[k]] for k in idx[:2]]
    if is_site:
        names.append(joint_names[tip] + END_SITE_SUFFIX)
        wrist = sites[0]
    else:
        names.append(joint_names[chain[idx[2]]])
        wrist = chain[idx[2]]
    return ArmJoints(side, (names[0], names[1], names[2]), (chain[idx[0]], chain[idx[1]], wrist), is_site, "structure")


def _main_chain(start: int, children: list[list[int]], rest: np.ndarray) -> list[int]:
    """Joints from ``start`` down, always into the child with the longest reach."""

    def reach(j: int) -> float:
        return float(max((np.linalg.norm(rest[c] - rest[j]) + reach(c) for c in children[j]), default=0.0))

    chain = [start]
    while children[chain[-1]]:
        chain.append(max(children[chain[-1]], key=reach))
    return chain


def _subtree_side(start: int, children: list[list[int]], joint_names: Sequence[str]) -> str | None:
    votes = {"left": 0, "right": 0}
    stack = [start]
    while stack:
        j = stack.pop()
        side, _ = name_side(joint_names[j])
        if side:
            votes[side] += 1
        stack.extend(children[j])
    if votes["left"] == votes["right"]:
        return None
    return max(votes, key=votes.__getitem__)


# ------------------------------------------------------------------------------------------ units


@dataclass(frozen=True)
class UnitsGuess:
    """What a skeleton's size suggests about its length unit.

    ``unit`` is ``"m"``, ``"cm"``, ``"mm"``, ``"in"`` or ``"unknown"``;
    ``height`` is the standing height in file units (rest pose extent along
    ``up_axis``); ``metres_per_unit`` is the scale that makes the skeleton
    1.7 m tall when the unit is unknown, else the unit's exact size.
    """

    unit: str
    height: float
    up_axis: str
    metres_per_unit: float


_UNITS = (("m", 1.0, 1.2, 2.3), ("cm", 0.01, 120.0, 230.0), ("mm", 0.001, 1200.0, 2300.0), ("in", 0.0254, 45.0, 90.0))


def guess_units(rest_points: np.ndarray) -> UnitsGuess:
    """Guess the unit from ``rest_points`` ``(n, 3)`` (joints and End Sites, rest pose, file units).

    Up is Y (the BVH convention) unless the skeleton is much flatter along Y
    than along Z.  A human of 1.2-2.3 m is assumed.
    """
    pts = np.asarray(rest_points, dtype=np.float64).reshape(-1, 3)
    if pts.shape[0] == 0:
        return UnitsGuess("unknown", 0.0, "Y", 1.0)
    extent = pts.max(axis=0) - pts.min(axis=0)
    up = 1 if extent[1] >= 0.5 * extent.max() or extent[1] >= extent[2] else 2
    height = float(extent[up])
    for unit, size, low, high in _UNITS:
        if low <= height <= high:
            return UnitsGuess(unit, height, "XYZ"[up], size)
    return UnitsGuess("unknown", height, "XYZ"[up], 1.7 / height if height > 0 else 1.0)
