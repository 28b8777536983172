"""``block=ID:PULSES``: an object in a simulated servo's way.  The horn stops at it; pushing on it draws Goal
Current (capped by Current Limit) in current-based position mode and the stall current in position mode, where a
sustained push raises Overload and torque goes off (the factory Shutdown mask)."""

from __future__ import annotations

import pytest

from drivers.control_table import HardwareError, OperatingMode
from retarget.errors import ConfigError
from sim.obstacle import OVERLOAD_AFTER_S
from sim.transport import bus_from_url

GRIPPER = 9  #: the vx300s gripper, an XM430-W350 at 2048


def _push(mode: int, *, goal: int = 1500, seconds: float = 3.0, limit: int = 242) -> list[dict[str, int]]:
    """Close the vx300s gripper onto a wall at 1900 in ``mode``; the registers every 0.1 s."""
    bus = bus_from_url("sim://vx300s?clock=virtual&block=9:1900")
    s = bus.servo(GRIPPER)
    s.set("Operating Mode", mode)
    s.set("Current Limit", limit)
    s.set("Goal Current", limit)
    s.set("Torque Enable", 1)
    assert s.write(116, goal.to_bytes(4, "little", signed=True)) == 0
    out = []
    for _ in range(round(seconds / 0.1)):
        bus.clock.sleep_until(bus.clock.now() + 0.1)
        out.append(
            {n: s.get(n) for n in ("Present Position", "Present Current", "Hardware Error Status", "Torque Enable")}
        )
    return out


def test_current_based_position_stops_at_the_object_at_goal_current():
    trace = _push(OperatingMode.CURRENT_BASED_POSITION)
    assert {r["Present Position"] for r in trace[5:]} == {1900}
    assert {r["Present Current"] for r in trace[5:]} == {-242}  # the bound, pushing toward lower pulses
    assert all(r["Hardware Error Status"] == 0 and r["Torque Enable"] == 1 for r in trace)


def test_position_mode_pushes_at_stall_and_overloads():
    trace = _push(OperatingMode.POSITION)
    assert trace[2]["Present Current"] == -855  # 2.3 A stall / 2.69 mA
    assert trace[2]["Hardware Error Status"] == 0
    tripped = [k for k, r in enumerate(trace) if r["Hardware Error Status"]]
    assert tripped and trace[tripped[0]]["Hardware Error Status"] == HardwareError.OVERLOAD
    assert (tripped[0] + 1) * 0.1 == pytest.approx(OVERLOAD_AFTER_S + 0.2, abs=0.21)  # contact after ~0.1 s
    assert trace[-1]["Torque Enable"] == 0 and trace[-1]["Present Current"] == 0


def test_a_goal_short_of_the_object_never_pushes():
    assert all(r["Hardware Error Status"] == 0 for r in _push(OperatingMode.POSITION, goal=1950))
    assert _push(OperatingMode.POSITION, goal=1950)[-1]["Present Position"] == 1950
    assert _push(OperatingMode.POSITION, goal=1950)[-1]["Present Current"] == 0


def test_moving_away_from_the_object_is_free():
    trace = _push(OperatingMode.POSITION, goal=2500)
    assert trace[-1]["Present Position"] == 2500 and trace[-1]["Hardware Error Status"] == 0


@pytest.mark.parametrize(
    ("url", "match"),
    [
        pytest.param("sim://vx300s?block=9", "ID:PULSES", id="no-pulses"),
        pytest.param("sim://vx300s?block=9:5000", "ID:PULSES", id="out-of-range"),
        pytest.param("sim://vx300s?block=x:10", "ID:PULSES", id="not-a-number"),
        pytest.param("sim://vx300s?block=42:100", "servo ID on the bus", id="unknown-id"),
    ],
)
def test_bad_block_options(url, match):
    with pytest.raises(ConfigError, match=match):
        bus_from_url(url)
