"""``retarget replay``: play a BVH clip's arm motion on an arm, in a fixed-rate control loop.

With no arguments it replays the bundled demo clip on the default arm (wx250s)
over an in-process simulated bus in real time.  On a bus, a lead-in first moves
the arm from where it is to the clip's first pose at a gentle joint speed
(``--lead-in``), then the clip plays from its start.  ``--fast`` runs as fast as
possible on a virtual clock shared with the simulator; ``--dry-run`` solves
every tick without any bus, starting on the first target's solution (no lead-in:
no arm to move), like ``retarget export``.  Also home of the options ``retarget
export`` shares (clip window, mapping flags); the bus options live in
``retarget.cli._bus``, the arm options in ``retarget.cli._arm``.
"""

from __future__ import annotations

import argparse
import dataclasses
import re
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any, TypeVar

import retarget
from retarget.arm import Arm
from retarget.bvh import DEMO_CLIP
from retarget.bvh.motion import Motion
from retarget.cli import print_json
from retarget.cli._arm import add_arm_arguments, add_collision_arguments, collision_model, load_arm_option
from retarget.cli._bus import (
    add_bus_arguments,
    build_bus,
    check_bus_options,
    failure_summary,
    one_port,
    say,
    signals_stop,
)
from retarget.cli._gripper import add_replay_option as add_gripper_option
from retarget.cli._gripper import clip_track, gripper_on_tick
from retarget.cli._rig_replay import check_rig_replay, replay_rig
from retarget.cli._rig_run import add_rig_option, load_rig_inputs, played_mapping
from retarget.cli._view import add_view_arguments, check_view_options, forward, live_view, serve_web
from retarget.collision import CollisionModel
from retarget.control import ControlLoop, LoopConfig, TickRecord
from retarget.control.bus import connected
from retarget.control.clock import Clock, MonotonicClock, VirtualClock
from retarget.control.park import check_moves, park
from retarget.control.plan import JERK_COST
from retarget.control.summary import RunSummary
from retarget.control.telemetry import TelemetryWriter
from retarget.control.tracking import TickTracker
from retarget.errors import BusError, ConfigError
from retarget.mapping import Targets, retarget_targets
from retarget.mapping.config import MappingConfig

T = TypeVar("T")

EXAMPLES = """\
examples:
  retarget replay                                  the demo clip on wx250s, in-process simulated bus, real time
  retarget replay --fast --json                    as fast as possible (virtual clock), summary as JSON on stdout
  retarget replay dance.bvh --start 2 --end 300f   seconds or frames (suffix f) of the clip
  retarget replay dance.bvh --side left --speed 0.5 --telemetry run.csv
  retarget replay dance.bvh --dry-run --fast       solve every tick, no bus
  retarget replay dance.bvh --dry-run --no-look-ahead   solve each tick as it comes (lags fast motion)
  retarget replay dance.bvh --filter-cutoff 3 --dry-run   smoother targets (no lag; --no-filter: none)
  retarget replay dance.bvh --arm vx300s --port /dev/ttyUSB0 --shutdown rest
  retarget replay dance.bvh --port /dev/ttyUSB0 --lead-in 0.3   a gentler move to the clip's first pose
  retarget replay dance.bvh --arm robot.urdf --tip ee_link --port /dev/ttyUSB0   a URDF with several leaves
  retarget replay --port 'sim://wx250s?drop=0.05&seed=1'   a simulated bus with faults, by URL
  retarget replay dance.bvh --keep-out sphere:0.3,0,0.2,0.05 --clearance 15   stay 15 mm clear of a ball
  retarget replay pinch.bvh --arm vx300s --telemetry run.csv   the gripper follows the hand (thumb-index pinch)
  retarget replay dance.bvh --arm vx300s --gripper close        or a fixed closure, or --gripper track.csv
  retarget replay dance.bvh --rig aloha --fast     both arms of a rig, each on its rig file's port (sim://)
  retarget replay dance.bvh --rig aloha --port left=/dev/ttyUSB0 --port right=/dev/ttyUSB1   a rig on hardware
"""


# --------------------------------------------------------------------------------------------- shared options


def add_clip_arguments(parser: argparse.ArgumentParser) -> None:
    """CLIP, --arm/--base/--tip, the clip window and the tick rate (shared with ``export``)."""
    parser.add_argument("clip", nargs="?", metavar="CLIP", help="BVH file (default: the bundled demo clip)")
    add_arm_arguments(parser)
    parser.add_argument("--rate", default="100", metavar="HZ", help="control ticks per second (default 100)")
    parser.add_argument("--speed", default="1", metavar="F", help="playback speed factor (default 1)")
    parser.add_argument("--start", default=None, metavar="T", help="clip window start: seconds, or frames as 300f")
    parser.add_argument("--end", default=None, metavar="T", help="clip window end: seconds, or frames as 300f")
    parser.add_argument(
        "--velocity-scale", default="1", metavar="F", help="fraction of each joint's max speed (default 1)"
    )
    parser.add_argument(
        "--no-look-ahead",
        action="store_true",
        help="solve each tick as it comes and follow it within the speed and acceleration limits (lags fast "
        "motion: wx250s on motion_dance left, p95 82 mm from the target instead of 23); default: solve the whole clip "
        "first and plan the joint path ahead, within the same limits (a few passes over the ticks before the "
        "first one; a --loop run is always causal)",
    )
    parser.add_argument(
        "--jerk-cost",
        default=None,
        metavar="W",
        help=f"the look-ahead plan's cost on the change of acceleration from tick to tick (default {JERK_COST:g}; "
        "0: follow the clip as closely as the limits allow, the acceleration flipping between them where it moves "
        "fast: wx250s on motion_basket right, p95 1.3 mm instead of 1.8 at 10x the jerk; 0-1)",
    )
    add_collision_arguments(parser)


def add_mapping_arguments(parser: argparse.ArgumentParser) -> None:
    """Flags overriding the arm file's ``[mapping]`` table (see ``retarget.mapping.config``)."""
    g = parser.add_argument_group("mapping (overrides the arm file's [mapping] table)")
    g.add_argument("--side", default=None, metavar="left|right", help="which human arm drives the robot")
    g.add_argument(
        "--forward",
        default=None,
        metavar="AXIS",
        help="fixed BVH forward axis +z|-z|+x|-x instead of the torso's facing direction (auto)",
    )
    g.add_argument("--up", default=None, metavar="AXIS", help="BVH up axis (default +y)")
    g.add_argument(
        "--robot-forward",
        default=None,
        metavar="AXIS",
        help="the robot's forward +x|-x|+y|-y (default: from its home pose)",
    )
    g.add_argument("--arm-scale", default=None, metavar="F", help="human arm length -> this fraction of the reach")
    g.add_argument("--origin", default=None, metavar="X,Y,Z", help="where the human shoulder lands, metres, base frame")
    g.add_argument("--floor", default=None, metavar="Z", help="lowest target height, metres")
    g.add_argument("--orientation-weight", default=None, metavar="W", help="0 = position only; > 0 hand orientation")
    g.add_argument(
        "--filter-cutoff",
        default=None,
        metavar="HZ|auto",
        help="low-pass the clip's mapped targets forward and backward before the workspace clamp: zero lag, "
        "-6 dB at HZ, 2nd-order Butterworth run twice (0.1-100); default auto, or the arm file's cutoff_hz: "
        "chosen from the clip's own noise (none for a clean capture; -v logs the choice), 6 Hz when played "
        "causally (--loop, --no-look-ahead)",
    )
    g.add_argument("--no-filter", action="store_true", help="command the mapped targets unfiltered (--filter-cutoff 0)")


_TIME = re.compile(r"^\s*(\d+(?:\.\d*)?|\.\d+)\s*(s|f)?\s*$", re.IGNORECASE)


def parse_clip_time(text: str | None, *, frame_time: float, option: str) -> float | None:
    """``"2.5"``/``"2.5s"`` seconds or ``"300f"`` frames -> seconds; ConfigError naming the option."""
    if text is None:
        return None
    m = _TIME.match(text)
    if not m:
        raise ConfigError("Expected seconds (2.5, 2.5s) or frames (300f)", key=option, value=text)
    value = float(m.group(1))
    return value * frame_time if (m.group(2) or "s").lower() == "f" else value


@dataclass(frozen=True)
class Inputs:
    clip: Path
    motion: Motion
    arm: Arm
    targets: Targets
    collision: CollisionModel  #: every target, IK pose and goal is checked against it


def load_inputs(args: argparse.Namespace) -> Inputs:
    """Load the clip and the arm, build the mapping from the arm file + flags, and map every frame."""

    if args.clip is None:
        clip = Path(DEMO_CLIP)
    else:
        clip = Path(args.clip)
    arm = load_arm_option(args)
    table = MappingConfig.from_table(arm.mapping, path=arm.source, overrides=mapping_overrides(args))
    config = played_mapping(table, args)
    motion = retarget.load_bvh(clip)
    collision = collision_model(args, arm)
    targets = retarget_targets(motion, arm, config, collision=collision)
    return Inputs(clip=clip, motion=motion, arm=arm, targets=targets, collision=collision)


def mapping_overrides(args: argparse.Namespace) -> dict[str, Any]:
    """The mapping flags that were given (``--side``, ``--arm-scale``, ``--filter-cutoff``, ...), as mapping fields,
    checked alone first: a bad one is the flag's error (``mapping.floor`` with no file, which the CLI prints as
    ``--floor``), never the arm file's."""
    overrides = {
        "side": args.side,
        "forward": args.forward,
        "up": args.up,
        "robot_forward": args.robot_forward,
        "arm_scale": args.arm_scale,
        "origin": args.origin,
        "floor": args.floor,
        "orientation_weight": args.orientation_weight,
        "cutoff_hz": 0.0 if args.no_filter else args.filter_cutoff,
    }
    given = {name: value for name, value in overrides.items() if value is not None}
    MappingConfig.from_table({}, overrides=given)
    return given


def write_trajectory(output: str, joint_names: Sequence[str], play: Callable[[Callable[[TickRecord], None]], T]) -> T:
    """Run ``play(on_tick)`` with an ``on_tick`` that writes each tick's goals as a CSV row to ``output`` (a path,
    ``-`` = stdout) under the header ``time_s, <joint>_rad ...``; returns what ``play`` returns."""
    out: IO[str] = sys.stdout if output == "-" else open(output, "w", newline="", encoding="utf-8")  # noqa: SIM115
    try:
        out.write(",".join(["time_s", *(f"{name}_rad" for name in joint_names)]) + "\n")
        row = ",".join(["%.6f"] * (1 + len(joint_names))) + "\n"  # (a %-format of plain floats: 3x an f-string's pace)

        def write(r: TickRecord) -> None:
            out.write(row % (r.time, *r.q_cmd.tolist()))

        result = play(write)
        out.flush()
    finally:
        if out is not sys.stdout:
            out.close()
    return result


def number(text: str, *, option: str) -> float:
    """An option's text -> float; ConfigError naming the option."""
    try:
        return float(text)
    except ValueError:
        raise ConfigError("Expected a number", key=option, value=text) from None


def optional_number(text: str | None, *, option: str) -> float | None:
    """:func:`number`, or None for an option that was not given."""
    return None if text is None else number(text, option=option)


def optional_count(text: str | None, *, option: str) -> int | None:
    """An option's text -> int, or None when not given; ConfigError naming the option."""
    if text is None:
        return None
    try:
        return int(text)
    except ValueError:
        raise ConfigError("Expected an integer", key=option, value=text) from None


def loop_config(args: argparse.Namespace, motion: Motion, **extra: Any) -> LoopConfig:
    """A :class:`~retarget.control.LoopConfig` from the shared options."""

    return LoopConfig(
        rate=number(args.rate, option="--rate"),
        speed=number(args.speed, option="--speed"),
        start=parse_clip_time(args.start, frame_time=motion.frame_time, option="--start") or 0.0,
        end=parse_clip_time(args.end, frame_time=motion.frame_time, option="--end"),
        velocity_scale=number(args.velocity_scale, option="--velocity-scale"),
        jerk_cost=JERK_COST if args.jerk_cost is None else number(args.jerk_cost, option="--jerk-cost"),
        **extra,
    )


# --------------------------------------------------------------------------------------------- replay


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    parser: argparse.ArgumentParser = subparsers.add_parser(
        "replay",
        help="play a BVH clip's arm motion on an arm (simulated by default)",
        description=__doc__.split("\n\n")[0].split(": ", 1)[1],
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_clip_arguments(parser)
    parser.add_argument("--loop", action="store_true", help="wrap to --start after --end until Ctrl-C")
    add_gripper_option(parser)
    parser.add_argument("--max-ticks", default=None, metavar="N", help="stop after N ticks of the clip")
    parser.add_argument(
        "--lead-in",
        default="0.5",
        metavar="RAD_PER_S",
        help="on a bus, first move to the clip's first pose at this peak joint speed (default 0.5; 0 = none: "
        "the first ticks go there at each joint's full speed)",
    )
    parser.add_argument(
        "--dry-run", action="store_true", help="solve every tick without any bus (from the first pose, no lead-in)"
    )
    add_bus_arguments(parser, shutdown="rest", rig_ports=True)
    add_mapping_arguments(parser)
    add_view_arguments(parser, live=True)
    add_rig_option(parser)
    return parser


def _progress_printer(loop: ControlLoop) -> Callable[[TickRecord], None]:
    total = loop.n_ticks
    start, end = loop.window

    def show(r: TickRecord) -> None:
        if r.lead_in:
            print(f"retarget: lead-in t={r.time:6.1f} s  to the clip's first pose", file=sys.stderr, flush=True)
            return
        pct = f" {100.0 * r.tick / total:3.0f}%" if total else ""
        print(
            f"retarget:{pct} t={r.time:6.1f} s  clip {r.clip_time:6.2f}/{end:.2f} s  IK {r.ik_error * 1e3:5.2f} mm",
            file=sys.stderr,
            flush=True,
        )

    return show


def replay_config(args: argparse.Namespace, motion: Motion, **extra: Any) -> LoopConfig:
    """The loop's config of a replay: the shared options, ``--loop``, ``--max-ticks`` and ``--lead-in``."""
    return loop_config(
        args,
        motion,
        loop=args.loop,
        max_ticks=optional_count(args.max_ticks, option="--max-ticks"),
        lead_in_speed=number(args.lead_in, option="--lead-in"),
        **extra,
    )


def run(args: argparse.Namespace) -> int:
    if args.rig is not None:  # every arm of a rig (the rig modules take this module's options as values)
        check_rig_replay(args)
        rig_inputs = load_rig_inputs(args, mapping_overrides(args))
        return replay_rig(args, rig_inputs, replay_config(args, rig_inputs.motion))
    args.port = one_port(args.port)
    check_bus_options(args)
    check_view_options(args)
    if args.dry_run and args.port is not None:
        raise ConfigError("--dry-run uses no bus; drop --port", key="--port", value=args.port)
    inputs = load_inputs(args)
    config = replay_config(args, inputs.motion, collision=inputs.collision)
    side = MappingConfig.from_table(inputs.arm.mapping, path=inputs.arm.source, overrides={"side": args.side}).side
    gripper = clip_track(args.gripper, inputs.arm, inputs.motion, side.value)  # before the bus: errors first
    setup = None if args.dry_run else build_bus(args, inputs.arm, config)
    telemetry = None
    try:
        clock: Clock = setup.clock if setup is not None else VirtualClock() if args.fast else MonotonicClock()
        loop = ControlLoop(
            inputs.arm,
            inputs.targets,
            config=config,
            clock=clock,
            clip_name=inputs.clip.name,
            look_ahead=not args.no_look_ahead,
        )
        if args.progress or sys.stderr.isatty():
            loop.on_progress = _progress_printer(loop)
        if args.telemetry is not None:
            out = sys.stdout if args.telemetry == "-" else args.telemetry
            tracking = TickTracker.for_clip(inputs.arm, inputs.targets.reference)
            telemetry = TelemetryWriter(
                out, inputs.arm.joint_names, gripper=gripper is not None, tracking=tracking
            ).open()
            loop.on_tick = telemetry
        loop.on_tick = gripper_on_tick(gripper.at if gripper else None, setup.bus if setup else None, loop.on_tick)
        with (
            signals_stop(loop.stop) as stopped,
            live_view(args, inputs.arm, motion=inputs.motion, targets=inputs.targets, name=inputs.clip.name) as live,
        ):
            loop.on_tick = forward(on_tick=loop.on_tick, live=live)
            if setup is None:  # no arm to lead in: start on the first target's solution, as export does
                summary = loop.run(None, q_start=loop.initial_pose())
            else:
                first = loop.initial_pose() if config.lead_in_speed > 0 else None
                check_moves(inputs.arm, config, first=first, rest=args.shutdown == "rest")  # before torque is on
                loop.plan()  # the look-ahead plan too: the whole clip's IK, before torque is on
                with connected(setup.bus):
                    summary = loop.run(setup.bus)
                    if args.shutdown == "rest":  # the bus's rest move next: through home when straight collides
                        park(inputs.arm, setup.bus, config=config, clock=setup.clock)
    except BusError as exc:
        if args.json and isinstance(exc.summary, RunSummary):  # the loop's summary of the ticks that ran
            print_json(failure_summary(exc.summary.to_dict(), exc))
        raise
    finally:
        if telemetry is not None:
            telemetry.close()
        if setup is not None:
            setup.release()
    if gripper is not None:
        summary = dataclasses.replace(summary, gripper=gripper.rule)
    say(summary.format())  # a hung-up terminal (SIGHUP) must not turn a clean stop into a traceback
    if args.json:
        print_json(summary.to_dict())
    serve_web(args)
    return stopped.exit_status if summary.interrupted else 0
