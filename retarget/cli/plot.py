"""``retarget plot``: draw a telemetry CSV (written by ``--telemetry``) as a PNG, without any GUI.

Per joint the commanded and present angles in degrees with the limits shaded, the IK error with the clamped
and velocity-limited ticks marked, the tick and bus times with the overruns marked.  The limits come from
``--arm`` (default: the default arm, when its joint names match the file's).  Needs ``pip install 'retarget[viz]'``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from retarget.cli._arm import add_arm_arguments, load_arm_option
from retarget.errors import ConfigError

EXAMPLES = """\
examples:
  retarget replay dance.bvh --telemetry run.csv && retarget plot run.csv -o run.png
  retarget plot run.csv --arm vx300s -o run.png      the limits of another arm
"""


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    parser: argparse.ArgumentParser = subparsers.add_parser(
        "plot",
        help="draw a telemetry CSV as a PNG (angles, limits, IK error, timing)",
        description=__doc__.split("\n\n")[0].split(": ", 1)[1],
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("telemetry", metavar="CSV", help="a telemetry file written by --telemetry")
    parser.add_argument("-o", "--output", required=True, metavar="PNG", help="the picture to write")
    add_arm_arguments(parser)
    return parser


def run(args: argparse.Namespace) -> int:
    from retarget.view import require

    require("retarget plot", "matplotlib")
    from retarget.view.plot import plot_telemetry, read_telemetry

    telemetry = read_telemetry(Path(args.telemetry))
    arm = load_arm_option(args)
    limits = None
    if arm.joint_names == telemetry.joints:
        limits = (arm.lower, arm.upper)
    elif args.arm is not None:
        raise ConfigError(f"Expected the joints {', '.join(telemetry.joints)} of {args.telemetry}, "
                          f"got {', '.join(arm.joint_names)}", key="--arm", value=args.arm)  # fmt: skip
    plot_telemetry(telemetry, Path(args.output), limits=limits, title=f"{Path(args.telemetry).name} ({arm.name} limits)"
                   if limits is not None else "")  # fmt: skip
    rows = len(telemetry["time_s"])
    print(f"retarget: {rows} ticks of {args.telemetry} -> {args.output}", file=sys.stderr)
    return 0
