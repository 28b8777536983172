"""retarget: BVH human arm motion onto Dynamixel servo arms.

Public API (imported lazily, so ``import retarget`` stays cheap)::

    motion = retarget.load_bvh("clip.bvh")        # Motion: parse + vectorised FK
    arm = retarget.load_arm("wx250s")             # Arm: TOML or URDF description
    result = retarget.solve_ik(arm, target, q0)   # IKResult from CCD

Errors form one small tree rooted at :class:`RetargetError`.
"""

from __future__ import annotations

import importlib
from typing import Any

from retarget.errors import BusError, BvhError, ConfigError, RetargetError

__version__ = "0.1.0"

_LAZY = {
    "load_bvh": "retarget.bvh.parse",
    "Motion": "retarget.bvh.motion",
    "load_arm": "retarget.arm.config",
    "Arm": "retarget.arm.model",
    "solve_ik": "retarget.ik.ccd",
    "IKResult": "retarget.ik.ccd",
    "CCDSolver": "retarget.ik.ccd",
    "Weighting": "retarget.ik.ccd",
}

__all__ = ["BusError", "BvhError", "ConfigError", "RetargetError", "__version__", *_LAZY]


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'retarget' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value
