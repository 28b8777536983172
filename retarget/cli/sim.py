"""``retarget sim``: serve simulated Dynamixel servos on a pseudo-terminal or loopback TCP until interrupted."""

from __future__ import annotations

import argparse
import math
import sys
import threading
from typing import Any

from drivers.control_table import parse_ids
from retarget.arm.model import SERVO_BAUDS, SERVO_MODELS, Arm
from retarget.cli._arm import add_link_arguments, load_arm_option
from retarget.cli._sim_rig import refuse_one_arm_options, serve_rig, stop_on_signals
from retarget.control.clock import MonotonicClock
from retarget.errors import ConfigError
from sim.bus import SimBus
from sim.control import ControlServer, parse_address
from sim.faults import Faults
from sim.hand_commands import HandCommand, HandSchedule, parse_hand
from sim.mount import Mounting
from sim.server import PtyServer, SimServer, TcpServer

EPILOG = """\
examples:
  retarget sim                                   the WidowX-250 6DOF (wx250s) on a new pty; prints its path
  retarget sim --arm wx250s --tcp 127.0.0.1:4000 on loopback TCP; open it as socket://127.0.0.1:4000
  retarget sim --ids 1-6 --model XL430-W250 --baud 57600
                                                 six factory-fresh XL430s at 57600 baud
  retarget sim --drop 0.05 --seed 1              lose 5 % of the replies, repeatably
  retarget sim --unplug 4@10 --hwerror 3:overload@5
                                                 servo 4 goes silent after 10 s; servo 3 overloads after 5 s
  retarget sim --delay-ms 6:3 --boot-ms 0        servo 6 answers 3 ms late; a REBOOT is silent for no time
  retarget sim --no-wire                         answer at once (no wire time at the baud rate): faster tests
  retarget sim --hand 2:sweep:1024-3072:2        a hand turns limp servo 2 back and forth, 2 s per pass
  retarget sim --hand 3:to:3000:1@5 --hand 3:release@8
                                                 5 s in, servo 3 is turned to 3000 in 1 s; let go at 8 s
  retarget sim --control 127.0.0.1:4001          take commands on a socket: echo 'hand 2 to 3000 1' | nc ...
  retarget sim --arm koch --mount 1:+300 --reverse 3
                                                 a hand-built Koch: servo 1's horn 300 pulses off, servo 3 reversed
  retarget sim --arm robot.urdf --tip ee_link    the servos of a URDF arm (servo IDs from robot.servos.toml)
  retarget sim --rig aloha                       both arms of a rig, each on its own pty: prints NAME=PATH lines
  retarget sim --rig aloha --tcp 127.0.0.1:4000  ... on TCP ports 4000 and 4001 (--tcp ...:0: any free ports)

The first line on stdout is what to open: a device path (/dev/pts/N) or a socket:// URL; with --control the
second line is the control address (HOST:PORT or unix:PATH); messages go to stderr.  Fault values take an
optional servo ID: --drop 0.1 (every servo) or --drop 3:0.5 (servo 3).  Replies take the time a real wire
takes at the baud rate (10 bits per byte each way), unless --no-wire.

Hands move servos whose torque is off (as a person turns a limp joint, e.g. for lerobot-calibrate); pulses
are Present Position's (4096 per turn).  --hand ID:sweep:LO-HI:SECONDS, ID:to:PULSES:SECONDS, ID:release,
each with an optional @START (seconds after start).  The control socket takes one command per line and
answers one JSON line: hand ID sweep LO HI SECONDS | hand ID to PULSES SECONDS | release ID | status [ID...].
Ctrl-C or SIGTERM stops the server cleanly (exit status 0); with the wire model it then says how many replies
left more than 0.5 ms after their wire time (a machine too busy to keep real time).  With --rig each arm's bus
runs in its own process, as each arm of a real rig has its own wire; if one ends on its own, the others are
stopped and the exit status is 1.
"""


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    parser: argparse.ArgumentParser = subparsers.add_parser(
        "sim",
        help="serve simulated Dynamixel servos on a pty or loopback TCP",
        description=(
            "Serve a simulated Dynamixel Protocol 2.0 bus (the servos of an arm, or IDs of one model) on a "
            "pseudo-terminal or a TCP socket until interrupted.  Any program, dynamixel-sdk included, opens it "
            "like a real port."
        ),
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    servos = parser.add_argument_group("servos")
    servos.add_argument("--arm", default=None, help="bundled arm name or description file (default wx250s)")
    add_link_arguments(servos)
    servos.add_argument(
        "--rig", default=None, help="every arm of a rig (bundled name or .toml), each on its own pty or TCP port"
    )
    servos.add_argument("--ids", default=None, help="IDs instead of an arm, e.g. 1-6 or 1,2,5")
    servos.add_argument("--model", default=None, help="servo model with --ids (default XL430-W250)")
    servos.add_argument("--baud", type=int, default=None, help="the servos' baud rate (default: the arm's, or 1000000)")
    servos.add_argument(
        "--rdt", type=int, default=None, help="Return Delay Time item, 2 us units (default 250, factory)"
    )
    servos.add_argument(
        "--boot-ms",
        type=float,
        default=DEFAULT_BOOT_MS,
        help=f"how long a servo stays silent after answering REBOOT (default {DEFAULT_BOOT_MS:g}, measured on XC330)",
    )
    servos.add_argument(
        "--mount",
        action="append",
        default=[],
        metavar="ID:PULSES",
        help="servo ID's horn sits PULSES off the arm file's zero, as on a hand-built arm (repeatable)",
    )
    servos.add_argument(
        "--reverse", action="append", default=[], metavar="ID", help="servo ID is mounted the other way round"
    )
    where = parser.add_mutually_exclusive_group()
    where.add_argument("--pty", action="store_true", help="serve on a new pseudo-terminal (the default)")
    where.add_argument("--tcp", metavar="[HOST:]PORT", help="serve on TCP, e.g. 127.0.0.1:4000 (port 0: any free)")
    faults = parser.add_argument_group("faults (repeatable; [ID:] limits one to a servo)")
    faults.add_argument("--drop", action="append", default=[], metavar="[ID:]FRACTION", help="lose replies")
    faults.add_argument("--corrupt", action="append", default=[], metavar="[ID:]FRACTION", help="bad-CRC replies")
    faults.add_argument("--delay-ms", action="append", default=[], metavar="[ID:]MS", help="late replies")
    faults.add_argument("--unplug", action="append", default=[], metavar="ID@SECONDS", help="servo goes silent")
    faults.add_argument(
        "--hwerror",
        action="append",
        default=[],
        metavar="ID:KIND@SECONDS",
        help="hardware error: overload, overheating, input_voltage, electrical_shock, motor_encoder",
    )
    faults.add_argument(
        "--wire",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="take the wire time at the baud rate, 10 bits per byte (default); --no-wire answers at once",
    )
    faults.add_argument("--seed", type=int, default=0, help="seed of the random faults (default 0)")
    hands = parser.add_argument_group("hands (move servos whose torque is off)")
    hands.add_argument(
        "--hand",
        action="append",
        default=[],
        metavar="ID:GESTURE[@START]",
        help="ID:sweep:LO-HI:SECONDS, ID:to:PULSES:SECONDS or ID:release (repeatable)",
    )
    hands.add_argument(
        "--control",
        default=None,
        metavar="[HOST:]PORT|unix:PATH",
        help="a control socket for hand and status commands, one per line (port 0: any free)",
    )
    return parser


def _tcp_address(text: str) -> tuple[str, int]:
    host, sep, port = text.rpartition(":")
    try:
        number = int(port)
    except ValueError:
        raise ConfigError("Expected [HOST:]PORT, e.g. 127.0.0.1:4000", key="--tcp", value=text) from None
    if not 0 <= number <= 65535:
        raise ConfigError("Expected a port 0..65535", key="--tcp", value=text)
    return (host if sep and host else "127.0.0.1"), number


#: Silence after answering REBOOT, ms: an XC330 "refuses to reply for about 0.4 seconds while rebooting"
#: (ROBOTIS-GIT/emanual#1698; the e-Manual documents no boot time).
DEFAULT_BOOT_MS = 400.0

#: The documented ranges of the simulator's numeric options.
MAX_RDT = 254  #: Return Delay Time item, 2 us units (e-Manual: 0..254)
MAX_BOOT_MS = 60_000.0  #: silence after REBOOT, ms
MAX_DELAY_MS = 10_000.0  #: a late reply, ms
MAX_FAULT_TIME_S = 86_400.0  #: when an --unplug or --hwerror happens, seconds after the start


def _finite(text: str, option: str, item: str, lo: float, hi: float) -> float:
    """``text`` as a number within ``lo..hi``, else a ConfigError naming ``option`` and the whole ``item``."""
    try:
        value = float(text)
    except ValueError:
        raise ConfigError("Expected a number", key=option, value=item) from None
    if not (math.isfinite(value) and lo <= value <= hi):
        within = f"from {lo:g} to {hi:g}" if math.isfinite(hi) else f">= {lo:g}"
        raise ConfigError(f"Expected a finite number {within}", key=option, value=item)
    return value


def _items(values: list[str]) -> list[str]:
    return [part.strip() for v in values for part in str(v).split(",") if part.strip()]


def check_options(args: argparse.Namespace) -> dict[str, set[int]]:
    """Check the numeric options (each ConfigError names its option); returns the servo IDs each fault option
    names, by option, to check against the bus's IDs."""
    if args.baud is not None and args.baud not in SERVO_BAUDS:
        rates = ", ".join(map(str, SERVO_BAUDS))
        raise ConfigError(f"Expected a Dynamixel baud rate ({rates})", key="--baud", value=args.baud)
    if args.rdt is not None and not 0 <= args.rdt <= MAX_RDT:
        raise ConfigError(f"Expected a Return Delay Time 0..{MAX_RDT} (2 us units)", key="--rdt", value=args.rdt)
    if not (math.isfinite(args.boot_ms) and 0 <= args.boot_ms <= MAX_BOOT_MS):
        message = f"Expected a finite number of ms from 0 to {MAX_BOOT_MS:g}"
        raise ConfigError(message, key="--boot-ms", value=args.boot_ms)
    if args.model is not None and args.ids is not None and args.model.upper() not in SERVO_MODELS:
        raise ConfigError(f"Expected one of {', '.join(SERVO_MODELS)}", key="--model", value=args.model)
    ids: dict[str, set[int]] = {}
    for option, values, hi in (
        ("--drop", args.drop, math.inf),  # (the fraction's 0..1 is the simulator's check)
        ("--corrupt", args.corrupt, math.inf),
        ("--delay-ms", args.delay_ms, MAX_DELAY_MS),
    ):
        for item in _items(values):
            sid, _, number = item.rpartition(":")
            _finite(number, option, item, 0.0, hi)
            if sid.strip().isdigit():
                ids.setdefault(option, set()).add(int(sid))
    for command in hand_commands(args):
        ids.setdefault("--hand", set()).add(command.id)
    if args.control is not None:
        parse_address(args.control)
    for option, values in (("--unplug", args.unplug), ("--hwerror", args.hwerror)):
        for item in _items(values):
            head, sep, at = item.rpartition("@")
            if sep:
                _finite(at, option, item, 0.0, MAX_FAULT_TIME_S)
            sid = head.partition(":")[0].strip()
            if sid.isdigit():
                ids.setdefault(option, set()).add(int(sid))
    return ids


def hand_commands(args: argparse.Namespace) -> list[HandCommand]:
    """The --hand items, parsed (ConfigError keyed --hand quoting the bad one)."""
    return [parse_hand(item) for item in args.hand]


def _check_fault_ids(fault_ids: dict[str, set[int]], bus_ids: tuple[int, ...]) -> None:
    for option, named in fault_ids.items():
        missing = sorted(named - set(bus_ids))
        if missing:
            message = f"Expected a servo ID on the bus ({', '.join(map(str, bus_ids))})"
            raise ConfigError(message, key=option, value=", ".join(map(str, missing)))


def build_bus(args: argparse.Namespace) -> SimBus:
    """The SimBus the options describe (real-time clock)."""

    fault_ids = check_options(args)
    faults = _faults(args)
    clock = MonotonicClock()
    if args.ids is not None:
        if args.arm is not None:
            raise ConfigError("give either --arm or --ids, not both", key="--ids", value=args.ids)
        if args.mount or args.reverse:
            option = "--mount" if args.mount else "--reverse"
            raise ConfigError(f"{option} goes with an --arm, not --ids", key=option, value=args.ids)
        if args.base is not None or args.tip is not None:
            option = "--base" if args.base is not None else "--tip"
            raise ConfigError(f"{option} goes with a URDF --arm, not --ids", key=option, value=args.ids)
        ids = parse_ids(args.ids)
        _check_fault_ids(fault_ids, tuple(ids))
        return SimBus.from_ids(
            ids,
            args.model or "XL430-W250",
            clock=clock,
            baud=args.baud or 1_000_000,
            return_delay_time=args.rdt,
            boot_time=args.boot_ms / 1000.0,
            faults=faults,
        )
    if args.model is not None:
        raise ConfigError("--model goes with --ids", key="--model", value=args.model)
    arm = load_arm_option(args)
    _check_fault_ids(fault_ids, arm.servo_ids)
    try:
        mount = Mounting.from_options(mount=args.mount, reverse=args.reverse)
    except ConfigError as exc:
        raise exc.with_key(f"--{exc.key}") from None
    _check_fault_ids({"--mount": set(mount.offsets), "--reverse": set(mount.reversed)}, arm.servo_ids)
    return arm_bus(args, arm, faults, mount)


def _faults(args: argparse.Namespace) -> Faults:
    return Faults.from_options(
        drop=args.drop,
        corrupt=args.corrupt,
        delay_ms=args.delay_ms,
        unplug=args.unplug,
        hwerror=args.hwerror,
        wire=args.wire,
        seed=args.seed,
    )


def arm_bus(args: argparse.Namespace, arm: Arm, faults: Faults, mount: Mounting | None = None) -> SimBus:
    """The servos of ``arm`` as the options describe them (real-time clock)."""
    return SimBus.from_arm(
        arm,
        clock=MonotonicClock(),
        baud=args.baud,
        return_delay_time=args.rdt,
        boot_time=args.boot_ms / 1000.0,
        faults=faults,
        mount=mount,
    )


def run(args: argparse.Namespace) -> int:
    if args.rig is not None:
        refuse_one_arm_options(args)
        check_options(args)
        address = _tcp_address(args.tcp) if args.tcp is not None else None
        return serve_rig(args, lambda arm: arm_bus(args, arm, _faults(args)), address)
    try:
        bus = build_bus(args)
    except KeyError as exc:  # every option is checked first: no option to name
        raise ConfigError(str(exc.args[0])) from None
    except ValueError as exc:
        if isinstance(exc, ConfigError):
            raise
        raise ConfigError(str(exc)) from None
    server: SimServer
    if args.tcp is not None:
        host, port = _tcp_address(args.tcp)
        tcp = TcpServer(bus, host, port)
        server, where = tcp, tcp.url
    else:
        pty = PtyServer(bus)
        server, where = pty, pty.path
    hands = HandSchedule(bus, hand_commands(args))
    server.add_hook(hands)
    control = None
    try:
        if args.control is not None:
            control = ControlServer(args.control, hands)
            server.add_hook(control)
    except BaseException:
        server.close()
        raise
    stop = threading.Event()
    with stop_on_signals(stop):
        try:
            print(where, flush=True)
            if control is not None:
                print(control.address, flush=True)
            wire = "wire time at the baud rate" if bus.faults.wire else "no wire time (--no-wire)"
            print(
                f"retarget sim: serving servos {', '.join(map(str, bus.ids))} at {bus.baud} baud on {where} ({wire})"
                + (f"; control socket on {control.address}" if control is not None else "")
                + "; Ctrl-C to stop",
                file=sys.stderr,
                flush=True,
            )
            server.serve_forever(stop)
        finally:
            server.close()
            if control is not None:
                control.close()
    if bus.faults.wire and server.pacing.replies:
        print(f"retarget sim: {server.pacing.summary()}", file=sys.stderr)
    print("retarget sim: stopped", file=sys.stderr)
    return 0
