"""``retarget replay --rig``: a clip on every arm of a rig, on the arms' buses, in lockstep.

Each arm's port comes from the rig file (the bundled rigs: ``sim://<arm>``), or from ``--port NAME=PORT``; each
arm gets its own driver, built from the one-arm bus options (:func:`~retarget.cli._bus.port_bus`), and one
:class:`~retarget.rig.RigBus` over them carries every tick.  With ``--fast`` every simulated arm runs on ONE virtual
clock, the loop's (a real port is refused).

Before torque is on: the whole clip's IK for every arm, and safe routes of the arms together (each against itself
and the world, and arm against arm) from home to the clip's first poses and, with ``--shutdown rest``, to rest; a
one-line error when there is none.  After the clip, ``--shutdown rest`` (the default) plays the rig's move to rest
through the tick loop, checked arm against arm every tick (straight when that is clear, else through the arms'
homes; when neither is, every arm holds where it is, torque on, and an error is logged): each driver's own rest
move then starts at rest and only turns torque off.  A bus fault on any arm ends the run for every arm: each
driver runs its own shutdown (its rest move is that arm's alone, not checked against the other arm, as after a
one-arm fault), and the one-line error names the arm (``right: servo 4: ...``, exit 4).
"""

from __future__ import annotations

import argparse
import logging
import sys
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from dataclasses import replace
from typing import IO, TYPE_CHECKING

import numpy as np
import numpy.typing as npt

import sim
from retarget.cli import print_json
from retarget.cli._bus import (
    BusSetup,
    check_bus_options,
    failure_summary,
    is_named_port,
    is_sim_port,
    port_bus,
    say,
    signals_stop,
)
from retarget.cli._rig_run import RigInputs, arm_lines, refuse_arm_options, rig_replay
from retarget.cli._view import wants_view
from retarget.cli.rig import parse_ports
from retarget.control.bus import ShutdownMode, connected
from retarget.control.clock import Clock, MonotonicClock, VirtualClock
from retarget.control.loop import LoopConfig, TickRecord, run_ticks
from retarget.control.park import RouteMoves
from retarget.control.replay import LeadIn
from retarget.control.safety import Route, plan_route, require_route
from retarget.errors import BusError, ConfigError
from retarget.ik.ccd import CCDSolver
from retarget.rig import Rig, RigBus, RigReplay, RigSummary, load_rig
from retarget.rig.check import RigGoalCheck, RigRoutes
from retarget.rig.clearance import RigClearance
from retarget.rig.plant import RigPlant
from retarget.rig.telemetry import RigTelemetry

if TYPE_CHECKING:
    from retarget.collision import CollisionModel

__all__ = ["check_rig_replay", "park_arms", "park_rig", "replay_rig"]

log = logging.getLogger(__name__)

Array = npt.NDArray[np.float64]


# --------------------------------------------------------------------------------------------- options


def check_rig_replay(args: argparse.Namespace) -> None:
    """Before any work: the options ``--rig`` refuses or constrains, and each arm's port (``--port NAME=PORT``)."""
    refuse_arm_options(args)
    if args.gripper is not None:
        raise ConfigError("Expected no --gripper with --rig (it follows one arm's hand)", key="--gripper",
                          value=args.gripper)  # fmt: skip
    if wants_view(args):
        raise ConfigError("Expected no live view with --rig (see 'retarget view --rig')", key="--view")
    check_bus_options(argparse.Namespace(**{**vars(args), "port": None}))  # the ports are checked per arm below
    if args.dry_run and args.port:
        raise ConfigError("--dry-run uses no bus; drop --port", key="--port", value=args.port[0])
    check_fast(args, ported(load_rig(args.rig), args.port))


def check_fast(args: argparse.Namespace, rig: Rig) -> None:
    """``--fast`` needs every arm of ``rig`` on a simulated bus: a ConfigError naming the first real port."""
    if args.fast:
        for a in rig.arms:
            if not is_sim_port(a.port):
                raise ConfigError("--fast needs every arm on a simulated bus (sim://), not a real port", key="--port",
                                  value=f"{a.name}={a.port}")  # fmt: skip


def ported(rig: Rig, items: list[str] | None) -> Rig:
    """``rig`` with the ports of ``--port NAME=PORT`` items; a ConfigError naming ``--port`` for a bare port or an
    arm the rig does not have."""
    for item in items or ():
        if not is_named_port(item):
            raise ConfigError(f"Expected NAME=PORT with --rig, NAME one of {', '.join(rig.names)} "
                              "(e.g. right=/dev/ttyUSB1)", key="--port", value=item)  # fmt: skip
    try:
        return rig.with_ports(parse_ports(items or []))
    except ConfigError as exc:
        if exc.key != "rig.arm":
            raise
        raise exc.with_key("--port") from exc


# --------------------------------------------------------------------------------------------- buses


def open_buses(args: argparse.Namespace, rig: Rig, config: LoopConfig) -> dict[str, BusSetup]:
    """Each arm's driver on its port (not connected), by arm name; with ``--fast`` every simulated one on one
    virtual clock (:func:`fast_clock`).  What was built is released when a later arm fails."""
    shared = fast_clock(rig) if args.fast else None
    setups: dict[str, BusSetup] = {}
    try:
        for a in rig.arms:
            setups[a.name] = port_bus(a.port, a.arm, args, config, clock=shared)
    except BaseException:
        release(setups)
        raise
    return setups


def fast_clock(rig: Rig) -> VirtualClock:
    """The one virtual clock of a ``--fast`` rig: that of the arms' registered ``sim://@NAME`` buses (they must
    share it), else a new one every simulated bus is built on."""
    for a in rig.arms:
        if a.port.startswith("sim://@"):
            try:
                clock = sim.registered(a.port).clock
            except KeyError:  # the bus's own error comes from port_bus
                continue
            if isinstance(clock, VirtualClock):
                return clock
    return VirtualClock()


def rig_clock(args: argparse.Namespace, setups: Mapping[str, BusSetup]) -> Clock:
    """The clock the rig's loop runs on: the arms' one clock (``--fast``: the virtual one; real time: any of their
    monotonic clocks); no buses (a dry run): a new one.  ConfigError when the arms run on different clocks."""
    if not setups:
        return VirtualClock() if args.fast else MonotonicClock()
    clocks = [s.clock for s in setups.values()]
    if all(c is clocks[0] for c in clocks) or all(isinstance(c, MonotonicClock) for c in clocks):
        return clocks[0]
    raise ConfigError("Expected every arm's bus on one clock (--fast puts every simulated arm on one)", key="--port")


def release(setups: Mapping[str, BusSetup]) -> None:
    for setup in setups.values():
        setup.release()


# --------------------------------------------------------------------------------------------- moves


def check_rig_moves(replay: RigReplay, *, first: Array | None, rest: bool) -> None:
    """Before connecting, as one arm's ``check_moves``: safe routes of the arms together from their homes to the
    clip's ``first`` poses (None: no lead-in) and, with ``rest``, to their rests; a one-line ConfigError when one
    has none."""
    if replay.models is None:
        return
    plant = replay.plant
    routes = RigRoutes(plant, replay.models, replay.between)
    if first is not None:
        require_route(routes, plant.home, first, waypoints=(plant.rest,), what="lead-in of the rig's arms to the "
                      "clip's first poses")  # fmt: skip
    if rest:
        require_route(routes, plant.home, plant.rest, waypoints=(), what="move of the rig's arms to rest")


def park_rig(replay: RigReplay, bus: RigBus) -> bool:
    """Before the drivers' REST shutdown: :func:`park_arms` after ``replay``."""
    return park_arms(replay.plant, bus, config=replay.config, clock=replay.clock, models=replay.models,
                     between=replay.between)  # fmt: skip


def park_arms(
    plant: RigPlant,
    bus: RigBus,
    *,
    config: LoopConfig,
    clock: Clock,
    models: Mapping[str, CollisionModel] | None,
    between: RigClearance,
) -> bool:
    """Before the drivers' REST shutdown: drive every arm to its rest pose through the tick loop, on a route the
    arms together keep clear on (straight, else through their homes), each goal checked arm against arm (``models``
    each arm's; None: no check).  When no route is clear, every arm's bus holds instead of its rest move (torque
    on) and an error is logged.  Returns True when the arms went to rest."""
    q = np.clip(np.asarray(bus.read_positions(), dtype=np.float64), plant.lower, plant.upper)
    check = None
    if models is None:
        poses: list[Array] | None = [plant.rest]
    else:
        poses = plan_route(RigRoutes(plant, models, between), q, plant.rest, waypoints=(plant.home,))

        def check(q_start: Array) -> RigGoalCheck:
            return RigGoalCheck(plant, models, between, q_start)

    if poses is None:
        log.error("the rig's move to rest collides and no safe waypoint avoids it: holding here (torque stays on)")
        for arm_bus in bus.buses.values():
            if hasattr(arm_bus, "shutdown_mode"):
                arm_bus.shutdown_mode = ShutdownMode.HOLD
        return False
    speed = np.minimum(config.lead_in_speed or 0.5, config.velocity_scale * plant.max_velocity)
    target = np.concatenate([a.arm.fk(a.arm.rest)[0][:3, 3] for a in plant.rig.arms])  # each arm's base frame
    legs, start, accel = [], q, plant.max_acceleration
    for pose in poses:
        legs.append(LeadIn.plan(start, pose, speed=speed, rate=config.rate, target=target, accel=accel))
        start = pose
    solver = CCDSolver(plant.rig.arms[0].arm)  # never called: every goal is a JointGoal
    run_ticks(plant, RouteMoves(Route(tuple(legs))), solver, config=replace(config, max_ticks=None), clock=clock,
              bus=bus, goal_check=check)  # fmt: skip
    return True


# --------------------------------------------------------------------------------------------- the run


def _progress_printer(replay: RigReplay) -> Callable[[TickRecord], None]:
    total = replay.n_slots

    def show(r: TickRecord) -> None:
        if r.lead_in:
            say(f"retarget: lead-in t={r.time:6.1f} s  to the clip's first poses")
            return
        errors = "  ".join(f"{n} IK {replay.arm_record(r, n).ik_error * 1e3:5.2f} mm" for n in replay.rig.names)
        say(f"retarget: {100.0 * r.tick / total:3.0f}% t={r.time:6.1f} s  clip {r.clip_time:6.2f} s  {errors}")

    return show


@contextmanager
def _telemetry(target: str | None, replay: RigReplay) -> Iterator[RigTelemetry | None]:
    """``--telemetry``: the rig's CSV on a file or stdout (``-``), closed (flushed) on every way out; None: none."""
    if target is None:
        yield None
        return
    out: str | IO[str] = sys.stdout if target == "-" else target
    with RigTelemetry(out, replay) as telemetry:
        yield telemetry


def summary_text(summary: RigSummary) -> str:
    """The rig's summary for stderr: its ticks, bus and collisions, then one line per arm (as ``export --rig``)."""
    # the rig's own IK line counts joint goals (no IK); each arm's line has that arm's IK
    rig = [line for line in summary.rig.format().splitlines() if not line.startswith("  IK:")]
    return "\n".join([*rig, *arm_lines(summary)])


def replay_rig(args: argparse.Namespace, inputs: RigInputs, config: LoopConfig) -> int:
    """``retarget replay --rig`` (see the module docstring), after :func:`check_rig_replay`; ``config`` is the
    loop's (``--rate``, the window, ``--loop``, ``--max-ticks``, ``--lead-in``...)."""
    rig = ported(inputs.rig, args.port)
    setups = {} if args.dry_run else open_buses(args, rig, config)
    try:
        replay = rig_replay(replace(inputs, rig=rig), config, clock=rig_clock(args, setups),
                            look_ahead=not args.no_look_ahead)  # fmt: skip
        if args.progress or sys.stderr.isatty():
            replay.on_progress = _progress_printer(replay)
        with _telemetry(args.telemetry, replay) as telemetry, signals_stop(replay.stop) as stopped:
            replay.on_tick = telemetry
            summary = _play(replay, setups, shutdown=args.shutdown)
    except BusError as exc:
        if args.json and isinstance(exc.summary, RigSummary):  # the ticks that ran, and the failure
            print_json(failure_summary(exc.summary.to_dict(), exc))
        raise
    finally:
        release(setups)
    say(summary_text(summary))  # a hung-up terminal (SIGHUP) must not turn a clean stop into a traceback
    if args.json:
        print_json(summary.to_dict())
    return stopped.exit_status if summary.rig.interrupted else 0


def _play(replay: RigReplay, setups: Mapping[str, BusSetup], *, shutdown: str) -> RigSummary:
    """Run ``replay`` on the arms' buses (none: a dry run from the first targets' solutions, as export does): the
    clip's IK and the routes before torque, then the clip, then with ``shutdown`` rest the rig's move to rest.
    A BusError carries the summary of the clip's ticks (``exc.summary``)."""
    if not setups:
        return replay.run(None, q_start=replay.initial_pose())
    first = replay.initial_pose() if replay.config.lead_in_speed > 0 else None  # every arm's IK, before torque
    check_rig_moves(replay, first=first, rest=shutdown == "rest")
    bus = RigBus({name: s.bus for name, s in setups.items()})
    with connected(bus):
        summary = replay.run(bus)
        if shutdown == "rest":
            try:
                park_rig(replay, bus)
            except BusError as exc:
                exc.summary = summary
                raise
    return summary
