"""How well the arm follows: the tracking error and the commanded trajectory's acceleration and jerk.

* **Tracking error**: the distance from the *mapped* target (unfiltered, clamped into the workspace:
  :meth:`~retarget.mapping.Targets.reference`; in teleop the target as it came in) to the commanded tool point,
  FK of the goals sent, ``q_cmd``.  It is kept apart from the IK residual (the solution to the target the loop
  solved for, after the filter, the speed and acceleration limits), and from the **filter's deviation**: the
  distance from the mapped target to the target the loop steered to.
* **Acceleration and jerk** of the commanded joint trajectory, by finite differences of ``q_cmd`` at the slots'
  times (rad/s^2, rad/s^3), per joint and over all joints.

A :class:`Trajectory` collects a run's ticks from its :class:`~retarget.control.loop.TickRecord` s (an
``on_tick`` callback, a few list appends per tick); :func:`following` measures them afterwards, the FK of every
tick in one batch (:meth:`~retarget.arm.kinematics.Chain.fk_batch`).  :class:`TickTracker` gives one tick's
figures for the telemetry row.

Arrays: joint angles ``(n_ticks, n_joints)`` radians; points ``(n_ticks, 3)`` metres, the arm's base frame.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Protocol, TypeVar

import numpy as np
import numpy.typing as npt

from retarget.arm.model import Arm

__all__ = ["AT_LIMIT", "Following", "TickTracker", "Trajectory", "at_velocity_limit", "following"]

Array = npt.NDArray[np.float64]


class TickRecord(Protocol):
    """What this module reads of a :class:`retarget.control.loop.TickRecord` (a protocol: the loop's stats import
    the summary, which imports this module, so it cannot import the loop)."""

    @property
    def tick(self) -> int: ...
    @property
    def clip_time(self) -> float: ...
    @property
    def target(self) -> Array: ...
    @property
    def q_cmd(self) -> Array: ...
    @property
    def lead_in(self) -> bool: ...


#: the unfiltered mapped targets ``(n, 3)`` m at clip times ``(n,)`` s (``Targets.reference``)
Reference = Callable[[Array], Array]


@dataclass(frozen=True)
class Following:
    """The figures of :func:`following`: millimetres, rad/s^2 and rad/s^3 (peaks are absolute values)."""

    tracking_median_mm: float  #: mapped target (unfiltered) to the commanded tool point
    tracking_p95_mm: float
    tracking_max_mm: float
    filter_p95_mm: float  #: mapped target to the target the loop steered to (filtered, clamped)
    filter_max_mm: float
    accel_peak: float  #: rad/s^2, over every joint and tick
    accel_rms: float  #: rad/s^2, root mean square over every joint and tick
    jerk_peak: float  #: rad/s^3
    jerk_rms: float  #: rad/s^3
    accel_peak_by_joint: dict[str, float]  #: rad/s^2, each joint's peak
    jerk_peak_by_joint: dict[str, float]  #: rad/s^3


R = TypeVar("R", bound=TickRecord)  #: the loop's own record type, passed through :meth:`Trajectory.chain`


class Trajectory:
    """The ticks of a run (lead-in ticks left out), collected from their records: ``on_tick`` itself, or
    :meth:`chain` in front of another callback.  ``reference(record)`` (optional): the tick's unfiltered target
    ``(3,)`` m, recorded as it goes (a live source knows it only then); else :func:`following` looks it up by
    clip time."""

    def __init__(self, reference: Callable[[TickRecord], Array | None] | None = None):
        self.slots: list[int] = []
        self.clip_times: list[float] = []
        self.targets: list[Array] = []
        self.q_cmd: list[Array] = []
        self.references: list[Array | None] = []
        self._reference = reference

    def __call__(self, record: TickRecord) -> None:
        if record.lead_in:
            return
        self.slots.append(record.tick)
        self.clip_times.append(record.clip_time)
        self.targets.append(record.target)
        self.q_cmd.append(record.q_cmd)
        if self._reference is not None:
            self.references.append(self._reference(record))

    def chain(self, on_tick: Callable[[R], None] | None) -> Callable[[R], None]:
        """A callback that records the tick here, then calls ``on_tick`` (if any)."""
        if on_tick is None:
            return self

        def both(record: R) -> None:
            self(record)
            on_tick(record)

        return both

    def __len__(self) -> int:
        return len(self.slots)


#: A joint commanded at this fraction of its max velocity or more is at its velocity limit.
AT_LIMIT = 0.999


def at_velocity_limit(q_cmd: npt.ArrayLike, *, rate: float, max_velocity: npt.ArrayLike) -> npt.NDArray[np.bool_]:
    """Per tick of the commanded joints ``q_cmd`` ``(n, n_joints)`` rad at ``rate`` ticks/s: some joint moved at
    :data:`AT_LIMIT` of its ``max_velocity`` ``(n_joints,)`` rad/s or more since the tick before (the first tick:
    False); ``(n,)`` bool.  Unlike the loop's limiter flag, a path planned ahead that runs at full speed counts.

    >>> at_velocity_limit([[0.0, 0.0], [0.01, 0.02], [0.02, 0.03]], rate=100.0, max_velocity=[1.0, 2.0]).tolist()
    [False, True, True]
    """
    q = np.asarray(q_cmd, dtype=np.float64)
    flags = np.zeros(len(q), dtype=bool)
    if len(q) > 1:
        speeds = np.abs(np.diff(q, axis=0)) * rate
        flags[1:] = np.any(speeds >= AT_LIMIT * np.asarray(max_velocity, dtype=np.float64), axis=1)
    return flags


def following(arm: Arm, trajectory: Trajectory, *, rate: float, reference: Reference | None = None) -> Following | None:
    """The run's :class:`Following`, or None without ticks.  ``rate``: ticks per second (slot ``k`` is at
    ``k / rate`` s); ``reference``: the unfiltered targets by clip time, when the trajectory has none of its own
    (default: the targets the loop steered to, so the filter's deviation is 0).

    >>> import retarget
    >>> arm = retarget.load_arm("wx250s")
    >>> trajectory = Trajectory()
    >>> T = arm.fk(arm.home)[0]
    >>> for k in range(4):  # the waist stepping 1, 2, 3 mrad per tick: 10 rad/s^2 at 100 Hz, no jerk...
    ...     trajectory.slots.append(k); trajectory.clip_times.append(k / 100)
    ...     trajectory.q_cmd.append(arm.home + [0.0005 * k * (k + 1), 0, 0, 0, 0, 0])
    ...     trajectory.targets.append(T[:3, 3])
    >>> f = following(arm, trajectory, rate=100.0)
    >>> round(f.accel_peak, 6), round(f.jerk_peak, 6), round(f.tracking_max_mm, 1)  # ...the tool 2.7 mm off at last
    (10.0, 0.0, 2.7)
    """
    n = len(trajectory)
    if n == 0:
        return None
    q = np.asarray(trajectory.q_cmd, dtype=np.float64)
    steered = np.asarray(trajectory.targets, dtype=np.float64)
    mapped = _references(trajectory, steered, reference)
    tool = arm.chain.tool_points(q)
    tracking = np.linalg.norm(tool - mapped, axis=1) * 1e3
    deviation = np.linalg.norm(steered - mapped, axis=1) * 1e3
    ok = np.isfinite(tracking)  # a tick without a target (a live run before the first) has no figure
    accel, jerk = derivatives(q, np.asarray(trajectory.slots, dtype=np.float64) / rate)
    names = arm.joint_names
    return Following(
        tracking_median_mm=_pct(tracking[ok], 50),
        tracking_p95_mm=_pct(tracking[ok], 95),
        tracking_max_mm=_max(tracking[ok]),
        filter_p95_mm=_pct(deviation[ok], 95),
        filter_max_mm=_max(deviation[ok]),
        accel_peak=_max(np.abs(accel)),
        accel_rms=_rms(accel),
        jerk_peak=_max(np.abs(jerk)),
        jerk_rms=_rms(jerk),
        accel_peak_by_joint=_by_joint(names, accel),
        jerk_peak_by_joint=_by_joint(names, jerk),
    )


def derivatives(q: Array, times: Array) -> tuple[Array, Array]:
    """Acceleration ``(n - 2, n_joints)`` rad/s^2 and jerk ``(n - 3, n_joints)`` rad/s^3 of joint angles ``q``
    ``(n, n_joints)`` rad at ``times`` ``(n,)`` s, by finite differences (uneven steps allowed: after an overrun
    the loop skips slots)."""
    velocity = np.diff(q, axis=0) / np.diff(times)[:, None]
    mid = 0.5 * (times[1:] + times[:-1])  # each velocity's time
    accel = np.diff(velocity, axis=0) / np.diff(mid)[:, None]
    jerk = np.diff(accel, axis=0) / np.diff(0.5 * (mid[1:] + mid[:-1]))[:, None]
    return accel, jerk


def _references(trajectory: Trajectory, steered: Array, reference: Reference | None) -> Array:
    if trajectory.references:
        nan = np.full(3, math.nan)
        return np.array([nan if r is None else r for r in trajectory.references], dtype=np.float64)
    if reference is None:
        return steered
    return np.asarray(reference(np.asarray(trajectory.clip_times, dtype=np.float64)), dtype=np.float64)


class TickTracker:
    """One tick's ``(tracking, filter deviation)`` in metres for a telemetry row (nan without a reference): the
    FK of the record's ``q_cmd`` (one pose, per tick) against ``reference(record)`` ``(3,)`` m, the unfiltered
    mapped target (None: none; default the record's own target)."""

    def __init__(self, arm: Arm, reference: Callable[[TickRecord], Array | None] | None = None):
        self.arm = arm
        self.reference = reference

    @classmethod
    def for_clip(cls, arm: Arm, reference: Reference) -> TickTracker:
        """For a clip: ``reference`` gives the unfiltered targets by clip time (``Targets.reference``)."""

        def at(record: TickRecord) -> Array | None:
            return None if record.lead_in else reference(np.array([record.clip_time]))[0]

        return cls(arm, at)

    def __call__(self, record: TickRecord) -> tuple[float, float]:
        mapped = record.target if self.reference is None else self.reference(record)
        if mapped is None or not np.all(np.isfinite(mapped)):
            return math.nan, math.nan
        tool = self.arm.fk(record.q_cmd)[0][:3, 3]
        return float(np.linalg.norm(tool - mapped)), float(np.linalg.norm(record.target - mapped))


def _pct(values: Array, q: float) -> float:
    return float(np.percentile(values, q)) if values.size else 0.0


def _max(values: Array) -> float:
    return float(values.max()) if values.size else 0.0


def _rms(values: Array) -> float:
    return float(np.sqrt(np.mean(values**2))) if values.size else 0.0


def _by_joint(names: Sequence[str], values: Array) -> dict[str, float]:
    peaks = np.abs(values).max(axis=0) if len(values) else np.zeros(len(names))
    return {name: float(v) for name, v in zip(names, peaks, strict=True)}
