"""Fixtures shared by the tests of the ``retarget`` package."""

from __future__ import annotations

import pytest

import retarget
from retarget.control.clock import VirtualClock


@pytest.fixture(scope="session")
def arm() -> retarget.Arm:
    """The default arm, WidowX-250 6DOF (frozen, so one instance serves every test)."""
    return retarget.load_arm("wx250s")


@pytest.fixture
def registered(arm):
    """A simulated wx250s with the wire model, on a virtual clock, registered as ``sim://@NAME``.

    Yields ``(simbus, url)``: the CLI opens the URL like any port, and the test reads the simulated servos'
    registers from ``simbus``.
    """
    import sim

    simbus = sim.SimBus.from_arm(arm, clock=VirtualClock(), faults=sim.Faults(wire=True))
    name = f"test-{id(simbus)}"
    url = sim.register(name, simbus)
    yield simbus, url
    sim.unregister(name)


@pytest.fixture
def sim_bus(arm):
    """A simulated wx250s (wire-time model on) on a shared virtual clock, reachable as sim://@NAME."""
    import sim

    def make(**faults):
        clock = VirtualClock()
        simbus = sim.SimBus.from_arm(arm, clock=clock, faults=sim.Faults(wire=True, **faults))
        url = sim.attach(simbus)
        names.append(url)  # sim.unregister takes the URL
        return simbus, url, clock

    names: list[str] = []
    yield make
    for name in names:
        sim.unregister(name)
