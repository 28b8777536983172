"""retarget: BVH human arm motion onto Dynamixel servo arms.

The layers, one subpackage each (imports go one way, down this list)::

    retarget.bvh       BVH parsing, vectorised FK, Motion, arm-chain detection
    retarget.arm       the arm model, TOML and URDF readers, kinematics
    retarget.ik        the CCD inverse kinematics solver
    retarget.mapping   human arm -> targets in the arm's workspace
    retarget.control   the tick loop, clip replay, the Bus protocol, clocks, telemetry
    retarget.teleop    the tool point to targets that arrive while the arm moves
    retarget.cli       the command line

The public names below are imported lazily (``import retarget`` stays cheap); type checkers and ``dir()``
see them all.  Retarget a clip and play it (here a dry run on a virtual clock: no bus)::

    >>> import retarget
    >>> motion = retarget.load_bvh(retarget.DEMO_CLIP)              # parse + FK of every frame
    >>> arm = retarget.load_arm("wx250s")                            # a bundled arm, a TOML or a URDF
    >>> targets = retarget.retarget_targets(motion, arm, retarget.MappingConfig.from_table(arm.mapping))
    >>> loop = retarget.ControlLoop(arm, targets, config=retarget.LoopConfig(end=0.5), clock=retarget.VirtualClock())
    >>> summary = loop.run(None)                                     # or loop.run(bus): see drivers.DynamixelBus
    >>> summary.ticks, summary.ik_converged_pct > 90
    (51, True)

Errors form one small tree rooted at :class:`RetargetError`: ``BvhError`` (path, line), ``ConfigError``
(path, key, value), ``BusError`` (servo ids).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from retarget.errors import BusError, BvhError, ConfigError, RetargetError

__version__ = "0.1.0"  #: the one definition; pyproject.toml reads it from here

if TYPE_CHECKING:
    from retarget.arm.config import list_arms
    from retarget.arm.load import load_arm
    from retarget.arm.model import Arm
    from retarget.bvh.motion import Motion
    from retarget.bvh.parse import DEMO_CLIP, load_bvh
    from retarget.control.bus import Bus, ShutdownMode
    from retarget.control.clock import MonotonicClock, VirtualClock
    from retarget.control.loop import LoopConfig, TickRecord
    from retarget.control.replay import ControlLoop
    from retarget.control.summary import RunSummary
    from retarget.ik.ccd import CCDSolver, IKResult, Weighting, solve_ik
    from retarget.mapping.config import MappingConfig, Side
    from retarget.mapping.targets import Targets, retarget_targets

#: public name -> the module that defines it
_LAZY = {
    "DEMO_CLIP": "retarget.bvh.parse",
    "load_bvh": "retarget.bvh.parse",
    "Motion": "retarget.bvh.motion",
    "load_arm": "retarget.arm.load",
    "list_arms": "retarget.arm.config",
    "Arm": "retarget.arm.model",
    "solve_ik": "retarget.ik.ccd",
    "IKResult": "retarget.ik.ccd",
    "CCDSolver": "retarget.ik.ccd",
    "Weighting": "retarget.ik.ccd",
    "MappingConfig": "retarget.mapping.config",
    "Side": "retarget.mapping.config",
    "Targets": "retarget.mapping.targets",
    "retarget_targets": "retarget.mapping.targets",
    "ControlLoop": "retarget.control.replay",
    "LoopConfig": "retarget.control.loop",
    "TickRecord": "retarget.control.loop",
    "RunSummary": "retarget.control.summary",
    "Bus": "retarget.control.bus",
    "ShutdownMode": "retarget.control.bus",
    "MonotonicClock": "retarget.control.clock",
    "VirtualClock": "retarget.control.clock",
}

__all__ = [
    "BusError",
    "BvhError",
    "ConfigError",
    "RetargetError",
    "__version__",
    "DEMO_CLIP",
    "load_bvh",
    "Motion",
    "load_arm",
    "list_arms",
    "Arm",
    "solve_ik",
    "IKResult",
    "CCDSolver",
    "Weighting",
    "MappingConfig",
    "Side",
    "Targets",
    "retarget_targets",
    "ControlLoop",
    "LoopConfig",
    "TickRecord",
    "RunSummary",
    "Bus",
    "ShutdownMode",
    "MonotonicClock",
    "VirtualClock",
]


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'retarget' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_LAZY})
