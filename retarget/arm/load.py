"""``load_arm``: an arm by bundled name, TOML file or URDF, the one entry point over both readers."""

from __future__ import annotations

from os import PathLike

from retarget.arm.config import ArmFileReader, is_urdf, read_toml, resolve_arm
from retarget.arm.model import Arm
from retarget.arm.urdf import load_urdf_arm
from retarget.errors import ConfigError

__all__ = ["load_arm"]


def load_arm(name_or_path: str | PathLike[str], *, base: str | None = None, tip: str | None = None) -> Arm:
    """Load an arm description.

    ``name_or_path`` is a bundled arm name (see :func:`list_arms`), a ``.toml`` file in the
    schema of this module, or a ``.urdf`` file with its servo file beside it (``base`` and
    ``tip`` name the chain's end links when the URDF is ambiguous; see :mod:`retarget.arm.urdf`).
    Raises :class:`~retarget.errors.ConfigError`.
    """
    path = resolve_arm(name_or_path)
    if is_urdf(path):
        return load_urdf_arm(path, base=base, tip=tip)
    if base is not None or tip is not None:
        raise ConfigError("base/tip only apply to a URDF file", path=path, key="base" if base else "tip")
    return ArmFileReader(path).arm(read_toml(path))
