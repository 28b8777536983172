"""``retarget sim``: serve simulated Dynamixel servos on a pseudo-terminal or loopback TCP until interrupted."""

from __future__ import annotations

import argparse
import signal
import sys
import threading
from typing import Any

from drivers.control_table import parse_ids
from retarget.cli._arm import add_link_arguments, load_arm_option
from retarget.control.clock import MonotonicClock
from retarget.errors import ConfigError
from sim.bus import SimBus
from sim.faults import Faults
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
  retarget sim --wire --delay-ms 6:3             wire time at the baud rate; servo 6 answers 3 ms late
  retarget sim --arm robot.urdf --tip ee_link    the servos of a URDF arm (servo IDs from robot.servos.toml)

The first line on stdout is what to open: a device path (/dev/pts/N) or a socket:// URL; messages go to
stderr.  Fault values take an optional servo ID: --drop 0.1 (every servo) or --drop 3:0.5 (servo 3).
Ctrl-C or SIGTERM stops the server cleanly (exit status 0).
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
    servos.add_argument("--ids", default=None, help="IDs instead of an arm, e.g. 1-6 or 1,2,5")
    servos.add_argument("--model", default=None, help="servo model with --ids (default XL430-W250)")
    servos.add_argument("--baud", type=int, default=None, help="the servos' baud rate (default: the arm's, or 1000000)")
    servos.add_argument(
        "--rdt", type=int, default=None, help="Return Delay Time item, 2 us units (default 250, factory)"
    )
    servos.add_argument(
        "--boot-ms", type=float, default=0.0, help="how long a servo stays silent after REBOOT (default 0)"
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
    faults.add_argument("--wire", action="store_true", help="model the wire time at the baud rate (10 bits/byte)")
    faults.add_argument("--seed", type=int, default=0, help="seed of the random faults (default 0)")
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


def build_bus(args: argparse.Namespace) -> SimBus:
    """The SimBus the options describe (real-time clock)."""

    faults = Faults.from_options(
        drop=args.drop,
        corrupt=args.corrupt,
        delay_ms=args.delay_ms,
        unplug=args.unplug,
        hwerror=args.hwerror,
        wire=args.wire,
        seed=args.seed,
    )
    clock = MonotonicClock()
    if args.ids is not None:
        if args.arm is not None:
            raise ConfigError("give either --arm or --ids, not both", key="--ids", value=args.ids)
        if args.base is not None or args.tip is not None:
            option = "--base" if args.base is not None else "--tip"
            raise ConfigError(f"{option} goes with a URDF --arm, not --ids", key=option, value=args.ids)
        return SimBus.from_ids(
            parse_ids(args.ids),
            args.model or "XL430-W250",
            clock=clock,
            baud=args.baud or 1_000_000,
            return_delay_time=args.rdt,
            boot_time=args.boot_ms / 1000.0,
            faults=faults,
        )
    if args.model is not None:
        raise ConfigError("--model goes with --ids", key="--model", value=args.model)
    return SimBus.from_arm(
        load_arm_option(args),
        clock=clock,
        baud=args.baud,
        return_delay_time=args.rdt,
        boot_time=args.boot_ms / 1000.0,
        faults=faults,
    )


def run(args: argparse.Namespace) -> int:

    try:
        bus = build_bus(args)
    except KeyError as exc:  # an unknown model
        raise ConfigError(str(exc.args[0]), key="--model") from None
    except ValueError as exc:
        if isinstance(exc, ConfigError):
            raise
        raise ConfigError(str(exc), key="--baud") from None
    server: SimServer
    if args.tcp is not None:
        host, port = _tcp_address(args.tcp)
        tcp = TcpServer(bus, host, port)
        server, where = tcp, tcp.url
    else:
        pty = PtyServer(bus)
        server, where = pty, pty.path
    stop = threading.Event()

    def on_signal(signum: int, frame: object) -> None:
        stop.set()

    previous = {sig: signal.signal(sig, on_signal) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        print(where, flush=True)
        print(
            f"retarget sim: serving servos {', '.join(map(str, bus.ids))} at {bus.baud} baud on {where}; "
            "Ctrl-C to stop",
            file=sys.stderr,
            flush=True,
        )
        server.serve_forever(stop)
    finally:
        server.close()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    print("retarget sim: stopped", file=sys.stderr)
    return 0
