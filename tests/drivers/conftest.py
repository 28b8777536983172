"""Fixtures for the driver tests: a simulated WidowX-250 6DOF on a shared VirtualClock, reached through a real
serial-port path (the in-process ``sim://@name`` URL, a pty or loopback TCP), so the real driver code runs.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator

import pytest

import retarget
import sim
from drivers.dynamixel_bus import DynamixelBus
from retarget.arm import Arm
from retarget.control.clock import VirtualClock
from sim.server import PtyServer, TcpServer


@pytest.fixture(scope="session")
def arm() -> Arm:
    return retarget.load_arm("wx250s")


@pytest.fixture
def clock() -> VirtualClock:
    return VirtualClock()


@pytest.fixture
def sim_bus(arm: Arm, clock: VirtualClock) -> Iterator[sim.SimBus]:
    """Every servo of the wx250s at its rest pose, factory settings otherwise (Return Delay Time 250)."""
    bus = sim.SimBus.from_arm(arm, clock=clock)
    yield bus


@pytest.fixture
def url(sim_bus: sim.SimBus) -> Iterator[str]:
    """The in-process URL of ``sim_bus``."""
    url = sim.register(f"drivers-{id(sim_bus)}", sim_bus)
    yield url
    sim.unregister(url)


needs_pty = pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs a POSIX pseudo-terminal")


@pytest.fixture(
    params=[
        pytest.param("inproc", id="inproc"),
        pytest.param("pty", id="pty", marks=[pytest.mark.pty, needs_pty]),
        pytest.param("tcp", id="tcp"),
    ]
)
def transport_url(request: pytest.FixtureRequest, sim_bus: sim.SimBus, url: str) -> Iterator[str]:
    """``sim_bus`` reached in process, over a pty (``/dev/pts/N``) or loopback TCP (``socket://``)."""
    if request.param == "inproc":
        yield url
        return
    server = PtyServer(sim_bus) if request.param == "pty" else TcpServer(sim_bus)
    with server:
        yield server.path if request.param == "pty" else server.url


@pytest.fixture
def make_bus(arm: Arm, clock: VirtualClock) -> Iterator[Callable[..., DynamixelBus]]:
    """``make_bus(url, **options)``: a DynamixelBus on the test clock; every bus made is closed afterwards."""
    made: list[DynamixelBus] = []

    def make(port: str, **options: object) -> DynamixelBus:
        options.setdefault("check_latency", False)
        bus = DynamixelBus(options.pop("arm", arm), port, clock=clock, **options)  # type: ignore[arg-type]
        made.append(bus)
        return bus

    yield make
    for bus in made:
        bus.close()
