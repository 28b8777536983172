"""Simulated Dynamixel Protocol 2.0 servos and bus, reachable as a serial port.

    bus = sim.SimBus.from_arm("wx250s", clock=VirtualClock())   # every servo of the arm
    url = sim.attach(bus)                                        # "sim://@bus1"
    port = serial.serial_for_url(url)                            # or sim://wx250s, sim://?ids=1-6

Importing ``sim`` registers the ``sim://`` URL scheme with pyserial (``serial.protocol_handler_packages``).
Modules: ``protocol`` (packet codec), ``servo`` (one servo), ``bus`` (the wire), ``faults`` (fault
injection), ``transport`` (the pyserial port), ``server`` (pty / TCP server).
"""

from __future__ import annotations

import serial

from sim.bus import Reply, SimBus
from sim.faults import Faults, HardwareFault, ReplyFaults
from sim.servo import SimServo
from sim.transport import attach, register, registered, unregister

if "sim" not in serial.protocol_handler_packages:
    serial.protocol_handler_packages.append("sim")

__all__ = [
    "Faults",
    "HardwareFault",
    "Reply",
    "ReplyFaults",
    "SimBus",
    "SimServo",
    "attach",
    "register",
    "registered",
    "unregister",
]
