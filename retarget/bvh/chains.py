"""What arm detection returns: :class:`ArmJoints` (a chain found), :class:`Rejected` (a candidate not chosen, and
why) and :class:`ArmSearch` (one side's outcome, with or without a chain).

Plain data, shared by the detection by names (:mod:`~retarget.bvh.names`), by structure
(:mod:`~retarget.bvh.structure`) and the entry points in :mod:`~retarget.bvh.skeleton`.
"""

from __future__ import annotations

from dataclasses import dataclass, field


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
    message of the :class:`~retarget.errors.BvhError` that
    :func:`~retarget.bvh.skeleton.find_arm` raises when ``found`` is None
    (empty otherwise).
    """

    side: str
    found: ArmJoints | None
    rejected: tuple[Rejected, ...] = ()
    detail: str = ""
    error: str = ""
