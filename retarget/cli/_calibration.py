"""``--calibration`` of the commands that drive an arm (``replay``, ``teleop``; ``scan --arm``).

:func:`calibrated_arm` applies the calibration of ``--calibration PATH|NAME|none``, or by default the one saved for
the arm's name (``retarget calibrate``'s default file), and says on stderr which one it uses.  An arm file with
``requires_calibration = true`` on a real port without one is an error naming the command that makes it.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from retarget.arm.calibration import apply_calibration, default_calibration_path, load_calibration
from retarget.arm.model import Arm
from retarget.errors import ConfigError

__all__ = ["add_calibration_argument", "calibrated_arm", "calibration_path"]


def add_calibration_argument(parser: argparse.ArgumentParser | Any) -> None:
    """--calibration PATH|NAME|none."""
    parser.add_argument(
        "--calibration",
        default=None,
        metavar="PATH|NAME|none",
        help="the arm's calibration file (retarget calibrate), or the NAME it was saved under; default: the one "
        "saved for the arm's name, if any; 'none': the arm file's offsets",
    )


def _say(text: str) -> None:
    print(text, file=sys.stderr, flush=True)


def calibration_path(choice: str | None, arm_name: str) -> Path | None:
    """The file ``--calibration`` names (a path, or a saved NAME), or the default one for ``arm_name`` when it
    exists; None for ``none`` or no saved default."""
    if choice is not None and choice.lower() == "none":
        return None
    if choice is not None:
        looks_like_path = "/" in choice or "\\" in choice or choice.endswith(".toml")
        return Path(choice) if looks_like_path else default_calibration_path(choice)
    try:
        path = default_calibration_path(arm_name)
    except ConfigError:  # an arm name that cannot name a file (a URDF robot's): no default
        return None
    return path if path.is_file() else None


def calibrated_arm(args: argparse.Namespace, arm: Arm) -> Arm:
    """``arm`` with the calibration of ``--calibration`` (or the default one) applied; see the module docstring.

    Says which calibration it uses on stderr (on a real port also when none).  Commands without the option
    (no ``calibration`` attribute) get ``arm`` back unchanged.
    """
    if not hasattr(args, "calibration"):
        return arm
    choice: str | None = args.calibration
    port: str | None = getattr(args, "port", None)
    real = port is not None and not port.startswith("sim://")
    path = calibration_path(choice, arm.name)
    if path is None:
        if arm.requires_calibration and real and choice is None:
            raise ConfigError(
                f"arm {arm.name!r} needs a calibration: run `retarget calibrate --arm {arm.name} --port {port}` "
                f"first (or give --calibration PATH; looked for {default_calibration_path(arm.name)})",
                key="--calibration",
            )
        if real:
            why = "--calibration none" if choice else "none saved"
            _say(f"retarget: calibration: none, the arm file's offsets ({why})")
        return arm
    if not path.is_file():
        raise ConfigError("calibration file not found", key="--calibration", value=str(path))
    cal = load_calibration(path)
    arm = apply_calibration(arm, cal)
    _say(f"retarget: calibration: {cal.name} ({path}, {cal.date})")
    return arm
