"""``load_arm``: an arm by bundled name, TOML file or URDF, the one entry point over both readers."""

from __future__ import annotations

from os import PathLike

from retarget.arm.config import ArmFileReader, is_urdf, read_toml, resolve_arm
from retarget.arm.model import Arm
from retarget.arm.urdf import load_urdf_arm
from retarget.errors import ConfigError

__all__ = ["load_arm"]


def load_arm(name_or_path: str | PathLike[str], *, base: str | None = None, tip: str | None = None) -> Arm:
    """Load an arm description: a bundled arm by name, a TOML arm file, or a URDF with its servo file.

    ``name_or_path``: a bundled arm name (see :func:`~retarget.arm.config.list_arms`), the path of a
    ``.toml`` arm file (the schema in :mod:`retarget.arm.config`), or of a ``.urdf``/``.xml`` file with
    its servo file ``<stem>.servos.toml`` beside it (see :mod:`retarget.arm.urdf`).  ``base``/``tip``
    (URDF only): the links that end the chain, when the URDF alone is ambiguous.

    Returns the frozen :class:`~retarget.arm.model.Arm`, in radians and metres (the files hold
    degrees): ``joints`` base to tip, ``home``/``rest`` ``(n_joints,)`` float64 radians inside the
    limits, the servos, the gripper and the raw ``[mapping]`` table.

    Raises :class:`~retarget.errors.ConfigError` naming the file, the key path and the bad value: an
    unknown arm name (the message lists the bundled ones), a missing or unreadable file, invalid TOML
    or XML, a value outside the schema, ``base``/``tip`` for a TOML file.

    >>> arm = load_arm("wx250s")
    >>> arm.name, arm.n_joints, arm.home.shape
    ('wx250s', 6, (6,))
    >>> arm.joint_names
    ('waist', 'shoulder', 'elbow', 'forearm_roll', 'wrist_angle', 'wrist_rotate')
    >>> load_arm("no_such_arm")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    retarget.errors.ConfigError: arm: unknown arm 'no_such_arm'; known arms: ...
    """
    path = resolve_arm(name_or_path)
    if is_urdf(path):
        return load_urdf_arm(path, base=base, tip=tip)
    if base is not None or tip is not None:
        raise ConfigError("base/tip only apply to a URDF file", path=path, key="base" if base else "tip")
    return ArmFileReader(path).arm(read_toml(path))
