"""The ``retarget`` command line.

Each subcommand lives in its own module ``retarget.cli.<name>`` with two
functions: ``add_parser(subparsers) -> argparse.ArgumentParser`` and
``run(args) -> int``.  Data goes to stdout; progress and messages to stderr.

Errors: a :class:`~retarget.errors.RetargetError` (bad file, bad config, bus
failure) prints one line ``retarget: <message>`` on stderr and exits with the
command's error status (2 for bad input by default); ``-v`` also prints the
traceback.  Ctrl-C exits 130 after the command's own cleanup ran; in ``replay`` and ``teleop`` SIGTERM
and SIGHUP run the same cleanup (the bus's shutdown) and exit 143 and 129.  The library's errors
name fields (``rate``, ``mapping.floor``); :mod:`retarget.cli.options` maps them to the
options that set them, in one table.  Shared options live in ``_arm`` and ``_bus``; the
curses screen of ``teleop --interactive`` in :mod:`retarget.cli.tui`.
"""

from __future__ import annotations

import argparse
import importlib
import json
import logging
import sys
import traceback
from collections.abc import Sequence

from retarget.cli.options import option_error
from retarget.errors import BusError, ConfigError, RetargetError

#: Subcommands in the order ``--help`` lists them.
COMMANDS: tuple[str, ...] = (
    "replay", "teleop", "export", "view", "plot", "inspect", "arm", "rig", "scan", "calibrate", "sim"
)  # fmt: skip

EXIT_OK = 0
EXIT_USAGE = 2  #: bad input: a file, a config key, an option value
EXIT_BUS = 4  #: the bus failed (no reply, hardware alert)
EXIT_UNREACHED = 3  #: teleop: the last target was not reached within tolerance
EXIT_INTERRUPTED = 130  #: Ctrl-C; SIGTERM 143 and SIGHUP 129 (128 + the signal number)

EPILOG = """\
examples:
  retarget replay                      the demo clip on wx250s, in-process simulated bus
  retarget replay clip.bvh --fast      as fast as possible on a virtual clock
  retarget teleop --to 0.3,0,0.2       move the tool point there; exit 0 reached, 3 unreachable
  retarget teleop --stdin --fast       follow 'x y z' / JSON target lines from stdin, in order
  retarget teleop --interactive        keys nudge the target; shows target, reached point, joints
  retarget export clip.bvh -o t.csv    the retargeted joint trajectory as CSV, no bus
  retarget inspect clip.bvh            show the skeleton, frame rate and arm chains
  retarget inspect clip.bvh --json     the same as JSON on stdout
  retarget arm vx300s                  an arm's joints, limits, servos and poses (--list: every bundled arm)
  retarget arm wx250s --ik 0.35,0,0.25 solve IK for a point in the base frame
  retarget rig aloha                   a rig's arms, base poses, ports and sides (--list: the bundled rigs)
  retarget scan --port /dev/ttyUSB0    list the servos on a port: ID, model, firmware, baud
  retarget calibrate --arm koch --port /dev/ttyUSB0   a hand-built arm's servo zeros, directions, ranges
  retarget sim --tcp 127.0.0.1:4000    simulated servos of wx250s on loopback TCP (or a pty by default)

run 'retarget COMMAND --help' for each command's own examples.
"""


def print_json(data: object) -> None:
    """Write ``data`` as the commands' ``--json`` output: indented JSON and a final newline, on stdout."""
    json.dump(data, sys.stdout, indent=2)
    sys.stdout.write("\n")


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The command line's parser: every subcommand, or only ``command`` (one of :data:`COMMANDS`), which parses that
    command's arguments the same way at a tenth of the cost (building every subcommand's options takes ~10 ms, a
    noticeable share of a short command such as ``export``).

    >>> build_parser("inspect").parse_args(["inspect", "clip.bvh", "--json"]).json
    True
    """
    parser = argparse.ArgumentParser(
        prog="retarget",
        description="Retarget BVH human arm motion onto Dynamixel servo arms.",
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("-v", "--verbose", action="count", default=0, help="more log output; show tracebacks")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name in COMMANDS if command is None else (command,):
        module = importlib.import_module(f"retarget.cli.{name}")
        sub_parser = module.add_parser(sub)
        sub_parser.set_defaults(_run=module.run)
        # let -v work after the subcommand too: `retarget inspect x.bvh -v`
        sub_parser.add_argument("-v", "--verbose", action="count", default=argparse.SUPPRESS, help=argparse.SUPPRESS)
    return parser


def named_command(argv: Sequence[str]) -> str | None:
    """The subcommand ``argv`` names when nothing but ``-v`` comes before it, else None (``--help``, a misspelt or
    missing command: the whole parser then says what is wrong or lists the commands).

    >>> named_command(["-v", "export", "clip.bvh"]), named_command(["--help"]), named_command(["exprt"])
    ('export', None, None)
    """
    for token in argv:
        if token in ("-v", "--verbose") or (token.startswith("-v") and set(token[1:]) == {"v"}):
            continue
        return token if token in COMMANDS else None
    return None


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser(named_command(sys.argv[1:] if argv is None else argv))
    args = parser.parse_args(argv)
    logging.basicConfig(
        level=logging.DEBUG if args.verbose > 1 else logging.INFO if args.verbose else logging.WARNING,
        format="%(levelname)s %(name)s: %(message)s",
        stream=sys.stderr,
    )
    try:
        return int(args._run(args) or 0)
    except RetargetError as exc:
        if args.verbose:
            traceback.print_exc()
        print(f"retarget: {option_error(exc) if isinstance(exc, ConfigError) else exc}", file=sys.stderr)
        return EXIT_BUS if isinstance(exc, BusError) else EXIT_USAGE
    except KeyboardInterrupt as exc:  # a second Ctrl-C, SIGTERM or SIGHUP (``_bus.SignalInterrupt``: its signum)
        try:
            print("retarget: interrupted", file=sys.stderr)
        except OSError:  # the terminal hung up
            pass
        signum = getattr(exc, "signum", None)
        return EXIT_INTERRUPTED if signum is None else 128 + int(signum)
    except BrokenPipeError:  # `retarget inspect x --json | head`
        return EXIT_OK
    except OSError as exc:  # a file that cannot be opened, a port that does not exist
        if args.verbose:
            traceback.print_exc()
        print(f"retarget: {exc}", file=sys.stderr)
        return EXIT_USAGE
