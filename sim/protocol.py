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

from collections.abc import Iterable, Sequence
from typing import NamedTuple

from drivers.control_table import BROADCAST_ID, Instruction, crc16

HEADER = b"\xff\xff\xfd\x00"
STATUS = Instruction.STATUS
MAX_LENGTH = 1024 - 7  #: largest LEN field accepted (dynamixel-sdk's RXPACKET_MAX_LEN is 1024 bytes in all)


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
        packet += bytes((crc & 0xFF, crc >> 8))
        crc = crc16(packet[-2:], crc)
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
