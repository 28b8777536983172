"""Dynamixel Protocol 2.0 packet codec: CRC-16, byte stuffing, a resyncing stream parser, status builders.

Packet layout (e-Manual ``protocol2``)::

    instruction: FF FF FD 00 ID LEN_L LEN_H INST PARAM... CRC_L CRC_H      LEN = len(PARAM) + 3
    status:      FF FF FD 00 ID LEN_L LEN_H 55 ERR PARAM... CRC_L CRC_H    LEN = len(PARAM) + 4

* CRC-16: polynomial 0x8005, initial value 0, not reflected, over every byte from the header to the last
  parameter, *after* stuffing.  The table below is the one in the e-Manual and in dynamixel-sdk.
* Byte stuffing: inside INST..PARAM, each ``FF FF FD`` is sent as ``FF FF FD FD``; LEN counts the stuffed
  bytes.  The receiver removes the extra ``FD`` once the CRC matched.
* Fast Sync Read / Fast Bulk Read replies are one packet from ID 0xFE whose parameters are slots
  ``[ERR ID DATA... CRC_L CRC_H]``, one per servo; each slot's CRC is the CRC of the whole packet up to that
  point, so the last slot's CRC is the packet CRC.  These replies are *not* stuffed (dynamixel-sdk reads them
  positionally and does not unstuff them).

Everything here is pure functions over ``bytes``; nothing knows about servos or time.
"""

from __future__ import annotations

import struct
from collections.abc import Iterable, Sequence
from typing import NamedTuple

from drivers.control_table import BROADCAST_ID, Instruction

HEADER = b"\xff\xff\xfd\x00"
STATUS = Instruction.STATUS
MAX_LENGTH = 1024 - 7  #: largest LEN field accepted (dynamixel-sdk's RXPACKET_MAX_LEN is 1024 bytes in all)

_CRC_TABLE = (
    0x0000, 0x8005, 0x800F, 0x000A, 0x801B, 0x001E, 0x0014, 0x8011, 0x8033, 0x0036, 0x003C, 0x8039,
    0x0028, 0x802D, 0x8027, 0x0022, 0x8063, 0x0066, 0x006C, 0x8069, 0x0078, 0x807D, 0x8077, 0x0072,
    0x0050, 0x8055, 0x805F, 0x005A, 0x804B, 0x004E, 0x0044, 0x8041, 0x80C3, 0x00C6, 0x00CC, 0x80C9,
    0x00D8, 0x80DD, 0x80D7, 0x00D2, 0x00F0, 0x80F5, 0x80FF, 0x00FA, 0x80EB, 0x00EE, 0x00E4, 0x80E1,
    0x00A0, 0x80A5, 0x80AF, 0x00AA, 0x80BB, 0x00BE, 0x00B4, 0x80B1, 0x8093, 0x0096, 0x009C, 0x8099,
    0x0088, 0x808D, 0x8087, 0x0082, 0x8183, 0x0186, 0x018C, 0x8189, 0x0198, 0x819D, 0x8197, 0x0192,
    0x01B0, 0x81B5, 0x81BF, 0x01BA, 0x81AB, 0x01AE, 0x01A4, 0x81A1, 0x01E0, 0x81E5, 0x81EF, 0x01EA,
    0x81FB, 0x01FE, 0x01F4, 0x81F1, 0x81D3, 0x01D6, 0x01DC, 0x81D9, 0x01C8, 0x81CD, 0x81C7, 0x01C2,
    0x0140, 0x8145, 0x814F, 0x014A, 0x815B, 0x015E, 0x0154, 0x8151, 0x8173, 0x0176, 0x017C, 0x8179,
    0x0168, 0x816D, 0x8167, 0x0162, 0x8123, 0x0126, 0x012C, 0x8129, 0x0138, 0x813D, 0x8137, 0x0132,
    0x0110, 0x8115, 0x811F, 0x011A, 0x810B, 0x010E, 0x0104, 0x8101, 0x8303, 0x0306, 0x030C, 0x8309,
    0x0318, 0x831D, 0x8317, 0x0312, 0x0330, 0x8335, 0x833F, 0x033A, 0x832B, 0x032E, 0x0324, 0x8321,
    0x0360, 0x8365, 0x836F, 0x036A, 0x837B, 0x037E, 0x0374, 0x8371, 0x8353, 0x0356, 0x035C, 0x8359,
    0x0348, 0x834D, 0x8347, 0x0342, 0x03C0, 0x83C5, 0x83CF, 0x03CA, 0x83DB, 0x03DE, 0x03D4, 0x83D1,
    0x83F3, 0x03F6, 0x03FC, 0x83F9, 0x03E8, 0x83ED, 0x83E7, 0x03E2, 0x83A3, 0x03A6, 0x03AC, 0x83A9,
    0x03B8, 0x83BD, 0x83B7, 0x03B2, 0x0390, 0x8395, 0x839F, 0x039A, 0x838B, 0x038E, 0x0384, 0x8381,
    0x0280, 0x8285, 0x828F, 0x028A, 0x829B, 0x029E, 0x0294, 0x8291, 0x82B3, 0x02B6, 0x02BC, 0x82B9,
    0x02A8, 0x82AD, 0x82A7, 0x02A2, 0x82E3, 0x02E6, 0x02EC, 0x82E9, 0x02F8, 0x82FD, 0x82F7, 0x02F2,
    0x02D0, 0x82D5, 0x82DF, 0x02DA, 0x82CB, 0x02CE, 0x02C4, 0x82C1, 0x8243, 0x0246, 0x024C, 0x8249,
    0x0258, 0x825D, 0x8257, 0x0252, 0x0270, 0x8275, 0x827F, 0x027A, 0x826B, 0x026E, 0x0264, 0x8261,
    0x0220, 0x8225, 0x822F, 0x022A, 0x823B, 0x023E, 0x0234, 0x8231, 0x8213, 0x0216, 0x021C, 0x8219,
    0x0208, 0x820D, 0x8207, 0x0202,
)  # fmt: skip


#: the CRC step of a byte into the register's high half: with ``x = register ^ (b0 << 8 | b1)``, feeding b0 then b1
#: leaves ``_HIGH_STEP[x >> 8] ^ _CRC_TABLE[x & 0xFF]`` (the CRC is linear; two 256-entry tables stay in the cache)
_HIGH_STEP = tuple(((_CRC_TABLE[h] << 8) & 0xFFFF) ^ _CRC_TABLE[_CRC_TABLE[h] >> 8] for h in range(256))


def crc16(data: bytes | bytearray | memoryview, crc: int = 0) -> int:
    """CRC-16 (poly 0x8005, init ``crc``) of ``data``; pass a previous result as ``crc`` to continue it.

    Two bytes per step (:data:`_HIGH_STEP`), the last of an odd length through the byte table: the same value as the
    byte-at-a-time loop of the e-Manual and dynamixel-sdk (``tests/sim/test_protocol.py`` compares them), in half
    the time.
    """
    high, table = _HIGH_STEP, _CRC_TABLE
    n = len(data)
    for word in struct.unpack_from(f">{n >> 1}H", data):
        x = crc ^ word
        crc = high[x >> 8] ^ table[x & 0xFF]
    if n & 1:
        crc = ((crc << 8) & 0xFF00) ^ table[(crc >> 8) ^ data[-1]]
    return crc


def stuff(body: bytes | bytearray) -> bytes:
    """Insert ``FD`` after every ``FF FF FD`` of ``body`` (the INST..PARAM bytes).

    The pattern is searched as the header sees it, so the two bytes before ``body`` (LEN_L LEN_H) are never
    part of it; dynamixel-sdk's ``addStuffing`` looks back into LEN, which only matters for lengths of
    0xFFFF and above and never happens.
    """
    if b"\xff\xff\xfd" not in body:
        return bytes(body)
    out = bytearray()
    ff_run = 0
    for b in body:
        out.append(b)
        if b == 0xFD and ff_run >= 2:
            out.append(0xFD)
        ff_run = ff_run + 1 if b == 0xFF else 0
    return bytes(out)


def unstuff(body: bytes | bytearray) -> bytes:
    """Remove the ``FD`` that :func:`stuff` inserted: ``FF FF FD FD`` -> ``FF FF FD``."""
    if b"\xff\xff\xfd\xfd" not in body:
        return bytes(body)
    out = bytearray()
    ff_run = 0
    skip_next_fd = False
    for b in body:
        if skip_next_fd:
            skip_next_fd = False
            if b == 0xFD:
                ff_run = 0
                continue
        out.append(b)
        if b == 0xFD and ff_run >= 2:
            skip_next_fd = True
        ff_run = ff_run + 1 if b == 0xFF else 0
    return bytes(out)


def _frame(dxl_id: int, body: bytes) -> bytes:
    """Header + ID + LEN + ``body`` (already stuffed) + CRC."""
    length = len(body) + 2
    head = HEADER + bytes((dxl_id & 0xFF, length & 0xFF, length >> 8))
    packet = head + body
    crc = crc16(packet)
    return packet + bytes((crc & 0xFF, crc >> 8))


def build_instruction(dxl_id: int, instruction: int, params: bytes | bytearray | Sequence[int] = b"") -> bytes:
    """An instruction packet with stuffing and CRC, as dynamixel-sdk's ``txPacket`` sends it."""
    return _frame(dxl_id, stuff(bytes((instruction,)) + bytes(params)))


def build_status(dxl_id: int, error: int, params: bytes | bytearray | Sequence[int] = b"") -> bytes:
    """A status packet ``FF FF FD 00 ID LEN 55 ERR PARAM CRC`` with stuffing."""
    return _frame(dxl_id, stuff(bytes((STATUS, error & 0xFF)) + bytes(params)))


def build_fast_read_status(slots: Iterable[tuple[int, int, bytes]]) -> bytes:
    """The single reply to FAST_SYNC_READ / FAST_BULK_READ from ``(error, id, data)`` slots, in order.

    ``FF FF FD 00 FE LEN 55`` then per slot ``ERR ID DATA CRC``, each CRC the running CRC of the packet so
    far (header included), the last one being the packet CRC.  Not stuffed.
    """
    slots = list(slots)
    if not slots:
        raise ValueError("Expected at least one slot, got none")
    length = 1 + sum(len(data) + 4 for _, _, data in slots)
    packet = bytearray(HEADER + bytes((BROADCAST_ID, length & 0xFF, length >> 8, STATUS)))
    crc = crc16(packet)
    for error, dxl_id, data in slots:
        chunk = bytes((error & 0xFF, dxl_id & 0xFF)) + bytes(data)
        packet += chunk
        crc = crc16(chunk, crc)
        low, high = crc & 0xFF, crc >> 8
        packet += bytes((low, high))
        x = crc ^ (low << 8 | high)  # crc16 of the two CRC bytes just added, inline
        crc = _HIGH_STEP[x >> 8] ^ _CRC_TABLE[x & 0xFF]
    return bytes(packet)


def parse_fast_read_status(packet: bytes, lengths: Sequence[int]) -> list[tuple[int, int, bytes]]:
    """Split a fast-read reply into ``(error, id, data)`` slots of the given data lengths; checks every CRC."""
    if packet[:4] != HEADER or packet[4] != BROADCAST_ID or packet[7] != STATUS:
        raise ValueError(f"Expected a fast-read status from ID 0xFE, got {packet[:8].hex(' ')}")
    out: list[tuple[int, int, bytes]] = []
    i = 8
    for n in lengths:
        end = i + 2 + n
        if end + 2 > len(packet):
            raise ValueError(f"Expected {end + 2} bytes, got {len(packet)}")
        crc = packet[end] | packet[end + 1] << 8
        if crc16(packet[:end]) != crc:
            raise ValueError(f"bad slot CRC at byte {end}")
        out.append((packet[i], packet[i + 1], bytes(packet[i + 2 : end])))
        i = end + 2
    return out


class Packet(NamedTuple):
    """One decoded packet.  ``params`` are unstuffed; for a status packet ``params[0]`` is ERR.

    Immutable; a NamedTuple rather than a frozen dataclass: the bus decodes one per instruction, on the tick path.
    """

    id: int
    instruction: int
    params: bytes
    crc_ok: bool = True
    raw: bytes = b""

    @property
    def is_broadcast(self) -> bool:
        return self.id == BROADCAST_ID


def decode(raw: bytes) -> Packet:
    """Decode one complete packet (instruction or status); ValueError when it is not one."""
    parser = PacketParser()
    packets = parser.feed(raw)
    if len(packets) != 1 or parser.pending:
        raise ValueError(f"Expected exactly one packet, got {len(packets)} and {parser.pending} stray bytes")
    return packets[0]


class PacketParser:
    """Incremental parser for a byte stream: feed it any chunks, get back whole packets.

    It resynchronises as a servo's receiver does: bytes before a header are dropped, a header whose
    reserved byte is not 00 or whose LEN is impossible is skipped one byte at a time, and a packet is
    returned only once all LEN bytes arrived.  Packets with a bad CRC are returned with ``crc_ok=False``
    (params left stuffed) so the caller decides what a servo does with them.
    """

    def __init__(self) -> None:
        self._buf = bytearray()

    @property
    def pending(self) -> int:
        """Bytes held back, waiting for the rest of a packet."""
        return len(self._buf)

    def clear(self) -> None:
        self._buf.clear()

    def feed(self, data: bytes | bytearray) -> list[Packet]:
        buf = self._buf
        buf += data
        out: list[Packet] = []
        while True:
            start = buf.find(b"\xff\xff\xfd")
            if start < 0:
                # keep a possible partial header at the end
                keep = 2 if buf.endswith(b"\xff\xff") else 1 if buf.endswith(b"\xff") else 0
                del buf[: len(buf) - keep]
                return out
            if start:
                del buf[:start]
            if len(buf) < 7:
                return out
            length = buf[5] | buf[6] << 8
            if buf[3] != 0x00 or length < 3 or length > MAX_LENGTH:
                del buf[0]  # not a real header (e.g. stuffed FF FF FD FD inside a packet we lost)
                continue
            total = 7 + length
            if len(buf) < total:
                return out
            raw = bytes(buf[:total])
            del buf[:total]
            crc_ok = crc16(raw[:-2]) == (raw[-2] | raw[-1] << 8)
            body = raw[7:-2]
            if crc_ok:
                body = unstuff(body)
            out.append(Packet(raw[4], body[0], bytes(body[1:]), crc_ok, raw))
