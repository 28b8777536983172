"""Find the shoulder -> elbow -> wrist chain of an arm in a BVH skeleton, and guess the skeleton's length unit.

Detection by name first, for the conventions seen in the wild:

==================  ===================  ================  ===============  ==================
convention          clavicle             upper arm         forearm          wrist
==================  ===================  ================  ===============  ==================
CMU/LAFAN/Mixamo    LeftShoulder         LeftArm           LeftForeArm      LeftHand
Collar (mocapbank)  LeftCollar           LeftShoulder      LeftElbow        LeftWrist
short               lTorso_Clavicle      lShoulder         lElbow           lWrist
Blender/Rigify      shoulder.L           upper_arm.L       forearm.L        hand.L or End Site
MakeHuman           clavicle.L           upperarm01.L      lowerarm01.L     wrist.L
MakeHuman MHX       Clavicle_L           UpArm_L           LoArm_L          Hand_L
3ds Max Biped       Bip01 L Clavicle     Bip01 L UpperArm  Bip01 L Forearm  Bip01 L Hand
Poser/DAZ/SL        lCollar              lShldr            lForeArm         lHand
DAZ Genesis 3/8     lCollar              lShldrBend        lForearmBend     lHand
OptiTrack Motive    Skeleton1_LShoulder  Skeleton1_LUArm   Skeleton1_LFArm  Skeleton1_LHand
==================  ===================  ================  ===============  ==================

Any prefix is ignored (``mixamorig:``, ``ns:``, ``DEF-``, ``Skeleton1_``, ``Bip01``), and so is the case.  A
name's side is ``Left``/``Right`` anywhere, a separated ``L``/``R`` (``.L``, ``_r``, ``" L "``), an ``l``/``r``
before a capital at the start or after a separator (``lShoulder``, ``Skeleton1_LUArm``), a trailing capital
(``HandL``), or a lone ``l``/``r`` before a role word (``lhumerus``, ``skeleton1_lfarm``).  A trailing ``Bend``
is dropped (DAZ); twist and roll bones (``lShldrTwist``, ``LeftArmRoll``, ``upperarm_twist_01_l``) and segments
numbered 2 and up (``upperarm02.L``) have no role, so they may sit inside a chain.  Among all shoulder -> elbow ->
wrist triples of one side linked down the hierarchy (at most 3 links apart), the one with the fewest numbered
segments, then the shortest links, wins; "LeftShoulder" is the upper arm only when nothing named like an arm sits
between it and the elbow.  A tie is an error listing the candidates.  Detection by names wins whenever it finds
a chain.

When no chain is named, the structure decides, but only for a plausible limb.  Every child of a joint with two
or more children starts a candidate limb; along its main chain (into the child with the longest reach, twist and
roll bones and zero-length bones skipped) the upper arm is the longest bone and the forearm the bone after it
(the bone before it when that one is over 1.25 times longer: then the longest bone was the forearm).  A
candidate is rejected, with the reason kept, when

- its joints' names say another side, or a leg, finger or head/face bone (``UpLeg``, ``Index1``, ``Tongue``);
- its upper arm or forearm is outside :data:`ARM_BONE_RANGE` of the skeleton's height (see
  :func:`height_from_bones`), or one is more than 2.5 times the other;
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

Arm bone thresholds (fractions of the skeleton's height from its bone lengths, which is within about 30 % of
the true height for the rigs seen: upper arms measure 0.15-0.19 and forearms 0.12-0.16 of a standing height):
:data:`ARM_BONE_RANGE` (6-40 %) is what the structure fallback accepts and, outside it, a warning for a chain
found otherwise; :data:`ARM_BONE_LIMITS` (2-75 %) is where a chain is an error (collapsed position channels,
the wrong joints).
"""

from __future__ import annotations

import logging
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from os import PathLike

import numpy as np

from retarget.errors import BvhError

log = logging.getLogger(__name__)

SIDES: tuple[str, str] = ("left", "right")
END_SITE_SUFFIX = "/End Site"

#: An upper arm or forearm of 6-40 % of the skeleton's height is plausible: the structure fallback takes no
#: other, and a chain found by names or named explicitly outside it gets a warning.
ARM_BONE_RANGE: tuple[float, float] = (0.06, 0.40)
#: An upper arm or forearm under 2 % or over 75 % of the skeleton's height is an error.
ARM_BONE_LIMITS: tuple[float, float] = (0.02, 0.75)
#: The structure fallback's upper arm / forearm ratio (humans: about 1.0-1.45 joint to joint).
ARM_RATIO_RANGE: tuple[float, float] = (0.4, 2.5)
#: The longest path through a human skeleton (a toe to the other hand's fingertip) is about 1.4 heights.
DIAMETER_PER_HEIGHT = 1.4

_UPPER = ("upperarm", "uparm", "humerus", "shldr", "arm")
_FORE = ("forearm", "lowerarm", "lowarm", "loarm", "farm", "elbow", "radius", "ulna")
_HAND = ("hand", "wrist")
_CLAVICLE = ("clavicle", "collar")
_AMBIGUOUS = ("shoulder",)  # the clavicle in CMU naming, the upper arm in Collar naming
_ROLE_WORDS = (("fore", _FORE), ("upper", _UPPER), ("hand", _HAND), ("clavicle", _CLAVICLE), ("shoulder", _AMBIGUOUS))
_WHOLE_WORD = ("farm",)  # only as a word of its own (OptiTrack's LFArm), not the end of "DEF-Arm"
_ROLE_NAMES = {"upper": "upper arm", "shoulder": "upper arm", "fore": "forearm", "hand": "hand", "clavicle": "clavicle"}

#: Words that make a limb anything but an arm, by kind.
_NOT_ARM = (
    ("leg", ("upleg", "leg", "thigh", "knee", "shin", "calf", "foot", "ankle", "toe", "hip", "femur", "tibia")),
    ("finger", ("finger", "thumb", "index", "middle", "ring", "pinky", "pinkie", "little", "phalanx", "carpal")),
    ("head", ("head", "neck", "jaw", "tongue", "eye", "eyelid", "lip", "brow", "cheek", "teeth", "nose", "ear")),
)

_SEP = r"[._\s:|-]"
_SIDE_WORD = re.compile(r"left|right", re.IGNORECASE)
_SIDE_SEPARATED = re.compile(r"(?:^|(?<=[._\s-]))([LlRr])(?=$|[._\s-])")
_SIDE_LEADING = re.compile(rf"(?:^|(?<={_SEP}))([lLrR])(?=[A-Z_])")
_SIDE_TRAILING = re.compile(r"(?<=[a-z])([LR])$")
_TRAILING_NUMBER = re.compile(r"(\d+)$")
_TOKENS = re.compile(r"[A-Z]?[a-z]+|[A-Z]+(?![a-z])")


@dataclass(frozen=True)
class Rejected:
    """A candidate chain that was not chosen: its joints (shoulder, elbow and, when it got that far, wrist) and why."""

    names: tuple[str, ...]
    reason: str

    def __str__(self) -> str:
        return f"{' > '.join(self.names)} ({self.reason})"


@dataclass(frozen=True)
class ArmJoints:
    """Which joints make an arm: shoulder, elbow, wrist.

    ``indices`` are joint indices, except the wrist's when
    ``wrist_is_end_site``: then it indexes the End Sites.  ``detail`` says
    how the chain was found; ``rejected`` lists the other candidates.
    """

    side: str
    names: tuple[str, str, str]
    indices: tuple[int, int, int]
    wrist_is_end_site: bool
    method: str = "names"  #: "names", "structure" or "explicit"
    rejected: tuple[Rejected, ...] = field(default=(), compare=False)
    detail: str = field(default="", compare=False)


@dataclass(frozen=True)
class ArmSearch:
    """What arm detection found for one side: the chain or None, the candidates not chosen, and why.

    ``detail`` says how the chain was found, or why none was; ``error`` is the
    message of the :class:`BvhError` that :func:`find_arm` raises when
    ``found`` is None (empty otherwise).
    """

    side: str
    found: ArmJoints | None
    rejected: tuple[Rejected, ...] = ()
    detail: str = ""
    error: str = ""


def check_side(side: str) -> str:
    """``side`` if it is ``"left"`` or ``"right"``; ``ValueError`` otherwise."""
    if side not in SIDES:
        raise ValueError(f"Expected side 'left' or 'right', got {side!r}")
    return side


def base_name(name: str) -> str:
    """The name without a namespace (``mixamorig:LeftArm`` -> ``LeftArm``, ``a|b`` -> ``b``)."""
    return re.split(r"[:|]", name)[-1]


def name_side(name: str) -> tuple[str | None, str]:
    """``(side or None, the base name with the side marker removed)``.

    >>> name_side("mixamorig:LeftForeArm"), name_side("Skeleton1_LUArm")[0], name_side("lshldr")[0]
    (('left', ' ForeArm'), 'left', 'left')
    """
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
    # ASF-style lhumerus / rwrist, also after a prefix (skeleton1_lfarm, lupper_arm)
    low = base.lower()
    for start in [0, *(m.end() for m in re.finditer(_SEP, base))]:
        if low[start : start + 1] in ("l", "r") and _role_of(low[start + 1 :])[0] is not None:
            return ("left" if low[start] == "l" else "right"), base[:start] + " " + base[start + 1 :]
    return None, base


def _squash(rest: str) -> str:
    return re.sub(r"[^a-z0-9]", "", rest.lower())


def _role_of(rest: str) -> tuple[str | None, int]:
    """Role (``upper``, ``fore``, ``hand``, ``clavicle``, ``shoulder``) of a side-less name and its penalty.

    Penalty 0 for no number or ``01``, 1 for another number 1 (``.001``);
    twist segments numbered 2 and up, and twist or roll bones, have no role.
    """
    text = _squash(rest)
    penalty = 0
    m = _TRAILING_NUMBER.search(text)
    if m:
        number = int(m.group(1))
        if number >= 2:
            return None, 0
        penalty = 0 if m.group(1) == "01" else 1
        text = text[: m.start()]
    if text.endswith("bend"):  # DAZ Genesis: lShldrBend is the upper arm, lShldrTwist a twist bone
        text = text[: -len("bend")]
    chunk = re.split(r"[^a-z0-9]+", rest.lower().strip(" ._-"))[-1]  # the last word: "farm" in "Skeleton1_ FArm"
    for role, words in _ROLE_WORDS:
        for word in words:
            if text.endswith(word) and (word not in _WHOLE_WORD or chunk.startswith(word)):
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


def _is_twist(name: str) -> bool:
    """A twist or roll bone by its name (``lShldrTwist``, ``LeftForeArmRoll``, ``upperarm_twist_01_l``)."""
    text = _TRAILING_NUMBER.sub("", _squash(base_name(name)))
    return "twist" in text or text.endswith("roll")


def _not_arm_kind(name: str) -> str | None:
    """``"leg"``, ``"finger"`` or ``"head"`` when the name says so, else None."""
    base = base_name(name)
    tokens = [t.lower() for t in _TOKENS.findall(base)]
    tokens += [t[1:] for t in tokens if len(t) > 2 and t[0] in "lr"]
    text = re.sub(r"\d+$", "", _squash(base))
    for kind, words in _NOT_ARM:
        if any(t in words for t in tokens) or any(text.endswith(w) for w in words):
            return kind
    return None


def _depth_below(parents: np.ndarray, child: int, ancestor: int, limit: int) -> int | None:
    """Number of links from ``ancestor`` down to ``child`` (at most ``limit``), else None."""
    d, j = 0, child
    while j >= 0 and d <= limit:
        if j == ancestor:
            return d
        j = int(parents[j])
        d += 1
    return None


def _children(parents: np.ndarray) -> list[list[int]]:
    out: list[list[int]] = [[] for _ in range(len(parents))]
    for j, p in enumerate(parents):
        if p >= 0:
            out[int(p)].append(j)
    return out


# ------------------------------------------------------------------------------------------ height


def height_from_bones(
    parents: np.ndarray,
    lengths: Sequence[float] | np.ndarray,
    end_site_parents: Sequence[int] = (),
    end_site_lengths: Sequence[float] = (),
) -> float:
    """A skeleton's standing height from its bone lengths alone, whatever its pose: file units.

    ``lengths`` ``(n_joints,)``: each joint's distance from its parent (the
    root's is ignored); ``end_site_lengths``: each End Site's from its joint.
    The longest path through the skeleton, summed bone by bone (a toe to the
    other hand's fingertip), is about :data:`DIAMETER_PER_HEIGHT` (1.4)
    heights: 1.39-1.44 on the CMU-style, Unity, push and demo rigs; an
    upper-body-only rig (hand to hand) reads about 30 % short.

    >>> parents = np.array([-1, 0, 1, 0, 3])   # a hip and two legs of 0.1 + 0.9 + 0.8 units
    >>> round(height_from_bones(parents, [0, 0.1, 0.8, 0.1, 0.8], [2, 4], [0.1, 0.1]), 3)
    1.429
    """
    parents = np.asarray(parents, dtype=np.intp)
    n = len(parents)
    bone = np.asarray(lengths, dtype=np.float64).reshape(n)
    branches: list[list[float]] = [[] for _ in range(n)]  # per joint, the reach down each child and End Site
    for k, p in enumerate(end_site_parents):
        branches[int(p)].append(float(end_site_lengths[k]))
    down = np.zeros(n)
    best = 0.0
    for j in range(n - 1, -1, -1):  # parents come before children
        paths = sorted(branches[j], reverse=True)
        down[j] = paths[0] if paths else 0.0
        best = max(best, sum(paths[:2]))
        if parents[j] >= 0:
            branches[int(parents[j])].append(float(bone[j]) + float(down[j]))
    return best / DIAMETER_PER_HEIGHT


def _rest_positions(parents: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    rest = np.zeros((len(parents), 3))
    for j in range(len(parents)):
        rest[j] = np.asarray(offsets[j], dtype=np.float64) + (rest[parents[j]] if parents[j] >= 0 else 0.0)
    return rest


# ------------------------------------------------------------------------------------------ the search


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
    file units for the plausibility checks (default: :func:`height_from_bones` of the OFFSETs).
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
    candidates, skipped = _name_chains(side, joint_names, parents, end_site_parents)
    if candidates:
        best = candidates[0][0]
        tied = [c for rank, c in candidates if rank == best]
        if len(tied) > 1:
            listed = "; ".join(" > ".join(c.names) for c in tied)
            error = (
                f"Expected one {side} arm chain, found {len(tied)} equally good: {listed}; name the joints explicitly"
            )
            rejected = tuple(Rejected(c.names, "tied") for c in tied)
            return ArmSearch(side, None, rejected, f"{len(tied)} chains named equally well", error)
        chain = tied[0]
        rejected_list = [Rejected(c.names, _rank_reason(rank, best, chain)) for rank, c in candidates[1:]]
        detail = (
            f"joint names: {chain.names[0]} is an upper arm, {chain.names[1]} a forearm, {chain.names[2]} the wrist"
        )
        found = ArmJoints(
            side, chain.names, chain.indices, chain.wrist_is_end_site, "names", tuple(rejected_list + skipped), detail
        )
        return ArmSearch(side, found, found.rejected, detail)
    if height is None:
        lengths = np.linalg.norm(offsets, axis=1)
        site_lengths = [float(np.linalg.norm(np.asarray(o, dtype=np.float64))) for o in end_site_offsets]
        height = height_from_bones(parents, lengths, end_site_parents, site_lengths)
    hint = _name_hint(side, joint_names)
    return _by_structure(side, joint_names, parents, offsets, end_site_parents, end_site_offsets, height, hint)


def arm_candidates(
    side: str, *, joint_names: Sequence[str], parents: np.ndarray, end_site_parents: Sequence[int] = ()
) -> list[tuple[tuple[int, int], ArmJoints]]:
    """Name-based chains of ``side``, best first, each with its rank ``(penalty, links)``."""
    check_side(side)
    return _name_chains(side, joint_names, np.asarray(parents, dtype=np.intp), end_site_parents)[0]


def _name_chains(
    side: str, joint_names: Sequence[str], parents: np.ndarray, end_site_parents: Sequence[int]
) -> tuple[list[tuple[tuple[int, int], ArmJoints]], list[Rejected]]:
    """Name-based chains, best first with their ranks, and the triples skipped (a clavicle called shoulder)."""
    roles = joint_roles(joint_names)
    children = _children(parents)
    sided = [j for j in range(len(joint_names)) if roles[j][0] == side]
    uppers = [j for j in sided if roles[j][1] in ("upper", "shoulder")]
    fores = [j for j in sided if roles[j][1] == "fore"]
    hands = [j for j in sided if roles[j][1] == "hand"]
    out: list[tuple[tuple[int, int], ArmJoints]] = []
    skipped: list[Rejected] = []
    for u in uppers:
        for f in fores:
            d1 = _depth_below(parents, f, u, 3)
            if not d1:
                continue
            # "LeftShoulder" is the clavicle when an upper-arm-named joint sits between it and the elbow
            between = [k for k in _path_between(parents, f, u) if roles[k][1] == "upper"]
            if roles[u][1] == "shoulder" and between:
                reason = (
                    f"{joint_names[u]} is the clavicle here: {joint_names[between[-1]]} lies between it and the elbow"
                )
                skipped.append(Rejected((joint_names[u], joint_names[f]), reason))
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
    return out, skipped


def _rank_reason(rank: tuple[int, int], best: tuple[int, int], chosen: ArmJoints) -> str:
    if rank[0] > best[0]:
        return f"ranked below {' > '.join(chosen.names)}: a numbered segment or an unnamed wrist"
    return f"ranked below {' > '.join(chosen.names)}: {rank[1]} links instead of {best[1]}"


def _name_hint(side: str, joint_names: Sequence[str]) -> str:
    """What the names say about the ``side`` arm when they name no whole chain."""
    roles = joint_roles(joint_names)
    named: dict[str, list[str]] = {}
    for name, (s, role, _) in zip(joint_names, roles, strict=True):
        if s == side and role is not None:
            named.setdefault(_ROLE_NAMES[role], []).append(name)
    if not any(k in named for k in ("upper arm", "forearm", "hand")):
        return f"no joint is named as a {side} upper arm, forearm or hand"
    found = "; ".join(f"{role} {', '.join(names)}" for role, names in named.items())
    missing = [k for k in ("upper arm", "forearm", "hand") if k not in named]
    if missing:
        return f"named {side}: {found}; no {' or '.join(missing)}"
    return f"named {side}: {found}; not linked as upper arm > forearm > hand within 3 links"


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
    return ArmJoints(
        side,
        (names[0], names[1], names[2]),
        (found[0], found[1], found[2]),
        wrist_is_site,
        "explicit",
        detail="named explicitly",
    )


# ------------------------------------------------------------------------------------------ structure


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


def _by_structure(
    side: str,
    joint_names: Sequence[str],
    parents: np.ndarray,
    offsets: np.ndarray,
    end_site_parents: Sequence[int],
    end_site_offsets: Sequence[Sequence[float]],
    height: float,
    hint: str,
) -> ArmSearch:
    n = len(joint_names)
    rest = _rest_positions(parents, offsets)
    children = _children(parents)
    reach = _reach(children, rest)
    sites: dict[int, np.ndarray] = {}  # the first End Site of a joint: its index and position
    site_index: dict[int, int] = {}
    for k, p in enumerate(end_site_parents):
        if int(p) not in site_index:
            site_index[int(p)] = k
            sites[int(p)] = rest[int(p)] + np.asarray(end_site_offsets[k], dtype=np.float64)
    by_chain: dict[tuple[int, int, int, bool], _Limb] = {}
    for b in range(n):
        if len(children[b]) < 2:
            continue
        for c in children[b]:
            limb = _limb(b, c, joint_names, children, rest, reach, site_index, sites)
            key = (*limb.indices, limb.wrist_is_site) if limb else None
            if limb and key and (key not in by_chain or _depth(parents, b) > _depth(parents, by_chain[key].branch)):
                by_chain[key] = limb  # the same chain from further down: keep the branch nearest to it
    limbs = list(by_chain.values())
    for limb in limbs:
        _judge(limb, joint_names, rest, height)
    plausible = [m for m in limbs if not m.reasons and m.side in SIDES]
    for limb in plausible:  # a pair of arms: each has a mirror image on the other side
        mirrored = any(
            m.side != limb.side and _within(m.upper, limb.upper, 1.5) and _within(m.fore, limb.fore, 1.5)
            for m in plausible
        )
        if not mirrored and not limb.arm_named:
            limb.side_reason = f"no limb mirrors it on the {'right' if limb.side == 'left' else 'left'}"
    paired = [m for m in plausible if not m.side_reason]
    for limb in paired:  # near the top of the spine: no plausible limb on its side branches off further up
        above = [
            m
            for m in paired
            if m.side == limb.side and m.branch != limb.branch and _depth_below(parents, m.branch, limb.branch, n)
        ]
        if above:
            limb.side_reason = (
                f"branches off {joint_names[limb.branch]}, below {' > '.join(above[0].names)} "
                f"off {joint_names[above[0].branch]}"
            )
    chosen = [m for m in paired if not m.side_reason and m.side == side]
    named = [m for m in chosen if m.arm_named]
    for m in chosen:
        if named and not m.arm_named:
            m.side_reason = f"its names do not say arm, while those of {' > '.join(named[0].names)} do"
    chosen = named or chosen
    if chosen:
        deepest = max(_depth(parents, m.branch) for m in chosen)
        for m in chosen:
            if _depth(parents, m.branch) < deepest:
                m.side_reason = f"branches off {joint_names[m.branch]}, higher up the hierarchy than another"
        chosen = [m for m in chosen if _depth(parents, m.branch) == deepest]

    def why(m: _Limb) -> str:
        if m.reasons:
            return "; ".join(m.reasons)
        if m.side is not None and m.side != side:
            return f"on the {m.side} {'by its names' if m.names_side else 'in the rest pose'}"
        if m.side_reason:
            return m.side_reason
        return "tied" if m.side == side else "neither its names nor the rest pose put it on a side"

    others = [m for m in limbs if len(chosen) != 1 or m is not chosen[0]]
    others.sort(key=lambda m: (len(m.reasons) + (m.side != side), -(m.upper + m.fore)))
    listed = tuple(Rejected(m.names, why(m)) for m in others)
    if len(chosen) == 1:
        limb = chosen[0]
        detail = f"{hint}; by structure: the {side} limb off {joint_names[limb.branch]}"
        mirror = [m for m in paired if m.side not in (side, None) and not m.side_reason]
        if mirror:
            detail += f", mirrored by {' > '.join(mirror[0].names)}"
        if limb.arm_named:
            detail += ", named like an arm"
        found = ArmJoints(side, limb.names, limb.indices, limb.wrist_is_site, "structure", listed, detail)
        return ArmSearch(side, found, listed, detail)
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


def _within(a: float, b: float, factor: float) -> bool:
    return a > 0 and b > 0 and max(a / b, b / a) <= factor


def _depth(parents: np.ndarray, j: int) -> int:
    d = 0
    while parents[j] >= 0:
        j = int(parents[j])
        d += 1
    return d


def _reach(children: list[list[int]], rest: np.ndarray) -> np.ndarray:
    """Per joint, the longest path down to a leaf joint (rest pose, file units)."""
    reach = np.zeros(len(children))
    for j in range(len(children) - 1, -1, -1):  # parents come before children
        reach[j] = max((float(np.linalg.norm(rest[c] - rest[j])) + reach[c] for c in children[j]), default=0.0)
    return reach


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
    points += [(j, False, rest[j]) for j in main if not _is_twist(joint_names[j])]
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
        kind = _not_arm_kind(joint_names[j])
        if kind and kind not in kinds:
            kinds.append(kind)
        if _role_of(rest_name)[0] is not None or "arm" in _squash(rest_name):
            limb.arm_named = True
    if votes["left"] != votes["right"]:
        limb.names_side = max(votes, key=votes.__getitem__)
    limb.reasons += [f"its names say {kind}" for kind in kinds]
    limb.arm_named = limb.arm_named and not kinds
    lo, hi = ARM_BONE_RANGE
    if not all(lo * height <= b <= hi * height for b in (limb.upper, limb.fore)):
        limb.reasons.append(
            f"bones {limb.upper:.3g} and {limb.fore:.3g} units, {_percent(limb.upper, height)} and "
            f"{_percent(limb.fore, height)} of the skeleton's height ({height:.4g} units); an arm's are "
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


def _percent(part: float, whole: float) -> str:
    return f"{100 * part / whole:.2g} %" if whole > 0 else "? %"


# ------------------------------------------------------------------------------------------ arm lengths


def check_arm_lengths(
    chain: ArmJoints,
    upper: float,
    fore: float,
    height: float,
    *,
    measured: str = "over the frames",
    path: str | PathLike[str] | None = None,
) -> str | None:
    """A warning when the chain's bones are unusual for the skeleton's ``height``; :class:`BvhError` when absurd.

    ``upper``, ``fore``: the chain's upper-arm and forearm lengths and ``height`` the skeleton's (see
    :func:`height_from_bones`), file units; ``measured`` says where the lengths come from.  Outside
    :data:`ARM_BONE_LIMITS` (2-75 % of the height) is an error naming the joints and lengths; outside
    :data:`ARM_BONE_RANGE` (6-40 %) returns a one-line warning; else None.
    """
    if not (height > 0 and np.isfinite(height)):
        return None  # nothing to compare with (a one-joint skeleton)
    s, e, w = chain.names
    got = (
        f"{s} > {e} {upper:.3g} units ({_percent(upper, height)}) and {e} > {w} {fore:.3g} units "
        f"({_percent(fore, height)}), measured {measured}"
    )
    lo, hi = ARM_BONE_LIMITS
    if not all(lo * height <= b <= hi * height for b in (upper, fore)):
        raise BvhError(
            f"Expected the {chain.side} upper arm and forearm to be {lo * 100:.0f}-{hi * 100:.0f} % of the "
            f"skeleton's height ({height:.4g} units from its bone lengths), got {got}; check those joints' "
            "position channels or name the joints explicitly",
            path=path,
        )
    lo, hi = ARM_BONE_RANGE
    if not all(lo * height <= b <= hi * height for b in (upper, fore)):
        return (
            f"the {chain.side} upper arm and forearm are usually {lo * 100:.0f}-{hi * 100:.0f} % of the skeleton's "
            f"height ({height:.4g} units from its bone lengths), got {got}"
        )
    return None


# ------------------------------------------------------------------------------------------ units


@dataclass(frozen=True)
class UnitsGuess:
    """What a skeleton's size suggests about its length unit.

    ``unit`` is ``"m"``, ``"cm"``, ``"mm"``, ``"in"`` or ``"unknown"``;
    ``height`` is the standing height in file units, measured as ``basis``
    says: ``"rest pose"`` (the rest pose's extent along ``up_axis``),
    ``"motion"`` (the median extent over the frames) or ``"bone lengths"``
    (:func:`height_from_bones`); ``metres_per_unit`` is the scale that makes
    the skeleton 1.7 m tall when the unit is unknown, else the unit's exact size.
    """

    unit: str
    height: float
    up_axis: str
    metres_per_unit: float
    basis: str = "rest pose"


_UNITS = (("m", 1.0, 1.2, 2.3), ("cm", 0.01, 120.0, 230.0), ("mm", 0.001, 1200.0, 2300.0), ("in", 0.0254, 45.0, 90.0))
#: A measured extent counts as the standing height when within this factor of the height from bone lengths.
HEIGHT_AGREEMENT = 1.6


def _extent(extent: np.ndarray) -> tuple[float, int]:
    """``(height, up axis index)`` of an ``(3,)`` extent: Y unless much flatter than Z."""
    up = 1 if extent[1] >= 0.5 * extent.max() or extent[1] >= extent[2] else 2
    return float(extent[up]), up


def units_for_height(height: float, up_axis: str = "Y", basis: str = "rest pose") -> UnitsGuess:
    """The unit that makes ``height`` (file units) a human of 1.2-2.3 m, else ``"unknown"``.

    >>> units_for_height(172.0).unit, units_for_height(21.0).unit
    ('cm', 'unknown')
    """
    for unit, size, low, high in _UNITS:
        if low <= height <= high:
            return UnitsGuess(unit, height, up_axis, size, basis)
    return UnitsGuess("unknown", height, up_axis, 1.7 / height if height > 0 else 1.0, basis)


def guess_units(
    rest_points: np.ndarray, *, bone_height: float | None = None, frames: np.ndarray | None = None
) -> UnitsGuess:
    """Guess the unit from ``rest_points`` ``(n, 3)`` (joints and End Sites, rest pose, file units).

    Up is Y (the BVH convention) unless the skeleton is much flatter along Y
    than along Z.  A human of 1.2-2.3 m is assumed.  With ``bone_height`` (the
    height from bone lengths, :func:`height_from_bones`), the rest pose's
    extent counts only when within a factor :data:`HEIGHT_AGREEMENT` (1.6) of
    it: a zero-rotation pose need not be upright (LAFAN lays every bone along
    X).  Then the median extent over ``frames`` ``(n_frames, n, 3)`` is tried
    the same way, and last ``bone_height`` itself.

    >>> lying = np.array([[0.0, 0, 0], [170.0, 10, 15]])   # 170 cm along X, 10 along Y
    >>> guess_units(lying).unit
    'unknown'
    >>> guess = guess_units(lying, bone_height=165.0)
    >>> guess.unit, guess.height, guess.basis
    ('cm', 165.0, 'bone lengths')
    """
    pts = np.asarray(rest_points, dtype=np.float64).reshape(-1, 3)
    if pts.shape[0] == 0:
        return UnitsGuess("unknown", 0.0, "Y", 1.0)
    height, up = _extent(pts.max(axis=0) - pts.min(axis=0))
    if bone_height is None or _agrees(height, bone_height):
        return units_for_height(height, "XYZ"[up])
    axis = "Y"
    if frames is not None and np.asarray(frames).size:
        f = np.asarray(frames, dtype=np.float64)
        moving, moving_up = _extent(np.median(f.max(axis=1) - f.min(axis=1), axis=0))
        axis = "XYZ"[moving_up]
        if _agrees(moving, bone_height):
            return units_for_height(moving, axis, "motion")
    return units_for_height(float(bone_height), axis, "bone lengths")


def _agrees(measured: float, bone_height: float) -> bool:
    return measured > 0 and bone_height > 0 and max(measured / bone_height, bone_height / measured) <= HEIGHT_AGREEMENT
