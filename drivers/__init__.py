"""The Dynamixel servo bus on dynamixel-sdk.

Lazy exports, so ``import drivers`` stays cheap (the SDK and pyserial load on first use)::

    from drivers import DynamixelBus, ShutdownMode
    with DynamixelBus(retarget.load_arm("wx250s"), "/dev/ttyUSB0") as bus:
        q = bus.read_positions()

Modules: ``control_table`` (registers as data), ``units`` (radians <-> pulses), ``port`` (PortHandler on any
pyserial URL), ``comm`` (transactions with retries), ``dynamixel_bus`` (the arm's bus), ``latency`` (FTDI
latency timer), ``scan`` (find servos on a port), ``servo_plan`` (per-servo limits and settings).
"""

from __future__ import annotations

import importlib
from typing import Any

_LAZY = {
    "DynamixelBus": "drivers.dynamixel_bus",
    "Profile": "drivers.servo_plan",
    "ServoPlan": "drivers.servo_plan",
    "ServoSettings": "drivers.servo_plan",
    "ServoState": "drivers.dynamixel_bus",
    "plan_servos": "drivers.servo_plan",
    "ShutdownMode": "retarget.control.bus",
    "UrlPortHandler": "drivers.port",
    "open_port": "drivers.port",
    "check_latency_timer": "drivers.latency",
    "scan": "drivers.scan",
    "FoundServo": "drivers.scan",
}

__all__ = list(_LAZY)


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'drivers' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value
