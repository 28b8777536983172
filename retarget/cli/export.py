"""``retarget export``: write a clip's retargeted joint trajectory as CSV, without any bus.

The trajectory is what ``retarget replay`` would command, tick by tick, at
``--rate``: IK warm-started from the previous tick, joint limits and velocity
limits applied.  It starts at the IK solution of the first target (no lead-in
from a rest pose: there is no arm; on a bus, replay's lead-in moves there first
and then commands this trajectory).  By default the whole clip is solved first and the joint path planned
ahead within the velocity and acceleration limits, so the arm does not lag fast motion (``--no-look-ahead``: each
tick solved and limited as it comes, as ``replay --loop`` runs).  The clip's targets are low-passed without lag
first (``--filter-cutoff``, default ``auto``: from the clip's noise; ``--no-filter``).  Columns: ``time_s`` then
one ``<joint>_rad`` per joint (radians, the arm's joint order).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from typing import Any

from retarget.cli._rig_run import add_rig_option, export_rig, load_rig_inputs
from retarget.cli.replay import (
    Inputs,
    add_clip_arguments,
    add_mapping_arguments,
    load_inputs,
    loop_config,
    mapping_overrides,
    write_trajectory,
)
from retarget.control import ControlLoop, TickRecord
from retarget.control.clock import VirtualClock
from retarget.control.summary import RunSummary

EXAMPLES = """\
examples:
  retarget export dance.bvh --arm wx250s -o traj.csv       100 Hz joint trajectory, radians
  retarget export dance.bvh --arm px100 --rate 50 -o -     to stdout
  retarget export dance.bvh --side left --start 2 --end 10 -o left.csv
  retarget export dance.bvh --arm robot.urdf --tip ee_link -o traj.csv   a URDF with several leaves
  retarget export dance.bvh --rig aloha -o both.csv       both arms of a rig: time_s, <arm>/<joint>_rad
  retarget export dance.bvh --jerk-cost 0 -o tight.csv     follow as closely as the limits allow (more jerk)
  retarget export mocap.bvh --filter-cutoff 6 -o traj.csv  a fixed cutoff instead of auto (from the clip's noise)
"""


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    parser: argparse.ArgumentParser = subparsers.add_parser(
        "export",
        help="write a clip's retargeted joint trajectory as CSV (no bus)",
        description=__doc__.split("\n\n")[0].split(": ", 1)[1] + " Columns: time_s, then <joint>_rad per joint.",
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_clip_arguments(parser)
    parser.add_argument("-o", "--output", default="-", metavar="CSV", help="output file, '-' = stdout (default)")
    add_mapping_arguments(parser)
    add_rig_option(parser)
    return parser


def offline_loop(args: argparse.Namespace) -> tuple[Inputs, ControlLoop]:
    """The clip's inputs and the loop that solves it without a bus (virtual clock), as export and ``retarget view``
    run it: ``loop.run(None, q_start=loop.initial_pose())``."""
    inputs = load_inputs(args)
    config = loop_config(args, inputs.motion, collision=inputs.collision)
    loop = ControlLoop(
        inputs.arm,
        inputs.targets,
        config=config,
        clock=VirtualClock(),
        clip_name=inputs.clip.name,
        look_ahead=not args.no_look_ahead,
    )
    return inputs, loop


def run(args: argparse.Namespace) -> int:
    if args.rig is not None:  # the rig module takes this module's options as values (it never imports replay)
        rig_inputs = load_rig_inputs(args, mapping_overrides(args))
        return export_rig(args, rig_inputs, loop_config(args, rig_inputs.motion), write_trajectory)

    inputs, loop = offline_loop(args)
    q0 = loop.initial_pose()

    def play(on_tick: Callable[[TickRecord], None]) -> RunSummary:
        loop.on_tick = on_tick
        return loop.run(None, q_start=q0)

    summary = write_trajectory(args.output, inputs.arm.joint_names, play)
    print(
        f"retarget: {summary.ticks} ticks of {inputs.arm.name} ({summary.duration_s:.2f} s of {inputs.clip.name}) "
        f"-> {args.output}; IK {summary.ik_converged_pct:.1f}% converged, "
        f"clamped {summary.clamped_ticks}, velocity-limited {summary.velocity_limited_ticks}, "
        f"blocked {summary.blocked_ticks} (IK stopped short by a collision {summary.ik_blocked_ticks}), "
        f"pushed out of blocked zones {summary.pushed_targets}; "
        f"tracking error p95 {summary.tracking_p95_mm or 0:.1f} mm, "
        f"joint acceleration peak {summary.accel_peak_rad_s2 or 0:.0f} rad/s^2",
        file=sys.stderr,
    )
    return 0
