"""One simulated servo: access rules, errors, motion profiles, drive mode, load, hardware errors, resets."""

from __future__ import annotations

import random

import pytest

from drivers.control_table import ALERT_BIT, DriveMode, HardwareError, StatusError
from retarget.control.clock import VirtualClock
from sim.servo import PULSES_PER_S2_PER_ACCEL_UNIT, PULSES_PER_S_PER_VELOCITY_UNIT, SimServo
from tests.helpers import GOAL, PRESENT, PROFILE_ACCELERATION, PROFILE_VELOCITY, TORQUE, address

DRIVE_MODE = address("Drive Mode")
OPERATING_MODE = address("Operating Mode")
HOMING_OFFSET = address("Homing Offset")
MAX_POSITION_LIMIT = address("Max Position Limit")  #: Min Position Limit follows it
GOAL_VELOCITY = address("Goal Velocity")
LED = address("LED")


def u32(v: int) -> bytes:
    return (v & 0xFFFFFFFF).to_bytes(4, "little")


@pytest.fixture
def clock() -> VirtualClock:
    return VirtualClock()


@pytest.fixture
def servo(clock) -> SimServo:
    return SimServo("XM430-W350", 1, clock=clock)


def test_defaults_from_the_table(servo):
    assert servo.get("Model Number") == 1020
    assert servo.get("Return Delay Time") == 250
    assert servo.get("Shutdown") == 52
    assert servo.get("Present Position") == 2048
    assert servo.get("Present Input Voltage") == 120
    assert servo.ping() == bytes((0xFC, 0x03, 46))


@pytest.mark.parametrize(
    ("address", "data", "error"),
    [
        pytest.param(address("Model Number"), b"\x00\x00", StatusError.ACCESS, id="read-only-model-number"),
        pytest.param(PRESENT, u32(5), StatusError.ACCESS, id="read-only-present-position"),
        pytest.param(14, b"\x00", StatusError.ACCESS, id="undefined-address"),
        pytest.param(700, b"\x00", StatusError.ACCESS, id="beyond-the-table"),
        pytest.param(GOAL, b"\x00\x08", StatusError.DATA_LENGTH, id="half-a-register"),
        pytest.param(117, u32(1), StatusError.DATA_LENGTH, id="mid-register"),
        pytest.param(GOAL, b"", StatusError.DATA_LENGTH, id="no-data"),
        pytest.param(address("Status Return Level"), b"\x03", StatusError.DATA_RANGE, id="status-return-level-3"),
        pytest.param(address("ID"), b"\xfd", StatusError.DATA_RANGE, id="id-253"),
        pytest.param(OPERATING_MODE, b"\x02", StatusError.DATA_RANGE, id="operating-mode-2"),
        pytest.param(GOAL, u32(4096), StatusError.DATA_LIMIT, id="goal-above-max-limit"),
        pytest.param(GOAL_VELOCITY, u32(201), StatusError.DATA_LIMIT, id="goal-velocity-above-limit"),
        pytest.param(
            address("Goal Current"),
            (-1194).to_bytes(2, "little", signed=True),
            StatusError.DATA_LIMIT,
            id="goal-current",
        ),
    ],
)
def test_write_errors(servo, address, data, error):
    before = servo.memory
    assert servo.write(address, data) == error
    assert servo.check_write(address, data) == error
    assert servo.memory[:120] == before[:120]  # nothing changed


def test_eeprom_is_locked_while_torque_is_on(servo):
    assert servo.write(TORQUE, b"\x01") == StatusError.NONE
    assert servo.write(MAX_POSITION_LIMIT, u32(3000)) == StatusError.ACCESS
    assert servo.write(TORQUE, b"\x00") == StatusError.NONE
    assert servo.write(MAX_POSITION_LIMIT, u32(3000)) == StatusError.NONE


def test_xl430_has_no_current_mode(clock):
    xl = SimServo("XL430-W250", 1, clock=clock)
    assert xl.write(OPERATING_MODE, b"\x00") == StatusError.DATA_RANGE
    assert xl.write(OPERATING_MODE, b"\x10") == StatusError.NONE  # PWM
    assert xl.write(address("Goal Current"), b"\x00\x00") == StatusError.ACCESS  # no Goal Current on XL430


def test_goal_position_limit_only_in_position_mode(servo):
    assert servo.write(OPERATING_MODE, b"\x04") == StatusError.NONE  # extended position
    assert servo.write(GOAL, u32(100_000)) == StatusError.NONE
    assert servo.write(GOAL, u32(2_000_000)) == StatusError.DATA_RANGE


def test_limits_written_in_the_same_packet_apply(servo):
    # Max Position Limit (48) and Min Position Limit (52) together, then a goal inside the new range
    assert servo.write(MAX_POSITION_LIMIT, u32(3000) + u32(1000)) == StatusError.NONE
    assert servo.write(GOAL, u32(999)) == StatusError.DATA_LIMIT
    assert servo.write(GOAL, u32(1000)) == StatusError.NONE


def test_read_errors(servo):
    assert servo.read(0, 0) == (StatusError.DATA_LENGTH, b"")
    assert servo.read(660, 4) == (StatusError.ACCESS, b"")
    assert servo.read(PRESENT, 4) == (StatusError.NONE, u32(2048))


def test_velocity_profile_timing(servo, clock):
    pv, pa = 200, 100  # 45.8 rpm, 21458 rev/min^2
    servo.write(PROFILE_VELOCITY, u32(pv))
    servo.write(PROFILE_ACCELERATION, u32(pa))
    servo.write(TORQUE, b"\x01")
    servo.write(GOAL, u32(3048))
    v = pv * PULSES_PER_S_PER_VELOCITY_UNIT
    a = pa * PULSES_PER_S2_PER_ACCEL_UNIT
    t_total = 1000 / v + v / a
    clock.advance(v / a / 2)  # mid acceleration
    assert servo.get("Present Velocity") == pytest.approx(pv / 2, abs=1)
    assert servo.get("Moving Status") & 0x32 == 0x32  # profile ongoing, trapezoid
    assert servo.get("Present Current") > 0.06 * 2300 / 2.69  # accelerating: more than holding
    clock.sleep_until(t_total - 0.02)
    assert 3040 < servo.get("Present Position") < 3048
    clock.sleep_until(t_total + 1e-3)
    assert servo.get("Present Position") == 3048
    assert (servo.get("Moving"), servo.get("Present Velocity")) == (0, 0)
    assert servo.get("Moving Status") & 0x01  # in position


def test_time_based_profile_reaches_the_goal_on_time(servo, clock):
    servo.write(DRIVE_MODE, bytes((DriveMode.TIME_BASED_PROFILE,)))
    servo.write(PROFILE_VELOCITY, u32(1500))  # ms total
    servo.write(PROFILE_ACCELERATION, u32(300))  # ms ramps
    servo.write(TORQUE, b"\x01")
    servo.write(GOAL, u32(2548))
    clock.sleep_until(0.75)
    assert servo.get("Present Position") == 2298  # symmetric trapezoid: half way at half time
    clock.sleep_until(1.45)
    assert servo.get("Present Position") < 2548
    clock.sleep_until(1.5)
    assert servo.get("Present Position") == 2548


def test_no_load_speed_caps_the_profile(clock):
    xl = SimServo("XL330-M288", 1, clock=clock)
    assert xl.write(address("Velocity Limit"), u32(2047)) == StatusError.NONE  # Velocity Limit above the motor too
    xl.write(PROFILE_VELOCITY, u32(32767))  # far above the motor
    xl.write(TORQUE, b"\x01")
    xl.write(GOAL, u32(4000))
    clock.advance(0.1)
    no_load = 103 / 60 * 4096
    assert xl.get("Present Position") == round(2048 + 0.1 * no_load)


def test_goal_changed_in_mid_move_blends(servo, clock):
    servo.write(PROFILE_ACCELERATION, u32(50))
    servo.write(TORQUE, b"\x01")
    servo.write(GOAL, u32(4000))
    clock.advance(0.3)
    moving_up = servo.get("Present Velocity")
    assert moving_up > 0
    servo.write(GOAL, u32(1000))  # reverse: decelerate first, no velocity jump
    clock.advance(0.01)
    assert 0 < servo.get("Present Velocity") < moving_up
    clock.advance(10)
    assert servo.get("Present Position") == 1000


def test_torque_off_stops_where_it_is(servo, clock):
    servo.write(TORQUE, b"\x01")
    servo.write(GOAL, u32(4000))
    clock.advance(0.2)
    servo.write(TORQUE, b"\x00")
    here = servo.get("Present Position")
    clock.advance(5)
    assert servo.get("Present Position") == here
    assert servo.get("Present Current") == 0


def test_torque_on_holds_the_present_position(servo):
    servo.set_position(1234)
    servo.write(TORQUE, b"\x01")
    assert servo.get("Goal Position") == 1234


def test_reverse_mode_and_homing_offset(servo, clock):
    servo.set_position(2148)  # 100 pulses CCW of centre
    servo.write(DRIVE_MODE, b"\x01")
    assert servo.get("Present Position") == 1948  # mirrored about the centre
    servo.write(HOMING_OFFSET, u32(-48))
    assert servo.get("Present Position") == 1900  # Present = Actual + Homing Offset
    servo.write(TORQUE, b"\x01")
    servo.write(GOAL, u32(2000))
    clock.advance(5)
    assert servo.get("Present Position") == 2000
    servo.write(TORQUE, b"\x00")
    servo.write(DRIVE_MODE, b"\x00")
    servo.write(HOMING_OFFSET, u32(0))
    assert servo.get("Present Position") == 4096 - 2048  # the shaft moved CW: 2048 actual


def test_velocity_mode_ramps_and_keeps_going(servo, clock):
    servo.write(OPERATING_MODE, b"\x01")
    servo.write(PROFILE_ACCELERATION, u32(100))
    servo.write(TORQUE, b"\x01")
    servo.write(GOAL_VELOCITY, u32(100))
    clock.advance(1.0)
    assert servo.get("Present Velocity") == 100
    p1 = servo.get("Present Position")
    clock.advance(1.0)
    assert servo.get("Present Position") - p1 == pytest.approx(100 * PULSES_PER_S_PER_VELOCITY_UNIT, abs=1)


def test_hardware_error_shuts_down_per_the_mask(servo, clock):
    servo.write(TORQUE, b"\x01")
    servo.trigger_hardware_error(HardwareError.ELECTRICAL_SHOCK)  # bit 4 (0x10) is in 52
    assert servo.hardware_error == 0x10 and not servo.torque
    assert servo.error_byte(0) == ALERT_BIT
    other = SimServo("XM430-W350", 2, clock=clock)
    other.write(64, b"\x01")
    other.trigger_hardware_error(HardwareError.INPUT_VOLTAGE)  # 0x01 is not in 52: alert, torque stays
    assert other.torque and other.error_byte(StatusError.DATA_LIMIT) == 0x86
    assert other.get("Present Input Voltage") > other.get("Max Voltage Limit")


def test_scheduled_overheating(servo, clock):
    servo.write(TORQUE, b"\x01")
    servo.schedule_hardware_error(HardwareError.OVERHEATING, at=2.0)
    clock.advance(1.9)
    assert servo.hardware_error == 0
    clock.advance(0.2)
    assert servo.hardware_error == HardwareError.OVERHEATING and not servo.torque
    assert servo.get("Present Temperature") > servo.get("Temperature Limit")


def test_reboot_resets_ram_and_keeps_eeprom(servo):
    servo.write(address("Return Delay Time"), b"\x00")
    servo.write(LED, b"\x01")
    servo.write(TORQUE, b"\x01")
    servo.trigger_hardware_error(HardwareError.OVERLOAD)
    servo.reboot()
    assert (servo.get("LED"), servo.get("Torque Enable"), servo.hardware_error) == (0, 0, 0)
    assert servo.get("Return Delay Time") == 0


def test_reboot_is_silent_for_the_boot_time(clock):
    s = SimServo("XM430-W350", 1, clock=clock, boot_time=0.5)
    s.reboot()
    assert not s.listening()
    clock.advance(0.5)
    assert s.listening()


@pytest.mark.parametrize(
    ("option", "expected_id", "expected_baud"),
    [
        pytest.param(0xFF, 1, 1, id="all"),
        pytest.param(0x01, 7, 1, id="except-id"),
        pytest.param(0x02, 7, 3, id="except-id-and-baud"),
    ],
)
def test_factory_reset_options(clock, option, expected_id, expected_baud):
    s = SimServo("XM430-W350", 7, clock=clock, baud=1_000_000, return_delay_time=0)
    assert s.factory_reset(option) == StatusError.NONE
    assert (s.id, s.get("Baud Rate"), s.get("Return Delay Time")) == (expected_id, expected_baud, 250)


def test_factory_reset_bad_option(servo):
    assert servo.factory_reset(0x03) == StatusError.DATA_RANGE


def test_reg_write_and_action(servo):
    assert servo.action() == StatusError.INSTRUCTION
    assert servo.reg_write(GOAL, u32(5000)) == StatusError.DATA_LIMIT
    assert servo.reg_write(LED, b"\x01") == StatusError.NONE
    assert (servo.get("LED"), servo.get("Registered Instruction")) == (0, 1)
    assert servo.action() == StatusError.NONE
    assert (servo.get("LED"), servo.get("Registered Instruction")) == (1, 0)


def test_clear_multi_turn(servo, clock):
    servo.write(OPERATING_MODE, b"\x04")
    servo.set_position(4096 * 3 + 100)
    assert servo.clear(bytes((0x01, 0x44, 0x58, 0x4C, 0x22))) == StatusError.NONE
    assert servo.get("Present Position") == 100
    assert servo.clear(b"\x01") == StatusError.DATA_RANGE


def test_indirect_addressing_reads_and_writes_through(servo):
    # Indirect Address 1..4 -> Present Position (132..135); 5 -> LED (65)
    for k, target in enumerate((132, 133, 134, 135, 65)):
        assert servo.write(168 + 2 * k, target.to_bytes(2, "little")) == StatusError.NONE
    servo.set_position(3000)
    assert servo.read(224, 4) == (StatusError.NONE, u32(3000))
    assert servo.write(228, b"\x01") == StatusError.NONE
    assert servo.get("LED") == 1


def test_load_follows_motion_seeded():
    rng = random.Random(7)
    for _ in range(20):
        clock = VirtualClock()
        s = SimServo("XL430-W250", 1, clock=clock)
        s.write(PROFILE_ACCELERATION, u32(rng.randint(20, 200)))
        s.write(TORQUE, b"\x01")
        goal = rng.choice((rng.randint(0, 1900), rng.randint(2200, 4095)))
        s.write(GOAL, u32(goal))
        clock.advance(0.01)
        load = s.get("Present Load")
        assert -1000 <= load <= 1000
        assert (load > 0) == (goal > 2048)  # accelerating toward the goal
        clock.advance(30)
        assert s.get("Present Position") == goal


def test_raw_set_and_attributes_take_effect_at_once(servo):
    servo.get("Present Position")
    servo.set("Homing Offset", 100)
    assert servo.get("Present Position") == 2148
    servo.input_voltage = 11.5
    servo.ambient_temperature = 40
    assert (servo.get("Present Input Voltage"), servo.get("Present Temperature")) == (115, 40)
