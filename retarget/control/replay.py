"""Clip replay: :class:`ControlLoop` plays retargeted motion on a bus (or dry) at a fixed rate.

It runs the tick loop of :mod:`retarget.control.loop` (target, IK, step limit, one write, read-back; the
read-back pipelined with the next tick's compute on a bus) on a :class:`ClipSource`, the
:class:`~retarget.control.source.TargetSource` that answers each clip slot with a
:class:`~retarget.control.source.TickTarget` and each lead-in slot with a :class:`JointGoal`.  Tick ``k`` plays
clip time ``start + k * speed / rate``, wrapped into ``[start, end)`` with ``loop``; the clip's frames are
resampled to ticks by linear interpolation and pulled into the workspace, a block of slots at a time.

**Lead-in.**  On a bus, :meth:`ControlLoop.run` first moves the arm from its
present pose to the clip's first pose (:meth:`ControlLoop.initial_pose`, the IK
solution of the first target) along a straight line in joint space with a
raised-cosine time profile (at rest at both ends, synchronised so all joints
arrive together), at a peak speed of ``lead_in_speed`` rad/s per joint (capped
by ``velocity_scale x max_velocity``); after an overrun too, each lead-in tick
steps at most that speed's one slot (:attr:`JointGoal.max_step`): the arm lags
the plan and catches up as it slows down, never faster.  Its ticks are slots ``-n .. -1`` of the
same tick loop, before the clip's clock starts (their ``time`` is negative,
``TickRecord.lead_in`` is set, ``clip_time`` is the clip's start), so the clip
still starts at slot 0 with the same bus calls, limits and velocity limiting.
Its ticks are counted apart (:mod:`~retarget.control.stats`): the summary's ticks, IK stats, tick times,
overruns and real-time factor are the clip's; ``lead_in_ticks`` and
``lead_in_s`` report the lead-in; ``max_ticks`` counts clip ticks, and bounds the lead-in too: a lead-in
planned longer than ``max_ticks`` slots runs only its first ``max_ticks`` (with a warning), and the clip's
ticks then carry on from there under the velocity limit, so a run never takes more than ``2 x max_ticks``
ticks (``--velocity-scale 0.01 --max-ticks 5`` ends).  A dry run
has no lead-in (no arm to move): start it from ``initial_pose()`` to get the
trajectory the clip part of a bus run commands.

Ctrl-C: :meth:`ControlLoop.stop` (signal-safe) ends the run at the next tick
boundary, and a ``KeyboardInterrupt`` raised inside a tick (e.g. by a
telemetry callback) ends it too; either way the summary says ``interrupted``.
:func:`run_on_bus` connects the bus and always closes it, so the bus's own
shutdown sequence (hold, rest or torque off) runs.

**Look-ahead.**  A clip is known before it plays, so by default (``look_ahead=True``, ``--no-look-ahead`` to
turn it off) :meth:`ControlLoop.plan` first solves IK for every tick of the window (the loop's own solver and
collision guard, each tick warm-started from the last solution), then plans that joint path within the
velocity, acceleration and joint limits looking ahead (:func:`~retarget.control.plan.plan_path`: the causal
limiter's lag, balanced by a lead), and the ticks play the plan as :class:`JointGoal` s that carry their IK
solution (the summary's IK figures stay the IK's).  The loop's limiter and collision check still run on every
tick, as the last line of defence; a plan is feasible, so the limiter passes it unchanged.  On a bus the plan is
made before the lead-in (the CLI calls :meth:`~ControlLoop.plan` before torque goes on), starting from the
clip's first pose; a dry run plans from its start pose.  It plays one pass of the window at ``speed`` (the
ticks actually played, ``max_ticks`` included); a ``loop`` run wraps, and plays causally instead (IK in each
tick).  Its cost, the IK and a few passes of the profile before the first tick, counts in the summary's wall
time and real-time factor.

The tick loop's names (:class:`LoopConfig`, :class:`TickRecord`, :func:`run_ticks`, ...) are importable
from here too.
"""

from __future__ import annotations

import logging
import math
import threading
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
import numpy.typing as npt

from retarget.arm.model import Arm
from retarget.control.bus import Bus, connected
from retarget.control.clock import Clock, MonotonicClock
from retarget.control.loop import LoopConfig, Plant, TickRecord, run_ticks
from retarget.control.plan import PathPlan, solve_and_plan
from retarget.control.safety import Route, RouteModel, require_route
from retarget.control.source import JointGoal, TargetSource, TickGoal, TickSolver, TickTarget
from retarget.control.stats import TickStats
from retarget.control.summary import RunSummary
from retarget.control.tracking import Trajectory, following
from retarget.errors import BusError, ConfigError
from retarget.ik.ccd import CCDSolver
from retarget.mapping.targets import Targets
from retarget.mapping.workspace import ik_weights

__all__ = [
    "ClipSlots",
    "ClipSource",
    "ControlLoop",
    "JointGoal",
    "LeadIn",
    "LoopConfig",
    "TargetSource",
    "TickRecord",
    "TickStats",
    "TickTarget",
    "run_on_bus",
    "run_ticks",
]

log = logging.getLogger(__name__)

_BLOCK = 256  #: targets are resampled this many slots at a time


class ControlLoop:
    """Plays :class:`~retarget.mapping.Targets` on ``arm`` at a fixed rate.  See the module docstring.

    ``targets``: the clip's tool targets (``(n_frames, 3)`` metres, base frame, and optional rotations);
    ``config``: rate, window, speed and limits (default :class:`LoopConfig`); ``clock``: the loop's clock
    (default real time, :class:`~retarget.control.clock.MonotonicClock`).  ``solver`` defaults to a
    :class:`~retarget.ik.CCDSolver` with the config's budget and tolerance, the mapping's per-joint weights
    (and its orientation weight when the targets carry rotations).  ``on_tick(record)`` is called after
    every tick with its :class:`TickRecord`; ``on_progress(record)`` on the first tick, then about once per
    ``config.progress_every`` real seconds (so ``--fast`` runs do not flood the terminal), as read from
    ``progress_time()`` (default ``time.perf_counter``; a test passes a fake one to check the pacing).
    ``clip_name`` labels the summary.  ``pipeline``: overlap each tick's read-back with the next tick's
    compute on a bus (see :mod:`~retarget.control.readback`); False reads back within the tick.  ``look_ahead``:
    play a plan made ahead of the run (see the module docstring; a ``loop`` run plays causally).
    :meth:`run` plays it and returns the :class:`~retarget.control.summary.RunSummary`.

    A dry run (no bus) of a 2 s circle at 100 Hz, on a virtual clock so it takes no real time:

    >>> import retarget
    >>> from retarget.control.clock import VirtualClock
    >>> from retarget.mapping import Targets, Workspace
    >>> arm = retarget.load_arm("wx250s")
    >>> t = np.linspace(0.0, 2.0, 21)  # 21 frames at 10 fps
    >>> circle = np.stack([0.35 + 0 * t, 0.08 * np.sin(np.pi * t), 0.25 + 0.08 * np.cos(np.pi * t)], axis=-1)
    >>> targets = Targets.from_raw(circle, frame_time=0.1, workspace=Workspace.for_arm(arm))
    >>> summary = ControlLoop(arm, targets, clock=VirtualClock()).run(None)
    >>> summary.ticks, summary.run_time_s, summary.ik_converged_pct > 90
    (201, 2.01, True)
    """

    def __init__(
        self,
        arm: Arm,
        targets: Targets,
        *,
        config: LoopConfig | None = None,
        clock: Clock | None = None,
        solver: TickSolver | None = None,
        on_tick: Callable[[TickRecord], None] | None = None,
        on_progress: Callable[[TickRecord], None] | None = None,
        clip_name: str = "",
        progress_time: Callable[[], float] | None = None,
        pipeline: bool = True,
        look_ahead: bool = True,
    ):
        self.arm = arm
        self.pipeline = pipeline
        self.look_ahead = look_ahead
        self._plan: PathPlan | None = None  #: the last plan (:meth:`plan`), kept for a run from the same pose
        self._plan_from: npt.NDArray[np.float64] | None = None
        self.targets = targets
        self.config = config = config or LoopConfig()
        self.clock: Clock = clock if clock is not None else MonotonicClock()
        self._weights = ik_weights(arm, targets.config)
        self.solver: TickSolver = solver if solver is not None else self._ik(config.ik_iterations)
        self.on_tick = on_tick
        self.on_progress = on_progress
        self.progress_time = progress_time
        self.clip_name = clip_name
        self._stop = threading.Event()

        clip_duration = (targets.n_frames - 1) * targets.frame_time
        end = clip_duration if config.end is None else min(config.end, clip_duration)
        if config.start >= end and targets.n_frames > 1:
            raise ConfigError(
                f"Expected a start time before the clip's end ({end:g} s)", key="start", value=config.start
            )
        self.window = (float(config.start), float(end))
        self.step = step = config.speed / config.rate  #: clip seconds per tick
        span = end - config.start
        if config.loop:
            n = max(1, round(span / step))
        else:
            n = int(math.floor(span / step + 1e-9)) + 1
        #: slots of one pass over the window (a looping run wraps slot ``k`` to ``k % n_slots``)
        self.n_slots = n
        self.frames = int(round(span / targets.frame_time)) + 1

    def _ik(self, max_iterations: int) -> CCDSolver:
        """A CCD solver for these targets with a budget of ``max_iterations`` sweeps per solve."""
        arm, tolerance, mapping = self.arm, self.config.ik_tolerance, self.targets.config
        collision = self.config.collision
        if self.targets.rotations is None:
            return CCDSolver(
                arm, max_iterations=max_iterations, tolerance=tolerance, weights=self._weights, collision=collision
            )
        return CCDSolver(
            arm,
            max_iterations=max_iterations,
            tolerance=tolerance,
            weights=self._weights,
            orientation_weight=mapping.orientation_weight,
            collision=collision,
        )

    def clip_time(self, i: int) -> float:
        """Clip seconds of slot ``i`` of a pass (``0 <= i < n_slots``)."""
        return self.config.start + i * self.step

    def sample(
        self, first: int, stop: int
    ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64] | None, npt.NDArray[np.bool_]]:
        """Targets of slots ``first..stop-1`` of a pass: positions ``(n, 3)`` m, rotations ``(n, 3, 3)`` or None,
        clamped ``(n,)``."""
        return self.targets.sample(self.config.start + np.arange(first, stop) * self.step)

    @property
    def n_ticks(self) -> int | None:
        """The most ticks the run will take (None: a loop without ``max_ticks`` runs until stopped)."""
        n = None if self.config.loop else self.n_slots
        if self.config.max_ticks is not None:
            n = self.config.max_ticks if n is None else min(n, self.config.max_ticks)
        return n

    def stop(self) -> None:
        """Ask the run to end at the next tick boundary (safe from a signal handler or another thread)."""
        self._stop.set()

    def initial_pose(self, *, iterations: int = 200) -> npt.NDArray[np.float64]:
        """The IK solution of the first target, solved cold from home with a large budget: ``(n_joints,)`` rad."""
        solver = self._ik(iterations)
        positions, rotations, _ = self.sample(0, 1)
        rotation = None if rotations is None else rotations[0]
        return np.array(solver.solve(positions[0], self.arm.home, rotation).q, dtype=np.float64)

    def plan(self, q_start: npt.NDArray[np.float64] | None = None) -> PathPlan | None:
        """The look-ahead plan of the ticks a run plays (see the module docstring), from ``q_start`` ``(n_joints,)``
        rad at rest (default :meth:`initial_pose`), made once per start pose; None when the loop plays causally
        (``look_ahead`` off, or a ``loop`` run)."""
        if not self.look_ahead or self.config.loop:
            return None
        q0 = self.initial_pose() if q_start is None else np.asarray(q_start, dtype=np.float64)
        if q0.shape != (self.arm.n_joints,):  # the loop's own message (run_ticks checks it too)
            raise ValueError(f"Expected a start pose of shape ({self.arm.n_joints},), got {q0.shape}")
        q0 = np.clip(q0, self.arm.lower, self.arm.upper)
        if self._plan is not None and self._plan_from is not None and np.array_equal(q0, self._plan_from):
            return self._plan
        n, cfg, arm = self.n_ticks or self.n_slots, self.config, self.arm
        positions, rotations, clamped = self.sample(0, n)
        self._plan = solve_and_plan(
            self.solver,
            positions,
            rotations,
            clamped,
            q0,
            lower=arm.lower,
            upper=arm.upper,
            max_step=arm.max_velocity * cfg.velocity_scale / cfg.rate,
            max_accel=arm.max_acceleration / cfg.rate**2,
            chain=arm.chain,
            jerk_cost=cfg.jerk_cost,
        )
        self._plan_from = q0
        log.info("look-ahead: %d ticks solved and planned in %.3f s", n, self._plan.seconds)
        return self._plan

    def run(
        self, bus: Bus | None = None, *, q_start: npt.NDArray[np.float64] | None = None, lead_in: bool | None = None
    ) -> RunSummary:
        """Run the loop on a connected ``bus`` (``None``: dry run) and return the summary.

        The start pose ``(n_joints,)`` rad is the bus's present positions, else ``q_start``, else the
        arm's rest pose.  ``lead_in``: first move from the start pose to
        :meth:`initial_pose` (see the module docstring; nothing when
        ``config.lead_in_speed`` is 0); default on a bus only, True previews it in
        a dry run.  With ``look_ahead`` the clip's ticks play :meth:`plan`, from the lead-in's end, else (a dry
        run) from the start pose.  ``BusError`` propagates (the caller closes the bus).
        """
        if lead_in is None:
            lead_in = bus is not None
        lead_to = self.initial_pose() if lead_in and self.config.lead_in_speed > 0 else None
        if lead_to is not None or bus is not None:
            plan = self.plan(lead_to)
        else:
            plan = self.plan(q_start if q_start is not None else self.arm.rest)
        source = ClipSource(self, lead_in_to=lead_to, plan=plan)
        trajectory = Trajectory()  # the clip's ticks, for the tracking error and the acceleration (tracking.py)
        try:
            ticks = run_ticks(
                self.arm,
                source,
                self.solver,
                config=self.config,
                clock=self.clock,
                bus=bus,
                q_start=q_start,
                on_tick=trajectory.chain(self.on_tick),
                on_progress=self.on_progress,
                progress_time=self.progress_time,
                stop=self._stop,
                pipeline=self.pipeline,
            )
        except BusError as exc:  # the summary of the ticks that ran goes with the error
            if isinstance(exc.stats, TickStats):
                exc.summary = self._summary(exc.stats, trajectory)
            raise
        summary = self._summary(ticks, trajectory)
        if plan is None:
            return summary
        wall = summary.wall_time_s + plan.seconds  # the plan's time is the clip's too, though it ran before
        return replace(summary, wall_time_s=wall, real_time_factor=summary.run_time_s / wall)

    def _summary(self, ticks: TickStats, trajectory: Trajectory | None = None) -> RunSummary:
        """The summary of a run that ended with ``ticks`` (and how it followed the targets: ``trajectory``)."""
        played = (ticks.last_slot + 1) * self.config.speed / self.config.rate if ticks.last_slot >= 0 else 0.0
        measured = None
        if trajectory is not None:
            measured = following(self.arm, trajectory, rate=self.config.rate, reference=self.targets.reference)
        summary = ticks.summary(
            arm=self.arm.name, clip=self.clip_name, frames=self.frames, duration_s=played, following=measured
        )
        if self.config.collision is None or self.targets.pushed is None:
            return summary
        first = int(round(self.window[0] / self.targets.frame_time))
        pushed = int(np.count_nonzero(self.targets.pushed[first : first + self.frames]))
        return replace(summary, pushed_targets=pushed)


@dataclass(frozen=True)
class LeadIn:
    """A joint-space move from ``q_from`` to ``q_to`` ``(n_joints,)`` rad over slots ``-n_slots .. -1``.

    Straight in joint space with a raised-cosine time profile: at slot ``-n_slots - 1 + i`` the pose is
    ``q_from + s_i (q_to - q_from)``, ``s_i = (1 - cos(pi i / n)) / 2``, so it starts and ends at rest, every
    joint arrives together at slot -1, and joint ``j``'s largest step, ``|dq_j| sin(pi / 2n)``, stays within
    ``speed_j / rate``; with ``accel``, its largest change of step, ``|dq_j| (1 - cos(pi / n))``, stays within
    ``accel_j / rate^2`` too (the loop's acceleration limit then never has to cut it).  No slots when a single
    step is already within both.
    """

    q_from: npt.NDArray[np.float64]
    q_to: npt.NDArray[np.float64]
    target: npt.NDArray[
        np.float64
    ]  #: ``(3,)`` metres: the target whose solution ``q_to`` is, reported by the lead-in ticks
    n_slots: int
    #: rad per joint, ``speed / rate``: each goal's step limit in the loop, so a tick after an overrun moves on at
    #: the lead-in's speed (and the lead-in catches up on its slower end) instead of jumping to the planned pose
    max_step: tuple[float, ...] | None = None
    #: the slots of the whole plan when only its first ``n_slots`` run (:meth:`truncated`); None: the whole plan
    planned_slots: int | None = None

    @classmethod
    def plan(
        cls,
        q_from: npt.NDArray[np.float64],
        q_to: npt.NDArray[np.float64],
        *,
        speed: npt.NDArray[np.float64],
        rate: float,
        target: npt.NDArray[np.float64],
        accel: npt.NDArray[np.float64] | None = None,
    ) -> LeadIn:
        """The lead-in at peak joint speeds ``speed`` ``(n_joints,)`` rad/s (> 0), peak accelerations ``accel``
        ``(n_joints,)`` rad/s^2 (> 0; None: no bound) and ``rate`` ticks per second."""
        q_from = np.asarray(q_from, dtype=np.float64)
        q_to = np.asarray(q_to, dtype=np.float64)
        ratio = float(np.max(np.abs(q_to - q_from) / speed)) * rate  # slots the move takes at constant speed
        n = 0 if ratio <= 1.0 else math.ceil(math.pi / (2.0 * math.asin(1.0 / ratio)))
        if accel is not None:  # |dq| (1 - cos(pi / n)) <= accel / rate^2, with a hair to spare for rounding
            worst = float(np.max(np.abs(q_to - q_from) * rate**2 / np.asarray(accel, dtype=np.float64)))
            if worst > 1.0:
                n = max(n, math.ceil(math.pi / math.acos(1.0 - (1.0 - 1e-9) / worst)))
        # a hair above speed / rate: the plan's own steps (<= speed / rate up to rounding) pass unchanged
        max_step = tuple((np.broadcast_to(speed, q_from.shape) / rate * (1.0 + 1e-9)).tolist())
        return cls(q_from=q_from, q_to=q_to, target=np.asarray(target, dtype=np.float64), n_slots=n, max_step=max_step)

    def truncated(self, n_slots: int) -> LeadIn:
        """Only the first ``n_slots`` slots of this plan (at its speed: it stops partway to ``q_to``)."""
        if n_slots >= self.n_slots:
            return self
        return replace(self, n_slots=n_slots, planned_slots=self.planned_slots or self.n_slots)

    def goal(self, slot: int) -> JointGoal:
        """The goal of lead-in slot ``slot`` (``-n_slots <= slot < 0``)."""
        i = slot + self.n_slots + 1
        n = self.planned_slots or self.n_slots
        if i >= n:
            return JointGoal(self.q_to, self.target, self.max_step)
        s = 0.5 - 0.5 * math.cos(math.pi * i / n)
        return JointGoal(self.q_from + s * (self.q_to - self.q_from), self.target, self.max_step)


class ClipSlots(TargetSource):
    """What every clip source shares (:class:`ClipSource`, a rig's): the slots of ``loop``'s clip window (played
    once, or looped with ``config.loop``), each slot's clip time, and the lead-in before slot 0 (``lead_in``,
    planned by the subclass's ``start``: slots ``-n .. -1``)."""

    def __init__(self, loop: ControlLoop):
        self.loop = loop  #: the loop whose clip window and clip times the slots are
        self.n_slots = loop.n_slots
        self.looping = loop.config.loop
        self.lead_in: LeadIn | Route | None = None  #: planned by ``start``

    def finished(self, tick: int) -> bool:
        return not self.looping and tick >= self.n_slots

    def clip_time(self, tick: int, t: float) -> float:
        """The clip seconds of slot ``tick`` (``t``, the slot's time, is not needed: the window and speed are)."""
        if tick < 0:  # the lead-in: the clip waits at its start
            return self.loop.config.start
        return self.loop.clip_time(self.slot(tick))

    def slot(self, tick: int) -> int:
        """The clip slot that ``tick`` (>= 0) plays: the tick itself, or the tick in the window's pass when looping."""
        return tick % self.n_slots if self.looping else tick

    def lead_in_goal(self, tick: int) -> TickGoal:
        """The lead-in's goal of ``tick`` (< 0)."""
        if self.lead_in is None:
            raise RuntimeError("Expected start() to plan a lead-in before a slot < 0")
        return self.lead_in.goal(tick)


class ClipSource(ClipSlots):
    """The :class:`TargetSource` of a :class:`ControlLoop`: its clip window, sampled a block of slots at a time.

    With ``lead_in_to`` (a pose ``(n_joints,)`` rad, normally :meth:`ControlLoop.initial_pose`), ``start``
    plans a :class:`LeadIn` from the start pose to it at the config's ``lead_in_speed`` and the clip starts
    after it, at slot 0.  With ``plan`` (:meth:`ControlLoop.plan`) slot ``k`` of the clip answers the plan's pose
    as a :class:`JointGoal` carrying its IK solution (slots past the plan: the target, for IK in the tick).
    """

    def __init__(
        self,
        loop: ControlLoop,
        *,
        lead_in_to: npt.NDArray[np.float64] | None = None,
        plan: PathPlan | None = None,
    ):
        super().__init__(loop)
        self.plan = plan
        self.lead_in_to = lead_in_to
        self._block0 = self._block1 = 0  # the slots [block0, block1) of a pass whose targets are sampled
        self._positions: npt.NDArray[np.float64] = np.empty((0, 3))  # theirs, (n, 3) m
        self._rotations: npt.NDArray[np.float64] | None = None  # (n, 3, 3), or None: no rotations
        self._clamped: list[bool] = []

    def start(self, q_start: npt.NDArray[np.float64]) -> int:
        """Plan the lead-in from ``q_start`` (if any); returns the first slot, ``-n`` for ``n`` lead-in slots."""
        if self.lead_in_to is None:
            return 0
        loop, cfg = self.loop, self.loop.config
        speed = np.minimum(cfg.lead_in_speed, cfg.velocity_scale * loop.arm.max_velocity)
        positions, _, _ = loop.sample(0, 1)
        self.lead_in = plan_lead_in(loop.arm, q_start, self.lead_in_to, speed=speed, rate=cfg.rate,
                                    target=positions[0], collision=cfg.collision)  # fmt: skip
        if cfg.max_ticks is not None and self.lead_in.n_slots > cfg.max_ticks:  # the run stays as long as asked
            log.warning(
                "lead-in: cut to max_ticks = %d of its %d ticks; the clip starts from where it got to",
                cfg.max_ticks,
                self.lead_in.n_slots,
            )
            self.lead_in = self.lead_in.truncated(cfg.max_ticks)
        if self.lead_in.n_slots:
            log.info(
                "lead-in: %d ticks (%.2f s) to the clip's first pose at <= %.3g rad/s",
                self.lead_in.n_slots,
                self.lead_in.n_slots / cfg.rate,
                cfg.lead_in_speed,
            )
        return -self.lead_in.n_slots

    def target_at(self, tick: int, t: float) -> TickGoal:
        if tick < 0:
            return self.lead_in_goal(tick)
        i = self.slot(tick)
        plan = self.plan
        if plan is not None and i < len(plan):
            return JointGoal(plan.q[i], plan.positions[i], None, plan.ik[i], plan.clamped[i])
        if not self._block0 <= i < self._block1:  # sample the targets of the next slots, a block at a time
            if i == self._block1 or self._rotations is not None:
                self._block0, self._block1 = i, min(i + _BLOCK, self.n_slots)
                self._positions, self._rotations, clamped = self.loop.sample(self._block0, self._block1)
                self._clamped = clamped.tolist()
            else:  # after a skip only this slot (an overrunning loop skips every tick)
                one, moved = self.loop.targets.at(self.loop.clip_time(i))
                self._block0, self._block1 = i, i + 1
                self._positions, self._clamped = one[None], [moved]
                return TickTarget(one, None, moved)
        j = i - self._block0
        rotations = self._rotations
        return TickTarget(self._positions[j], None if rotations is None else rotations[j], self._clamped[j])


def plan_lead_in(
    arm: Plant,
    q_from: npt.NDArray[np.float64],
    q_to: npt.NDArray[np.float64],
    *,
    speed: npt.NDArray[np.float64],
    rate: float,
    target: npt.NDArray[np.float64],
    collision: RouteModel | None,
) -> LeadIn | Route:
    """The lead-in from ``q_from`` to ``q_to`` (rad) at ``rate`` ticks per second: one :class:`LeadIn`, or with a
    ``collision`` model the legs of its safe route (straight, else through home or rest; ConfigError ``collision``
    when there is none)."""
    accel = arm.max_acceleration
    if collision is None:
        return LeadIn.plan(q_from, q_to, speed=speed, rate=rate, target=target, accel=accel)
    waypoints = (arm.home, arm.rest)
    poses = require_route(collision, q_from, q_to, waypoints=waypoints, what="lead-in to the clip's first pose")
    if len(poses) == 1:
        return LeadIn.plan(q_from, q_to, speed=speed, rate=rate, target=target, accel=accel)
    log.info("lead-in: the straight path collides; going through a safe waypoint")
    legs, start = [], q_from
    for pose in poses:
        legs.append(LeadIn.plan(start, pose, speed=speed, rate=rate, target=target, accel=accel))
        start = pose
    return Route(tuple(legs))


def run_on_bus(loop: ControlLoop, bus: Bus) -> RunSummary:
    """Connect ``bus``, run ``loop`` on it and always close it (its shutdown sequence runs even on Ctrl-C)."""
    with connected(bus):
        return loop.run(bus)
