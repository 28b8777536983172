"""Bimanual teleop: each arm of a rig follows its own targets, from one stream of two-arm messages.

Messages (:mod:`~retarget.rig.messages`) arrive on a :class:`~retarget.rig.inputs.RigInput`: one line of stdin,
one datagram (:mod:`~retarget.rig.inputs`), or a message fed by hand.  Its :class:`~retarget.rig.messages.RigGate`
parses each, takes it whole or not at all, and passes every arm's part to that arm's own target
:class:`~retarget.teleop.sources.Source` (:attr:`~retarget.rig.inputs.RigInput.sources`).

Each arm has its own :class:`~retarget.teleop.follower.Follower` on that source: the same queue, Cartesian speed
limit (``max_speed``), pass/reach/stall rules, smoothing and stale timeout as one arm's teleop.  Each tick
(:func:`run_rig_teleop`) asks every follower for its setpoint, solves each arm's IK with that arm's own
collision-aware solver (:class:`~retarget.teleop.follower.PoseSolver`, warm-started from its commanded pose; an arm
with nothing to steer toward holds its commanded pose) and hands the joined pose to the tick loop
(:func:`~retarget.control.loop.run_ticks` on the rig's :class:`~retarget.rig.plant.RigPlant`) as a
:class:`~retarget.control.source.JointGoal`.  The loop steps every joint within its limits and checks the rig's
goal (:class:`~retarget.rig.check.RigGoalCheck`: each arm against itself and its world, and the arms against each
other) before one write to every arm.  A goal that would bring the arms within the clearance is written for no
arm (the rig moves as one): both brake, and a follower that makes no progress gives its target up after
``stall_time``.  A bus fault on any arm ends the run for all (the caller's close runs every arm's shutdown).

Frames: messages are in the rig's world frame; targets, setpoints and reached points are each arm's base frame
(:class:`RigTeleopResult` adds world-frame copies).  Metres, radians inside.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from retarget.control.bus import Bus
from retarget.control.clock import Clock
from retarget.control.limits import SEED_LEAD
from retarget.control.loop import LoopConfig, TickRecord, run_ticks
from retarget.control.source import HOLD, JointGoal, TargetSource, TickGoal
from retarget.control.stats import TickStats
from retarget.control.summary import RunSummary
from retarget.control.tracking import TickTracker
from retarget.errors import BusError
from retarget.ik.result import IKResult
from retarget.mapping.filter import OneEuro
from retarget.rig.check import RigGoalCheck
from retarget.rig.clearance import RigClearance
from retarget.rig.inputs import RigInput
from retarget.rig.plant import RigPlant
from retarget.rig.spec import Rig
from retarget.teleop.follower import (
    DEFAULT_TOLERANCE,
    Follower,
    PoseSolver,
    Settle,
    TeleopResult,
    follower_result,
    require_tolerance,
)
from retarget.teleop.sources import Source

if TYPE_CHECKING:
    from retarget.collision import CollisionModel

__all__ = ["RigTeleopRecords", "RigTeleopResult", "rig_followers", "run_rig_teleop"]

Array = npt.NDArray[np.float64]


class _RigRun(TargetSource):
    """The followers seen by the loop: each arm's setpoint through its IK, joined into one JointGoal; ends when
    every follower is finished and the servos settled (``settle``)."""

    observes = True

    def __init__(
        self,
        plant: RigPlant,
        followers: Mapping[str, Follower],
        solvers: Mapping[str, PoseSolver],
        *,
        settle: Settle,
        lockstep: RigInput | None,
        idle_wait: float,
        records: RigTeleopRecords | None = None,
    ):
        self.plant, self.followers, self.solvers = plant, dict(followers), dict(solvers)
        self.settle, self.lockstep, self.idle_wait = settle, lockstep, idle_wait
        self.q_cmd: dict[str, Array] = {}
        self.q_before: dict[str, Array] = {}  #: the commanded poses of the tick before (the seeds' last step)
        lower, upper = plant.split(plant.lower), plant.split(plant.upper)
        self.limits = {name: (lower[name], upper[name]) for name in lower}  #: each arm's joint limits, rad
        self.records = records

    def start(self, q_start: Array) -> int:
        self.q_cmd = {name: np.array(q) for name, q in self.plant.split(q_start).items()}
        for name, follower in self.followers.items():
            follower.start(self.q_cmd[name])
        return 0

    def _idle(self) -> bool:
        return all(f.goal is None and not f.pending and not f.source.queued for f in self.followers.values())

    def target_at(self, tick: int, t: float) -> TickGoal:
        if self.lockstep is not None and not self.lockstep.closed and self._idle():
            self.lockstep.wait(self.idle_wait)  # lockstep on a virtual clock: time waits for the input
        goals = {name: f.target_at(tick, t) for name, f in self.followers.items()}
        own: dict[str, IKResult | None] = dict.fromkeys(goals)
        if self.records is not None:
            self.records.ik = own  # this tick's, filled in below
        if all(goal is HOLD for goal in goals.values()):
            return HOLD
        parts, targets, results = {}, [], []
        for name, goal in goals.items():
            if goal is None:  # this arm holds where it is commanded; the other moves
                parts[name] = self.q_cmd[name]
                tool = self.followers[name].tool
                targets.append(np.zeros(3) if tool is None else tool)
                continue
            result = own[name] = self.solvers[name].solve(goal.position, self._seed(name), goal.rotation)
            parts[name] = result.q
            targets.append(goal.position)
            results.append(result)
        q = self.plant.join(parts)
        ik = IKResult(
            q,
            max(r.error for r in results),
            sum(r.iterations for r in results),
            all(r.converged for r in results),
            blocked=any(r.blocked for r in results),
        )
        return JointGoal(q, np.concatenate(targets), ik=ik)

    def _seed(self, name: str) -> Array:
        """Arm ``name``'s IK seed: where its commanded pose is heading, :data:`~retarget.control.limits.SEED_LEAD` of
        its last step ahead, within its limits, as the one-arm loop seeds its IK (``StepLimiter.seed``).  Seeded from
        the commanded pose itself, a move the goal check held was solved again to the same goal and held again: an
        arm at rest by its base never left it for a target in front of it."""
        q = self.q_cmd[name]
        ahead = q + SEED_LEAD * (q - self.q_before.get(name, q))
        lower, upper = self.limits[name]
        return np.clip(ahead, lower, upper)

    def observe(self, tick: int, q_cmd: Array, q_present: Array | None) -> None:
        self.q_before = self.q_cmd
        self.q_cmd = {name: np.array(q) for name, q in self.plant.split(q_cmd).items()}
        present = None if q_present is None else self.plant.split(q_present)
        for name, follower in self.followers.items():
            follower.observe(tick, self.q_cmd[name], None if present is None else present[name])
        self.settle.observe(q_cmd, q_present)

    def finished(self, tick: int) -> bool:
        return self.settle.finished(tick, all(f.finished(tick) for f in self.followers.values()))


class RigTeleopRecords:
    """Each arm's part of a rig teleop's tick records, for the rig's telemetry
    (:class:`~retarget.rig.telemetry.RigTelemetry`): pass it to :func:`run_rig_teleop` (``records``), which notes
    each arm's IK outcome every tick.  ``followers``: the run's, by arm name (their targets as they came in are the
    tracking references, :meth:`trackers`)."""

    def __init__(self, rig: Rig, followers: Mapping[str, Follower]):
        self.rig, self.plant, self.followers = rig, RigPlant.of(rig), dict(followers)
        #: each arm's IK of the latest tick (None: it held, no IK), set by the run
        self.ik: dict[str, IKResult | None] = {}

    def arm_record(self, record: TickRecord, name: str) -> TickRecord:
        """Arm ``name``'s part of the rig's tick ``record`` (the latest): its target (base frame), goals and
        read-back, and its own IK outcome."""
        i = self.rig.names.index(name)
        part = self.plant.slices[i]
        present = None if record.q_present is None else record.q_present[part]
        ik = self.ik.get(name)
        return replace(
            record,
            target=record.target[3 * i : 3 * i + 3],
            q_cmd=record.q_cmd[part],
            q_present=present,
            ik_error=0.0 if ik is None else float(ik.error),
            ik_sweeps=0 if ik is None else int(ik.iterations),
            ik_converged=True if ik is None else bool(ik.converged),
        )

    def trackers(self) -> dict[str, TickTracker]:
        """Each arm's :class:`~retarget.control.tracking.TickTracker`: its commanded tool point against its target
        as it came in (the follower's ``reference``; none before the first)."""

        def reference(follower: Follower) -> Callable[[Any], Array | None]:
            return lambda _record: follower.reference

        return {a.name: TickTracker(a.arm, reference(self.followers[a.name])) for a in self.rig.arms}


@dataclass(frozen=True)
class RigTeleopResult:
    """The outcome of a rig's teleop run: the rig's summary and stats, and each arm's
    :class:`~retarget.teleop.follower.TeleopResult` (its base frame; its rejects are its own part's: box, reach,
    blocked), plus the message-level rejects (``rejects``: oversize, malformed, non-finite)."""

    rig: Rig
    summary: RunSummary
    stats: TickStats
    arms: dict[str, TeleopResult]
    rejects: dict[str, int]

    @property
    def any_target(self) -> bool:
        """True when some arm got a target."""
        return any(r.target is not None for r in self.arms.values())

    @property
    def reached_targets(self) -> bool:
        """True when every arm that got a target reached its last one."""
        return all(r.reached_target for r in self.arms.values() if r.target is not None)

    def world(self, name: str) -> tuple[Array | None, Array]:
        """Arm ``name``'s last target (None: none) and reached point, world frame, ``(3,)`` m."""
        r, placement = self.arms[name], self.rig[name].placement
        return None if r.target is None else placement.to_world(r.target), placement.to_world(r.reached)

    def to_dict(self) -> dict[str, object]:
        """JSON-ready: ``rejected`` (message-level) and ``arms``: each arm's result (as one arm's teleop) with its
        target and reached point in the world too."""
        arms: dict[str, object] = {}
        for name, r in self.arms.items():
            target, reached = self.world(name)
            arms[name] = {
                **r.to_dict(),
                "target_world_m": None if target is None else [round(float(v), 6) for v in target],
                "reached_world_m": [round(float(v), 6) for v in reached],
            }
        return {"reached": self.reached_targets, "rejected": self.rejects, "arms": arms}

    def format(self) -> str:
        """Human lines for stderr: the message-level rejects, then each arm's counts."""
        by_reason = ", ".join(f"{k} {v}" for k, v in self.rejects.items() if v)
        lines = [f"  messages: {sum(self.rejects.values())} rejected" + (f" ({by_reason})" if by_reason else "")]
        lines += [f"  {name}:" + r.format().removeprefix(" ") for name, r in self.arms.items()]
        return "\n".join(lines)


def rig_followers(
    rig: Rig,
    sources: RigInput | Mapping[str, Source],
    *,
    clock: Clock,
    rate: float,
    smoothing: Callable[[], OneEuro] | None = None,
    **knobs: Any,
) -> dict[str, Follower]:
    """One :class:`~retarget.teleop.follower.Follower` per arm of ``rig`` on its source (a :class:`RigInput`'s, or
    arm name -> source, e.g. the keys' :class:`~retarget.cli.tui.RigKeys` sources), by arm name, all with the same
    keyword knobs (``max_speed``, ``tolerance``, ``timeout``, ...; see Follower); ``smoothing`` makes each arm's own
    One-Euro filter (None: no smoothing)."""
    by_arm = sources.sources if isinstance(sources, RigInput) else sources
    return {
        a.name: Follower(
            a.arm,
            by_arm[a.name],
            clock=clock,
            rate=rate,
            smoothing=None if smoothing is None else smoothing(),
            **knobs,
        )  # fmt: skip
        for a in rig.arms
    }


def run_rig_teleop(
    rig: Rig,
    followers: Mapping[str, Follower],
    *,
    config: LoopConfig,
    clock: Clock,
    bus: Bus | None = None,
    models: Mapping[str, CollisionModel] | None = None,
    clearance: float | None = None,
    rig_input: RigInput | None = None,
    lockstep: bool = False,
    q_start: Array | None = None,
    tolerance: float = DEFAULT_TOLERANCE,
    settle_time: float = 2.0,
    idle_wait: float = 0.1,
    on_tick: Callable[[TickRecord], None] | None = None,
    on_progress: Callable[[TickRecord], None] | None = None,
    stop: threading.Event | None = None,
    name: str = "teleop",
    records: RigTeleopRecords | None = None,
) -> RigTeleopResult:
    """Run the tick loop on ``rig``'s plant with one :class:`~retarget.teleop.follower.Follower` per arm (by arm
    name, each on its arm's source of ``rig_input``) until every follower is finished and the servos settled (at
    most ``settle_time`` s more), ``config.max_ticks``, ``stop`` or Ctrl-C.  See the module docstring.

    ``bus``: a connected bus over every arm in rig order (a ``RigBus``; None: a dry run); ``clock`` the loop's (and
    the followers'); the start pose ``(plant n_joints,)`` rad is the bus's present positions, else ``q_start``,
    else every arm's rest pose.  ``models``: each arm's collision model, by arm name (its IK and its own check);
    None: no collision check at all; ``clearance``: metres between the arms (default the rig's).  ``rig_input``: where
    the followers' targets come from (its message-level rejects go into the result); ``lockstep`` (a virtual clock):
    while no arm has anything to do, the loop waits up to ``idle_wait`` real seconds for its input, so virtual time
    does not race ahead of a reader thread.  ``records``: noted each arm's IK every tick (for the telemetry,
    ``on_tick``).  A ``BusError`` propagates with the summary so far.

    >>> from retarget.control.clock import VirtualClock
    >>> from retarget.rig import RigGate, RigInput, load_rig
    >>> rig, clock = load_rig("wx250s-pair"), VirtualClock()
    >>> rig_input = RigInput(RigGate.for_rig(rig, clock=clock))
    >>> rig_input.feed("left 0.3 0.35 0.2 right 0.3 -0.3 0.25"); rig_input.close()
    >>> followers = rig_followers(rig, rig_input, clock=clock, rate=100.0)
    >>> result = run_rig_teleop(rig, followers, config=LoopConfig(), clock=clock, rig_input=rig_input)
    >>> result.reached_targets, [round(float(r.residual or 1) * 1e3) for r in result.arms.values()]
    (True, [0, 0])
    """
    tolerance = require_tolerance(tolerance)
    plant = RigPlant.of(rig)
    loop_config = replace(config, collision=None)  # the rig's check below replaces one arm's
    solvers = {
        a.name: PoseSolver(a.arm, replace(config, collision=None if models is None else models[a.name]))
        for a in rig.arms
    }
    run = _RigRun(plant, followers, solvers, settle=Settle(settle_time, config.rate),
                  lockstep=rig_input if lockstep else None, idle_wait=idle_wait, records=records)  # fmt: skip
    check = None
    if models is not None:
        own = dict(models)
        between = RigClearance(rig) if clearance is None else RigClearance(rig, clearance=clearance)

        def check(q0: Array) -> RigGoalCheck:
            return RigGoalCheck(plant, own, between, q0)

    def received() -> int:
        return sum(f.received for f in followers.values())

    try:
        stats = run_ticks(plant, run, solvers[rig.names[0]], config=loop_config, clock=clock, bus=bus,
                          q_start=q_start, on_tick=on_tick, on_progress=on_progress, stop=stop,
                          goal_check=check)  # fmt: skip
    except BusError as exc:
        if isinstance(exc.stats, TickStats):
            exc.summary = exc.stats.summary(arm=rig.name, clip=name, frames=received(), duration_s=exc.stats.run_time)
        raise
    summary = stats.summary(arm=rig.name, clip=name, frames=received(), duration_s=stats.run_time)
    q_final = stats.q_present if stats.q_present is not None else stats.q_cmd
    if q_final is None:
        raise RuntimeError("Expected the run's last goals in its stats")
    parts = plant.split(np.asarray(q_final, dtype=np.float64))
    arms = {
        a.name: follower_result(followers[a.name], parts[a.name], summary, stats, tolerance=tolerance) for a in rig.arms
    }
    rejects = rig_input.gate.counts() if rig_input is not None else {}
    return RigTeleopResult(rig=rig, summary=summary, stats=stats, arms=arms, rejects=rejects)
