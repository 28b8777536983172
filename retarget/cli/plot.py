"""``retarget plot``: draw a telemetry CSV (written by ``--telemetry``) as a PNG, without any GUI.

Per joint the commanded and present angles in degrees with the limits shaded, the IK and tracking errors with the
clamped and velocity-limited ticks marked, the tick and bus times with the overruns marked.  The limits come from
``--arm`` (default: the default arm, when its joint names match the file's); a rig's telemetry (``--rig`` runs) is
drawn arm by arm, with the limits of ``--rig``'s arms when given.  Needs ``pip install 'retarget[viz]'``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from retarget.cli._arm import add_arm_arguments, load_arm_option
from retarget.errors import ConfigError

if TYPE_CHECKING:
    from retarget.view.plot import Telemetry

EXAMPLES = """\
examples:
  retarget replay dance.bvh --telemetry run.csv && retarget plot run.csv -o run.png
  retarget plot run.csv --arm vx300s -o run.png      the limits of another arm
  retarget replay dance.bvh --rig aloha --telemetry rig.csv && retarget plot rig.csv --rig aloha -o rig.png
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
    add_arm_arguments(parser, default=None)
    parser.add_argument("--rig", default=None, metavar="NAME|FILE", help="a rig's telemetry: the limits of its arms")
    return parser


def run(args: argparse.Namespace) -> int:
    from retarget.view import require

    require("retarget plot", "matplotlib")
    from retarget.view.plot import plot_telemetry, read_telemetry

    telemetry = read_telemetry(Path(args.telemetry))
    limits, source = _rig_limits(args, telemetry) if telemetry.arms != ("",) else _arm_limits(args, telemetry)
    title = f"{Path(args.telemetry).name} ({source} limits)" if limits is not None else ""
    plot_telemetry(telemetry, Path(args.output), limits=limits, title=title)
    rows = len(telemetry["time_s"])
    print(f"retarget: {rows} ticks of {args.telemetry} -> {args.output}", file=sys.stderr)
    return 0


Limits = tuple[np.ndarray, np.ndarray]


def _arm_limits(args: argparse.Namespace, telemetry: Telemetry) -> tuple[Limits | None, str]:
    """One arm's file: (lower, upper) of ``--arm`` (or the default arm when its joints match the file's)."""
    if args.rig is not None:
        raise ConfigError(f"Expected a rig's telemetry with --rig, got one arm's ({args.telemetry})", key="--rig",
                          value=args.rig)  # fmt: skip
    arm = load_arm_option(args)
    if arm.joint_names == telemetry.joints:
        return (arm.lower, arm.upper), arm.name
    if args.arm is not None:
        raise ConfigError(f"Expected the joints {', '.join(telemetry.joints)} of {args.telemetry}, "
                          f"got {', '.join(arm.joint_names)}", key="--arm", value=args.arm)  # fmt: skip
    return None, ""


def _rig_limits(args: argparse.Namespace, telemetry: Telemetry) -> tuple[Limits | None, str]:
    """A rig's file: (lower, upper) of ``--rig``'s arms in its joint order; none without ``--rig``."""
    if args.arm is not None:
        raise ConfigError(f"Expected --rig for a rig's telemetry ({args.telemetry}), not --arm", key="--arm",
                          value=args.arm)  # fmt: skip
    if args.rig is None:
        return None, ""
    from retarget.rig import load_rig

    rig = load_rig(args.rig)
    joints = tuple(f"{a.name}/{j}" for a in rig.arms for j in a.arm.joint_names)
    if joints != telemetry.joints:
        raise ConfigError(f"Expected the joints {', '.join(telemetry.joints)} of {args.telemetry}, "
                          f"got {', '.join(joints)}", key="--rig", value=args.rig)  # fmt: skip
    lower = np.concatenate([a.arm.lower for a in rig.arms])
    return (lower, np.concatenate([a.arm.upper for a in rig.arms])), rig.name
