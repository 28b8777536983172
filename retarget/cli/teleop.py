"""'retarget teleop': move the arm's tool point to where you say: one point, a stream (stdin, UDP), or keys.

Targets are metres in the arm's base frame (x forward, y left, z up), or in the world frame with
'--frame world' (the base sits at '--base-pose' in it; arm files carry no world pose, so by default
world = base).  Every target goes through the same gate (size limit, parse, finite, inside the box and
within reach + margin); rejected ones are counted and never move the arm.  The tool point's setpoint
moves at most '--max-speed' m/s and each joint at most its max velocity; the same control loop,
bus options, telemetry, summary and Ctrl-C shutdown as 'retarget replay'.

A stream (--stdin, --udp) is smoothed as it arrives by a One-Euro filter (a low-pass whose cutoff rises
with the hand's speed: '--filter-min-cutoff' + '--filter-beta' x speed).  Its lag with the defaults, for a
100 Hz stream at steady speed: 31 ms at 0.05 m/s, 15 ms at 0.2 m/s, 5 ms at 1 m/s (measured); '--no-filter'
turns it off.  A single '--to' target and the keys are not filtered: there is nothing to smooth.

Exit status: 0 when the last target was reached within '--tolerance' (checked by FK of the positions
read back from the servos), 3 when it was not (the arm stays at the nearest point it reached), 2 for bad
input, 4 for a bus failure, 130 after Ctrl-C, 143 after SIGTERM, 129 after SIGHUP (each runs the same
shutdown, '--shutdown').
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
import threading
from collections.abc import Callable
from typing import Any

from retarget.arm import Arm
from retarget.cli import EXIT_UNREACHED, print_json
from retarget.cli._arm import add_arm_arguments, add_collision_arguments, collision_model, load_arm_option
from retarget.cli._bus import (
    BusSetup,
    Stopped,
    add_bus_arguments,
    build_bus,
    check_bus_options,
    failure_summary,
    one_port,
    say,
    signals_stop,
)
from retarget.cli._gripper import TELEOP_HELP as TELEOP_GRIPPER_HELP
from retarget.cli._gripper import gripper_on_tick, parse_closure
from retarget.cli._view import add_view_arguments, check_view_options, forward, live_view, serve_web
from retarget.cli.options import OPTIONS
from retarget.cli.replay import number, optional_count, optional_number
from retarget.cli.tui import Jog, KeySource, TerminalUI
from retarget.control.bus import connected
from retarget.control.loop import LoopConfig, TickRecord
from retarget.control.park import check_moves, park
from retarget.control.summary import RunSummary
from retarget.control.telemetry import TelemetryWriter
from retarget.control.tracking import TickTracker
from retarget.errors import BusError, ConfigError
from retarget.mapping.filter import DEFAULT_BETA, DEFAULT_MIN_CUTOFF_HZ, OneEuro
from retarget.teleop import Follower, TeleopResult, run_teleop, tool_point
from retarget.teleop.gate import BasePose, TargetBounds, TargetGate
from retarget.teleop.sources import OneShotSource, Source, StdinSource, UdpSource, parse_address

DEFAULT_UDP_TIMEOUT = 1.0  #: s, the dead-man timeout of --udp unless --timeout says otherwise
DEFAULT_UDP_MAX_LAG = 1.0  #: s, --udp skips targets this far behind the newest unless --max-lag says otherwise

EXAMPLES = """\
examples:
  retarget teleop --to 0.3,0,0.2                    move the tool point there (simulated wx250s), report, exit 0/3
  retarget teleop --to 0.3,0,0.2 --rpy 0,90,0 --fast   with the tool pointing down, on a virtual clock
  retarget teleop --to 1,2,0.2 --frame world --base-pose 0.7,2,0,0,0,90
  retarget teleop --arm koch --to=-0.16,0,0.18 --fast   a negative first value needs '='
  printf '0.3 0 0.2\\n0.3 0.1 0.25\\n' | retarget teleop --stdin --fast --json
  retarget teleop --udp 9000 --timeout 0.5 --port /dev/ttyUSB0     datagrams on 127.0.0.1:9000
  retarget teleop --interactive --port /dev/ttyUSB0 --max-speed 0.05
  retarget teleop --stdin --telemetry run.csv < path.txt            one 'x y z' or JSON line per target
  retarget teleop --udp 9000 --filter-min-cutoff 0.5 --filter-beta 40   a still hand smoother, a fast one quicker
  retarget teleop --udp 9000 --no-filter            the stream as it comes (no One-Euro smoothing, no lag)
  retarget teleop --to 0.3,0,0.2 --keep-out box:0.25,-0.05,0,0.35,0.05,0.1   a box the arm keeps out of
  retarget teleop --arm vx300s --to 0.3,0,0.2 --gripper close    and close the gripper
  printf '0.3 0 0.2 g=0\\ng=1\\n' | retarget teleop --arm vx300s --stdin --fast   g: gripper 0 (open)..1 (closed)
  retarget teleop --rig aloha --to "left 0.3 0.35 0.2 right 0.3 -0.35 0.2" --fast   both arms, world frame
  printf 'left 0.3 0.35 0.2\\nright 0.3 -0.3 0.25\\n' | retarget teleop --rig wx250s-pair --stdin --dry-run
  retarget teleop --rig aloha --udp 9000 --port left=/dev/ttyUSB0 --port right=/dev/ttyUSB1
  retarget teleop --rig wx250s-pair --interactive --dry-run     keys move one arm (world frame), Tab the other
  retarget teleop --rig aloha --stdin --shutdown rest --telemetry rig.csv < moves.txt   both to rest at the end
"""


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    parser: argparse.ArgumentParser = subparsers.add_parser(
        "teleop",
        help="move the tool point to a target: one point, a stream on stdin/UDP, or keys",
        description=__doc__.split("\n\n")[0].split(": ", 1)[1] + "\n\n" + "\n\n".join(__doc__.split("\n\n")[1:]),
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    mode = parser.add_argument_group("where the targets come from (one of)").add_mutually_exclusive_group(required=True)
    mode.add_argument(
        "--to",
        metavar="X,Y,Z",
        help="one target, metres; exit 0 when reached, 3 when unreachable (a negative X: --to=-0.2,0,0.1)",
    )
    mode.add_argument("--stdin", action="store_true", help='targets as lines: \'x y z\' or JSON {"x":..,"y":..,"z":..}')
    mode.add_argument("--udp", metavar="[HOST:]PORT", help="targets as datagrams; binds 127.0.0.1 unless HOST is given")
    mode.add_argument("--interactive", action="store_true", help="keys nudge the target (needs a terminal)")

    t = parser.add_argument_group("targets")
    t.add_argument("--rpy", metavar="R,P,Y", help="with --to: tool orientation, degrees (URDF roll-pitch-yaw)")
    t.add_argument("--gripper", metavar="open|close|0..1", help=TELEOP_GRIPPER_HELP)
    t.add_argument("--frame", choices=("base", "world"), default="base", help="frame of the targets (default base)")
    t.add_argument("--base-pose", metavar="X,Y,Z[,R,P,Y]", help="the arm base in the world (m, deg); default origin")
    t.add_argument(
        "--timeout", metavar="S", help=f"hold when no target came for S s (default: off; --udp {DEFAULT_UDP_TIMEOUT:g})"
    )
    t.add_argument(
        "--max-lag",
        metavar="S",
        help=f"skip targets S s older than the newest (default: visit all; --udp {DEFAULT_UDP_MAX_LAG:g})",
    )
    t.add_argument("--max-speed", default="0.2", metavar="M/S", help="Cartesian speed limit of the tool (default 0.2)")
    t.add_argument("--tolerance", default="0.005", metavar="M", help="reached within this distance (default 0.005)")
    t.add_argument("--box", metavar="X0,Y0,Z0,X1,Y1,Z1", help="accept targets only inside this box, metres, base frame")
    t.add_argument("--margin", default="0.2", metavar="M", help="accept targets up to reach + M from the shoulder")
    t.add_argument("--max-bytes", default="1024", metavar="N", help="size limit of a line or datagram (default 1024)")
    f = parser.add_argument_group("smoothing of a stream (--stdin, --udp): One-Euro, on by default")
    f.add_argument(
        "--filter-min-cutoff",
        default=None,
        metavar="HZ",
        help=f"cutoff of a still hand (default {DEFAULT_MIN_CUTOFF_HZ:g}; lower: smoother, more lag when slow)",
    )
    f.add_argument(
        "--filter-beta",
        default=None,
        metavar="HZ_PER_M_S",
        help=f"cutoff rise per m/s of speed (default {DEFAULT_BETA:g}; higher: less lag when fast, more jitter)",
    )
    f.add_argument("--no-filter", action="store_true", help="follow the stream unfiltered")

    b = parser.add_argument_group("arm, bus and loop (as in replay; --shutdown defaults to hold here)")
    add_arm_arguments(b)
    add_collision_arguments(b)
    b.add_argument("--rate", default="100", metavar="HZ", help="control ticks per second (default 100)")
    b.add_argument("--velocity-scale", default="1", metavar="F", help="fraction of each joint's max speed (default 1)")
    b.add_argument("--max-ticks", default=None, metavar="N", help="stop after N ticks")
    b.add_argument(
        "--rig",
        default=None,
        metavar="NAME|FILE",
        help="every arm of a rig (aloha, wx250s-pair, a file); 'left x y z right x y z', world frame",
    )
    b.add_argument(
        "--dry-run",
        action="store_true",
        help="with --rig: no bus, from the rest poses, on a virtual clock (--udp, --interactive: real time)",
    )
    add_bus_arguments(b, shutdown="hold", rig_ports=True)
    add_view_arguments(b, live=True)
    return parser


def _numbers(text: str | None, *, option: str, count: tuple[int, ...]) -> list[float] | None:
    if text is None:
        return None
    try:
        values = [float(v) for v in text.replace(" ", "").split(",")]
    except ValueError:
        values = []
    if len(values) not in count:
        want = " or ".join(str(c) for c in count)
        raise ConfigError(f"Expected {want} comma-separated numbers", key=option, value=text)
    return values


def _check_options(args: argparse.Namespace) -> dict[str, Any]:
    """Validate the option values (ConfigError naming the option); returns the parsed numbers."""

    check_bus_options(args)
    if args.rpy is not None and args.to is None:
        raise ConfigError("--rpy goes with --to (stream messages carry their own rpy)", key="--rpy", value=args.rpy)
    if args.interactive and args.fast:
        raise ConfigError("--interactive runs in real time; drop --fast", key="--fast", value=True)
    smoothing = (args.filter_min_cutoff, args.filter_beta)
    if (args.no_filter or any(v is not None for v in smoothing)) and not (args.stdin or args.udp is not None):
        option = "--no-filter" if args.no_filter else "--filter-min-cutoff" if smoothing[0] else "--filter-beta"
        raise ConfigError("the stream filter goes with --stdin or --udp (a single target or keys: nothing to smooth)",
                          key=option)  # fmt: skip
    if args.base_pose is not None and args.frame != "world":
        raise ConfigError("--base-pose goes with --frame world", key="--base-pose", value=args.base_pose)
    out: dict[str, Any] = {
        "max_speed": number(args.max_speed, option="--max-speed"),
        "tolerance": number(args.tolerance, option="--tolerance"),
        "margin": number(args.margin, option="--margin"),
        "max_bytes": optional_count(args.max_bytes, option="--max-bytes"),
        "timeout": optional_number(args.timeout, option="--timeout"),
        "max_lag": optional_number(args.max_lag, option="--max-lag"),
        "box": _numbers(args.box, option="--box", count=(6,)),
        "base_pose": _numbers(args.base_pose, option="--base-pose", count=(3, 6)),
        "min_cutoff": number(args.filter_min_cutoff or str(DEFAULT_MIN_CUTOFF_HZ), option="--filter-min-cutoff"),
        "beta": number(args.filter_beta or str(DEFAULT_BETA), option="--filter-beta"),
    }
    OneEuro(min_cutoff=out["min_cutoff"], beta=out["beta"])  # checked now: a bad value names its option
    if out["base_pose"] is not None and not all(math.isfinite(v) for v in out["base_pose"]):
        # the pose is the CLI's own: a NaN in it would reach the gate as a NaN target, which names --to
        raise ConfigError("Expected finite numbers", key="--base-pose", value=args.base_pose)
    if args.udp is not None:
        out["timeout"] = DEFAULT_UDP_TIMEOUT if out["timeout"] is None else out["timeout"]
        out["max_lag"] = DEFAULT_UDP_MAX_LAG if out["max_lag"] is None else out["max_lag"]
    for key in ("tolerance", "timeout", "max_lag"):
        value = out[key]
        if value is not None and not (value > 0 and value < float("inf")):
            raise ConfigError("Expected a number > 0", key=OPTIONS[key], value=value)
    if not out["max_speed"] > 0:
        raise ConfigError("Expected a speed > 0 m/s ('inf' for none)", key="--max-speed", value=out["max_speed"])
    if not out["max_bytes"] >= 1:
        raise ConfigError("Expected at least 1 byte", key="--max-bytes", value=out["max_bytes"])
    return out


def _gate(args: argparse.Namespace, arm: Arm, clock: Any, opts: dict[str, Any]) -> TargetGate:

    bounds = TargetBounds.for_arm(arm, margin=opts["margin"], box=opts["box"], collision=opts.get("collision"))
    pose = None
    if args.frame == "world":
        values = opts["base_pose"] or [0.0, 0.0, 0.0]
        pose = BasePose.from_xyz_rpy(values[:3], values[3:6] or (0.0, 0.0, 0.0))
    return TargetGate(bounds, clock=clock, frame_pose=pose, max_bytes=opts["max_bytes"])


def _source(args: argparse.Namespace, gate: TargetGate) -> Source:

    if args.to is not None:
        return OneShotSource(gate, args.to, rpy=args.rpy)
    if args.stdin:
        return StdinSource(gate)
    if args.udp is not None:
        host, port = parse_address(args.udp)
        source = UdpSource(gate, host, port)
        print(f"retarget: listening for targets on udp {source.address[0]}:{source.address[1]}", file=sys.stderr)
        return source
    raise AssertionError("the argument parser requires a mode")


def _progress(follower: Follower) -> Any:
    def show(r: TickRecord) -> None:
        tool = follower.tool
        goal = follower.last_target
        dist = (
            "" if goal is None or tool is None else f"  {1e3 * float(((tool - goal) ** 2).sum() ** 0.5):6.1f} mm to go"
        )
        print(f"retarget: t={r.time:6.1f} s  {follower.phase.value:<8}{dist}", file=sys.stderr, flush=True)

    return show


def _name(args: argparse.Namespace) -> str:
    if args.to is not None:
        return f"--to {args.to}" + (f" --rpy {args.rpy}" if args.rpy else "")
    return "--stdin" if args.stdin else f"--udp {args.udp}" if args.udp else "--interactive"


def run(args: argparse.Namespace) -> int:

    ports = args.port
    args.port = None if args.rig is not None else one_port(ports)  # --rig: NAME=PORT per arm
    if args.dry_run and args.rig is None:
        raise ConfigError("--dry-run goes with --rig (one arm: no --port runs a simulated bus)", key="--dry-run")
    opts = _check_options(args)
    check_view_options(args)
    config = LoopConfig(
        rate=number(args.rate, option="--rate"),
        velocity_scale=number(args.velocity_scale, option="--velocity-scale"),
        max_ticks=optional_count(args.max_ticks, option="--max-ticks"),
        ik_tolerance=min(1e-3, opts["tolerance"] / 2),  # a tight --tolerance tightens the IK too
    )
    if args.interactive and not (sys.stdin.isatty() and sys.stdout.isatty()):
        raise ConfigError("--interactive needs a terminal on stdin and stdout", key="--interactive", value=True)
    if args.rig is not None:
        from retarget.cli._rig_teleop import run_rig

        return run_rig(argparse.Namespace(**{**vars(args), "port": ports}), opts, config)
    arm = load_arm_option(args)
    config = dataclasses.replace(config, collision=collision_model(args, arm))
    setup = build_bus(args, arm, config)
    source: Source | None = None
    telemetry: TelemetryWriter | None = None
    on_tick: Callable[[TickRecord], None] | None = None
    followers: list[Follower] = []  # the run's follower, once built: the telemetry's tracking reference
    stop = threading.Event()
    stopped = Stopped()
    try:
        gate = _gate(args, arm, setup.clock, {**opts, "collision": config.collision})
        if args.gripper is not None:
            if arm.gripper is None:
                message = f"Expected an arm with a [gripper], got {arm.name}"
                raise ConfigError(message, key="gripper", value=args.gripper)
            gate.gripper = parse_closure(args.gripper)
        if not args.interactive:
            source = _source(args, gate).start()
        if args.telemetry is not None:
            out = sys.stdout if args.telemetry == "-" else args.telemetry
            tracking = TickTracker(arm, lambda _record: followers[-1].reference if followers else None)
            on_tick = telemetry = TelemetryWriter(
                out, arm.joint_names, gripper=arm.gripper is not None, tracking=tracking
            ).open()
        check_moves(arm, config, first=None, rest=args.shutdown == "rest")  # before torque is on
        with signals_stop(stop.set) as stopped, connected(setup.bus), live_view(args, arm, name=_name(args)) as live:
            on_tick = forward(on_tick=on_tick, live=live)
            if arm.gripper is not None:  # the latest g of the messages (or --gripper, or keys) each tick
                on_tick = gripper_on_tick(lambda _t: gate.gripper, setup.bus, on_tick)
            if source is None:
                result = _interactive(arm, setup, gate, config, opts, stop, on_tick, followers)
            else:
                follower = Follower(
                    arm,
                    source,
                    clock=setup.clock,
                    rate=config.rate,
                    max_speed=opts["max_speed"],
                    tolerance=min(1.5 * config.ik_tolerance, opts["tolerance"]),
                    timeout=opts["timeout"],
                    max_lag=opts["max_lag"],
                    lockstep=args.fast,
                    smoothing=None if args.no_filter else OneEuro(min_cutoff=opts["min_cutoff"], beta=opts["beta"]),
                )
                followers.append(follower)
                progress = _progress(follower) if args.progress or sys.stderr.isatty() else None
                result = run_teleop(
                    arm,
                    follower,
                    config=config,
                    clock=setup.clock,
                    bus=setup.bus,
                    tolerance=opts["tolerance"],
                    on_tick=on_tick,
                    on_progress=progress,
                    stop=stop,
                    name=_name(args),
                )
            if args.shutdown == "rest":  # the bus's rest move next: through home when straight collides
                park(arm, setup.bus, config=config, clock=setup.clock)
    except BusError as exc:
        if args.json and isinstance(exc.summary, RunSummary):  # the loop's summary of the ticks that ran
            print_json(failure_summary({**exc.summary.to_dict(), "teleop": None}, exc))
        raise
    finally:
        if source is not None:
            source.close()
        if telemetry is not None:
            telemetry.close()
        setup.release()
    _report(args, result, gate.frame_pose)
    serve_web(args)
    if result.summary.interrupted:
        return stopped.exit_status
    if result.target is not None and not result.reached_target and not args.interactive:
        return EXIT_UNREACHED
    return 0


def _report(args: argparse.Namespace, result: TeleopResult, pose: BasePose | None) -> None:
    """The summary on stderr; the result on stdout (JSON, or a line in the frame the targets were given in), or on
    stderr when stdout carries the telemetry (``--telemetry -``)."""
    s = result.summary
    head = f"teleop{' (interrupted)' if s.interrupted else ''}: {s.clip} on {s.arm}: {s.ticks} ticks at "
    head += f"{s.rate_hz:g} Hz, {s.run_time_s:.2f} s in {s.wall_time_s:.3f} s ({s.real_time_factor:.1f}x real time)"
    say("\n".join([head, *s.format().split("\n")[1:], result.format()]))  # SIGHUP: the terminal may be gone
    if args.json:
        doc = result.to_dict()
        if pose is not None and result.target is not None:
            doc["target_world_m"] = [round(float(v), 6) for v in pose.to_world(result.target)]
            doc["reached_world_m"] = [round(float(v), 6) for v in pose.to_world(result.reached)]
        print_json({**s.to_dict(), "teleop": doc})
        return
    if result.target is None or result.residual is None:
        print("no target received", file=sys.stderr)
        return
    out = sys.stderr if args.telemetry == "-" else sys.stdout
    r, t = result.reached, result.target
    frame = "base"
    if pose is not None:
        r, t, frame = pose.to_world(r), pose.to_world(t), "world"
    verdict = "reached" if result.reached_target else "NOT reached (nearest point)"
    error = result.orientation_error
    angle = "" if math.isnan(error) else f"  orientation {math.degrees(error):.2f} deg"
    print(
        f"target {t[0]:.4f} {t[1]:.4f} {t[2]:.4f} m  reached {r[0]:.4f} {r[1]:.4f} {r[2]:.4f} m ({frame} frame)  "
        f"residual {result.residual * 1e3:.2f} mm{angle}  {verdict} (tolerance {result.tolerance * 1e3:g} mm)",
        file=out,
    )


def _interactive(
    arm: Arm,
    setup: BusSetup,
    gate: TargetGate,
    config: LoopConfig,
    opts: dict[str, Any],
    stop: threading.Event,
    telemetry: Callable[[TickRecord], None] | None,
    followers: list[Follower],
) -> TeleopResult:
    """The curses UI around the loop: keys feed a KeySource, the screen is drawn from on_tick (the follower is
    added to ``followers``)."""
    import curses  # here, not at the top: Windows Pythons have no curses, and only --interactive needs it

    q0 = setup.bus.read_positions()
    jog = Jog(target=tool_point(arm, q0), home=tool_point(arm, arm.home), bounds=gate.bounds)
    source = KeySource(gate, jog)
    follower = Follower(
        arm, source, clock=setup.clock, rate=config.rate, max_speed=opts["max_speed"], timeout=opts["timeout"]
    )  # no smoothing: a key's target is exact, there is no noise to smooth
    followers.append(follower)

    def session(screen: Any) -> TeleopResult:
        ui = TerminalUI(screen, source, arm, stop=follower.cancel)  # q: hold, settle, end (Ctrl-C: interrupt)

        def on_tick(record: TickRecord) -> None:
            ui(record)
            if telemetry is not None:
                telemetry(record)

        return run_teleop(
            arm,
            follower,
            config=config,
            clock=setup.clock,
            bus=setup.bus,
            tolerance=opts["tolerance"],
            on_tick=on_tick,
            stop=stop,
            name="--interactive",
        )

    return curses.wrapper(session)
