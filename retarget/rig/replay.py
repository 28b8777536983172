"""Bimanual replay: one clip on every arm of a rig, in lockstep, by the tick loop of one arm.

:class:`RigReplay` runs :func:`~retarget.control.loop.run_ticks` on the rig's :class:`~retarget.rig.plant.RigPlant`
(every arm's joints as one vector), so each tick steps every arm within its velocity and acceleration limits,
checks the whole rig (:class:`~retarget.rig.check.RigGoalCheck`: each arm against itself and the world, and the
arms against each other, pose and path) and writes every arm in one bus call (a ``RigBus`` over the arms' buses).
A fault on any bus ends the run for every arm, and the caller's close runs every arm's shutdown.

Before the run, IK solves each arm's targets for every slot of the clip window (:class:`ArmPath`): each arm's own
collision-aware :class:`~retarget.ik.CCDSolver`, warm-started from its previous solution; that path is planned
ahead within the limits (``look_ahead``, as one arm's clip is), and every planned move is bounded before the first
tick (:class:`~retarget.rig.proof.RigProof`: each arm's own bounds from the notes of its IK pass, the arms apart from
poses measured in batches).  The ticks then steer to those poses (:class:`~retarget.control.source.JointGoal`); the
loop's step limit and the rig check stay the last word before each write (a planned move whose bounds keep every
clearance is a look-up; any other move is checked).  On a bus a lead-in first moves every arm from where it is to
the clip's first poses (straight in joint space when that path is clear, else through the arms' homes or rests,
else refused: :func:`~retarget.control.replay.plan_lead_in` with :class:`~retarget.rig.check.RigRoutes`).

Each tick's record is one for the rig (targets ``(3 n_arms,)`` metres, every arm's base frame in turn, joints the
plant's); :meth:`RigReplay.arm_record` gives one arm's part of it, with that arm's IK outcome.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from retarget.control.bus import Bus
from retarget.control.clock import Clock, MonotonicClock
from retarget.control.fit import Halfspaces
from retarget.control.keepclear import keep_clear
from retarget.control.loop import LoopConfig, TickRecord, run_ticks
from retarget.control.plan import plan_path, tool_task
from retarget.control.polish import Polish
from retarget.control.replay import ClipSlots, ControlLoop, plan_lead_in
from retarget.control.source import JointGoal, TickGoal
from retarget.control.stats import TickStats
from retarget.control.summary import ik_figures
from retarget.control.tracking import Trajectory, at_velocity_limit, following
from retarget.errors import BusError
from retarget.ik.bound import State, shared_bound
from retarget.rig.check import RigGoalCheck, RigRoutes
from retarget.rig.clearance import RigClearance
from retarget.rig.keepclear import RigWorld
from retarget.rig.mapping import RigTargets
from retarget.rig.plant import RigPlant
from retarget.rig.proof import RigProof
from retarget.rig.spec import Rig
from retarget.rig.summary import RigSummary

if TYPE_CHECKING:
    from retarget.collision import CollisionModel

__all__ = ["ArmPath", "RigReplay"]

log = logging.getLogger(__name__)

Array = npt.NDArray[np.float64]


@dataclass(frozen=True)
class ArmPath:
    """One arm's IK over the slots of a pass: ``q`` ``(n_slots, n_joints)`` rad, ``targets`` ``(n_slots, 3)`` m
    (base frame), ``error`` ``(n_slots,)`` m, ``sweeps``, ``converged`` and ``blocked`` ``(n_slots,)``; with a
    collision-aware solver, the ``notes`` its collision bound made during the pass and per slot the ``index`` of the
    last one after its solve (what :meth:`~retarget.ik.bound.ClearanceBound.prove` bounds a plan of the path from)."""

    q: Array
    targets: Array
    error: Array
    sweeps: npt.NDArray[np.int64]
    converged: npt.NDArray[np.bool_]
    blocked: npt.NDArray[np.bool_]
    notes: tuple[State, ...] = ()
    index: npt.NDArray[np.intp] = field(default_factory=lambda: np.zeros(0, dtype=np.intp))

    @classmethod
    def solve(cls, loop: ControlLoop) -> ArmPath:
        """IK for every slot of ``loop``'s pass, warm-started from the previous solution (the first from
        :meth:`~retarget.control.replay.ControlLoop.initial_pose`), each solve's notes recorded, then polished
        (:class:`~retarget.control.polish.Polish`: one batched DLS step on every safe slot; ``error`` stays the
        solver's)."""
        positions, _, _ = loop.sample(0, loop.n_slots)
        q = loop.initial_pose()
        model = loop.config.collision
        bound = None if model is None else shared_bound(model)
        notes = [] if bound is None else bound.record()
        solve, results, index = loop.solver.solve, [], []
        try:
            for target in positions:
                result = solve(target, q, None)
                results.append(result)
                index.append(len(notes) - 1)
                q = result.q
        finally:
            if bound is not None:
                bound.record(False)
        out = np.array([r.q for r in results], dtype=np.float64).reshape(len(results), loop.arm.n_joints)
        polish = Polish.of(loop.solver)
        if polish is not None and len(out):  # the early-out's sawtooth taken out, every slot at once
            arm = loop.arm
            jacobians, residuals = tool_task([(arm.chain, slice(None))], out, positions)
            out, _ = polish.step(out, jacobians, residuals, polish.safe(results, positions), arm.lower, arm.upper)
        error = np.array([r.error for r in results], dtype=np.float64)
        sweeps = np.array([r.iterations for r in results], dtype=np.int64)
        converged = np.array([r.converged for r in results], dtype=bool)
        blocked = np.array([r.blocked for r in results], dtype=bool)
        return cls(out, positions, error, sweeps, converged, blocked, tuple(notes), np.array(index, dtype=np.intp))


class RigReplay:
    """Plays a clip's :class:`~retarget.rig.mapping.RigTargets` on every arm of ``rig`` (see the module docstring).

        ``config``: rate, window, speed and limits for every arm (its ``collision`` is ignored: ``models`` holds each
        arm's own collision model, by arm name; None: no collision check at all); ``clearance``: metres between the
        arms.  ``on_tick(record)`` gets every tick's record (the rig's; :meth:`arm_record` splits it), ``on_progress``
        as in :class:`~retarget.control.replay.ControlLoop`; ``look_ahead``: the arms' IK paths are planned ahead within
    their limits (:func:`~retarget.control.plan.plan_path`; a ``loop`` run plays them causally).  :meth:`run` plays
    it and returns a
        :class:`~retarget.rig.summary.RigSummary`.

        >>> from retarget.bvh.parse import DEMO_CLIP, load_bvh
        >>> from retarget.control.clock import VirtualClock
        >>> from retarget.rig import load_rig, rig_targets
        >>> rig = load_rig("wx250s-pair")
        >>> replay = RigReplay(rig, rig_targets(load_bvh(DEMO_CLIP), rig), config=LoopConfig(max_ticks=50),
        ...                    clock=VirtualClock())
        >>> summary = replay.run(None)
        >>> summary.rig.ticks, sorted(summary.arms)
        (50, ['left', 'right'])
    """

    def __init__(
        self,
        rig: Rig,
        targets: RigTargets,
        *,
        config: LoopConfig | None = None,
        models: Mapping[str, CollisionModel] | None = None,
        clearance: float | None = None,
        clock: Clock | None = None,
        on_tick: Callable[[TickRecord], None] | None = None,
        on_progress: Callable[[TickRecord], None] | None = None,
        clip_name: str = "",
        pipeline: bool = True,
        look_ahead: bool = True,
    ):
        self.rig, self.targets = rig, targets
        self.look_ahead = look_ahead
        self.plant = RigPlant.of(rig)
        self.config = config = replace(config or LoopConfig(), collision=None)
        self.clock: Clock = clock if clock is not None else MonotonicClock()
        self.models = None if models is None else dict(models)
        between = RigClearance(rig) if clearance is None else RigClearance(rig, clearance=clearance)
        self.between = between
        #: each arm's own loop: its targets, window, IK (collision-aware with its model)
        self.loops = {
            a.name: ControlLoop(
                a.arm,
                targets.arms[a.name],
                config=replace(config, collision=None if self.models is None else self.models[a.name]),
                clock=self.clock,
            )
            for a in rig.arms
        }
        first = self.loops[rig.names[0]]
        self.n_slots, self.frames = first.n_slots, first.frames
        self.on_tick, self.on_progress = on_tick, on_progress
        self.clip_name, self.pipeline = clip_name, pipeline
        self._stop = threading.Event()
        self._paths: dict[str, ArmPath] | None = None

    @property
    def paths(self) -> dict[str, ArmPath]:
        """Each arm's IK over the pass, by arm name (solved once, on first use)."""
        if self._paths is None:
            self._paths = {name: ArmPath.solve(loop) for name, loop in self.loops.items()}
        return self._paths

    def stop(self) -> None:
        """Ask the run to end at the next tick boundary (safe from a signal handler or another thread)."""
        self._stop.set()

    def initial_pose(self) -> Array:
        """Every arm's pose at the clip's first slot, ``(plant n_joints,)`` rad."""
        return self.plant.join({name: path.q[0] for name, path in self.paths.items()})

    def arm_record(self, record: TickRecord, name: str) -> TickRecord:
        """Arm ``name``'s part of the rig's tick ``record``: its target, goals and read-back, and its IK outcome."""
        i = self.rig.names.index(name)
        part = self.plant.slices[i]
        present = None if record.q_present is None else record.q_present[part]
        record = replace(record, target=record.target[3 * i : 3 * i + 3], q_cmd=record.q_cmd[part], q_present=present)
        if record.lead_in or record.tick < 0:
            return record
        path, k = self.paths[name], record.tick % self.n_slots
        return replace(
            record,
            ik_error=float(path.error[k]),
            ik_sweeps=int(path.sweeps[k]),
            ik_converged=bool(path.converged[k]),
        )

    def run(self, bus: Bus | None = None, *, q_start: Array | None = None, lead_in: bool | None = None) -> RigSummary:
        """Run on a connected ``bus`` over every arm (None: a dry run) and return the summary.  The start pose is
        the bus's present positions, else ``q_start`` ``(plant n_joints,)`` rad, else every arm's rest pose.
        ``lead_in``: default on a bus only.  ``BusError`` propagates with the summary so far (``exc.summary``)."""
        if lead_in is None:
            lead_in = bus is not None
        source = _RigSource(self, lead_in=lead_in and self.config.lead_in_speed > 0)
        records: list[TickRecord] = []

        def on_tick(record: TickRecord) -> None:
            records.append(record)
            if self.on_tick is not None:
                self.on_tick(record)

        check = None
        if self.models is not None:
            models, between, plant = self.models, self.between, self.plant

            def check(q_start: Array) -> RigGoalCheck:  # (made after source.start(): the plan's bounds are in)
                return RigGoalCheck(plant, models, between, q_start, proof=source.proof)

        try:
            ticks = run_ticks(
                self.plant,
                source,
                self.loops[self.rig.names[0]].solver,  # never called: every goal is a JointGoal
                config=self.config,
                clock=self.clock,
                bus=bus,
                q_start=q_start,
                on_tick=on_tick,
                on_progress=self.on_progress,
                stop=self._stop,
                pipeline=self.pipeline,
                goal_check=check,
            )
        except BusError as exc:
            if isinstance(exc.stats, TickStats):
                exc.summary = self._summary(exc.stats, records)
            raise
        return self._summary(ticks, records)

    def _summary(self, ticks: TickStats, records: list[TickRecord]) -> RigSummary:
        played = (ticks.last_slot + 1) * self.config.speed / self.config.rate if ticks.last_slot >= 0 else 0.0
        return _summarize(self, ticks, records, duration_s=played)


class _RigSource(ClipSlots):
    """Each slot's goal of a :class:`RigReplay`: the lead-in's, then every arm's IK pose of the slot (the slots and
    clip times of the first arm's loop: every arm's are the same)."""

    def __init__(self, replay: RigReplay, *, lead_in: bool):
        super().__init__(replay.loops[replay.rig.names[0]])
        self.replay, self.with_lead_in = replay, lead_in
        self.proof: RigProof | None = None  #: the plan's bounds (:meth:`start`; None: no plan, or no collision check)
        paths = replay.paths
        self.q = replay.plant.join({name: p.q for name, p in paths.items()})  # (n_slots, plant n_joints)
        self.targets = np.concatenate([paths[name].targets for name in replay.rig.names], axis=1)  # (n_slots, 3 n)

    def start(self, q_start: Array) -> int:
        replay, cfg = self.replay, self.replay.config
        if replay.look_ahead and not self.looping:  # plan the played ticks ahead, from where the clip starts
            n = self.n_slots if cfg.max_ticks is None else min(self.n_slots, cfg.max_ticks)
            plant = replay.plant
            self.q = self.q.copy()
            start = self.q[0] if self.with_lead_in else np.clip(q_start, plant.lower, plant.upper)
            parts = [(a.arm.chain, part) for a, part in zip(replay.rig.arms, plant.slices, strict=True)]
            blocked = np.stack([replay.paths[name].blocked[:n] for name in replay.rig.names], axis=1)
            jacobians, residuals = tool_task(parts, self.q[:n], self.targets[:n], blocked)  # each arm's own point
            goals = self.q[:n].copy()

            def plan(halfspaces: Halfspaces | None) -> Array:
                return plan_path(goals, start, lower=plant.lower, upper=plant.upper,
                                 max_step=plant.max_velocity * cfg.velocity_scale / cfg.rate,
                                 max_accel=plant.max_acceleration / cfg.rate**2, jerk_cost=cfg.jerk_cost,
                                 jacobians=jacobians, residuals=residuals, halfspaces=halfspaces)  # fmt: skip

            self.q[:n] = plan(None) if replay.models is None else self._kept_clear(plan, goals)
            if replay.models is not None:
                self._prove(np.vstack([start[None], self.q[:n]]))
        if not self.with_lead_in:
            return 0
        speed = np.minimum(cfg.lead_in_speed, cfg.velocity_scale * replay.plant.max_velocity)
        routes = None if replay.models is None else RigRoutes(replay.plant, replay.models, replay.between)
        self.lead_in = plan_lead_in(replay.plant, q_start, self.q[0], speed=speed, rate=cfg.rate,
                                    target=self.targets[0], collision=routes)  # fmt: skip
        if cfg.max_ticks is not None and self.lead_in.n_slots > cfg.max_ticks:
            self.lead_in = self.lead_in.truncated(cfg.max_ticks)
        return -self.lead_in.n_slots

    def _kept_clear(self, plan: Callable[[Halfspaces | None], Array], goals: Array) -> Array:
        """``plan``'s path kept clear of every arm's world (:func:`~retarget.control.keepclear.keep_clear`, over
        :class:`~retarget.rig.keepclear.RigWorld`), from the notes of the arms' IK passes."""
        replay = self.replay
        models = replay.models or {}
        world = RigWorld(models, list(zip(replay.rig.names, replay.plant.slices, strict=True)))
        notes = {name: path.notes for name, path in replay.paths.items()}
        index = {name: path.index for name, path in replay.paths.items()}
        return keep_clear(world, plan, lambda path: world.pose_lows(path, notes, index), goals)

    def _prove(self, path: Array) -> None:
        """Bound every planned move ``path[k] -> path[k + 1]`` ``(n + 1, plant n_joints)`` rad before the run
        (:class:`~retarget.rig.proof.RigProof`): each arm's own, by its collision bound from the notes of its IK pass
        (:meth:`~retarget.ik.bound.ClearanceBound.prove`), and the arms' against each other."""
        replay = self.replay
        models, paths = replay.models or {}, replay.paths
        own = {}
        for name, part in zip(replay.rig.names, replay.plant.slices, strict=True):
            arm = paths[name]
            if arm.notes and name in models:
                starts, ends = path[:-1, part], path[1:, part]
                own[name] = shared_bound(models[name]).prove(starts, ends, arm.notes, arm.index[: len(ends)]).lows
        self.proof = RigProof.prove(replay.between, path, own)

    def target_at(self, tick: int, t: float) -> TickGoal:
        if tick < 0:
            return self.lead_in_goal(tick)
        i = self.slot(tick)
        return JointGoal(self.q[i], self.targets[i])


def _summarize(replay: RigReplay, ticks: TickStats, records: list[TickRecord], *, duration_s: float) -> RigSummary:
    """The summary of ``replay``'s run that ended with ``ticks``, from its tick ``records`` (the rig's): each arm's
    part of them (as :meth:`RigReplay.arm_record` gives it), taken from the records' arrays at once."""
    rig = ticks.summary(arm=replay.rig.name, clip=replay.clip_name, frames=replay.frames, duration_s=duration_s)
    clip = [r for r in records if not r.lead_in]
    rate = replay.config.rate
    slots = [r.tick for r in clip]
    clip_times = [r.clip_time for r in clip]
    q_all = np.array([r.q_cmd for r in clip], dtype=np.float64).reshape(len(clip), replay.plant.n_joints)
    targets_all = np.array([r.target for r in clip], dtype=np.float64).reshape(len(clip), 3 * len(replay.rig.arms))
    played = np.array(slots, dtype=np.intp) % replay.n_slots
    arms = {}
    for i, (a, part) in enumerate(zip(replay.rig.arms, replay.plant.slices, strict=True)):
        q = q_all[:, part]
        trajectory = Trajectory()
        trajectory.slots, trajectory.clip_times = list(slots), list(clip_times)
        trajectory.targets, trajectory.q_cmd = list(targets_all[:, 3 * i : 3 * i + 3]), list(q)
        limited = int(np.count_nonzero(at_velocity_limit(q, rate=rate, max_velocity=replay.plant.max_velocity[part])))
        path = replay.paths[a.name]
        ik = ik_figures(path.error[played], path.sweeps[played], path.converged[played])
        summary = replace(
            rig,
            arm=f"{a.name} ({a.arm.name})",
            velocity_limited_ticks=limited,
            ik_blocked_ticks=int(np.count_nonzero(path.blocked[played])),
            **ik,
        )
        reference = replay.targets.arms[a.name].reference
        arms[a.name] = summary.with_following(following(a.arm, trajectory, rate=rate, reference=reference))
    return RigSummary(rig=rig, arms=arms)
