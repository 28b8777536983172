"""A skeleton's height from its bone lengths, and how long its arm bones may be against it.

Arm bone thresholds (fractions of the skeleton's height from its bone lengths, which is within about 30 % of
the true height for the rigs seen: upper arms measure 0.15-0.19 and forearms 0.12-0.16 of a standing height):
:data:`ARM_BONE_RANGE` (6-40 %) is what the structure fallback (:mod:`~retarget.bvh.structure`) accepts and,
outside it, a warning for a chain found otherwise; :data:`ARM_BONE_LIMITS` (2-75 %) is where a chain is an error
(collapsed position channels, the wrong joints).
"""

from __future__ import annotations

from collections.abc import Sequence
from os import PathLike

import numpy as np

from retarget.bvh.chains import ArmJoints
from retarget.errors import BvhError

#: An upper arm or forearm of 6-40 % of the skeleton's height is plausible: the structure fallback takes no
#: other, and a chain found by names or named explicitly outside it gets a warning.
ARM_BONE_RANGE: tuple[float, float] = (0.06, 0.40)
#: An upper arm or forearm under 2 % or over 75 % of the skeleton's height is an error.
ARM_BONE_LIMITS: tuple[float, float] = (0.02, 0.75)
#: The structure fallback's upper arm / forearm ratio (humans: about 1.0-1.45 joint to joint).
ARM_RATIO_RANGE: tuple[float, float] = (0.4, 2.5)
#: The longest path through a human skeleton (a toe to the other hand's fingertip) is about 1.4 heights.
DIAMETER_PER_HEIGHT = 1.4


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
        f"{s} > {e} {upper:.3g} units ({percent(upper, height)}) and {e} > {w} {fore:.3g} units "
        f"({percent(fore, height)}), measured {measured}"
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


def percent(part: float, whole: float) -> str:
    """``part`` as a percentage of ``whole`` for a message (``"17 %"``; ``"? %"`` when ``whole`` is not positive)."""
    return f"{100 * part / whole:.2g} %" if whole > 0 else "? %"
