"""Bus Watchdog (98), e-Manual ``control_table_buswatchdog.md``: unit 20 ms; with torque on it trips when no
instruction packet arrives for that long, stops the servo where it is, reads -1 (0xFF), and goal writes answer
Data Range (4) until it is written 0.  Over dynamixel-sdk on each transport, on a virtual clock."""

from __future__ import annotations

import pytest
from dynamixel_sdk import COMM_SUCCESS

from drivers.control_table import OperatingMode, StatusError
from retarget.control.clock import VirtualClock
from sim.servo import PULSES_PER_S_PER_VELOCITY_UNIT, SimServo
from tests.helpers import GOAL, PRESENT, TORQUE, address

BUS_WATCHDOG = address("Bus Watchdog")
GOAL_VELOCITY = address("Goal Velocity")
PRESENT_VELOCITY = address("Present Velocity")
OPERATING_MODE = address("Operating Mode")
UNITS = 100  #: Goal Velocity, 22.9 rpm
SPEED = UNITS * PULSES_PER_S_PER_VELOCITY_UNIT  #: pulses/s


def signed32(value: int) -> int:
    return value - (1 << 32) if value & 0x80000000 else value


def spin(rig, dxl_id: int, watchdog: int) -> tuple[float, float]:
    """Velocity mode at UNITS with Bus Watchdog ``watchdog``: clock times of the goal write and of the last packet."""
    ph, port = rig.ph, rig.port
    assert ph.write1ByteTxRx(port, dxl_id, OPERATING_MODE, OperatingMode.VELOCITY) == (COMM_SUCCESS, 0)
    assert ph.write1ByteTxRx(port, dxl_id, TORQUE, 1) == (COMM_SUCCESS, 0)
    assert ph.write4ByteTxRx(port, dxl_id, GOAL_VELOCITY, UNITS) == (COMM_SUCCESS, 0)
    t_goal = rig.bus.log[-1].t
    assert ph.write1ByteTxRx(port, dxl_id, BUS_WATCHDOG, watchdog) == (COMM_SUCCESS, 0)
    return t_goal, rig.bus.log[-1].t


def test_silence_trips_it_and_the_servo_stops_where_it_was_then(rig):
    t_goal, t_last = spin(rig, 1, watchdog=5)  # 5 x 20 ms
    rig.clock.advance(2.0)  # the host says nothing for 2 s, then reads
    value, result, error = rig.ph.read4ByteTxRx(rig.port, 1, PRESENT)
    assert (result, error) == (COMM_SUCCESS, 0)
    # Profile Acceleration 0: at speed from the goal write until the trip, 100 ms after the last packet
    assert signed32(value) == pytest.approx(2048 + SPEED * (t_last + 0.100 - t_goal), abs=1)
    assert rig.ph.read4ByteTxRx(rig.port, 1, PRESENT_VELOCITY)[0] == 0
    assert rig.ph.read1ByteTxRx(rig.port, 1, BUS_WATCHDOG) == (0xFF, COMM_SUCCESS, 0)  # -1: Bus Watchdog Error
    rig.clock.advance(1.0)
    assert signed32(rig.ph.read4ByteTxRx(rig.port, 1, PRESENT)[0]) == signed32(value)  # holds there


def test_goals_are_read_only_until_it_is_written_0(rig):
    spin(rig, 2, watchdog=1)
    rig.clock.advance(0.5)
    ph, port = rig.ph, rig.port
    assert ph.write4ByteTxRx(port, 2, GOAL_VELOCITY, 150) == (COMM_SUCCESS, StatusError.DATA_RANGE)
    assert ph.write4ByteTxRx(port, 2, GOAL, 2048) == (COMM_SUCCESS, StatusError.DATA_RANGE)
    assert ph.write2ByteTxRx(port, 2, address("Goal Current"), 10) == (COMM_SUCCESS, StatusError.DATA_RANGE)
    assert ph.write2ByteTxRx(port, 2, address("Goal PWM"), 10) == (COMM_SUCCESS, StatusError.DATA_RANGE)
    assert ph.write1ByteTxRx(port, 2, address("LED"), 1) == (COMM_SUCCESS, 0)  # other items are not locked
    assert ph.write1ByteTxRx(port, 2, BUS_WATCHDOG, 0) == (COMM_SUCCESS, 0)  # clears the error
    assert ph.write4ByteTxRx(port, 2, GOAL_VELOCITY, 150) == (COMM_SUCCESS, 0)
    rig.clock.advance(1.0)  # watchdog off: no trip however long the silence
    assert signed32(ph.read4ByteTxRx(port, 2, PRESENT_VELOCITY)[0]) == 150


def test_packets_in_time_keep_it_running(rig):
    spin(rig, 3, watchdog=5)
    for _ in range(10):  # a packet every 80 ms < 100 ms
        rig.clock.advance(0.08)
        assert rig.ph.read4ByteTxRx(rig.port, 3, PRESENT_VELOCITY)[:2] == (UNITS, COMM_SUCCESS)
    assert rig.bus.servo(3).get("Bus Watchdog") == 5


def test_packets_for_other_servos_do_not_feed_it(rig):
    spin(rig, 4, watchdog=5)
    for _ in range(3):
        rig.clock.advance(0.08)
        assert rig.ph.ping(rig.port, 5)[1] == COMM_SUCCESS
    assert rig.ph.read1ByteTxRx(rig.port, 4, BUS_WATCHDOG)[0] == 0xFF


def test_out_of_range_settings_are_refused(rig):
    assert rig.ph.write1ByteTxRx(rig.port, 6, BUS_WATCHDOG, 128) == (COMM_SUCCESS, StatusError.DATA_RANGE)
    assert rig.ph.write1ByteTxRx(rig.port, 6, BUS_WATCHDOG, 0xFF) == (COMM_SUCCESS, StatusError.DATA_RANGE)


@pytest.mark.parametrize(
    ("torque", "tripped"), [pytest.param(0, False, id="torque-off-not-watched"), pytest.param(1, True, id="torque-on")]
)
def test_only_watched_with_torque_on(torque, tripped):
    clock = VirtualClock()
    servo = SimServo("XM430-W350", 1, clock=clock)
    assert servo.write(TORQUE, bytes((torque,))) == StatusError.NONE
    assert servo.write(BUS_WATCHDOG, b"\x01") == StatusError.NONE
    clock.advance(0.021)
    assert servo.get("Bus Watchdog") == (0xFF if tripped else 1)


def test_a_trip_in_position_mode_stops_mid_move_and_sets_the_goal_there():
    clock = VirtualClock()
    servo = SimServo("XM430-W350", 1, clock=clock)
    servo.write(address("Profile Velocity"), (100).to_bytes(4, "little"))
    servo.write(TORQUE, b"\x01")
    servo.write(GOAL, (3048).to_bytes(4, "little"))
    servo.write(BUS_WATCHDOG, bytes((10,)))  # 200 ms, at 1563 pulses/s: about 313 pulses of the 1000
    clock.advance(5.0)
    stopped = servo.get("Present Position")
    assert stopped == pytest.approx(2048 + 0.2 * SPEED, abs=1)
    assert servo.get("Goal Position") == stopped
    servo.write(TORQUE, b"\x00")
    servo.write(TORQUE, b"\x01")  # torque off and on: it stays
    clock.advance(1.0)
    assert servo.get("Present Position") == stopped
