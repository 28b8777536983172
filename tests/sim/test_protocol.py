"""The Protocol 2.0 codec against the e-Manual's example packets and dynamixel-sdk's own encoder."""

from __future__ import annotations

import random

import pytest
from dynamixel_sdk.protocol2_packet_handler import Protocol2PacketHandler

from sim.protocol import (
    PacketParser,
    build_fast_read_status,
    build_instruction,
    build_status,
    crc16,
    decode,
    parse_fast_read_status,
    stuff,
    unstuff,
)


def h(text: str) -> bytes:
    return bytes.fromhex(text.replace(" ", ""))


# (id, instruction, params, the packet as printed in the e-Manual's protocol2 page)
MANUAL_INSTRUCTIONS = [
    pytest.param(0x01, 0x01, "", "FF FF FD 00 01 03 00 01 19 4E", id="ping"),
    pytest.param(0xFE, 0x01, "", "FF FF FD 00 FE 03 00 01 31 42", id="broadcast-ping"),
    pytest.param(0x01, 0x02, "84 00 04 00", "FF FF FD 00 01 07 00 02 84 00 04 00 1D 15", id="read"),
    pytest.param(0x01, 0x03, "74 00 00 02 00 00", "FF FF FD 00 01 09 00 03 74 00 00 02 00 00 CA 89", id="write"),
    pytest.param(0x01, 0x04, "68 00 C8 00 00 00", "FF FF FD 00 01 09 00 04 68 00 C8 00 00 00 AE 8E", id="reg-write"),
    pytest.param(0x01, 0x05, "", "FF FF FD 00 01 03 00 05 02 CE", id="action"),
    pytest.param(0x01, 0x06, "01", "FF FF FD 00 01 04 00 06 01 A1 E6", id="factory-reset"),
    pytest.param(0x01, 0x08, "", "FF FF FD 00 01 03 00 08 2F 4E", id="reboot"),
    pytest.param(0x01, 0x10, "01 44 58 4C 22", "FF FF FD 00 01 08 00 10 01 44 58 4C 22 B1 DC", id="clear"),
    pytest.param(0xFE, 0x82, "84 00 04 00 01 02", "FF FF FD 00 FE 09 00 82 84 00 04 00 01 02 CE FA", id="sync-read"),
    pytest.param(
        0xFE,
        0x83,
        "74 00 04 00 01 96 00 00 00 02 AA 00 00 00",
        "FF FF FD 00 FE 11 00 83 74 00 04 00 01 96 00 00 00 02 AA 00 00 00 82 87",
        id="sync-write",
    ),
    pytest.param(
        0xFE, 0x92, "01 90 00 02 00 02 92 00 01 00", "FF FF FD 00 FE 0D 00 92 01 90 00 02 00 02 92 00 01 00 1A 05",
        id="bulk-read",
    ),
    pytest.param(
        0xFE,
        0x93,
        "01 20 00 02 00 A0 00 02 1F 00 01 00 50",
        "FF FF FD 00 FE 10 00 93 01 20 00 02 00 A0 00 02 1F 00 01 00 50 B7 68",
        id="bulk-write",
    ),
]  # fmt: skip

MANUAL_STATUS = [
    pytest.param(0x01, 0, "06 04 26", "FF FF FD 00 01 07 00 55 00 06 04 26 65 5D", id="ping-1"),
    pytest.param(0x02, 0, "06 04 26", "FF FF FD 00 02 07 00 55 00 06 04 26 6F 6D", id="ping-2"),
    pytest.param(0x01, 0, "A6 00 00 00", "FF FF FD 00 01 08 00 55 00 A6 00 00 00 8C C0", id="read"),
    pytest.param(0x02, 0, "1F 08 00 00", "FF FF FD 00 02 08 00 55 00 1F 08 00 00 BA BE", id="sync-read-2"),
    pytest.param(0x01, 0, "", "FF FF FD 00 01 04 00 55 00 A1 0C", id="write"),
    pytest.param(0x01, 0, "77 00", "FF FF FD 00 01 06 00 55 00 77 00 C3 69", id="bulk-read-1"),
    pytest.param(0x02, 0, "24", "FF FF FD 00 02 05 00 55 00 24 8B A9", id="bulk-read-2"),
]


@pytest.mark.parametrize(("dxl_id", "inst", "params", "packet"), MANUAL_INSTRUCTIONS)
def test_instruction_packets_match_the_manual(dxl_id, inst, params, packet):
    assert build_instruction(dxl_id, inst, h(params)) == h(packet)
    decoded = decode(h(packet))
    assert (decoded.id, decoded.instruction, decoded.params, decoded.crc_ok) == (dxl_id, inst, h(params), True)


@pytest.mark.parametrize(("dxl_id", "error", "params", "packet"), MANUAL_STATUS)
def test_status_packets_match_the_manual(dxl_id, error, params, packet):
    assert build_status(dxl_id, error, h(params)) == h(packet)


def test_crc_continues_from_a_previous_value():
    data = h("FF FF FD 00 01 03 00 01")
    assert crc16(data) == 0x4E19
    assert crc16(data[4:], crc16(data[:4])) == 0x4E19


@pytest.mark.parametrize("seed", range(3))
def test_crc_is_the_sdks_byte_loop_on_random_data(seed):
    """Two bytes per step (crc16) against dynamixel-sdk's updateCRC, one byte per step: odd and even lengths, any
    starting register, bytes, bytearrays and memoryviews."""
    rng = random.Random(seed)
    sdk = Protocol2PacketHandler()
    for _ in range(300):
        data = bytes(rng.randrange(256) for _ in range(rng.randrange(0, 80)))
        start = rng.choice((0, rng.randrange(0x10000)))
        expected = sdk.updateCRC(start, list(data), len(data))
        assert crc16(data, start) == crc16(bytearray(data), start) == crc16(memoryview(data), start) == expected


@pytest.mark.parametrize(
    ("body", "stuffed"),
    [
        pytest.param("03 FF FF FD 00", "03 FF FF FD FD 00", id="once"),
        pytest.param("FF FF FD FF FF FD", "FF FF FD FD FF FF FD FD", id="twice"),
        pytest.param("FF FF FF FD", "FF FF FF FD FD", id="three-ff"),
        pytest.param("FF FD FF FF", "FF FD FF FF", id="no-pattern"),
        pytest.param("FF FF FD FD", "FF FF FD FD FD", id="already-fd-fd"),
    ],
)
def test_stuffing_examples(body, stuffed):
    assert stuff(h(body)) == h(stuffed)
    assert unstuff(h(stuffed)) == h(body)


def test_stuffed_write_of_a_value_containing_ff_ff_fd():
    packet = build_instruction(1, 0x03, h("74 00 FF FF FD 00"))
    assert packet[5] == 10  # LEN counts the inserted FD
    assert h("FF FF FD FD 00") in packet
    assert decode(packet).params == h("74 00 FF FF FD 00")


def _sdk_packet(dxl_id: int, inst: int, params: bytes) -> bytes:
    """What dynamixel-sdk's txPacket puts on the wire, without a port."""
    ph = Protocol2PacketHandler()
    pkt = [0] * (len(params) + 10)
    pkt[4], pkt[7] = dxl_id, inst
    pkt[5], pkt[6] = (len(params) + 3) & 0xFF, (len(params) + 3) >> 8
    pkt[8 : 8 + len(params)] = list(params)
    pkt = ph.addStuffing(pkt)
    total = (pkt[5] | pkt[6] << 8) + 7
    pkt[0:4] = [0xFF, 0xFF, 0xFD, 0x00]
    crc = ph.updateCRC(0, pkt, total - 2)
    pkt[total - 2], pkt[total - 1] = crc & 0xFF, crc >> 8
    return bytes(pkt[:total])


def test_matches_the_sdk_encoder_and_round_trips_seeded():
    rng = random.Random(4)
    for _ in range(500):
        params = bytes(rng.choice((0xFF, 0xFD, 0x00, rng.randrange(256))) for _ in range(rng.randrange(0, 20)))
        packet = build_instruction(rng.randrange(253), rng.randrange(256), params)
        assert packet == _sdk_packet(packet[4], packet[7], params)
        assert decode(packet).params == params
        assert unstuff(stuff(params)) == params


def test_parser_resyncs_on_garbage_and_partial_packets():
    ping = build_instruction(1, 0x01)
    write = build_instruction(2, 0x03, h("74 00 FF FF FD 00"))
    stream = h("00 FF 13 FF FF") + ping + h("FF FF FD 07 FF") + write
    parser = PacketParser()
    got = []
    for b in stream:  # one byte at a time
        got += parser.feed(bytes((b,)))
    assert [(p.id, p.instruction) for p in got] == [(1, 0x01), (2, 0x03)]
    assert got[1].params == h("74 00 FF FF FD 00")
    assert parser.pending == 0


def test_parser_waits_for_the_whole_packet():
    parser = PacketParser()
    packet = build_instruction(3, 0x02, h("84 00 04 00"))
    assert parser.feed(packet[:9]) == []
    assert parser.pending == 9
    assert [p.id for p in parser.feed(packet[9:])] == [3]


def test_parser_flags_a_bad_crc():
    packet = bytearray(build_instruction(1, 0x01))
    packet[-1] ^= 0xFF
    (got,) = PacketParser().feed(bytes(packet))
    assert got.crc_ok is False and got.id == 1


def test_parser_skips_an_impossible_length():
    bogus = h("FF FF FD 00 01 FF FF")  # LEN 65535
    got = PacketParser().feed(bogus + build_instruction(4, 0x01))
    assert [p.id for p in got] == [4]


def test_decode_rejects_anything_but_one_packet():
    with pytest.raises(ValueError, match="exactly one packet"):
        decode(build_instruction(1, 1) + build_instruction(2, 1))
    with pytest.raises(ValueError, match="exactly one packet"):
        decode(b"\xff\xff")


def test_fast_read_status_chains_running_crcs():
    slots = [(0, 1, h("A6 00 00 00")), (0x80, 2, h("1F 08 00 00")), (0, 3, h("FF FF FD 00"))]
    packet = build_fast_read_status(slots)
    assert packet[:8] == h("FF FF FD 00 FE") + bytes((1 + 3 * 8, 0)) + h("55")
    assert packet.find(h("03 FF FF FD 00"), 8) > 0  # slot 3: ID then data, not stuffed
    assert parse_fast_read_status(packet, [4, 4, 4]) == slots
    assert crc16(packet[:-2]) == packet[-2] | packet[-1] << 8  # the last slot CRC is the packet CRC
    broken = bytearray(packet)
    broken[12] ^= 1
    with pytest.raises(ValueError, match="bad slot CRC"):
        parse_fast_read_status(bytes(broken), [4, 4, 4])


def test_fast_read_status_needs_a_slot():
    with pytest.raises(ValueError, match="at least one slot"):
        build_fast_read_status([])
