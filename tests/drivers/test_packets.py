"""drivers.packets against dynamixel-sdk's own Protocol2PacketHandler: the same CRCs, the same stuffed and unstuffed
packets, the same bytes on the wire, on seeded random packets (with and without the patterns that need stuffing)."""

from __future__ import annotations

import random

import pytest
from dynamixel_sdk import COMM_SUCCESS, Protocol2PacketHandler

from drivers.packets import PacketHandler, crc16

SDK, FAST = Protocol2PacketHandler(), PacketHandler()
SEEDS = range(4)


def _random_body(rng: random.Random, n: int) -> list[int]:
    """``n`` bytes, a third of them the bytes of a stuffing pattern (FF, FD), so both paths are taken."""
    return [rng.choice((0xFF, 0xFF, 0xFD)) if rng.random() < 0.35 else rng.randrange(256) for _ in range(n)]


def _packet(rng: random.Random, n_params: int) -> list[int]:
    """A raw instruction list as the SDK's builders leave it for txPacket: header left 0, LEN, INST, params, CRC
    room."""
    packet = [0] * (10 + n_params)
    packet[4] = rng.choice((1, 7, 0xFE))
    packet[5], packet[6] = (n_params + 3) & 0xFF, (n_params + 3) >> 8
    packet[7:-2] = _random_body(rng, n_params + 1)
    return packet


@pytest.mark.parametrize("seed", SEEDS)
def test_crc_is_the_sdks_on_random_data(seed):
    rng = random.Random(seed)
    for _ in range(300):
        data = _random_body(rng, rng.randrange(0, 90))
        start = rng.choice((0, rng.randrange(0x10000)))
        n = rng.randrange(0, len(data) + 1)
        expected = SDK.updateCRC(start, data, n)
        assert FAST.updateCRC(start, data, n) == expected
        assert crc16(bytes(data[:n]), start) == expected


@pytest.mark.parametrize(
    ("data", "size", "start"),
    [
        pytest.param([300, 1, 2], 3, 0, id="value-above-255"),
        pytest.param([1, 2, 3], 2, 0x1FFFF, id="register-above-16-bits"),
        pytest.param([1, 2, 3], -1, 7, id="negative-size"),
        pytest.param((0xFF, 0xFD), 2, 0, id="tuple"),
    ],
)
def test_crc_of_unusual_arguments_is_the_sdks(data, size, start):
    assert FAST.updateCRC(start, data, size) == SDK.updateCRC(start, data, size)


def test_a_packet_sent_again_has_its_crc_and_a_changed_one_its_own():
    """The handler keeps the last CRC of each length: a repeat is answered from it, nothing else is."""
    handler, rng = PacketHandler(), random.Random(5)
    packet = _random_body(rng, 30)
    first = handler.updateCRC(0, packet, 28)
    assert handler.updateCRC(0, list(packet), 28) == first == SDK.updateCRC(0, packet, 28)
    changed = list(packet)
    changed[17] ^= 0x40  # one bit: CRC-16 tells every single-bit change
    assert handler.updateCRC(0, changed, 28) == SDK.updateCRC(0, changed, 28) != first
    assert handler.updateCRC(0x1234, packet, 28) == SDK.updateCRC(0x1234, packet, 28)
    assert handler.updateCRC(0, packet, 29) == SDK.updateCRC(0, packet, 29)  # longer: its own bytes


def test_crc_past_the_data_raises_as_the_sdk():
    with pytest.raises(IndexError, match="list index out of range"):
        SDK.updateCRC(0, [1, 2], 3)
    with pytest.raises(IndexError, match="list index out of range"):
        FAST.updateCRC(0, [1, 2], 3)


@pytest.mark.parametrize("seed", SEEDS)
def test_stuffing_is_the_sdks_on_random_packets(seed):
    rng = random.Random(seed)
    stuffed = 0
    for _ in range(300):
        packet = _packet(rng, rng.randrange(0, 60))
        expected = SDK.addStuffing(list(packet))
        got = FAST.addStuffing(list(packet))
        assert got == expected
        stuffed += len(expected) != len(packet)
        # and back: the SDK unstuffs what it stuffed (after a header, as rxPacket sees it)
        expected[:4] = [0xFF, 0xFF, 0xFD, 0x00]
        assert FAST.removeStuffing(list(expected)) == SDK.removeStuffing(list(expected))
    assert 30 < stuffed < 270  # both paths taken


@pytest.mark.parametrize("seed", SEEDS)
def test_unstuffing_is_the_sdks_on_random_status_packets(seed):
    rng = random.Random(seed)
    for _ in range(300):
        n = rng.randrange(0, 40)
        packet = [0xFF, 0xFF, 0xFD, 0x00, 1, (n + 4) & 0xFF, (n + 4) >> 8, 0x55, *_random_body(rng, n + 3)]
        assert FAST.removeStuffing(list(packet)) == SDK.removeStuffing(list(packet))


@pytest.mark.parametrize(
    "packet",
    [
        pytest.param([0xFF, 0xFF, 0xFD, 0x00, 1, 1, 0, 0xFD, 9], id="length-1"),
        pytest.param([0xFF, 0xFF, 0xFD, 0x00, 1, 0, 0, 0xFD, 9], id="length-0"),
        pytest.param([0xFF, 0xFF, 0xFD, 0x00, 1, 0xFF, 0xFF, 1, 2], id="length-past-the-list"),
        pytest.param([0, 0, 0, 0, 1, 3, 0, 0x1FD, 0, 0], id="value-above-255"),
        pytest.param([0, 0, 0, 0, 1, 0xFF, 0xFF, 0xFD, 0, 0, 0, 0], id="length-ffff-its-ff-ff-fd-past-the-list"),
    ],
)
def test_unusual_packets_are_stuffed_and_unstuffed_as_the_sdk_does(packet):
    for name in ("addStuffing", "removeStuffing"):
        try:
            expected: object = getattr(SDK, name)(list(packet))
        except IndexError as exc:
            expected = type(exc)
        try:
            got: object = getattr(FAST, name)(list(packet))
        except IndexError as exc:
            got = type(exc)
        assert got == expected, name


def test_an_overlong_packet_is_refused_as_the_sdk_does():
    packet = [0] * 1100
    packet[5], packet[6] = 1090 & 0xFF, 1090 >> 8
    with pytest.raises(IndexError, match="list assignment index out of range"):
        SDK.addStuffing(list(packet))
    with pytest.raises(IndexError, match="list assignment index out of range"):
        FAST.addStuffing(list(packet))


class _Port:
    """The part of a PortHandler txPacket and the group builders use: records what was written."""

    def __init__(self) -> None:
        self.is_using = False
        self.written: list[bytes] = []

    def clearPort(self) -> None:  # noqa: N802 - the SDK's name
        pass

    def writePort(self, packet: list[int]) -> int:  # noqa: N802 - the SDK's name
        self.written.append(bytes(packet))
        return len(packet)

    def setPacketTimeout(self, packet_length: int) -> None:  # noqa: N802 - the SDK's name
        pass


@pytest.mark.parametrize("seed", SEEDS)
def test_the_packets_on_the_wire_are_the_sdks(seed):
    """The tick's instructions and the setup's, built by the SDK's own builders on both handlers: the same bytes."""
    rng = random.Random(seed)
    for _ in range(60):
        ids = rng.sample(range(1, 253), rng.randrange(1, 10))
        address, size = rng.randrange(0, 700), rng.choice((1, 2, 4))
        param = [b for i in ids for b in (i, *_random_body(rng, size))]
        bulk = [b for i in ids for b in (i, *_random_body(rng, 4))]
        calls = [
            ("syncWriteTxOnly", (address, size, param, len(param))),
            ("syncReadTx", (address, size, ids, len(ids), rng.random() < 0.5)),
            ("bulkReadTx", (bulk, len(bulk), False)),
            ("bulkWriteTxOnly", (bulk, len(bulk))),
            ("writeTxOnly", (ids[0], address, size, _random_body(rng, size))),
            ("regWriteTxOnly", (ids[0], address, size, _random_body(rng, size))),
            ("readTx", (ids[0], address, size)),
        ]
        for name, args in calls:
            ports = _Port(), _Port()
            results = [getattr(handler, name)(port, *args) for handler, port in zip((SDK, FAST), ports, strict=True)]
            assert results[0] == results[1] == COMM_SUCCESS, name
            assert ports[0].written == ports[1].written, name
            assert len(ports[0].written) == 1


class _Replies:
    """A port that hands out ``data`` a few bytes per read, then times out."""

    def __init__(self, data: bytes, rng: random.Random) -> None:
        self.data, self.rng, self.is_using = data, rng, True

    def readPort(self, length: int) -> bytes:  # noqa: N802 - the SDK's name
        n = min(length, self.rng.randrange(1, 20))
        out, self.data = self.data[:n], self.data[n:]
        return out

    def isPacketTimeout(self) -> bool:  # noqa: N802 - the SDK's name
        return not self.data


@pytest.mark.parametrize("seed", SEEDS)
def test_status_packets_are_received_as_the_sdk_receives_them(seed):
    """rxPacket (the SDK's) on both handlers, over status packets built and stuffed by the SDK, some corrupt, some
    after noise: the same packets, the same results."""
    rng = random.Random(seed)
    results = set()
    for _ in range(150):
        n = rng.randrange(0, 30)
        packet = [0, 0, 0, 0, rng.randrange(1, 253), (n + 4) & 0xFF, (n + 4) >> 8, 0x55, *_random_body(rng, n + 1)]
        packet += [0, 0]
        packet = SDK.addStuffing(packet)
        packet[:4] = [0xFF, 0xFF, 0xFD, 0x00]
        crc = SDK.updateCRC(0, packet, len(packet) - 2)
        packet[-2:] = [crc & 0xFF, crc >> 8]
        if rng.random() < 0.2:
            packet[-1] ^= 1
        wire = bytes(_random_body(rng, rng.choice((0, 0, 3))) + packet)
        fast_option = rng.random() < 0.3
        got = [handler.rxPacket(_Replies(wire, random.Random(seed)), fast_option) for handler in (SDK, FAST)]
        assert got[0] == got[1]
        results.add(got[0][1])
    assert COMM_SUCCESS in results and len(results) > 1
