"""dynamixel-sdk's own PacketHandler and group classes against the simulator, over the in-process port and a pty."""

from __future__ import annotations

import math

import pytest
from dynamixel_sdk import (
    COMM_RX_CORRUPT,
    COMM_RX_TIMEOUT,
    COMM_SUCCESS,
    GroupBulkRead,
    GroupBulkWrite,
    GroupSyncRead,
    GroupSyncWrite,
)

import sim
from drivers.control_table import ALERT_BIT, HardwareError, StatusError
from retarget.control.clock import VirtualClock
from sim.faults import Faults, ReplyFaults
from sim.servo import PULSES_PER_S2_PER_ACCEL_UNIT, PULSES_PER_S_PER_VELOCITY_UNIT
from tests.helpers import (
    GOAL,
    PRESENT,
    PROFILE_ACCELERATION,
    PROFILE_VELOCITY,
    TORQUE,
    TRANSPORTS,
    address,
    close_rig,
    open_rig,
)

LED = address("LED")
HARDWARE_ERROR_STATUS = address("Hardware Error Status")
RETURN_DELAY_TIME = address("Return Delay Time")
STATUS_RETURN_LEVEL = address("Status Return Level")


def le32(value: int) -> list[int]:
    return list((value & 0xFFFFFFFF).to_bytes(4, "little"))


def signed32(value: int) -> int:
    return value - (1 << 32) if value & 0x80000000 else value


def test_ping_reports_model_numbers(rig):
    for dxl_id in (1, 6):
        model, result, error = rig.ph.ping(rig.port, dxl_id)
        assert (model, result, error) == (1020, COMM_SUCCESS, 0)


@pytest.mark.parametrize("transport", TRANSPORTS)
def test_ping_of_each_model(transport):
    models = ((1, "XL430-W250", 1060), (2, "XL330-M288", 1200), (3, "XM540-W270", 1120), (4, "XM430-W350", 1020))
    clock = VirtualClock()
    bus = sim.SimBus([sim.SimServo(name, i, clock=clock, baud=1_000_000) for i, name, _ in models], clock=clock)
    rig, resource = open_rig(bus, transport)  # the servos exist before any server thread reads them
    try:
        for dxl_id, _, number in models:
            assert rig.ph.ping(rig.port, dxl_id)[:2] == (number, COMM_SUCCESS)
    finally:
        close_rig(rig, resource)


def test_eeprom_write_with_torque_on_is_an_access_error(rig):
    assert rig.ph.write1ByteTxRx(rig.port, 1, address("Operating Mode"), 4) == (COMM_SUCCESS, 0)  # torque off: allowed
    assert rig.ph.write1ByteTxRx(rig.port, 1, TORQUE, 1) == (COMM_SUCCESS, 0)
    assert rig.ph.write1ByteTxRx(rig.port, 1, address("Operating Mode"), 3) == (COMM_SUCCESS, StatusError.ACCESS)
    assert rig.bus.servo(1).get("Operating Mode") == 4


def test_goal_outside_position_limits_is_a_data_limit_error(rig):
    assert rig.ph.write4ByteTxRx(rig.port, 2, address("Max Position Limit"), 3000) == (COMM_SUCCESS, 0)
    assert rig.ph.write4ByteTxRx(rig.port, 2, GOAL, 3001) == (COMM_SUCCESS, StatusError.DATA_LIMIT)
    assert rig.ph.write4ByteTxRx(rig.port, 2, GOAL, 3000) == (COMM_SUCCESS, 0)


@pytest.mark.parametrize(
    ("profile_velocity", "profile_accel"),
    [pytest.param(100, 0, id="rectangle"), pytest.param(100, 50, id="trapezoid"), pytest.param(0, 0, id="no-load")],
)
def test_goal_reached_at_the_expected_speed(rig, profile_velocity, profile_accel):
    ph, port, clock = rig.ph, rig.port, rig.clock
    assert ph.write4ByteTxRx(port, 1, PROFILE_VELOCITY, profile_velocity) == (COMM_SUCCESS, 0)
    assert ph.write4ByteTxRx(port, 1, PROFILE_ACCELERATION, profile_accel) == (COMM_SUCCESS, 0)
    assert ph.write1ByteTxRx(port, 1, TORQUE, 1) == (COMM_SUCCESS, 0)
    start = ph.read4ByteTxRx(port, 1, PRESENT)[0]
    distance = 1500
    assert ph.write4ByteTxRx(port, 1, GOAL, start + distance) == (COMM_SUCCESS, 0)
    t0 = clock.now()
    vmax = profile_velocity * PULSES_PER_S_PER_VELOCITY_UNIT if profile_velocity else 46 / 60 * 4096  # XM430 no-load
    accel = profile_accel * PULSES_PER_S2_PER_ACCEL_UNIT if profile_accel else math.inf
    expected = distance / vmax + (vmax / accel if profile_accel else 0.0)

    clock.sleep_until(t0 + 0.5 * expected)
    position = ph.read4ByteTxRx(port, 1, PRESENT)[0]
    assert start < position < start + distance
    assert ph.read1ByteTxRx(port, 1, address("Moving"))[0] == 1
    velocity = signed32(ph.read4ByteTxRx(port, 1, address("Present Velocity"))[0])
    assert velocity == pytest.approx(vmax / PULSES_PER_S_PER_VELOCITY_UNIT, abs=1)

    clock.sleep_until(t0 + 0.98 * expected)
    assert ph.read4ByteTxRx(port, 1, PRESENT)[0] < start + distance
    clock.sleep_until(t0 + 1.02 * expected)
    assert ph.read4ByteTxRx(port, 1, PRESENT)[0] == start + distance
    assert ph.read1ByteTxRx(port, 1, address("Moving"))[0] == 0


def test_torque_off_nothing_moves(rig):
    start = rig.ph.read4ByteTxRx(rig.port, 3, PRESENT)[0]
    assert rig.ph.write4ByteTxRx(rig.port, 3, GOAL, start + 1000) == (COMM_SUCCESS, 0)
    rig.clock.advance(5.0)
    assert rig.ph.read4ByteTxRx(rig.port, 3, PRESENT)[0] == start


def test_reboot_clears_a_hardware_error(rig):
    ph, port = rig.ph, rig.port
    assert ph.write1ByteTxRx(port, 4, TORQUE, 1) == (COMM_SUCCESS, 0)
    rig.bus.servo(4).trigger_hardware_error(HardwareError.OVERLOAD)
    value, result, error = ph.read1ByteTxRx(port, 4, HARDWARE_ERROR_STATUS)
    assert (value, result, error) == (HardwareError.OVERLOAD, COMM_SUCCESS, ALERT_BIT)
    assert ph.read1ByteTxRx(port, 4, TORQUE)[0] == 0  # overload is in the default Shutdown mask (52)
    assert ph.write1ByteTxRx(port, 4, TORQUE, 1) == (COMM_SUCCESS, ALERT_BIT)
    assert ph.read1ByteTxRx(port, 4, TORQUE)[0] == 0  # stays off until reboot
    assert ph.reboot(port, 4) == (COMM_SUCCESS, ALERT_BIT)  # the reply leaves before the reboot
    assert ph.read1ByteTxRx(port, 4, HARDWARE_ERROR_STATUS) == (0, COMM_SUCCESS, 0)
    assert ph.write1ByteTxRx(port, 4, TORQUE, 1) == (COMM_SUCCESS, 0)
    assert ph.read1ByteTxRx(port, 4, TORQUE)[0] == 1


def test_dropped_replies_are_rx_timeouts(rig):
    rig.bus.faults.servos[5] = ReplyFaults(drop=1.0)
    assert rig.ph.ping(rig.port, 5)[1] == COMM_RX_TIMEOUT
    assert rig.ph.ping(rig.port, 6)[1] == COMM_SUCCESS


def test_byte_stuffing_of_a_value_containing_ff_ff_fd(rig):
    ph, port = rig.ph, rig.port
    # Present Position = actual (2048) + Homing Offset; aim for bytes FF FF FD FF (-131073)
    wanted = -131073
    assert le32(wanted) == [0xFF, 0xFF, 0xFD, 0xFF]
    # extended position mode: position mode ignores a Homing Offset beyond +-1024 (e-Manual, Homing Offset(20))
    assert ph.write1ByteTxRx(port, 2, address("Operating Mode"), 4) == (COMM_SUCCESS, 0)
    assert ph.write4ByteTxRx(port, 2, address("Homing Offset"), (wanted - 2048) & 0xFFFFFFFF) == (COMM_SUCCESS, 0)
    value, result, error = ph.read4ByteTxRx(port, 2, PRESENT)
    assert (signed32(value), result, error) == (wanted, COMM_SUCCESS, 0)
    stuffed = [
        e
        for e in rig.bus.log
        if e.instruction == 0x03 and e.params[:2] == address("Homing Offset").to_bytes(2, "little")
    ]
    assert stuffed and stuffed[-1].params[2:] == bytes(le32(wanted - 2048))


def test_sync_write_then_sync_read_and_fast_sync_read(rig):
    ph, port = rig.ph, rig.port
    write = GroupSyncWrite(port, ph, GOAL, 4)
    for dxl_id in range(1, 7):
        assert ph.write1ByteTxRx(port, dxl_id, TORQUE, 1) == (COMM_SUCCESS, 0)
        assert write.addParam(dxl_id, le32(1000 + 100 * dxl_id))
    assert write.txPacket() == COMM_SUCCESS
    assert ph.ping(port, 1)[1] == COMM_SUCCESS  # a round trip: the pty server has seen the write
    rig.clock.advance(3.0)
    read = GroupSyncRead(port, ph, PRESENT, 4)
    for dxl_id in range(1, 7):
        read.addParam(dxl_id)
    assert read.txRxPacket() == COMM_SUCCESS
    assert [read.getData(i, PRESENT, 4) for i in range(1, 7)] == [1000 + 100 * i for i in range(1, 7)]
    rig.bus.servo(3).set_position(2222)
    assert read.fastSyncRead() == COMM_SUCCESS
    assert [read.getData(i, PRESENT, 4) for i in range(1, 7)] == [1100, 1200, 2222, 1400, 1500, 1600]


def test_fast_sync_read_with_a_silent_servo_is_corrupt(rig):
    read = GroupSyncRead(rig.port, rig.ph, PRESENT, 4)
    for dxl_id in (1, 2, 3):
        read.addParam(dxl_id)
    rig.bus.servo(2).unplug()
    assert read.fastSyncRead() == COMM_RX_CORRUPT


def test_bulk_read_and_fast_bulk_read(rig):
    ph, port = rig.ph, rig.port
    bulk = GroupBulkRead(port, ph)
    assert bulk.addParam(1, PRESENT, 4)
    assert bulk.addParam(2, address("Present Input Voltage"), 3)  # + Present Temperature
    for method in (bulk.txRxPacket, bulk.fastBulkRead):
        assert method() == COMM_SUCCESS
        assert bulk.getData(1, PRESENT, 4) == 2048
        assert bulk.getData(2, address("Present Input Voltage"), 2) == 120  # 12.0 V
        assert 20 <= bulk.getData(2, address("Present Temperature"), 1) <= 50


def test_bulk_write(rig):
    ph, port = rig.ph, rig.port
    write = GroupBulkWrite(port, ph)
    assert write.addParam(1, LED, 1, [1])
    assert write.addParam(2, PROFILE_VELOCITY, 4, le32(321))
    assert write.txPacket() == COMM_SUCCESS
    assert ph.read1ByteTxRx(port, 1, LED)[0] == 1
    assert ph.read4ByteTxRx(port, 2, PROFILE_VELOCITY)[0] == 321


def test_reg_write_waits_for_action(rig):
    ph, port = rig.ph, rig.port
    assert ph.regWriteTxRx(port, 1, LED, 1, [1]) == (COMM_SUCCESS, 0)
    assert ph.read1ByteTxRx(port, 1, address("Registered Instruction"))[0] == 1
    assert ph.read1ByteTxRx(port, 1, LED)[0] == 0
    assert ph.action(port, 0xFE) == COMM_SUCCESS  # broadcast ACTION: no reply
    assert ph.read1ByteTxRx(port, 1, LED)[0] == 1
    assert ph.read1ByteTxRx(port, 1, address("Registered Instruction"))[0] == 0


def test_factory_reset_keeps_the_id(rig):
    ph, port = rig.ph, rig.port
    assert ph.write1ByteTxRx(port, 2, RETURN_DELAY_TIME, 7) == (COMM_SUCCESS, 0)
    assert ph.factoryReset(port, 2, 0x02) == (COMM_SUCCESS, 0)  # all but ID and baud
    assert ph.read1ByteTxRx(port, 2, RETURN_DELAY_TIME)[0] == 250


def test_status_return_level_1_answers_reads_only(rig):
    ph, port = rig.ph, rig.port
    ph.write1ByteTxOnly(port, 6, STATUS_RETURN_LEVEL, 1)  # the new level applies to this write's own status already
    assert ph.read1ByteTxRx(port, 6, STATUS_RETURN_LEVEL) == (1, COMM_SUCCESS, 0)
    ph.write1ByteTxOnly(port, 6, LED, 1)  # no status expected at level 1
    assert ph.read1ByteTxRx(port, 6, LED)[0] == 1


def test_broadcast_ping_answers_in_id_order():
    clock = VirtualClock()
    bus = sim.SimBus.from_ids([5, 2, 9], "XM430-W350", clock=clock)
    rig, resource = open_rig(bus, "inproc")
    try:
        found, result = rig.ph.broadcastPing(rig.port)
        assert result == COMM_SUCCESS
        assert list(found) == [2, 5, 9]
        assert found[9] == [1020, 46]
    finally:
        close_rig(rig, resource)


def test_unplugged_servo_from_the_url_times_out():
    clock = VirtualClock()
    bus = sim.SimBus.from_ids([1, 2], "XL430-W250", clock=clock, faults=Faults.from_options(unplug=["2@1.0"]))
    rig, resource = open_rig(bus, "inproc")
    try:
        assert rig.ph.ping(rig.port, 2)[1] == COMM_SUCCESS
        clock.advance(1.0)
        assert rig.ph.ping(rig.port, 2)[1] == COMM_RX_TIMEOUT
        assert rig.ph.ping(rig.port, 1)[1] == COMM_SUCCESS
    finally:
        close_rig(rig, resource)
