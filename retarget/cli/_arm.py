"""The arm options shared by the commands that load an arm (``replay``, ``export``, ``teleop``, ``sim``).

``--arm`` (a bundled name, a TOML file or a URDF with its ``<stem>.servos.toml``) and, for a URDF,
``--base LINK``/``--tip LINK`` naming the chain's ends when the URDF has several roots or leaves.
:func:`load_arm_option` loads it; every problem is a one-line :class:`~retarget.errors.ConfigError`
naming the option (``--tip: cannot tell the tip link: leaves a, b; give --tip LINK``).
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING, Any

from retarget.errors import ConfigError

if TYPE_CHECKING:
    from retarget.arm import Arm

DEFAULT_ARM = "wx250s"

_URDF_SUFFIXES = (".urdf", ".xml")  # as retarget.arm.config treats them


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
    import retarget
    from retarget.arm.config import resolve_arm

    name = args.arm if args.arm is not None else DEFAULT_ARM
    base, tip = args.base, args.tip
    if base is not None or tip is not None:
        path = resolve_arm(name)
        if path.suffix.lower() not in _URDF_SUFFIXES:
            option, value = ("--base", base) if base is not None else ("--tip", tip)
            raise ConfigError(f"{option} only applies to a URDF --arm, not {path.name}", key=option, value=value)
    try:
        return retarget.load_arm(name, base=base, tip=tip)
    except ConfigError as exc:
        # the URDF chain's ends (retarget.urdf.find_chain) say "base"/"tip": name the options instead
        if exc.key in ("base", "tip") and exc.path is not None and Path(exc.path).suffix.lower() in _URDF_SUFFIXES:
            option = "--" + exc.key
            message = exc.message.replace(f"give {exc.key}=", f"give {option} LINK")
            if exc.value is None:
                raise ConfigError(message, path=exc.path, key=option) from exc
            raise ConfigError(message, path=exc.path, key=option, value=exc.value) from exc
        raise
