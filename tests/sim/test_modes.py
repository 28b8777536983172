"""No-load physics (sim.physics): load near zero at rest, PWM, current and current-based position modes."""

from __future__ import annotations

import pytest
from dynamixel_sdk import COMM_SUCCESS

from drivers.control_table import OperatingMode
from retarget.control.clock import VirtualClock
from sim.physics import STALL_ACCEL_TIME_S
from sim.servo import PULSES_PER_S_PER_VELOCITY_UNIT, SimServo
from tests.helpers import GOAL, PRESENT, TORQUE, address

OPERATING_MODE = address("Operating Mode")
PRESENT_CURRENT = address("Present Current")
PRESENT_VELOCITY = address("Present Velocity")
GOAL_CURRENT = address("Goal Current")
GOAL_PWM = address("Goal PWM")
XM430_NO_LOAD = 46 / 60 * 4096  #: pulses/s (e-Manual XM430-W350: 46 rpm at 12 V)


def signed(value: int, bits: int) -> int:
    return value - (1 << bits) if value & (1 << (bits - 1)) else value


@pytest.mark.parametrize("model", [pytest.param("XM430-W350", id="xm430"), pytest.param("XL430-W250", id="xl430")])
def test_an_unloaded_servo_holding_still_reads_no_load(model):
    clock = VirtualClock()
    servo = SimServo(model, 1, clock=clock)
    servo.write(TORQUE, b"\x01")
    clock.advance(1.0)
    assert servo.get(servo.model.load_register) == 0


def test_load_grows_with_acceleration_then_velocity(rig):
    ph, port = rig.ph, rig.port
    assert ph.write4ByteTxRx(port, 1, address("Profile Acceleration"), 100) == (COMM_SUCCESS, 0)
    assert ph.write1ByteTxRx(port, 1, TORQUE, 1) == (COMM_SUCCESS, 0)
    assert signed(ph.read2ByteTxRx(port, 1, PRESENT_CURRENT)[0], 16) == 0
    assert ph.write4ByteTxRx(port, 1, GOAL, 4000) == (COMM_SUCCESS, 0)
    rig.clock.advance(0.05)  # accelerating
    accelerating = signed(ph.read2ByteTxRx(port, 1, PRESENT_CURRENT)[0], 16)
    rig.clock.advance(0.25)  # cruising at Velocity Limit (200 units, 45.8 rpm: about the no-load speed)
    cruising = signed(ph.read2ByteTxRx(port, 1, PRESENT_CURRENT)[0], 16)
    assert accelerating > cruising > 0
    assert cruising == pytest.approx(0.10 * 2300 / 2.69, abs=1.5)  # VISCOUS_SHARE of 2.3 A stall, 2.69 mA units


@pytest.mark.parametrize("goal_pwm", [pytest.param(885, id="full"), pytest.param(-300, id="reverse-third")])
def test_pwm_mode_runs_at_the_duty_share_of_the_no_load_speed(rig, goal_pwm):
    ph, port = rig.ph, rig.port
    assert ph.write1ByteTxRx(port, 2, OPERATING_MODE, OperatingMode.PWM) == (COMM_SUCCESS, 0)
    assert ph.write2ByteTxRx(port, 2, GOAL_PWM, goal_pwm & 0xFFFF) == (COMM_SUCCESS, 0)
    assert ph.write1ByteTxRx(port, 2, TORQUE, 1) == (COMM_SUCCESS, 0)
    rig.clock.advance(0.5)
    velocity = signed(ph.read4ByteTxRx(port, 2, PRESENT_VELOCITY)[0], 32)
    assert velocity == round(goal_pwm / 885 * XM430_NO_LOAD / PULSES_PER_S_PER_VELOCITY_UNIT)
    assert signed(ph.read2ByteTxRx(port, 2, address("Present PWM"))[0], 16) == goal_pwm


def test_current_mode_accelerates_in_proportion_to_the_current():
    clock = VirtualClock()
    servo = SimServo("XM430-W350", 1, clock=clock)
    servo.write(OPERATING_MODE, bytes((OperatingMode.CURRENT,)))
    servo.write(TORQUE, b"\x01")
    assert servo.get("Present Velocity") == 0  # at rest when torque goes on
    units = round(0.5 * 2300 / 2.69)  # half the stall current
    servo.write(GOAL_CURRENT, units.to_bytes(2, "little"))
    dt = 0.01
    clock.advance(dt)
    expected = 0.5 * XM430_NO_LOAD / STALL_ACCEL_TIME_S * dt  # pulses/s after dt
    assert servo.get("Present Velocity") == round(expected / PULSES_PER_S_PER_VELOCITY_UNIT)
    clock.advance(1.0)  # back EMF: no faster than the no-load speed
    assert servo.get("Present Velocity") == round(XM430_NO_LOAD / PULSES_PER_S_PER_VELOCITY_UNIT)
    servo.write(GOAL_CURRENT, b"\x00\x00")
    clock.advance(2.0)  # friction (2 % of the stall current) brings it to rest within 1.25 s
    assert servo.get("Present Velocity") == 0


def test_goal_current_and_pwm_start_at_their_limits():
    servo = SimServo("XM430-W350", 1, clock=VirtualClock())
    assert (servo.get("Goal Current"), servo.get("Goal PWM")) == (1193, 885)


def test_current_based_position_reaches_the_goal_slower_under_a_low_current(rig):
    ph, port = rig.ph, rig.port
    times = []
    for dxl_id, goal_current in ((3, 1193), (4, 60)):
        mode = OperatingMode.CURRENT_BASED_POSITION
        assert ph.write1ByteTxRx(port, dxl_id, OPERATING_MODE, mode) == (COMM_SUCCESS, 0)
        assert ph.write1ByteTxRx(port, dxl_id, TORQUE, 1) == (COMM_SUCCESS, 0)
        assert ph.write2ByteTxRx(port, dxl_id, GOAL_CURRENT, goal_current) == (COMM_SUCCESS, 0)
        assert ph.write4ByteTxRx(port, dxl_id, GOAL, 2548) == (COMM_SUCCESS, 0)
        times.append(rig.bus.servo(dxl_id)._trajectory.t_end - rig.bus.log[-1].t)
    rig.clock.advance(2.0)
    assert [ph.read4ByteTxRx(port, i, PRESENT)[0] for i in (3, 4)] == [2548, 2548]
    assert times[1] > 2 * times[0]  # 60 units = 7 % of stall: little acceleration for a short move
