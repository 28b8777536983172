"""``retarget scan``: list the Dynamixel servos on a port (ID, model, firmware, baud)."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from drivers.control_table import parse_ids
from drivers.scan import ALL_BAUDS, scan
from retarget.cli import print_json
from retarget.errors import BusError, ConfigError

EPILOG = """\
examples:
  retarget scan --port /dev/ttyUSB0                    every ID at 1 Mbps (one broadcast ping)
  retarget scan --port /dev/ttyUSB0 --all-bauds        try every baud rate, most common first
  retarget scan --port COM3 --baud 57600 --ids 1-9     factory-default baud, IDs 1 to 9 only
  retarget scan --port sim://wx250s --json             the simulated WidowX-250 6DOF, as JSON on stdout
  retarget scan --port socket://192.168.1.20:4000      a servo bus behind a TCP serial bridge

exit status: 0 when at least one servo answered, 4 when none did or the port failed, 2 for a bad option.
"""


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    parser: argparse.ArgumentParser = subparsers.add_parser(
        "scan",
        help="list the Dynamixel servos on a port: ID, model, firmware, baud",
        description="Ping every ID on a serial port (or pyserial URL) and list the servos that answer.",
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument(
        "--port", required=True, help="device or pyserial URL: /dev/ttyUSB0, COM3, socket://h:p, sim://"
    )
    bauds = parser.add_mutually_exclusive_group()
    bauds.add_argument("--baud", type=int, default=None, help="baud rate to scan (default 1000000)")
    bauds.add_argument("--all-bauds", action="store_true", help="scan every baud rate an X-series servo can use")
    parser.add_argument("--ids", default="0-252", help="IDs to look for, e.g. 0-252 (default) or 1-9 or 1,3,5")
    parser.add_argument(
        "--no-broadcast", action="store_true", help="ping each ID on its own instead of one broadcast ping"
    )
    parser.add_argument("--json", action="store_true", help="print a JSON list instead of a table")
    return parser


def run(args: argparse.Namespace) -> int:

    if args.baud is not None and args.baud not in ALL_BAUDS:  # a bad option (exit 2), not a port failure (4)
        rates = ", ".join(map(str, sorted(ALL_BAUDS)))
        raise ConfigError(f"Expected a baud rate a servo can use: {rates}", key="--baud", value=args.baud)
    ids = parse_ids(args.ids)
    bauds = ALL_BAUDS if args.all_bauds else (args.baud if args.baud is not None else 1_000_000,)
    found = scan(
        args.port,
        bauds,
        ids,
        broadcast=not args.no_broadcast,
        progress=lambda message: print(message, file=sys.stderr),
    )
    if not found:
        raise BusError(
            f"no servo answered on {args.port} at {', '.join(map(str, bauds))} baud: "
            "check power, the cable, and try --all-bauds"
        )
    if args.json:
        print_json([s.as_dict() for s in found])
    else:
        print(f"{'ID':>3}  {'MODEL':<12} {'NUMBER':>6}  {'FIRMWARE':>8}  {'BAUD':>8}")
        for s in found:
            print(f"{s.id:>3}  {s.model:<12} {s.model_number:>6}  {s.firmware:>8}  {s.baud:>8}")
    print(f"{len(found)} servo(s) found", file=sys.stderr)
    return 0
