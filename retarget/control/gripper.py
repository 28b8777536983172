"""The gripper on the control loop: each tick's command from a closure source, its readings into the tick record.

The gripper is outside IK and outside the joints' sync write: the bus takes a closure (0 open .. 1 closed of the
arm's ``[gripper]`` limits) with ``set_gripper`` and writes it on its own tick path when it changed, reading the
gripper's position and current at its watch rate (``drivers.DynamixelBus``).  :class:`GripperFeed` sits on the
loop's ``on_tick``: it asks the source for the closure at the tick's clip time, hands it to the bus, and fills the
record's ``gripper_cmd``/``gripper_present``/``gripper_current`` for telemetry before passing it on.  The command
therefore reaches the servo one tick after the joints' goals of the same clip time (10 ms at 100 Hz).

>>> from retarget.mapping.gripper import GripperTrack
>>> seen = []
>>> feed = GripperFeed(GripperTrack.constant(0.5).at, bus=None, on_tick=seen.append)
>>> import numpy as np
>>> from retarget.control.loop import TickRecord
>>> z = np.zeros(3)
>>> feed(TickRecord(0, 0.0, 0.0, z, z, None, 0.0, 0, True, 0.0, 0.0, False, False, False, 0))
>>> seen[0].gripper_cmd
0.5
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from typing import Protocol

from retarget.control.loop import TickRecord

__all__ = ["GripperBus", "GripperFeed"]


class GripperBus(Protocol):
    """What :class:`GripperFeed` needs of a bus (``drivers.DynamixelBus`` has it)."""

    def set_gripper(self, closure: float) -> None: ...

    def gripper_reading(self) -> object | None: ...


class GripperFeed:
    """An ``on_tick`` wrapper: ``closure_at(clip_time)`` (or None: no command) to the bus, readings to the record.

    ``closure_at`` returns a closure 0..1 for a clip time (s); ``bus``: a connected bus with a gripper, or None (a
    dry run: the command is recorded, nothing is sent); ``on_tick``: where the filled record goes (None: nowhere).
    """

    def __init__(
        self,
        closure_at: Callable[[float], float | None],
        *,
        bus: GripperBus | None,
        on_tick: Callable[[TickRecord], None] | None,
    ):
        self.closure_at, self.bus, self.on_tick = closure_at, bus, on_tick
        self.last: float | None = None  #: the last closure commanded

    def __call__(self, record: TickRecord) -> None:
        closure = self.closure_at(record.clip_time)
        if closure is not None:
            self.last = closure
            if self.bus is not None:
                self.bus.set_gripper(closure)
        angle, current = math.nan, math.nan
        reading = self.bus.gripper_reading() if self.bus is not None else None
        if reading is not None:
            angle = float(getattr(reading, "angle", math.nan))
            current = float(getattr(reading, "current", math.nan))
            if math.isnan(current):  # XL430: Present Load, a fraction
                current = float(getattr(reading, "load", math.nan))
        record = dataclasses.replace(
            record,
            gripper_cmd=math.nan if self.last is None else self.last,
            gripper_present=angle,
            gripper_current=current,
        )
        if self.on_tick is not None:
            self.on_tick(record)
