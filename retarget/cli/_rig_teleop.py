"""``retarget teleop --rig``: every arm of a rig follows its own targets, from one stream of two-arm messages.

A message names the rig's arms and gives each a point in the rig's WORLD frame (metres; degrees for an optional
roll pitch yaw); an arm left out keeps its target::

    left 0.3 0.35 0.2 right 0.3 -0.35 0.2
    {"left": {"x": 0.3, "y": 0.35, "z": 0.2}, "right": {"x": 0.3, "y": -0.35, "z": 0.2, "rpy": [0, 90, 0]}}

Each arm's part passes that arm's own gate (box, reach + ``--margin``, blocked zones, in its base frame); a message
is taken whole or not at all (:mod:`retarget.rig.messages`).  Each arm follows at ``--max-speed``; every tick both
arms are checked against themselves, the world and each other, and written together (:mod:`retarget.rig.teleop`).
Ports come from the rig file (``sim://`` by default), ``--port NAME=PORT`` overrides one arm's; a fault on any arm
ends the run and every arm's shutdown runs.  ``--dry-run``: no bus, from the arms' rest poses, on a virtual
clock (``--udp``: in real time).

Exit status as one arm's teleop: 0 when every arm that got a target reached its last one, 3 when one did not,
2 bad input, 4 a bus failure, 130/143/129 after a signal.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
import threading
from collections.abc import Callable, Iterator
from typing import Any

from retarget.cli import EXIT_UNREACHED, print_json
from retarget.cli._arm import DEFAULT_ARM, collision_model
from retarget.cli._bus import Stopped, failure_summary, say, signals_stop
from retarget.cli._rig_replay import check_fast, open_buses, ported, release, rig_clock
from retarget.control.bus import Bus, connected
from retarget.control.clock import MonotonicClock, VirtualClock
from retarget.control.loop import LoopConfig, TickRecord
from retarget.control.summary import RunSummary
from retarget.errors import BusError, ConfigError
from retarget.mapping.filter import OneEuro
from retarget.rig import RigBus, RigGate, RigInput, RigPlant, RigStdinSource, RigUdpSource, load_rig
from retarget.rig.teleop import RigTeleopResult, rig_followers, run_rig_teleop
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
    ("telemetry", "--telemetry", None),
    ("record", "--record", None),
)


def _refuse(args: argparse.Namespace) -> None:
    """The options of one arm, and those not done for a rig yet: a ConfigError naming the option."""
    for field, option, default in _ONE_ARM:
        value = getattr(args, field, default)
        if value != default:
            raise ConfigError("Expected no such option with --rig (the rig file names its arms; messages carry "
                              "each arm's orientation)", key=option, value=value)  # fmt: skip
    for field, option in (("view", "--view"), ("web", "--web"), ("interactive", "--interactive")):
        if getattr(args, field, False):
            raise ConfigError("not available with --rig yet", key=option, value=True)
    if args.frame != "base":
        raise ConfigError("Expected no --frame with --rig: its messages are in the rig's world frame", key="--frame",
                          value=args.frame)  # fmt: skip
    if args.shutdown == "rest":
        raise ConfigError("Expected hold or off with --rig (a rig's collision-checked move to rest is not done yet)",
                          key="--shutdown", value=args.shutdown)  # fmt: skip
    if args.dry_run and (args.port or args.fast):
        option, value = ("--port", args.port[0]) if args.port else ("--fast", True)
        raise ConfigError("--dry-run uses no bus (and always a virtual clock)", key=option, value=value)


# ------------------------------------------------------------------------------------------ buses
# TODO(lead): a local copy of the rig's bus setup; merge with retarget.cli._rig_replay.open_buses/rig_clock.


# ------------------------------------------------------------------------------------------ the run


def _name(args: argparse.Namespace) -> str:
    if args.to is not None:
        return f"--to {args.to}"
    return "--stdin" if args.stdin else f"--udp {args.udp}"


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
    setups = {} if args.dry_run else open_buses(args, rig, config)
    # a dry run on virtual time, but live UDP in real time
    clock = rig_clock(args, setups) if setups else MonotonicClock() if args.udp is not None else VirtualClock()
    bus = RigBus({name: s.bus for name, s in setups.items()}) if setups else None
    reader: Source | None = None
    stop = threading.Event()
    stopped = Stopped()
    try:
        gate = RigGate.for_rig(rig, clock=clock, margin=opts["margin"], models=models, max_bytes=opts["max_bytes"])
        rig_input = RigInput(gate)
        reader = _reader(args, gate, rig_input)
        stream = reader is not None and not args.no_filter

        def smoothing() -> OneEuro:
            return OneEuro(min_cutoff=opts["min_cutoff"], beta=opts["beta"])

        knobs = {"max_speed": opts["max_speed"], "tolerance": min(1.5 * config.ik_tolerance, opts["tolerance"]),
                 "timeout": opts["timeout"], "max_lag": opts["max_lag"]}  # fmt: skip
        followers = rig_followers(rig, rig_input, clock=clock, rate=config.rate,
                                  smoothing=smoothing if stream else None, **knobs)  # fmt: skip
        progress = _progress(followers) if args.progress or sys.stderr.isatty() else None
        with signals_stop(stop.set) as stopped, _maybe_connected(bus):
            result = run_rig_teleop(
                rig, followers, config=config, clock=clock, bus=bus, models=models,
                clearance=min(m.clearance for m in models.values()), rig_input=rig_input,
                lockstep=isinstance(clock, VirtualClock), q_start=None if bus is not None else RigPlant.of(rig).rest,
                tolerance=opts["tolerance"], on_progress=progress, stop=stop, name=_name(args),
            )  # fmt: skip
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
    if result.any_target and not result.reached_targets:
        return EXIT_UNREACHED
    return 0


def _report(args: argparse.Namespace, result: RigTeleopResult) -> None:
    """The summary on stderr; the result on stdout: JSON, or one line per arm (world frame)."""
    s = result.summary
    head = f"teleop{' (interrupted)' if s.interrupted else ''}{' (dry run)' if s.dry_run else ''}: {s.clip} on rig "
    head += f"{result.rig.name}: {s.ticks} ticks "
    head += f"at {s.rate_hz:g} Hz, {s.run_time_s:.2f} s in {s.wall_time_s:.3f} s ({s.real_time_factor:.1f}x real time)"
    say("\n".join([head, *s.format().split("\n")[1:], result.format()]))
    if args.json:
        print_json({**s.to_dict(), "teleop": result.to_dict()})
        return
    for name, r in result.arms.items():
        target, reached = result.world(name)
        if target is None or r.residual is None:
            print(f"{name}: no target received")
            continue
        verdict = "reached" if r.reached_target else "NOT reached (nearest point)"
        print(
            f"{name}: target {target[0]:.4f} {target[1]:.4f} {target[2]:.4f} m  reached {reached[0]:.4f} "
            f"{reached[1]:.4f} {reached[2]:.4f} m (world frame)  residual {r.residual * 1e3:.2f} mm  {verdict} "
            f"(tolerance {r.tolerance * 1e3:g} mm)"
        )
