"""What the tick loop asks each tick, and of whom: :class:`TargetSource`, its answer, and :class:`TickSolver`.

A source answers ``target_at(tick, t)`` with one :data:`TickGoal`:

- a :class:`TickTarget` ``(position (3,) m, rotation (3, 3) | None, clamped)``: the loop solves IK for it;
- a :class:`JointGoal` ``(q (n_joints,) rad, target (3,) m, max_step, ik, clamped)``: a pose in joint space, no
  IK in the tick (``ik``: the solution it was planned from ahead of the run, reported as the tick's);
- :data:`HOLD` (``None``): keep the commanded pose, no IK (0 sweeps).

Sources inherit :class:`TargetSource` and get its defaults for the optional hooks.  :func:`as_target_source`
lets a duck-typed source (one written to the protocol's shape without inheriting it, as older tests do)
into the loop by filling in those defaults once, before the first tick.

Positions are metres in the arm's base frame, joint angles radians in ``Arm.joint_names`` order.
"""

from __future__ import annotations

from typing import Any, Final, NamedTuple, Protocol, TypeAlias, runtime_checkable

import numpy as np
import numpy.typing as npt

from retarget.ik.ccd import IKResult

__all__ = ["HOLD", "JointGoal", "TargetSource", "TickGoal", "TickSolver", "TickTarget", "as_target_source"]


class TickTarget(NamedTuple):
    """A tick's goal as a point for the tool (a :class:`TargetSource` may return it): the loop solves IK for it.

    >>> TickTarget(np.array([0.3, 0.0, 0.2]), None).clamped
    False
    """

    position: npt.NDArray[np.float64]  #: ``(3,)`` metres, base frame
    rotation: npt.NDArray[np.float64] | None = None  #: ``(3, 3)`` the tool frame's orientation, or None: any
    clamped: bool = False  #: the source pulled the point into the workspace


class JointGoal(NamedTuple):
    """A tick's goal as a pose in joint space (a :class:`TargetSource` may return it): the tick runs no IK."""

    q: npt.NDArray[np.float64]  #: ``(n_joints,)`` rad, the pose to move toward (step-limited and clamped like IK's)
    target: npt.NDArray[np.float64]  #: ``(3,)`` metres, base frame: what the tick reports as its target
    #: ``(n_joints,)`` rad, a tighter per-tick step limit than ``velocity_scale x max_velocity / rate`` for this
    #: tick (a lead-in's own speed, kept after an overrun too); None: the loop's
    max_step: tuple[float, ...] | None = None
    #: the IK solution this pose was planned from, ahead of the run (a clip's look-ahead plan,
    #: :mod:`~retarget.control.plan`): the tick reports its error, sweeps, converged and blocked as its own;
    #: None: no IK (0 sweeps, converged)
    ik: IKResult | None = None
    clamped: bool = False  #: the target was pulled into the workspace


HOLD: Final = None  #: a tick's goal when there is nothing to steer toward: keep the commanded pose, run no IK

#: What :meth:`TargetSource.target_at` returns: a point (IK), a pose in joint space (no IK), or :data:`HOLD`.
TickGoal: TypeAlias = TickTarget | JointGoal | None


@runtime_checkable
class TargetSource(Protocol):
    """Where each tick's goal comes from: a clip (``ClipSource``) or a live stream (``retarget.teleop``).

    Required: ``target_at(tick, t)`` gets the slot index and its time since the run's start (loop clock, s)
    and returns the tick's :data:`TickGoal`; ``finished(tick)`` ends the run before slot ``tick``.

    Optional, with defaults here (inherit this class to get them):

    - ``start(q_start)`` is called once with the start pose ``(n_joints,)`` rad before the first tick and
      returns the first slot: ``-n`` runs ``n`` lead-in slots ``-n .. -1`` before the run's clock starts
      (counted apart, see ``TickStats``); default 0;
    - ``observe(tick, q_cmd, q_present)`` after each tick: the goals sent and the positions read back (None
      in a dry run).  The loop calls it only when the class says ``observes = True``; such a source must see
      tick ``k`` before choosing tick ``k + 1``, so it cannot run with the pipelined read-back;
    - ``clip_time(tick, t)``: the tick's clip seconds for its record; default ``t``, the slot's time.
    """

    observes: bool = False  #: True when :meth:`observe` does something (the loop then calls it)

    def target_at(self, tick: int, t: float) -> TickGoal: ...

    def finished(self, tick: int) -> bool: ...

    def start(self, q_start: npt.NDArray[np.float64]) -> int:
        return 0

    def observe(self, tick: int, q_cmd: npt.NDArray[np.float64], q_present: npt.NDArray[np.float64] | None) -> None:
        return None

    def clip_time(self, tick: int, t: float) -> float:
        return t


class TickSolver(Protocol):
    """The IK the loop calls each tick a source gives a :class:`TickTarget` (``retarget.ik.CCDSolver`` is one).

    ``solve(target (3,) m, q0 (n_joints,) rad, rotation (3, 3) | None)`` returns an
    :class:`~retarget.ik.IKResult` whose ``q`` is inside the joint limits.
    """

    def solve(
        self,
        target: npt.NDArray[np.float64],
        q0: npt.NDArray[np.float64],
        rotation: npt.NDArray[np.float64] | None = None,
    ) -> IKResult: ...


def as_target_source(source: object) -> TargetSource:
    """``source`` when it has every member of :class:`TargetSource` (normally: it inherits it); else a wrapper
    that gives it the protocol's defaults for the hooks it lacks (it observes when it has an ``observe``).

    A source that overrides ``observe`` must say ``observes = True``, else the loop would never call it: checked
    here, once per run.
    """
    if isinstance(source, TargetSource):
        if type(source).observe is not TargetSource.observe and not source.observes:
            raise TypeError(f"{type(source).__name__} overrides observe() but does not say observes = True")
        return source
    return _DuckSource(source)


class _DuckSource(TargetSource):
    """A source that has ``target_at`` and ``finished`` (and maybe ``start``, ``observe``, ``clip_time``) without
    inheriting :class:`TargetSource`: the hooks it lacks are the protocol's defaults."""

    def __init__(self, source: Any):
        self.source = source
        self._start = getattr(source, "start", None)
        self._observe = getattr(source, "observe", None)
        self._clip_time = getattr(source, "clip_time", None)
        self.observes = self._observe is not None

    def target_at(self, tick: int, t: float) -> TickGoal:
        goal: TickGoal = self.source.target_at(tick, t)
        return goal

    def finished(self, tick: int) -> bool:
        return bool(self.source.finished(tick))

    def start(self, q_start: npt.NDArray[np.float64]) -> int:
        first = self._start(q_start) if self._start is not None else 0
        return int(first or 0)

    def observe(self, tick: int, q_cmd: npt.NDArray[np.float64], q_present: npt.NDArray[np.float64] | None) -> None:
        if self._observe is not None:
            self._observe(tick, q_cmd, q_present)

    def clip_time(self, tick: int, t: float) -> float:
        return float(self._clip_time(tick)) if self._clip_time is not None else t
