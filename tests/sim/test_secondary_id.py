"""Secondary (Shadow) ID (12), e-Manual X-series "Secondary(Shadow) ID(12)": 0..252 on, 253..255 off; a shadow
carries out writes for that ID without a status packet, never the EEPROM area; ID (7) has priority.  Over
dynamixel-sdk on each transport."""

from __future__ import annotations

import pytest
from dynamixel_sdk import COMM_RX_TIMEOUT, COMM_SUCCESS, GroupBulkWrite, GroupSyncWrite

from tests.helpers import GOAL, TORQUE, address

SECONDARY_ID = address("Secondary(Shadow) ID")
LED = address("LED")


def shadow(rig, servo_id: int, of: int) -> None:
    assert rig.ph.write1ByteTxRx(rig.port, servo_id, SECONDARY_ID, of) == (COMM_SUCCESS, 0)


def test_a_write_to_the_primary_moves_its_shadow_and_only_the_primary_answers(rig):
    shadow(rig, 3, of=2)
    assert rig.ph.write1ByteTxRx(rig.port, 2, LED, 1) == (COMM_SUCCESS, 0)
    assert [rig.bus.servo(i).get("LED") for i in (1, 2, 3)] == [0, 1, 1]
    replies = [e for e in rig.bus.log if e.instruction == 0x03]
    assert len(replies) == 2  # the Secondary ID write and the LED write: one status each, from ID 2


def test_the_e_manual_example_a_group_id_nobody_owns_changes_all_silently(rig):
    for i in (1, 2, 3):
        shadow(rig, i, of=100)
    result, error = rig.ph.write1ByteTxRx(rig.port, 100, LED, 1)
    assert result == COMM_RX_TIMEOUT  # "As no DYNAMIXEL uses ID 100, no Status Packet will be returned"
    assert [rig.bus.servo(i).get("LED") for i in (1, 2, 3, 4)] == [1, 1, 1, 0]


def test_reads_and_pings_of_a_shadow_id_are_not_answered(rig):
    shadow(rig, 4, of=100)
    assert rig.ph.ping(rig.port, 100)[1] == COMM_RX_TIMEOUT
    assert rig.ph.read1ByteTxRx(rig.port, 100, LED)[1] == COMM_RX_TIMEOUT


def test_the_eeprom_area_is_not_changed_through_a_secondary_id(rig):
    shadow(rig, 5, of=100)
    rig.ph.write1ByteTxRx(rig.port, 100, address("Return Delay Time"), 7)
    assert rig.bus.servo(5).get("Return Delay Time") == 0


@pytest.mark.parametrize("value", [pytest.param(253, id="253"), pytest.param(255, id="255-default")])
def test_253_and_above_turn_it_off(rig, value):
    shadow(rig, 6, of=value)
    rig.ph.write1ByteTxRx(rig.port, value, LED, 1)  # no servo listens: nothing happens, nobody answers
    assert rig.bus.servo(6).get("LED") == 0


def test_sync_write_slot_of_the_primary_drives_the_shadow_and_its_own_slot_wins(rig):
    shadow(rig, 3, of=2)
    shadow(rig, 5, of=4)
    for i in (2, 3, 4, 5):
        assert rig.ph.write1ByteTxRx(rig.port, i, TORQUE, 1) == (COMM_SUCCESS, 0)
    group = GroupSyncWrite(rig.port, rig.ph, GOAL, 4)
    group.addParam(2, list((2100).to_bytes(4, "little")))
    group.addParam(4, list((2200).to_bytes(4, "little")))
    group.addParam(5, list((2300).to_bytes(4, "little")))  # servo 5's own slot beats its Secondary ID's
    assert group.txPacket() == COMM_SUCCESS
    assert rig.ph.ping(rig.port, 1)[1] == COMM_SUCCESS  # a round trip: the pty server has seen the write
    assert [rig.bus.servo(i).get("Goal Position") for i in (2, 3, 4, 5)] == [2100, 2100, 2200, 2300]


def test_bulk_write_and_reg_write_action_reach_the_shadow(rig):
    shadow(rig, 6, of=1)
    group = GroupBulkWrite(rig.port, rig.ph)
    group.addParam(1, LED, 1, [1])
    assert group.txPacket() == COMM_SUCCESS
    assert rig.ph.ping(rig.port, 1)[1] == COMM_SUCCESS  # a round trip: the pty server has seen the write
    assert rig.bus.servo(6).get("LED") == 1
    assert rig.ph.regWriteTxRx(rig.port, 1, LED, 1, [0]) == (COMM_SUCCESS, 0)
    assert rig.bus.servo(6).get("Registered Instruction") == 1
    assert rig.ph.action(rig.port, 1) == COMM_SUCCESS
    assert rig.ph.ping(rig.port, 1)[1] == COMM_SUCCESS
    assert (rig.bus.servo(1).get("LED"), rig.bus.servo(6).get("LED")) == (0, 0)
