"""Simulated Dynamixel Protocol 2.0 servos and bus, reachable as a serial port.

Importing ``sim`` registers the ``sim://`` URL scheme with pyserial (``serial.protocol_handler_packages``)::

    >>> import serial
    >>> from retarget.control.clock import VirtualClock
    >>> bus = SimBus.from_arm("wx250s", clock=VirtualClock())   # every servo of the arm, at its rest pose
    >>> url = attach(bus)                                        # "sim://@bus1": this bus, in this process
    >>> port = serial.serial_for_url(url, timeout=0)             # or sim://wx250s, sim://?ids=1-6
    >>> port.bus is bus
    True
    >>> port.close()
    >>> unregister(url)

Modules: ``protocol`` (packet codec), ``servo`` (one servo), ``bus`` (the wire), ``faults`` (fault
injection), ``transport`` (the pyserial port), ``server`` (pty / TCP server), ``profile`` (motion profiles),
``rules``/``servo_writes``/``watchdog``/``physics`` (the e-Manual's register rules, Bus Watchdog and no-load
motion), ``hand``/``hand_commands`` (joints turned by hand while limp, and their CLI gestures), ``control``
(``retarget sim``'s control socket).
``Reply`` is the first release's name of :class:`ScheduledReply`.
"""

from __future__ import annotations

import serial

from sim.bus import Reply, ScheduledReply, SimBus
from sim.faults import Faults, HardwareFault, ReplyFaults
from sim.servo import SimServo
from sim.transport import attach, bus_from_url, register, registered, unregister

if "sim" not in serial.protocol_handler_packages:
    serial.protocol_handler_packages.append("sim")

__all__ = [
    "Faults",
    "HardwareFault",
    "Reply",
    "ReplyFaults",
    "ScheduledReply",
    "SimBus",
    "SimServo",
    "attach",
    "bus_from_url",
    "register",
    "registered",
    "unregister",
]
