"""``retarget calibrate``: measure a real arm's servo offsets and directions, check its ranges, verify, save."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any
from urllib.parse import parse_qs, urlsplit

import sim
from retarget.arm.calibration import check_name, default_calibration_path, save_calibration
from retarget.calibrate import AutoPrompter, Prompter, SimHands, TerminalPrompter, calibrate
from retarget.calibrate.hands import Hands
from retarget.cli._arm import add_link_arguments, load_arm_option
from retarget.control.clock import Clock, MonotonicClock
from retarget.errors import ConfigError
from sim.transport import bus_from_url

EPILOG = """\
examples:
  retarget calibrate --arm koch --port /dev/ttyUSB0               a Koch v1.1, saved as koch (used from then on)
  retarget calibrate --arm wx250s --port COM3 --name left         a second WidowX, saved as left
  retarget calibrate --arm omx --port /dev/ttyUSB0 -o omx.toml    into a file of your choosing
  retarget calibrate --arm koch --port 'sim://koch?mount=1:+300&reverse=3' --yes
                                                                  unattended on a simulated hand-built Koch

The steps, one prompt at a time (Ctrl-C at any point leaves torque off and saves nothing):
  1. connect, check every servo's model, torque off (hold the arm: it goes limp);
  2. put the arm in its calibration pose (each joint's angle and a hint are shown): every servo's zero;
  3. arms whose servos may sit either way (Koch, OpenMANIPULATOR-X; or --directions): turn each joint a little
     towards its upper limit: every servo's direction;
  4. turn each joint through its whole range by hand (live angle and limits shown): limits the arm cannot
     reach are reported, and narrowed if you agree;
  5. torque on at 20 deg/s: home, the calibration pose, rest, each after Enter; say whether each looks right.
Then the file is written (atomically): offsets, directions, the ranges seen, the date and each servo's firmware.
replay and teleop use it for the arm's name automatically (or --calibration PATH|NAME).

--yes answers every prompt: on a sim:// port the simulator's hands pose and sweep the joints; on a real arm
the pose must be set beforehand, the arm file's directions stay, and nothing is swept or moved.

exit status: 0 saved, 1 a verification pose looked wrong (nothing saved), 2 bad input, 4 bus failure, 130 Ctrl-C.
"""


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    parser: argparse.ArgumentParser = subparsers.add_parser(
        "calibrate",
        help="measure a real arm's servo offsets, directions and ranges; save them for replay and teleop",
        description="Calibrate one arm instance interactively: its servos' zeros and directions, its ranges.",
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--arm", required=True, help="arm name or TOML/URDF path, e.g. koch")
    add_link_arguments(parser)
    parser.add_argument("--port", required=True, help="device or pyserial URL: /dev/ttyUSB0, COM3, sim://koch?...")
    parser.add_argument("--baud", type=int, default=None, help="bus baud rate (default: the arm file's)")
    parser.add_argument("--name", default=None, help="this arm's name, the file's stem (default: the arm's name)")
    parser.add_argument("-o", "--output", default=None, metavar="PATH", help="write here instead of the default")
    parser.add_argument("--yes", action="store_true", help="answer every prompt (scripts, tests; see below)")
    parser.add_argument(
        "--directions",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="find each servo's direction too (default: the arm file's calibrate_directions)",
    )
    parser.add_argument("--no-verify", action="store_true", help="skip step 5 (no torque, no move)")
    return parser


def _sim_bus(port: str, fast: bool) -> tuple[sim.SimBus, str]:
    """The in-process simulated bus of a ``sim://`` port, on a virtual clock with --yes unless the URL says."""
    if port.startswith("sim://@"):
        try:
            return bus_from_url(port), port
        except KeyError as exc:
            raise ConfigError(str(exc.args[0]), key="--port", value=port) from exc
    if fast and "clock" not in parse_qs(urlsplit(port).query):
        port += ("&" if "?" in port else "?") + "clock=virtual"
    simbus = bus_from_url(port)
    return simbus, sim.attach(simbus)


def run(args: argparse.Namespace) -> int:
    arm = load_arm_option(args)
    name = check_name(args.name, key="--name") if args.name is not None else arm.name
    out = Path(args.output) if args.output is not None else default_calibration_path(check_name(name, key="--name"))
    io: Prompter = AutoPrompter() if args.yes else TerminalPrompter()
    port: str = args.port
    clock: Clock = MonotonicClock()
    hands: Hands | None = None
    registered = None
    if port.startswith("sim://"):
        simbus, port = _sim_bus(port, args.yes)
        registered = None if args.port.startswith("sim://@") else port
        clock = simbus.clock
        if args.yes and simbus.body is not None:
            hands = SimHands(simbus.body, clock)
    try:
        io.say(f"retarget calibrate: {arm.title or arm.name} as {name!r} on {args.port}; saves to {out}")
        if out.exists() and not io.confirm(f"{out} exists: replace it at the end?", default=True):
            return 1
        result = calibrate(
            arm,
            port,
            io,
            name=name,
            hands=hands,
            clock=clock,
            directions=args.directions,
            verify=not args.no_verify,
            auto=args.yes,
            baud=args.baud,
        )
    except EOFError as exc:
        raise ConfigError(str(exc), key="stdin") from None
    finally:
        if registered is not None:
            sim.unregister(registered)
    if result.verified is False:
        io.say("retarget calibrate: not saved (a verification pose looked wrong); run it again")
        return 1
    save_calibration(result.calibration, out)
    io.say(f"retarget calibrate: saved {out}; replay and teleop use it for {name!r}")
    print(out)
    sys.stdout.flush()
    return 0
