"""``retarget teleop --rig``: every arm of a rig follows its own targets, from one stream of two-arm messages, or keys.

A message names the rig's arms and gives each a point in the rig's WORLD frame (metres; degrees for an optional
roll pitch yaw); an arm left out keeps its target::

    left 0.3 0.35 0.2 right 0.3 -0.35 0.2
    {"left": {"x": 0.3, "y": 0.35, "z": 0.2}, "right": {"x": 0.3, "y": -0.35, "z": 0.2, "rpy": [0, 90, 0]}}

Each arm's part passes that arm's own gate (box, reach + ``--margin``, blocked zones, in its base frame); a message
is taken whole or not at all (:mod:`retarget.rig.messages`).  ``--interactive``: the keys of one arm's interactive
mode move the selected arm's target, in the rig's world frame too (the same direction for every arm however its
base is turned); Tab selects the next arm (:class:`~retarget.cli.tui.RigKeys`, ``RigTerminalUI``).
Each arm follows at ``--max-speed``; every tick both arms are checked against themselves, the world and each other,
and written together (:mod:`retarget.rig.teleop`).  Ports come from the rig file (``sim://`` by default),
``--port NAME=PORT`` overrides one arm's; a fault on any arm ends the run and every arm's shutdown runs (each arm's
own, as after a one-arm fault).  ``--shutdown rest``: after the run (done, or stopped by a signal) the arms go to
rest together through the tick loop, checked arm against arm (:func:`~retarget.cli._rig_replay.park_arms`, as
``replay --rig``); the route is checked before torque is on.  ``--telemetry``: the rig's CSV
(:class:`~retarget.rig.telemetry.RigTelemetry`), each arm's tracking error against its targets as they came in.
``--dry-run``: no bus, from the arms' rest poses, on a virtual clock (``--udp``, ``--interactive``: in real time).

Exit status as one arm's teleop: 0 when every arm that got a target reached its last one (``--interactive``:
always), 3 when one did not, 2 bad input, 4 a bus failure, 130/143/129 after a signal.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
import threading
from collections.abc import Callable, Iterator
from typing import IO, Any

from retarget.cli import EXIT_UNREACHED, print_json
from retarget.cli._arm import DEFAULT_ARM, collision_model
from retarget.cli._bus import Stopped, failure_summary, say, signals_stop
from retarget.cli._rig_replay import check_fast, open_buses, park_arms, ported, release, rig_clock
from retarget.control.bus import Bus, connected
from retarget.control.clock import Clock, MonotonicClock, VirtualClock
from retarget.control.loop import LoopConfig, TickRecord, tee
from retarget.control.safety import require_route
from retarget.control.summary import RunSummary
from retarget.errors import BusError, ConfigError
from retarget.mapping.filter import OneEuro
from retarget.rig import Rig, RigBus, RigGate, RigInput, RigPlant, RigStdinSource, RigUdpSource, load_rig
from retarget.rig.check import RigRoutes
from retarget.rig.clearance import RigClearance
from retarget.rig.telemetry import RigTelemetry
from retarget.rig.teleop import RigTeleopRecords, RigTeleopResult, rig_followers, run_rig_teleop
from retarget.teleop import tool_point
from retarget.teleop.follower import Follower
from retarget.teleop.sources import Source, parse_address

__all__ = ["run_rig"]

#: one-arm options that --rig refuses: (field, option, its default)
_ONE_ARM = (
    ("arm", "--arm", DEFAULT_ARM),
    ("base", "--base", None),
    ("tip", "--tip", None),
    ("calibration", "--calibration", None),
    ("rpy", "--rpy", None),
    ("gripper", "--gripper", None),
    ("base_pose", "--base-pose", None),
    ("box", "--box", None),
    ("record", "--record", None),
)


def _refuse(args: argparse.Namespace) -> None:
    """The options of one arm, and the live views (not done for a rig yet): a ConfigError naming the option."""
    for field, option, default in _ONE_ARM:
        value = getattr(args, field, default)
        if value != default:
            raise ConfigError("Expected no such option with --rig (the rig file names its arms; messages carry "
                              "each arm's orientation)", key=option, value=value)  # fmt: skip
    for field, option in (("view", "--view"), ("web", "--web")):
        if getattr(args, field, False):
            raise ConfigError("not available with --rig yet", key=option, value=True)
    if args.frame != "base":
        raise ConfigError("Expected no --frame with --rig: its messages are in the rig's world frame", key="--frame",
                          value=args.frame)  # fmt: skip
    if args.dry_run and (args.port or args.fast):
        option, value = ("--port", args.port[0]) if args.port else ("--fast", True)
        raise ConfigError("--dry-run uses no bus (and its own clock)", key=option, value=value)


# ------------------------------------------------------------------------------------------ the run


def _name(args: argparse.Namespace) -> str:
    if args.to is not None:
        return f"--to {args.to}"
    return "--stdin" if args.stdin else f"--udp {args.udp}" if args.udp is not None else "--interactive"


def _progress(followers: dict[str, Follower]) -> Callable[[TickRecord], None]:
    def show(r: TickRecord) -> None:
        arms = "  ".join(f"{name} {f.phase.value:<8}" for name, f in followers.items())
        print(f"retarget: t={r.time:6.1f} s  {arms}", file=sys.stderr, flush=True)

    return show


def _reader(args: argparse.Namespace, gate: RigGate, rig_input: RigInput) -> Source | None:
    """Start taking messages: the one-shot ``--to`` is queued now (None: no reader), else a reader thread."""
    if args.to is not None:
        rig_input.put(gate.one_shot(args.to))
        rig_input.close()
        return None
    if args.stdin:
        return RigStdinSource(rig_input).start()
    host, port = parse_address(args.udp)
    source = RigUdpSource(rig_input, host, port)
    print(f"retarget: listening for targets on udp {source.address[0]}:{source.address[1]}", file=sys.stderr)
    return source.start()


@contextlib.contextmanager
def _maybe_connected(bus: Bus | None) -> Iterator[None]:
    if bus is None:
        yield
        return
    with connected(bus):
        yield


def run_rig(args: argparse.Namespace, opts: dict[str, Any], config: LoopConfig) -> int:
    """``retarget teleop --rig``: ``opts`` the option values checked by one arm's teleop, ``config`` its loop."""
    _refuse(args)
    rig = ported(load_rig(args.rig), args.port)
    check_fast(args, rig)
    models = {a.name: collision_model(args, a.arm) for a in rig.arms}
    between = RigClearance(rig, clearance=min(m.clearance for m in models.values()))
    plant = RigPlant.of(rig)
    rest = args.shutdown == "rest" and not args.dry_run
    if rest:  # before torque is on, as one arm's check_moves
        require_route(RigRoutes(plant, models, between), plant.home, plant.rest, waypoints=(),
                      what="move of the rig's arms to rest")  # fmt: skip
    setups = {} if args.dry_run else open_buses(args, rig, config)
    # a dry run on virtual time, but live UDP and keys in real time
    real_time = args.udp is not None or args.interactive
    clock = rig_clock(args, setups) if setups else MonotonicClock() if real_time else VirtualClock()
    bus = RigBus({name: s.bus for name, s in setups.items()}) if setups else None
    reader: Source | None = None
    stop = threading.Event()
    stopped = Stopped()
    try:
        gate = RigGate.for_rig(rig, clock=clock, margin=opts["margin"], models=models, max_bytes=opts["max_bytes"])
        rig_input = None if args.interactive else RigInput(gate)
        reader = None if rig_input is None else _reader(args, gate, rig_input)
        common = {"config": config, "clock": clock, "bus": bus, "models": models, "clearance": between.clearance,
                  "q_start": None if bus is not None else plant.rest, "tolerance": opts["tolerance"], "stop": stop,
                  "name": _name(args)}  # fmt: skip

        def follow(followers: dict[str, Follower], **more: Any) -> RigTeleopResult:
            """The run, with the telemetry of ``args.telemetry``; ``more``: run_rig_teleop's other arguments."""
            return _run(args.telemetry, rig, followers, **common, **more)

        with signals_stop(stop.set) as stopped, _maybe_connected(bus):
            if rig_input is None:
                result = _interactive(rig, gate, bus, clock, config, opts, follow)
            else:
                result = _stream(args, rig, rig_input, reader, clock, config, opts, follow)
            if rest and bus is not None:  # the arms to rest together, then each driver's rest move (torque off)
                try:
                    park_arms(plant, bus, config=config, clock=clock, models=models, between=between)
                except BusError as exc:
                    exc.summary = result.summary
                    raise
    except BusError as exc:
        if args.json and isinstance(exc.summary, RunSummary):
            print_json(failure_summary({**exc.summary.to_dict(), "teleop": None}, exc))
        raise
    finally:
        if reader is not None:
            reader.close()
        release(setups)
    _report(args, result)
    if result.summary.interrupted:
        return stopped.exit_status
    if result.any_target and not result.reached_targets and not args.interactive:
        return EXIT_UNREACHED
    return 0


def _stream(
    args: argparse.Namespace,
    rig: Rig,
    rig_input: RigInput,
    reader: Source | None,
    clock: Clock,
    config: LoopConfig,
    opts: dict[str, Any],
    follow: Callable[..., RigTeleopResult],
) -> RigTeleopResult:
    """``--to``, ``--stdin``, ``--udp``: each arm follows its part of the messages (a stream smoothed)."""
    stream = reader is not None and not args.no_filter

    def smoothing() -> OneEuro:
        return OneEuro(min_cutoff=opts["min_cutoff"], beta=opts["beta"])

    knobs = {"max_speed": opts["max_speed"], "tolerance": min(1.5 * config.ik_tolerance, opts["tolerance"]),
             "timeout": opts["timeout"], "max_lag": opts["max_lag"]}  # fmt: skip
    followers = rig_followers(rig, rig_input, clock=clock, rate=config.rate,
                              smoothing=smoothing if stream else None, **knobs)  # fmt: skip
    progress = _progress(followers) if args.progress or sys.stderr.isatty() else None
    return follow(followers, rig_input=rig_input, lockstep=isinstance(clock, VirtualClock), on_progress=progress)


def _interactive(
    rig: Rig,
    gate: RigGate,
    bus: Bus | None,
    clock: Clock,
    config: LoopConfig,
    opts: dict[str, Any],
    follow: Callable[..., RigTeleopResult],
) -> RigTeleopResult:
    """``--interactive``: the curses screen around the run; the keys move the selected arm's target, from where
    every arm's tool is now (world frame); ``q`` ends every arm's keys and cancels its target."""
    import curses  # here, not at the top: Windows Pythons have no curses, and only --interactive needs it

    from retarget.cli.tui import RigKeys, RigTerminalUI

    plant = RigPlant.of(rig)
    q0 = plant.split(bus.read_positions() if bus is not None else plant.rest)
    start = {a.name: a.placement.to_world(tool_point(a.arm, q0[a.name])) for a in rig.arms}
    home = {a.name: a.placement.to_world(tool_point(a.arm, a.arm.home)) for a in rig.arms}
    keys = RigKeys.for_gate(gate, start=start, home=home)
    # no smoothing: a key's target is exact, there is no noise to smooth
    followers = rig_followers(rig, keys.sources, clock=clock, rate=config.rate, max_speed=opts["max_speed"],
                              timeout=opts["timeout"])  # fmt: skip

    def cancel() -> None:
        for follower in followers.values():
            follower.cancel()

    def session(screen: Any) -> RigTeleopResult:
        return follow(followers, on_tick=RigTerminalUI(screen, keys, plant, followers, stop=cancel))

    result: RigTeleopResult = curses.wrapper(session)
    return result


def _run(
    telemetry: str | None,
    rig: Rig,
    followers: dict[str, Follower],
    *,
    on_tick: Callable[[TickRecord], None] | None = None,
    **run: Any,
) -> RigTeleopResult:
    """:func:`run_rig_teleop` with ``followers``, writing the rig's telemetry CSV to ``telemetry`` (a path, ``-``
    for stdout; None: none) after ``on_tick``; the file is flushed and closed on every way out."""
    records = RigTeleopRecords(rig, followers)
    with _telemetry(telemetry, records) as writer:
        ticks = tee(on_tick, writer)
        return run_rig_teleop(rig, followers, on_tick=ticks, records=records, **run)


@contextlib.contextmanager
def _telemetry(target: str | None, records: RigTeleopRecords) -> Iterator[RigTelemetry | None]:
    if target is None:
        yield None
        return
    out: str | IO[str] = sys.stdout if target == "-" else target
    with RigTelemetry(out, records, trackers=records.trackers()) as writer:
        yield writer


def _report(args: argparse.Namespace, result: RigTeleopResult) -> None:
    """The summary on stderr; the result on stdout: JSON, or one line per arm (world frame), on stderr when stdout
    carries the telemetry (``--telemetry -``)."""
    s = result.summary
    head = f"teleop{' (interrupted)' if s.interrupted else ''}{' (dry run)' if s.dry_run else ''}: {s.clip} on rig "
    head += f"{result.rig.name}: {s.ticks} ticks "
    head += f"at {s.rate_hz:g} Hz, {s.run_time_s:.2f} s in {s.wall_time_s:.3f} s ({s.real_time_factor:.1f}x real time)"
    say("\n".join([head, *s.format().split("\n")[1:], result.format()]))
    if args.json:
        print_json({**s.to_dict(), "teleop": result.to_dict()})
        return
    out = sys.stderr if args.telemetry == "-" else sys.stdout
    for name, r in result.arms.items():
        target, reached = result.world(name)
        if target is None or r.residual is None:
            print(f"{name}: no target received", file=out)
            continue
        verdict = "reached" if r.reached_target else "NOT reached (nearest point)"
        print(
            f"{name}: target {target[0]:.4f} {target[1]:.4f} {target[2]:.4f} m  reached {reached[0]:.4f} "
            f"{reached[1]:.4f} {reached[2]:.4f} m (world frame)  residual {r.residual * 1e3:.2f} mm  {verdict} "
            f"(tolerance {r.tolerance * 1e3:g} mm)",
            file=out,
        )
