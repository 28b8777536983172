"""The arm options shared by the commands that load an arm (``replay``, ``export``, ``teleop``, ``sim``).

``--arm`` (a bundled name, a TOML file or a URDF with its ``<stem>.servos.toml``) and, for a URDF,
``--base LINK``/``--tip LINK`` naming the chain's ends when the URDF has several roots or leaves.
:func:`load_arm_option` loads it; every problem is a one-line :class:`~retarget.errors.ConfigError`
naming the option (``robot.urdf: --tip: cannot tell the tip link: leaves a, b; name one``).
"""

from __future__ import annotations

import argparse
from typing import Any

from retarget.arm.config import is_urdf, resolve_arm
from retarget.arm.load import load_arm
from retarget.arm.model import Arm
from retarget.cli.options import option_error
from retarget.errors import ConfigError

DEFAULT_ARM = "wx250s"


def add_arm_arguments(parser: argparse.ArgumentParser | Any, *, default: str = DEFAULT_ARM) -> None:
    """--arm NAME|PATH, --base LINK, --tip LINK (on a parser or an argument group)."""
    parser.add_argument("--arm", default=default, help=f"arm name or TOML/URDF path (default {default})")
    add_link_arguments(parser)


def add_link_arguments(parser: argparse.ArgumentParser | Any) -> None:
    """--base LINK, --tip LINK alone, for a command that declares its own --arm."""
    parser.add_argument("--base", default=None, metavar="LINK", help="with a URDF --arm: the chain's base link")
    parser.add_argument("--tip", default=None, metavar="LINK", help="with a URDF --arm: the chain's tip (tool) link")


def load_arm_option(args: argparse.Namespace) -> Arm:
    """The arm of ``--arm`` (None: the default arm), ``--base``, ``--tip``; ConfigError naming the option."""
    name = args.arm if args.arm is not None else DEFAULT_ARM
    base, tip = args.base, args.tip
    if base is not None or tip is not None:
        path = resolve_arm(name)
        if not is_urdf(path):
            option, value = ("--base", base) if base is not None else ("--tip", tip)
            raise ConfigError(f"{option} only applies to a URDF --arm, not {path.name}", key=option, value=value)
    return load_arm_naming_links(name, base=base, tip=tip)


def load_arm_naming_links(name: str, *, base: str | None, tip: str | None) -> Arm:
    """``load_arm``; an error about the URDF chain's ends names the ``--base``/``--tip`` options."""
    try:
        return load_arm(name, base=base, tip=tip)
    except ConfigError as exc:
        # the URDF chain's ends (retarget.arm.urdf.find_chain) name the base/tip arguments: name the options
        if exc.key in ("base", "tip") and exc.path is not None and is_urdf(exc.path):
            raise option_error(exc, keyed_in_file=True) from exc
        raise
