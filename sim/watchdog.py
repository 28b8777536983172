"""The Bus Watchdog (98) timer of a simulated servo (e-Manual ``_includes/en/dxl/control_table_buswatchdog.md``).

What the e-Manual says, and what the simulator does with it:

* 0 deactivates it and clears a Bus Watchdog error; 1..127 activate it, unit 20 ms; it reads -1 (0xFF) after it
  tripped ("Bus Watchdog Error Status").
* It "monitors the communication interval (time) between the controller and DYNAMIXEL when Torque Enable (64)
  is 1"; "the communication is defined as all the Instruction Packet in the DYNAMIXEL Protocol".  The simulator
  restarts the interval on every instruction packet with a good CRC that the servo takes as its own: sent to its
  ID, to its active Secondary ID, or to the broadcast ID (sync/bulk instructions included).  Whether a real servo
  also counts packets for other IDs is not documented (unverified).
* When the interval exceeds the setting, "the DYNAMIXEL will stop ... the Profile Acceleration (108) and Profile
  Velocity (112) are applied as 0": it stops at once where it is and holds there (torque stays on).  The simulator
  sets Goal Position to the position it stopped at (as DynamixelSDK#584 reports a real servo doing) and zeroes the
  goal of velocity, current and PWM modes, so a later torque off/on does not start it again.
* While it reads -1 a write to a goal item answers Data Range (4) (:data:`sim.rules.WATCHDOG_LOCKED`).

The servo computes a trip lazily: whenever it is brought up to a time past :meth:`BusWatchdog.deadline` (a read, a
write, the next packet, or any ``update``), it first advances its motion to the deadline and stops there, so a
host that simply stops sending sees the servo stopped at the trip position when it next reads.

>>> wd = BusWatchdog(last_packet=10.0)
>>> wd.deadline(setting=5, torque=True)  # 5 x 20 ms after the last packet
10.1
>>> wd.deadline(setting=5, torque=False), wd.deadline(setting=0, torque=True)
(inf, inf)
"""

from __future__ import annotations

import math

WATCHDOG_UNIT_S = 0.020  #: Bus Watchdog unit, 20 ms
WATCHDOG_MAX = 127  #: largest setting that activates it
WATCHDOG_ERROR = 0xFF  #: the byte it reads after a trip (-1)


class BusWatchdog:
    """When the servo last took an instruction packet as its own (clock seconds)."""

    def __init__(self, last_packet: float):
        self.last_packet = float(last_packet)

    def packet(self, t: float) -> None:
        """An instruction packet for this servo arrived at clock time ``t``: the interval restarts."""
        t = float(t)
        if t > self.last_packet:  # max(), without the call: every servo hears every packet
            self.last_packet = t

    def deadline(self, *, setting: int, torque: bool) -> float:
        """Clock time it trips with Bus Watchdog item ``setting`` and Torque Enable ``torque``; inf when it cannot."""
        if not torque or not 1 <= setting <= WATCHDOG_MAX:
            return math.inf
        return round(self.last_packet + setting * WATCHDOG_UNIT_S, 9)
