"""A hand turning a limp servo (SimServo.move_by_hand / turn_by_hand), read back through dynamixel-sdk."""

from __future__ import annotations

import pytest
from dynamixel_sdk import COMM_SUCCESS

from retarget.control.clock import VirtualClock
from sim.servo import PULSES_PER_S_PER_VELOCITY_UNIT, SimServo
from tests.helpers import PRESENT, TORQUE, address

PRESENT_VELOCITY = address("Present Velocity")
MOVING = address("Moving")


def signed32(value: int) -> int:
    return value - (1 << 32) if value & 0x80000000 else value


def test_a_limp_joint_follows_the_hand_over_the_wire(rig):
    servo = rig.bus.servo(1)
    t0 = rig.clock.now()
    servo.move_by_hand(lambda t: 2048 + 500 * (t - t0))  # 500 pulses/s
    rig.clock.advance(1.0)
    position, result, _ = rig.ph.read4ByteTxRx(rig.port, 1, PRESENT)
    t = rig.bus.log[-1].t
    assert result == COMM_SUCCESS
    assert signed32(position) == round(2048 + 500 * (t - t0))
    assert rig.ph.read4ByteTxRx(rig.port, 1, PRESENT_VELOCITY)[0] == round(500 / PULSES_PER_S_PER_VELOCITY_UNIT)
    assert rig.ph.read1ByteTxRx(rig.port, 1, MOVING)[0] == 1
    servo.move_by_hand(None)  # let go
    left_at = servo.get("Present Position")
    rig.clock.advance(1.0)
    assert signed32(rig.ph.read4ByteTxRx(rig.port, 1, PRESENT)[0]) == left_at
    assert rig.ph.read1ByteTxRx(rig.port, 1, MOVING)[0] == 0


def test_with_torque_on_the_servo_holds_and_the_hand_takes_over_when_it_goes_limp(rig):
    servo = rig.bus.servo(2)
    end = servo.turn_by_hand(3000, duration=1.0)
    rig.clock.advance(0.5)
    assert rig.ph.write1ByteTxRx(rig.port, 2, TORQUE, 1) == (COMM_SUCCESS, 0)
    held = signed32(rig.ph.read4ByteTxRx(rig.port, 2, PRESENT)[0])
    assert 2048 < held < 3000
    rig.clock.sleep_until(end + 1.0)
    assert signed32(rig.ph.read4ByteTxRx(rig.port, 2, PRESENT)[0]) == held  # the motor wins
    assert rig.ph.write1ByteTxRx(rig.port, 2, TORQUE, 0) == (COMM_SUCCESS, 0)
    assert signed32(rig.ph.read4ByteTxRx(rig.port, 2, PRESENT)[0]) == 3000  # still held by the hand


@pytest.mark.parametrize(
    ("drive_mode", "homing"), [pytest.param(0, 0, id="normal"), pytest.param(1, 300, id="reverse-with-offset")]
)
def test_the_path_is_in_present_position_units_whatever_the_frame(drive_mode, homing):
    clock = VirtualClock()
    servo = SimServo("XL430-W250", 1, clock=clock)
    servo.set("Drive Mode", drive_mode)
    servo.set("Homing Offset", homing)
    end = servo.turn_by_hand(1000, duration=2.0)
    clock.advance(1.0)
    mid_speed = 1.5 * (1000 - (2048 + homing)) / 2.0  # pulses/s: smoothstep peak = 1.5 x mean
    assert servo.get("Present Velocity") == round(mid_speed / PULSES_PER_S_PER_VELOCITY_UNIT)
    clock.sleep_until(end)
    assert servo.get("Present Position") == 1000
    assert servo.get("Present Load") == 0  # limp: the motor carries nothing


def test_turn_by_hand_rejects_a_negative_duration():
    servo = SimServo("XM430-W350", 1, clock=VirtualClock())
    with pytest.raises(ValueError, match="Expected a duration >= 0 s, got -1"):
        servo.turn_by_hand(100, duration=-1)
