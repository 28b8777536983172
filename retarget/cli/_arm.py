"""The arm options shared by the commands that load an arm (``replay``, ``export``, ``teleop``, ``sim``).

``--arm`` (a bundled name, a TOML file or a URDF with its ``<stem>.servos.toml``) and, for a URDF,
``--base LINK``/``--tip LINK`` naming the chain's ends when the URDF has several roots or leaves.
:func:`load_arm_option` loads it; every problem is a one-line :class:`~retarget.errors.ConfigError`
naming the option (``robot.urdf: --tip: cannot tell the tip link: leaves a, b; name one``).

The collision options (``replay``, ``export``, ``teleop``): ``--clearance MM``, ``--keep-out box:X0,Y0,Z0,X1,Y1,Z1``
or ``sphere:X,Y,Z,R`` (metres, base frame; repeatable, added to the arm file's ``[world]``) and ``--no-table``;
:func:`collision_model` builds the :class:`~retarget.collision.CollisionModel` every goal is checked against.
"""

from __future__ import annotations

import argparse
import math
from typing import Any

from retarget.arm.config import is_urdf, resolve_arm
from retarget.arm.load import load_arm
from retarget.arm.model import Arm
from retarget.cli._calibration import add_calibration_argument, calibrated_arm
from retarget.cli.options import option_error
from retarget.collision import DEFAULT_CLEARANCE, Box, CollisionModel, KeepOut, Sphere, World
from retarget.errors import ConfigError

DEFAULT_ARM = "wx250s"


def add_arm_arguments(parser: argparse.ArgumentParser | Any, *, default: str | None = DEFAULT_ARM) -> None:
    """--arm NAME|PATH, --base LINK, --tip LINK (on a parser or an argument group); ``default`` None: the default
    arm, and the command can tell that no --arm was given."""
    parser.add_argument("--arm", default=default, help=f"arm name or TOML/URDF path (default {default or DEFAULT_ARM})")
    add_link_arguments(parser)
    add_calibration_argument(parser)  # --calibration (retarget.cli._calibration)


def add_link_arguments(parser: argparse.ArgumentParser | Any) -> None:
    """--base LINK, --tip LINK alone, for a command that declares its own --arm."""
    parser.add_argument("--base", default=None, metavar="LINK", help="with a URDF --arm: the chain's base link")
    parser.add_argument("--tip", default=None, metavar="LINK", help="with a URDF --arm: the chain's tip (tool) link")


MAX_CLEARANCE_MM = 100.0  #: the largest --clearance: beyond it an arm could hardly move


def add_collision_arguments(parser: argparse.ArgumentParser | Any) -> None:
    """--clearance MM, --keep-out SPEC (repeatable), --no-table."""
    parser.add_argument(
        "--clearance",
        default=None,
        metavar="MM",
        help=f"keep every link this far from the others, the table and the keep-out zones "
        f"(default {DEFAULT_CLEARANCE * 1e3:g} mm)",
    )
    parser.add_argument(
        "--keep-out",
        action="append",
        default=[],
        metavar="box:X0,Y0,Z0,X1,Y1,Z1|sphere:X,Y,Z,R",
        help="a zone the arm must stay out of, metres, base frame (repeatable; added to the arm file's [world])",
    )
    parser.add_argument("--no-table", action="store_true", help="no table plane at z = 0 (an arm mounted on a post)")


def parse_keep_out(text: str) -> KeepOut:
    """``box:X0,Y0,Z0,X1,Y1,Z1`` (two corners) or ``sphere:X,Y,Z,R``, metres -> a Box or a Sphere; ConfigError
    naming ``--keep-out``.

    >>> parse_keep_out("sphere:0.3,0,0.1,0.05")
    Sphere(center=(0.3, 0.0, 0.1), radius=0.05)
    >>> parse_keep_out("box:0.2,-0.1,0,0.3,0.1,0.2")
    Box(center=(0.25, 0.0, 0.1), half_size=(0.04999999999999999, 0.1, 0.1))
    """
    kind, _, rest = text.partition(":")
    count = {"box": 6, "sphere": 4}.get(kind.strip().lower())
    try:
        values = [float(v) for v in rest.split(",")]
    except ValueError:
        values = []
    if count is None or len(values) != count or not all(math.isfinite(v) for v in values):
        raise ConfigError("Expected box:X0,Y0,Z0,X1,Y1,Z1 or sphere:X,Y,Z,R (finite metres)", key="--keep-out",
                          value=text)  # fmt: skip
    if count == 4:
        if not values[3] > 0:
            raise ConfigError("Expected a sphere radius > 0 m", key="--keep-out", value=text)
        return Sphere((values[0], values[1], values[2]), values[3])
    lo, hi = values[:3], values[3:]
    if not all(a < b for a, b in zip(lo, hi, strict=True)):
        raise ConfigError("Expected each box minimum below its maximum", key="--keep-out", value=text)
    return Box(
        tuple((a + b) / 2 for a, b in zip(lo, hi, strict=True)),  # type: ignore[arg-type]
        tuple((b - a) / 2 for a, b in zip(lo, hi, strict=True)),  # type: ignore[arg-type]
    )


def collision_model(args: argparse.Namespace, arm: Arm) -> CollisionModel:
    """The collision model of ``arm`` with --clearance, --keep-out and --no-table; ConfigError naming them."""
    clearance_mm = DEFAULT_CLEARANCE * 1e3
    if getattr(args, "clearance", None) is not None:
        try:
            clearance_mm = float(args.clearance)
        except ValueError:
            raise ConfigError("Expected a number of millimetres", key="--clearance", value=args.clearance) from None
        if not 0 <= clearance_mm <= MAX_CLEARANCE_MM:
            raise ConfigError(f"Expected a clearance from 0 to {MAX_CLEARANCE_MM:g} mm", key="--clearance",
                              value=args.clearance)  # fmt: skip
    extra = tuple(parse_keep_out(text) for text in getattr(args, "keep_out", None) or ())
    world = World(table=arm.world.table and not getattr(args, "no_table", False), keep_out=arm.world.keep_out + extra)
    return CollisionModel.for_arm(arm, world=world, clearance=clearance_mm * 1e-3)


def load_arm_option(args: argparse.Namespace) -> Arm:
    """The arm of ``--arm`` (None: the default arm), ``--base``, ``--tip``, with its ``--calibration`` (commands that
    have the option); ConfigError naming the option."""
    name = args.arm if args.arm is not None else DEFAULT_ARM
    base, tip = args.base, args.tip
    if base is not None or tip is not None:
        path = resolve_arm(name)
        if not is_urdf(path):
            option, value = ("--base", base) if base is not None else ("--tip", tip)
            raise ConfigError(f"{option} only applies to a URDF --arm, not {path.name}", key=option, value=value)
    return calibrated_arm(args, load_arm_naming_links(name, base=base, tip=tip))


def load_arm_naming_links(name: str, *, base: str | None, tip: str | None) -> Arm:
    """``load_arm``; an error about the URDF chain's ends names the ``--base``/``--tip`` options."""
    try:
        return load_arm(name, base=base, tip=tip)
    except ConfigError as exc:
        # the URDF chain's ends (retarget.arm.urdf.find_chain) name the base/tip arguments: name the options
        if exc.key in ("base", "tip") and exc.path is not None and is_urdf(exc.path):
            raise option_error(exc, keyed_in_file=True) from exc
        raise
