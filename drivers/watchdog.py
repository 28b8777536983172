"""The servos' Bus Watchdog as a safety net of the driver: if the host dies, the arm stops.

A Dynamixel X servo whose Bus Watchdog item (address 98, unit 20 ms, 1..127) is set and whose torque is on stops
when no instruction packet reached it for that long: "the DYNAMIXEL will stop ... the Profile Acceleration (108)
and Profile Velocity (112) are applied as 0" (e-Manual, Bus Watchdog).  In position mode the joint stops where it
is within the period and holds there under torque, instead of finishing the move it was last sent (a host
killed, a USB cable pulled, a frozen process).  The item then reads -1 and the goal items refuse writes (Data
Range error) until Bus Watchdog is written 0.

:class:`HostWatchdog` is the driver's side (``DynamixelBus(watchdog=...)``): it sets the item on every servo when
the first goal goes out (connect, the lead-in's computing and any pause before it cannot trip it), keeps track of
the host's own silence, and when a tick comes after a silence longer than the period it reads the item back, so a
run whose servos stopped ends with a BusError naming them instead of sending goals they ignore.  close() writes 0
first, so the shutdown's move to rest is accepted.  Every tick's SYNC_WRITE (broadcast ID) restarts every servo's
interval, the gripper's included.

>>> watchdog_setting(0.1), watchdog_setting(0.105), watchdog_setting(2.54)
(5, 6, 127)
>>> watchdog_setting(3.0)
Traceback (most recent call last):
...
retarget.errors.ConfigError: watchdog: Expected a watchdog period from 0.02 to 2.54 s (got 3.0)
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence

from drivers.comm import Link
from drivers.control_table import common_register
from retarget.errors import BusError, ConfigError

log = logging.getLogger(__name__)

__all__ = ["UNIT_S", "HostWatchdog", "watchdog_setting"]

UNIT_S = 0.020  #: Bus Watchdog unit (e-Manual: 20 ms)
MAX_SETTING = 127  #: the largest value that arms it (e-Manual: 1 ~ 127)
TRIPPED = 0xFF  #: what the item reads after it stopped the servo (-1)
_REGISTER = common_register("Bus Watchdog")


def watchdog_setting(period: float) -> int:
    """The Bus Watchdog value for ``period`` seconds, rounded up to the 20 ms unit (ConfigError keyed ``watchdog``
    outside 0.02..2.54 s)."""
    if not (math.isfinite(period) and UNIT_S <= period <= MAX_SETTING * UNIT_S + 1e-9):
        message = f"Expected a watchdog period from {UNIT_S:g} to {MAX_SETTING * UNIT_S:g} s"
        raise ConfigError(message, key="watchdog", value=period)
    return min(MAX_SETTING, math.ceil(round(period / UNIT_S, 6)))


class HostWatchdog:
    """The driver's side of the Bus Watchdog of servos ``ids`` for ``period`` seconds (see the module docstring).

    ``dt`` (s), the control tick, must leave room: the period must be at least 3 ticks (ConfigError otherwise), or
    the servos would stop between two healthy ticks.
    """

    def __init__(self, period: float, ids: Sequence[int], *, dt: float | None = None):
        self.setting = watchdog_setting(period)
        self.period = self.setting * UNIT_S  #: seconds, as the servos count it
        if dt is not None and self.period < 3 * dt:
            message = f"Expected a watchdog period of at least 3 control ticks ({3 * dt:g} s)"
            raise ConfigError(message, key="watchdog", value=period)
        self.ids = tuple(ids)
        self.armed = False
        self._last = -math.inf  #: clock time the host last talked to the servos

    def arm(self, link: Link, now: float) -> None:
        """Set Bus Watchdog on every servo (each write acknowledged); from now on silence stops them."""
        for dxl_id in self.ids:
            link.write_register(dxl_id, _REGISTER, 0)  # clears a trip left by an earlier run
            link.write_register(dxl_id, _REGISTER, self.setting)
        self.armed = True
        self._last = now
        log.info("bus watchdog armed: the servos stop after %.0f ms without a packet", self.period * 1000)

    def talked(self, now: float) -> None:
        """The host sent the servos a packet at clock time ``now``."""
        self._last = now

    def check(self, link: Link, now: float) -> None:
        """Before a tick: after a host silence longer than the period, BusError if a servo stopped."""
        if not self.armed or now - self._last <= self.period:
            return
        silence = now - self._last
        stopped = [i for i in self.ids if link.read_register(i, _REGISTER) == TRIPPED]
        self._last = now
        if stopped:
            raise BusError(
                f"the Bus Watchdog stopped the servos: the host sent nothing for {silence:.3f} s, longer than "
                f"the {self.period * 1000:.0f} ms watchdog",
                ids=stopped,
            )

    def rearm(self, link: Link, dxl_id: int) -> None:
        """Set the item again on one servo (a REBOOT cleared it), when armed."""
        if self.armed:
            link.write_register(dxl_id, _REGISTER, self.setting)

    def disarm(self, link: Link) -> None:
        """Bus Watchdog 0 on every servo (clears a trip, so goals are accepted again); failures are logged only."""
        if not self.armed:
            return
        self.armed = False
        for dxl_id in self.ids:
            try:
                link.write_register(dxl_id, _REGISTER, 0)
            except (BusError, OSError) as exc:
                log.warning("could not clear the bus watchdog of servo %d: %s", dxl_id, exc)
