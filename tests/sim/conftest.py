"""Fixtures for the simulator tests: a dynamixel-sdk port on the in-process ``sim://`` transport or on a pty.

Both run the SDK's own PacketHandler and group classes unchanged; only ``PortHandler.setupPort`` differs for
the in-process port (it opens the URL with ``serial.serial_for_url``; the pty needs no change at all).
"""

from __future__ import annotations

from collections.abc import Iterator

import pytest

import sim
from retarget.control.clock import VirtualClock
from tests.helpers import TRANSPORTS, Rig, close_rig, open_rig


@pytest.fixture(autouse=True)
def _every_sim_test_has_a_patient_sdk(patient_sdk: None) -> None:
    """The pty responder is a thread of this process: see ``patient_sdk`` in tests/conftest.py."""


@pytest.fixture(params=TRANSPORTS)
def rig(request: pytest.FixtureRequest) -> Iterator[Rig]:
    """Six XM430-W350 (IDs 1-6) at 1 Mbps with Return Delay Time 0, on a VirtualClock, over each transport."""
    bus = sim.SimBus.from_ids(range(1, 7), "XM430-W350", clock=VirtualClock(), return_delay_time=0)
    r, resource = open_rig(bus, request.param)
    try:
        yield r
    finally:
        close_rig(r, resource)
