"""Fixtures for the simulator tests: a dynamixel-sdk port on the in-process ``sim://`` transport or on a pty.

Both run the SDK's own PacketHandler and group classes unchanged; only ``PortHandler.setupPort`` differs for
the in-process port (it opens the URL with ``serial.serial_for_url``; the pty needs no change at all).
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from dataclasses import dataclass

import pytest
import serial
from dynamixel_sdk import PacketHandler, PortHandler

import sim
from retarget.clock import VirtualClock
from sim.server import PtyServer


class UrlPortHandler(PortHandler):
    """The SDK port, opening any pyserial URL (the same seam drivers.port uses)."""

    def setupPort(self, cflag_baud):  # noqa: N802 - the SDK's name
        if self.is_open:
            self.closePort()
        self.ser = serial.serial_for_url(self.port_name, baudrate=self.baudrate, bytesize=serial.EIGHTBITS, timeout=0)
        self.is_open = True
        self.ser.reset_input_buffer()
        self.tx_time_per_byte = (1000.0 / self.baudrate) * 10.0
        return True


@dataclass
class Rig:
    """A simulated bus and an open dynamixel-sdk port on it."""

    bus: sim.SimBus
    clock: VirtualClock
    port: PortHandler
    ph: object
    transport: str


def open_rig(bus: sim.SimBus, transport: str) -> tuple[Rig, object]:
    """Open ``bus`` over ``transport`` ("inproc" or "pty"); returns the rig and the resource to close."""
    if transport == "inproc":
        name = f"test-{id(bus)}"
        port = UrlPortHandler(sim.register(name, bus))
        assert port.openPort()
        return Rig(bus, bus.clock, port, PacketHandler(2.0), transport), name
    server = PtyServer(bus).start()
    port = PortHandler(server.path)  # the plain SDK class
    assert port.setBaudRate(bus.baud)
    return Rig(bus, bus.clock, port, PacketHandler(2.0), transport), server


def close_rig(rig: Rig, resource: object) -> None:
    rig.port.closePort()
    if isinstance(resource, PtyServer):
        resource.close()
    else:
        sim.unregister(str(resource))


@pytest.fixture(autouse=True)
def _every_sim_test_has_a_patient_sdk(patient_sdk: None) -> None:
    """The pty responder is a thread of this process: see ``patient_sdk`` in tests/conftest.py."""


needs_pty = pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs a POSIX pseudo-terminal")
TRANSPORTS = [
    pytest.param("inproc", id="inproc"),
    pytest.param("pty", id="pty", marks=[pytest.mark.pty, needs_pty]),
]


@pytest.fixture(params=TRANSPORTS)
def rig(request: pytest.FixtureRequest) -> Iterator[Rig]:
    """Six XM430-W350 (IDs 1-6) at 1 Mbps with Return Delay Time 0, on a VirtualClock, over each transport."""
    bus = sim.SimBus.from_ids(range(1, 7), "XM430-W350", clock=VirtualClock(), return_delay_time=0)
    r, resource = open_rig(bus, request.param)
    try:
        yield r
    finally:
        close_rig(r, resource)
