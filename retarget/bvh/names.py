"""Joint names: the naming tables, a name's side and role, and the arm chain found by names alone.

Detection by names covers the conventions seen in the wild:

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

The words that make a limb a leg, a finger or a head bone (:func:`not_arm_kind`) and twist bones
(:func:`is_twist`) serve the structure fallback (:mod:`~retarget.bvh.structure`).
"""

from __future__ import annotations

import re
from collections.abc import Sequence

import numpy as np

import retarget.bvh.tree as tree
from retarget.bvh.chains import ArmJoints, ArmSearch, Rejected

SIDES: tuple[str, str] = ("left", "right")
END_SITE_SUFFIX = "/End Site"

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
_DIGITS = "0123456789"


def _trailing_number(text: str) -> tuple[str, str]:
    """``text`` split before its trailing ASCII digits: ``("hand", "01")`` for ``"hand01"``.  Linear, unlike
    ``re.search(r"[0-9]+$")``, which retries from every digit of a long run (quadratic); never ``int()``."""
    stem = text.rstrip(_DIGITS)
    return stem, text[len(stem) :]


_TOKENS = re.compile(r"[A-Z]?[a-z]+|[A-Z]+(?![a-z])")

#: A wrist candidate below a forearm: ``(penalty, links, index, is an End Site, name)``.
_Wrist = tuple[int, int, int, bool, str]


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
        if low[start : start + 1] in ("l", "r") and role_of(low[start + 1 :])[0] is not None:
            return ("left" if low[start] == "l" else "right"), base[:start] + " " + base[start + 1 :]
    return None, base


def squash(rest: str) -> str:
    """Lower case, letters and digits only (``"_Fore Arm.01"`` -> ``"forearm01"``)."""
    return re.sub(r"[^a-z0-9]", "", rest.lower())


def role_of(rest: str) -> tuple[str | None, int]:
    """Role (``upper``, ``fore``, ``hand``, ``clavicle``, ``shoulder``) of a side-less name and its penalty.

    Penalty 0 for no number or ``01``, 1 for another number 1 (``.001``);
    twist segments numbered 2 and up, and twist or roll bones, have no role.
    """
    text = squash(rest)
    penalty = 0
    stem, digits = _trailing_number(text)
    if digits:
        if digits.lstrip("0") not in ("", "1"):  # the number is 2 or more (compared without int(): any length)
            return None, 0
        penalty = 0 if digits == "01" else 1
        text = stem
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
        role, penalty = role_of(rest)
        out.append((side, role, penalty))
    return out


def is_twist(name: str) -> bool:
    """A twist or roll bone by its name (``lShldrTwist``, ``LeftForeArmRoll``, ``upperarm_twist_01_l``)."""
    text = _trailing_number(squash(base_name(name)))[0]
    return "twist" in text or text.endswith("roll")


def not_arm_kind(name: str) -> str | None:
    """``"leg"``, ``"finger"`` or ``"head"`` when the name says so, else None."""
    base = base_name(name)
    tokens = [t.lower() for t in _TOKENS.findall(base)]
    tokens += [t[1:] for t in tokens if len(t) > 2 and t[0] in "lr"]
    text = _trailing_number(squash(base))[0]
    for kind, words in _NOT_ARM:
        if any(t in words for t in tokens) or any(text.endswith(w) for w in words):
            return kind
    return None


# ------------------------------------------------------------------------------------------ detection by names


def search_by_names(
    side: str, joint_names: Sequence[str], parents: np.ndarray, end_site_parents: Sequence[int]
) -> ArmSearch | None:
    """The ``side`` arm by joint names alone: found, or tied (``found`` None, with ``error``); None if none is named."""
    candidates, skipped = name_chains(side, joint_names, parents, end_site_parents)
    if not candidates:
        return None
    best = candidates[0][0]
    tied = [c for rank, c in candidates if rank == best]
    if len(tied) > 1:
        listed = "; ".join(" > ".join(c.names) for c in tied)
        error = f"Expected one {side} arm chain, found {len(tied)} equally good: {listed}; name the joints explicitly"
        rejected = tuple(Rejected(c.names, "tied") for c in tied)
        return ArmSearch(side, None, rejected, f"{len(tied)} chains named equally well", error)
    chain = tied[0]
    rejected_list = [Rejected(c.names, _rank_reason(rank, best, chain)) for rank, c in candidates[1:]]
    detail = f"joint names: {chain.names[0]} is an upper arm, {chain.names[1]} a forearm, {chain.names[2]} the wrist"
    found = ArmJoints(
        side, chain.names, chain.indices, chain.wrist_is_end_site, "names", tuple(rejected_list + skipped), detail
    )
    return ArmSearch(side, found, found.rejected, detail)


def name_chains(
    side: str, joint_names: Sequence[str], parents: np.ndarray, end_site_parents: Sequence[int]
) -> tuple[list[tuple[tuple[int, int], ArmJoints]], list[Rejected]]:
    """Name-based chains, best first with their ranks, and the triples skipped (a clavicle called shoulder)."""
    roles = joint_roles(joint_names)
    children = tree.children(parents)
    sided = [j for j in range(len(joint_names)) if roles[j][0] == side]
    uppers = [j for j in sided if roles[j][1] in ("upper", "shoulder")]
    fores = [j for j in sided if roles[j][1] == "fore"]
    hands = [j for j in sided if roles[j][1] == "hand"]
    out: list[tuple[tuple[int, int], ArmJoints]] = []
    skipped: list[Rejected] = []
    for u in uppers:
        for f in fores:
            d1 = tree.depth_below(parents, f, u, 3)
            if not d1:
                continue
            # "LeftShoulder" is the clavicle when an upper-arm-named joint sits between it and the elbow
            between = [k for k in tree.path_between(parents, f, u) if roles[k][1] == "upper"]
            if roles[u][1] == "shoulder" and between:
                reason = (
                    f"{joint_names[u]} is the clavicle here: {joint_names[between[-1]]} lies between it and the elbow"
                )
                skipped.append(Rejected((joint_names[u], joint_names[f]), reason))
                continue
            for wp, d2, w, is_site, wname in _wrists(f, hands, roles, joint_names, parents, children, end_site_parents):
                rank = (roles[u][2] + roles[f][2] + wp, d1 + d2)
                chain = ArmJoints(side, (joint_names[u], joint_names[f], wname), (u, f, w), is_site, "names")
                out.append((rank, chain))
    out.sort(key=lambda rc: rc[0])
    return out, skipped


def _wrists(
    f: int,
    hands: list[int],
    roles: list[tuple[str | None, str | None, int]],
    joint_names: Sequence[str],
    parents: np.ndarray,
    children: list[list[int]],
    end_site_parents: Sequence[int],
) -> list[_Wrist]:
    """The wrist candidates below the forearm ``f``: hand-named joints within 3 links, else its first End Site,
    else its only child (penalised as an unnamed wrist)."""
    wrists: list[_Wrist] = []
    for h in hands:
        d2 = tree.depth_below(parents, h, f, 3)
        if d2:
            wrists.append((roles[h][2], d2, h, False, joint_names[h]))
    if not wrists:
        sites = [k for k, p in enumerate(end_site_parents) if p == f]
        if sites:
            wrists.append((0, 1, sites[0], True, joint_names[f] + END_SITE_SUFFIX))
        elif len(children[f]) == 1:
            c = children[f][0]
            wrists.append((1, 1, c, False, joint_names[c]))
    return wrists


def _rank_reason(rank: tuple[int, int], best: tuple[int, int], chosen: ArmJoints) -> str:
    if rank[0] > best[0]:
        return f"ranked below {' > '.join(chosen.names)}: a numbered segment or an unnamed wrist"
    return f"ranked below {' > '.join(chosen.names)}: {rank[1]} links instead of {best[1]}"


def name_hint(side: str, joint_names: Sequence[str]) -> str:
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
