"""``retarget rig``: show and check a rig (two or more arms in one world frame).

Loads a bundled rig or a rig TOML file, which validates it and every arm file it names, and prints each
arm: its arm, base position and yaw in the world, port and driving side; then the arms' nearest pair
(arm against arm) in the home and rest poses.  --list lists the bundled rigs; --port NAME=PORT overrides
an arm's port; --json prints JSON.
"""

from __future__ import annotations

import argparse
import math
import sys
from typing import Any

from retarget.cli import print_json
from retarget.errors import ConfigError
from retarget.rig import Rig, list_rigs, load_rig
from retarget.rig.clearance import RigClearance

EXAMPLES = """\
examples:
  retarget rig                                   the default rig (aloha: two vx300s)
  retarget rig --list                            the bundled rigs
  retarget rig wx250s-pair --json                one rig as JSON on stdout
  retarget rig my_rig.toml                       check a rig file and the arm files it names
  retarget rig aloha --port left=/dev/ttyUSB0 --port right=/dev/ttyUSB1
                                                 the ports the arms would open
"""


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    parser: argparse.ArgumentParser = subparsers.add_parser(
        "rig",
        help="show and check a rig: several arms in one world frame",
        description=__doc__.split("\n\n")[1].replace("\n", " "),
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("rig", nargs="?", default="aloha", help="bundled name or .toml (default aloha)")
    parser.add_argument("--list", action="store_true", help="list the bundled rigs and exit")
    parser.add_argument(
        "--port", action="append", default=[], metavar="NAME=PORT", help="an arm's port (repeat for each arm)"
    )
    parser.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    return parser


def parse_ports(items: list[str]) -> dict[str, str]:
    """``["left=/dev/ttyUSB0", ...]`` -> ``{"left": "/dev/ttyUSB0"}``; a ConfigError names ``--port`` and the item.

    >>> parse_ports(["left=/dev/ttyUSB0", "right=sim://vx300s"])
    {'left': '/dev/ttyUSB0', 'right': 'sim://vx300s'}
    """
    ports: dict[str, str] = {}
    for item in items:
        name, sep, port = item.partition("=")
        if not sep or not name or not port:
            raise ConfigError("Expected NAME=PORT, e.g. left=/dev/ttyUSB0", key="--port", value=item)
        if name in ports:
            raise ConfigError(f"Expected one port for arm {name!r}", key="--port", value=item)
        ports[name] = port
    return ports


def run(args: argparse.Namespace) -> int:
    if args.list:
        if args.json:
            print_json(list_rigs())
        else:
            sys.stdout.write("".join(f"{name}\n" for name in list_rigs()))
        return 0
    rig = load_rig(args.rig)
    try:
        rig = rig.with_ports(parse_ports(args.port))
    except ConfigError as exc:
        if exc.key != "rig.arm":
            raise
        raise exc.with_key("--port") from exc
    report = describe(rig)
    if args.json:
        print_json(report)
    else:
        sys.stdout.write(format_text(report))
    return 0


def describe(rig: Rig) -> dict[str, Any]:
    """The rig as plain data: each arm, and the arm-against-arm nearest pair at home and at rest."""
    check = RigClearance(rig)
    poses = {}
    for pose in ("home", "rest"):
        name, value = check.worst_pair({a.name: getattr(a.arm, pose) for a in rig.arms})
        poses[pose] = {"pair": name, "clearance_mm": round(value * 1e3, 1)}
    arms = [
        {
            "name": a.name,
            "arm": a.arm.name,
            "xyz_m": list(a.placement.xyz),
            "rpy_deg": [round(math.degrees(v), 6) for v in a.placement.rpy],
            "port": a.port,
            "side": a.side.value,
            "joints": a.arm.n_joints,
        }
        for a in rig.arms
    ]
    return {
        "rig": rig.name,
        "file": str(rig.path),
        "arms": arms,
        "nearest": poses,
        "clearance_mm": check.clearance * 1e3,
    }


def format_text(report: dict[str, Any]) -> str:
    lines = [f"rig {report['rig']}  ({report['file']})", ""]
    lines.append(f"  {'arm':<8} {'model':<10} {'base xyz (m)':<24} {'yaw':>7}  {'side':<6} port")
    for a in report["arms"]:
        xyz = ", ".join(f"{v:+.3f}" for v in a["xyz_m"])
        lines.append(f"  {a['name']:<8} {a['arm']:<10} {xyz:<24} {a['rpy_deg'][2]:>6.1f}°  {a['side']:<6} {a['port']}")
    lines.append("")
    lines.append(f"arm against arm (clearance {report['clearance_mm']:g} mm):")
    for pose, near in report["nearest"].items():
        lines.append(f"  at {pose:<5} nearest {near['pair']}: {near['clearance_mm']:.1f} mm")
    return "\n".join(lines) + "\n"
