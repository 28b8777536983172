"""SimBus at the byte level: dispatch, status return level, broadcast, CRC errors, timing and reply faults."""

from __future__ import annotations

import pytest

import sim
from drivers.control_table import Instruction, StatusError
from retarget.control.clock import VirtualClock
from retarget.errors import ConfigError
from sim.faults import Faults, ReplyFaults, wire_time
from sim.protocol import PacketParser, build_instruction, build_status, decode, parse_fast_read_status
from tests.helpers import PRESENT, PROFILE_VELOCITY, address

LED = address("LED")

PING, READ, WRITE = Instruction.PING, Instruction.READ, Instruction.WRITE


def u16(v: int) -> bytes:
    return v.to_bytes(2, "little")


def read_packet(dxl_id: int, address: int, length: int) -> bytes:
    return build_instruction(dxl_id, READ, u16(address) + u16(length))


def statuses(data: bytes):
    return PacketParser().feed(data)


@pytest.fixture
def bus() -> sim.SimBus:
    return sim.SimBus.from_ids([1, 2, 3], "XM430-W350", clock=VirtualClock(), return_delay_time=0)


def test_ping_reply_is_byte_exact(bus):
    assert bus.handle(build_instruction(2, PING)) == build_status(2, 0, bytes((0xFC, 0x03, 46)))


def test_absent_id_is_silent(bus):
    assert bus.handle(build_instruction(9, PING)) == b""


@pytest.mark.parametrize(
    ("level", "ping", "read", "write"),
    [
        pytest.param(0, True, False, False, id="srl0"),
        pytest.param(1, True, True, False, id="srl1"),
        pytest.param(2, True, True, True, id="srl2"),
    ],
)
def test_status_return_level(bus, level, ping, read, write):
    bus.servo(1).set("Status Return Level", level)
    assert bool(bus.handle(build_instruction(1, PING))) is ping
    assert bool(bus.handle(read_packet(1, PRESENT, 4))) is read
    assert bool(bus.handle(build_instruction(1, WRITE, u16(LED) + b"\x01"))) is write
    assert bus.servo(1).get("LED") == 1


def test_broadcast_write_and_read_get_no_reply(bus):
    assert bus.handle(build_instruction(0xFE, WRITE, u16(LED) + b"\x01")) == b""
    assert all(s.get("LED") == 1 for s in bus.servos)
    assert bus.handle(read_packet(0xFE, 65, 1)) == b""


def test_broadcast_ping_answers_in_id_order_each_after_its_return_delay():
    clock = VirtualClock()
    bus = sim.SimBus.from_ids([7, 3, 5], "XL430-W250", clock=clock)  # factory RDT 250 = 500 us
    replies = bus.feed(build_instruction(0xFE, PING))
    assert [r.id for r in replies] == [3, 5, 7]
    assert [r.due for r in replies] == pytest.approx([0.0005, 0.0010, 0.0015])


def test_unknown_instruction_is_an_instruction_error(bus):
    (status,) = statuses(bus.handle(build_instruction(1, 0x42)))
    assert status.params == bytes((StatusError.INSTRUCTION,))
    assert bus.handle(build_instruction(0xFE, 0x42)) == b""


def test_wrong_parameter_length_is_a_data_length_error(bus):
    (status,) = statuses(bus.handle(build_instruction(1, READ, b"\x84\x00\x04")))
    assert status.params == bytes((StatusError.DATA_LENGTH,))


def test_bad_crc_unicast_answers_crc_error_broadcast_is_ignored(bus):
    bad = bytearray(build_instruction(2, WRITE, u16(LED) + b"\x01"))
    bad[-1] ^= 0x55
    (status,) = statuses(bus.handle(bytes(bad)))
    assert (status.id, status.params) == (2, bytes((StatusError.CRC,)))
    assert bus.servo(2).get("LED") == 0
    bad_broadcast = bytearray(build_instruction(0xFE, PING))
    bad_broadcast[-2] ^= 1
    assert bus.handle(bytes(bad_broadcast)) == b""


def test_bad_crc_can_be_ignored_instead():
    bus = sim.SimBus.from_ids([1], clock=VirtualClock(), crc_error_reply=False)
    bad = bytearray(build_instruction(1, PING))
    bad[-1] ^= 1
    assert bus.handle(bytes(bad)) == b""


def test_garbage_before_a_packet_is_skipped(bus):
    assert statuses(bus.handle(b"\x00\xff\x12\xff\xff" + build_instruction(3, PING)))[0].id == 3


def test_packet_split_across_writes(bus):
    packet = build_instruction(1, PING)
    assert bus.handle(packet[:5]) == b""
    assert statuses(bus.handle(packet[5:]))[0].id == 1


def test_sync_read_replies_in_instruction_order(bus):
    request = build_instruction(0xFE, Instruction.SYNC_READ, u16(PRESENT) + u16(4) + bytes((3, 1, 9, 2)))
    assert [s.id for s in statuses(bus.handle(request))] == [3, 1, 2]


def test_fast_sync_read_layout_and_truncation(bus):
    bus.servo(2).set_position(1111)
    request = build_instruction(0xFE, Instruction.FAST_SYNC_READ, u16(PRESENT) + u16(4) + bytes((1, 2, 3)))
    reply = bus.handle(request)
    slots = parse_fast_read_status(reply, [4, 4, 4])
    assert [(e, i, int.from_bytes(d, "little")) for e, i, d in slots] == [(0, 1, 2048), (0, 2, 1111), (0, 3, 2048)]
    bus.servo(2).unplug()
    cut = bus.handle(request)
    assert len(cut) == 8 + 8 and cut[:8] == reply[:8]  # servo 1's slot only; LEN still announces three


def test_sync_and_bulk_write(bus):
    sync = build_instruction(
        0xFE,
        Instruction.SYNC_WRITE,
        u16(PROFILE_VELOCITY) + u16(4) + b"\x01" + u16(7) + u16(0) + b"\x03" + u16(9) + u16(0),
    )
    assert bus.handle(sync) == b""
    assert (bus.servo(1).get("Profile Velocity"), bus.servo(3).get("Profile Velocity")) == (7, 9)
    bulk = build_instruction(
        0xFE,
        Instruction.BULK_WRITE,
        b"\x02" + u16(LED) + u16(1) + b"\x01" + b"\x03" + u16(address("Return Delay Time")) + u16(1) + b"\x05",
    )
    assert bus.handle(bulk) == b""
    assert (bus.servo(2).get("LED"), bus.servo(3).get("Return Delay Time")) == (1, 5)


def test_broadcast_factory_reset_all_is_not_executed(bus):
    bus.servo(1).set("Return Delay Time", 9)
    assert bus.handle(build_instruction(0xFE, Instruction.FACTORY_RESET, b"\xff")) == b""
    assert bus.servo(1).get("Return Delay Time") == 9
    bus.handle(build_instruction(0xFE, Instruction.FACTORY_RESET, b"\x02"))
    assert bus.servo(1).get("Return Delay Time") == 250


def test_a_new_id_takes_effect_at_once(bus):
    bus.handle(build_instruction(3, WRITE, u16(address("ID")) + b"\x0a"))
    assert bus.ids == (1, 2, 10)
    assert statuses(bus.handle(build_instruction(10, PING)))[0].id == 10


def test_servos_listen_only_at_their_baud(bus):
    bus.line_baud = 57600
    assert bus.handle(build_instruction(1, PING)) == b""
    bus.line_baud = 1_000_000
    assert bus.handle(build_instruction(1, PING)) != b""


def test_wire_model_times_a_sync_read_at_1mbps():
    clock = VirtualClock()
    faults = Faults(wire=True)
    bus = sim.SimBus.from_ids(range(1, 7), "XM430-W350", clock=clock, return_delay_time=10, faults=faults)
    request = build_instruction(0xFE, Instruction.SYNC_READ, u16(PRESENT) + u16(4) + bytes(range(1, 7)))
    replies = bus.feed(request)
    assert len(request) == 20 and all(len(r.data) == 15 for r in replies)
    # request, then each reply after its 20 us return delay, 10 us per byte
    expected = [wire_time(20, 1_000_000) + (k + 1) * (20e-6 + wire_time(15, 1_000_000)) for k in range(6)]
    assert [r.due for r in replies] == pytest.approx(expected)
    assert replies[-1].due == pytest.approx(0.2e-3 + 6 * 0.17e-3)


def test_reply_faults_are_seeded_and_per_servo():
    def run(seed: int) -> list[int]:
        faults = Faults(bus=ReplyFaults(drop=0.5), seed=seed)
        bus = sim.SimBus.from_ids([1, 2], clock=VirtualClock(), faults=faults)
        return [len(bus.feed(build_instruction(1, PING))) for _ in range(40)]

    first = run(3)
    assert first == run(3)
    assert 5 < sum(first) < 35
    faults = Faults(servos={2: ReplyFaults(corrupt=1.0, delay=0.02)})
    bus = sim.SimBus.from_ids([1, 2], clock=VirtualClock(), faults=faults)
    (ok,) = bus.feed(build_instruction(1, PING))
    (bad,) = bus.feed(build_instruction(2, PING))
    assert decode(ok.data).crc_ok and not decode(bad.data).crc_ok
    assert bad.due - ok.due == pytest.approx(0.02)


def test_scheduled_faults_from_options():
    clock = VirtualClock()
    faults = Faults.from_options(unplug=["1@1"], hwerror=["2:overload@0.5"])
    bus = sim.SimBus.from_ids([1, 2], "XM430-W350", clock=clock, faults=faults)
    clock.advance(0.6)
    (status,) = statuses(bus.handle(build_instruction(2, PING)))
    assert status.params[0] == 0x80  # Alert
    assert bus.handle(build_instruction(1, PING)) != b""
    clock.advance(0.5)
    assert bus.handle(build_instruction(1, PING)) == b""


def test_reboot_replies_first():
    bus = sim.SimBus.from_ids([1], "XM430-W350", clock=VirtualClock())
    bus.servo(1).trigger_hardware_error(0x20)
    (status,) = statuses(bus.handle(build_instruction(1, Instruction.REBOOT)))
    assert status.params == b"\x80"
    assert bus.servo(1).hardware_error == 0


def test_from_arm_has_every_servo():
    bus = sim.SimBus.from_arm("wx250s", clock=VirtualClock())
    assert bus.ids == tuple(range(1, 10))
    assert {s.model.name for s in bus.servos} == {"XM430-W350", "XL430-W250"}
    assert bus.baud == 1_000_000 and all(s.baud == 1_000_000 for s in bus.servos)


def test_constructor_errors():
    clock = VirtualClock()
    with pytest.raises(ConfigError, match="distinct servo IDs"):
        sim.SimBus([sim.SimServo("XL430-W250", 1, clock=clock), sim.SimServo("XL430-W250", 1, clock=clock)])
    with pytest.raises(ValueError, match="another clock"):
        sim.SimBus([sim.SimServo("XL430-W250", 1, clock=clock), sim.SimServo("XL430-W250", 2, clock=VirtualClock())])
    with pytest.raises(KeyError, match="no servo with ID 4"):
        sim.SimBus.from_ids([1], clock=clock).servo(4)
    with pytest.raises(KeyError, match="XL430-W250"):
        sim.SimBus.from_ids([1], "XL999", clock=clock)
    with pytest.raises(ConfigError, match="joint angles"):
        sim.SimBus.from_arm("wx250s", clock=clock, pose=[0.0])


def test_wire_is_half_duplex_a_write_delays_the_next_request():
    clock = VirtualClock()
    bus = sim.SimBus.from_ids([1, 2], "XM430-W350", clock=clock, return_delay_time=0, faults=Faults(wire=True))
    sync_write = build_instruction(0xFE, Instruction.SYNC_WRITE, u16(LED) + u16(1) + b"\x01\x01\x02\x01")
    assert bus.feed(sync_write) == []
    (reply,) = bus.feed(build_instruction(1, PING))  # written at the same instant, sent after the sync write
    assert reply.due == pytest.approx(wire_time(len(sync_write) + 10 + 14, 1_000_000))


@pytest.mark.parametrize(
    "request_packet",
    [
        pytest.param(build_instruction(3, WRITE, u16(address("ID")) + b"\x0b"), id="write-id"),
        pytest.param(build_instruction(3, Instruction.FACTORY_RESET, b"\xff"), id="factory-reset-all"),
    ],
)
def test_a_status_comes_from_the_id_that_was_addressed(bus, request_packet):
    (status,) = statuses(bus.handle(request_packet))
    assert status.id == 3 and status.params == b"\x00"
    assert 3 not in bus.ids
