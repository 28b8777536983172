"""e-Manual rules beyond plain ranges: Protocol Type (13), the single-turn Homing Offset (20) rule, and Indirect
Data inheriting its target's access and range.  Over dynamixel-sdk on each transport."""

from __future__ import annotations

import pytest
from dynamixel_sdk import COMM_SUCCESS

from drivers.control_table import OperatingMode, StatusError
from tests.helpers import GOAL, PRESENT, TORQUE, address

PROTOCOL_TYPE = address("Protocol Type")
HOMING_OFFSET = address("Homing Offset")
OPERATING_MODE = address("Operating Mode")
LED = address("LED")
INDIRECT_ADDRESS_1 = 168  #: e-Manual XM430-W350: Indirect Address 1..28 at 168.., Indirect Data 1..28 at 224..
INDIRECT_DATA_1 = 224


def signed32(value: int) -> int:
    return value - (1 << 32) if value & 0x80000000 else value


def test_protocol_type_1_is_refused_the_simulator_speaks_2_0_only(rig):
    assert rig.ph.write1ByteTxRx(rig.port, 1, PROTOCOL_TYPE, 1) == (COMM_SUCCESS, StatusError.DATA_RANGE)
    assert rig.ph.write1ByteTxRx(rig.port, 1, PROTOCOL_TYPE, 2) == (COMM_SUCCESS, 0)
    assert rig.ph.read1ByteTxRx(rig.port, 1, PROTOCOL_TYPE) == (2, COMM_SUCCESS, 0)


@pytest.mark.parametrize(
    ("mode", "offset", "applied"),
    [
        pytest.param(OperatingMode.POSITION, 1024, True, id="position-1024-valid"),
        pytest.param(OperatingMode.POSITION, -1024, True, id="position-minus-1024-valid"),
        pytest.param(OperatingMode.POSITION, 1025, False, id="position-1025-ignored"),
        pytest.param(OperatingMode.POSITION, -4096, False, id="position-minus-4096-ignored"),
        pytest.param(OperatingMode.EXTENDED_POSITION, 4096, True, id="extended-4096"),
        pytest.param(OperatingMode.VELOCITY, 5000, True, id="velocity-5000"),
    ],
)
def test_homing_offset_beyond_1024_is_ignored_in_position_mode(rig, mode, offset, applied):
    ph, port = rig.ph, rig.port
    assert ph.write1ByteTxRx(port, 2, OPERATING_MODE, mode) == (COMM_SUCCESS, 0)
    assert ph.write4ByteTxRx(port, 2, HOMING_OFFSET, offset & 0xFFFFFFFF) == (COMM_SUCCESS, 0)
    assert signed32(ph.read4ByteTxRx(port, 2, HOMING_OFFSET)[0]) == offset  # stored either way
    assert signed32(ph.read4ByteTxRx(port, 2, PRESENT)[0]) == 2048 + (offset if applied else 0)


def map_indirect(rig, dxl_id: int, first: int, targets: list[int]) -> None:
    for k, target in enumerate(targets):
        result = rig.ph.write2ByteTxRx(rig.port, dxl_id, INDIRECT_ADDRESS_1 + 2 * (first + k), target)
        assert result == (COMM_SUCCESS, 0)


def test_indirect_data_mapped_to_a_read_only_item_answers_access_error(rig):
    map_indirect(rig, 3, 0, [PRESENT, PRESENT + 1, PRESENT + 2, PRESENT + 3])
    assert rig.ph.read4ByteTxRx(rig.port, 3, INDIRECT_DATA_1) == (2048, COMM_SUCCESS, 0)
    assert rig.ph.write4ByteTxRx(rig.port, 3, INDIRECT_DATA_1, 100) == (COMM_SUCCESS, StatusError.ACCESS)
    assert rig.ph.read4ByteTxRx(rig.port, 3, INDIRECT_DATA_1)[0] == 2048  # nothing changed


def test_indirect_data_takes_its_targets_range(rig):
    map_indirect(rig, 4, 0, [LED])
    assert rig.ph.write1ByteTxRx(rig.port, 4, INDIRECT_DATA_1, 2) == (COMM_SUCCESS, StatusError.DATA_RANGE)
    assert rig.bus.servo(4).get("LED") == 0
    assert rig.ph.write1ByteTxRx(rig.port, 4, INDIRECT_DATA_1, 1) == (COMM_SUCCESS, 0)  # e-Manual Example 1
    assert rig.bus.servo(4).get("LED") == 1


def test_indirect_goal_position_takes_its_limit_and_its_size(rig):
    ph, port = rig.ph, rig.port
    map_indirect(rig, 5, 1, [GOAL, GOAL + 1, GOAL + 2, GOAL + 3])  # e-Manual Example 2: Indirect Data 2..5
    assert ph.write1ByteTxRx(port, 5, TORQUE, 1) == (COMM_SUCCESS, 0)
    assert ph.write4ByteTxRx(port, 5, INDIRECT_DATA_1 + 1, 5000) == (COMM_SUCCESS, StatusError.DATA_LIMIT)
    assert ph.write1ByteTxRx(port, 5, INDIRECT_DATA_1 + 1, 0) == (COMM_SUCCESS, StatusError.DATA_LENGTH)  # 1 of 4
    assert ph.write4ByteTxRx(port, 5, INDIRECT_DATA_1 + 1, 1024) == (COMM_SUCCESS, 0)
    assert rig.bus.servo(5).get("Goal Position") == 1024


def test_a_write_refused_by_one_target_changes_no_other(rig):
    map_indirect(rig, 6, 0, [LED, address("Moving")])  # Indirect Data 1 -> LED, 2 -> a read-only byte
    assert rig.ph.write2ByteTxRx(rig.port, 6, INDIRECT_DATA_1, 0x0001) == (COMM_SUCCESS, StatusError.ACCESS)
    assert rig.bus.servo(6).get("LED") == 0


def test_unmapped_indirect_data_is_plain_storage(rig):
    assert rig.ph.write1ByteTxRx(rig.port, 1, INDIRECT_DATA_1, 200) == (COMM_SUCCESS, 0)
    assert rig.ph.read1ByteTxRx(rig.port, 1, INDIRECT_DATA_1) == (200, COMM_SUCCESS, 0)
