"""``retarget scan``: list the Dynamixel servos on a port (ID, model, firmware, baud)."""

from __future__ import annotations

import argparse
import math
import sys
from typing import Any

from drivers.control_table import PULSES_PER_REV, RAD_PER_PULSE, parse_ids
from drivers.scan import ALL_BAUDS, scan
from retarget.arm.calibration import Calibration, apply_calibration, load_calibration
from retarget.arm.model import Arm
from retarget.calibrate.servos import ServoLink
from retarget.calibrate.steps import wrap
from retarget.cli import print_json
from retarget.cli._arm import add_link_arguments, load_arm_naming_links
from retarget.cli._calibration import add_calibration_argument, calibration_path
from retarget.errors import BusError, ConfigError

EPILOG = """\
examples:
  retarget scan --port /dev/ttyUSB0                    every ID at 1 Mbps (one broadcast ping)
  retarget scan --port /dev/ttyUSB0 --all-bauds        try every baud rate, most common first
  retarget scan --port COM3 --baud 57600 --ids 1-9     factory-default baud, IDs 1 to 9 only
  retarget scan --port sim://wx250s --json             the simulated WidowX-250 6DOF, as JSON on stdout
  retarget scan --port socket://192.168.1.20:4000      a servo bus behind a TCP serial bridge
  retarget scan --port /dev/ttyUSB0 --arm koch         also check the Koch's servos (models) and show each
                                                       joint's angle through its calibration (if saved)

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
    parser.add_argument(
        "--arm", default=None, help="check the servos against this arm (name or TOML/URDF path): models, angles"
    )
    add_link_arguments(parser)
    add_calibration_argument(parser)
    return parser


def run(args: argparse.Namespace) -> int:

    if args.baud is not None and args.baud not in ALL_BAUDS:  # a bad option (exit 2), not a port failure (4)
        rates = ", ".join(map(str, sorted(ALL_BAUDS)))
        raise ConfigError(f"Expected a baud rate a servo can use: {rates}", key="--baud", value=args.baud)
    ids = parse_ids(args.ids)
    calibrated = scan_arm(args) if args.arm is not None else None  # says first which calibration it uses
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
    joints = arm_report(args, *calibrated) if calibrated is not None else None
    if args.json:
        data: Any = [s.as_dict() for s in found]
        print_json(data if joints is None else {"servos": data, "joints": joints})
    else:
        print(f"{'ID':>3}  {'MODEL':<12} {'NUMBER':>6}  {'FIRMWARE':>8}  {'BAUD':>8}")
        for s in found:
            print(f"{s.id:>3}  {s.model:<12} {s.model_number:>6}  {s.firmware:>8}  {s.baud:>8}")
        if joints is not None:
            print(f"\n{'JOINT':<14} {'ID':>3}  {'ANGLE':>7}  {'LIMITS':>17}  NOTE")
            for j in joints:
                limits = f"{j['lower_deg']:+.1f}..{j['upper_deg']:+.1f}"
                print(f"{j['joint']:<14} {j['id']:>3}  {j['angle_deg']:+7.1f}  {limits:>17}  {j['note']}")
    print(f"{len(found)} servo(s) found", file=sys.stderr)
    return 0


def scan_arm(args: argparse.Namespace) -> tuple[Arm, Calibration | None]:
    """``--arm`` with the calibration of ``--calibration`` (default: the one saved for the arm); says which."""
    arm = load_arm_naming_links(args.arm, base=args.base, tip=args.tip)
    path = calibration_path(args.calibration, arm.name)
    cal = None
    if path is not None:
        if not path.is_file():
            raise ConfigError("calibration file not found", key="--calibration", value=str(path))
        cal = load_calibration(path)
        arm = apply_calibration(arm, cal)
        print(f"retarget: calibration: {cal.name} ({path}, {cal.date})", file=sys.stderr)
    else:
        need = "needs one" if arm.requires_calibration else "uses the arm file's offsets"
        print(f"retarget: calibration: none for {arm.name} ({need}: retarget calibrate --arm {args.arm} "
              f"--port {args.port})", file=sys.stderr)  # fmt: skip
    return arm, cal


def arm_report(args: argparse.Namespace, arm: Arm, cal: Calibration | None) -> list[dict[str, Any]]:
    """Every joint servo of ``arm`` checked (present, model) and its joint angle, with the firmware it was
    calibrated with."""
    rows = []
    with ServoLink(arm, args.port, baud=args.baud) as link:
        info = link.check()
        actual = link.read_actual()
    for joint in arm.joints:
        for s in joint.servos:
            present = actual[s.id] if s.direction > 0 else PULSES_PER_REV - actual[s.id]
            angle = wrap(present - 2048 - s.offset) * RAD_PER_PULSE
            calibrated = cal.servo(s.id) if cal is not None else None
            note = ""
            if calibrated is not None and calibrated.firmware not in (None, info[s.id].firmware):
                firmware = info[s.id].firmware
                note = f"firmware {firmware}, calibrated with {calibrated.firmware}: replaced? calibrate again"
            elif not joint.lower - 0.05 <= angle <= joint.upper + 0.05:
                note = "outside the limits"
            rows.append({"joint": joint.name, "id": s.id, "angle_deg": round(math.degrees(angle), 2),
                         "lower_deg": math.degrees(joint.lower), "upper_deg": math.degrees(joint.upper),
                         "firmware": info[s.id].firmware, "note": note})  # fmt: skip
    return rows
