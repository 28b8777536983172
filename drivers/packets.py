"""dynamixel-sdk's Protocol 2.0 packet handler with its two pure helpers made fast: the same bytes, less CPU.

:class:`PacketHandler` is the SDK's ``Protocol2PacketHandler``; every transaction (``txPacket``, ``rxPacket``, the
sync and bulk reads and writes) stays the SDK's own code.  It overrides only what those call on every packet:

* ``updateCRC``: the SDK's is the e-Manual's byte loop, and builds its 256-entry table on every call (6 us for a
  sync write of 8 goals, 8 us for the 72-byte fast-read reply on the 2-core VM).  The shared
  :func:`~drivers.control_table.crc16` (the simulator's too) takes two bytes per step through two 256-entry
  tables: the same CRC for every input, in half the time.  (One 65 536-entry table,
  one lookup per step, is faster only while it stays in the cache: not between ticks, with a simulator or the
  control loop on the other core.)  The last CRC of each length is kept: a packet sent again (the tick's position
  read request, the same every tick) costs a comparison.
* ``addStuffing`` / ``removeStuffing``: the SDK copies every packet through a 1024-entry list, byte by byte, even
  when there is nothing to stuff (5 us per sync write).  When the bytes they scan hold no ``FF FF FD`` (to stuff)
  or ``FF FF FD FD`` (to unstuff), which one substring search tells, they leave the packet as it is, which is what
  the SDK's copy amounts to; otherwise the SDK's own code runs.

``tests/drivers/test_packets.py`` compares each against the SDK's on seeded random packets, byte for byte.

>>> ping = [0xFF, 0xFF, 0xFD, 0x00, 0x01, 0x03, 0x00, 0x01]  # the e-Manual's PING of servo 1, before its CRC (19 4E)
>>> hex(PacketHandler().updateCRC(0, ping, len(ping)))
'0x4e19'
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from dynamixel_sdk.protocol2_packet_handler import TXPACKET_MAX_LEN

from drivers.control_table import crc16

if TYPE_CHECKING:

    class _Protocol2PacketHandler:
        """The part of ``dynamixel_sdk.Protocol2PacketHandler`` this module overrides (the SDK has no hints)."""

        def updateCRC(self, crc_accum: int, data_blk_ptr: Sequence[int], data_blk_size: int) -> int: ...  # noqa: N802
        def addStuffing(self, packet: list[int]) -> list[int]: ...  # noqa: N802
        def removeStuffing(self, packet: list[int]) -> list[int]: ...  # noqa: N802
        def __getattr__(self, name: str) -> Any: ...

else:
    from dynamixel_sdk import Protocol2PacketHandler as _Protocol2PacketHandler

_LENGTH_L, _LENGTH_H = 5, 6  #: the LEN bytes of a packet
_STUFF, _STUFFED = b"\xff\xff\xfd", b"\xff\xff\xfd\xfd"


def _as_bytes(packet: Sequence[int], start: int, end: int) -> bytes | None:
    """``packet[start:end]`` as bytes; None when it is not that long or holds a value outside 0..255 (the SDK's own
    code then runs, with whatever it makes of them)."""
    if end > len(packet):
        return None
    try:
        return bytes(packet[start:end])
    except (TypeError, ValueError):
        return None


class PacketHandler(_Protocol2PacketHandler):
    """dynamixel-sdk's ``Protocol2PacketHandler`` with a fast ``updateCRC``, ``addStuffing`` and ``removeStuffing``
    (module docstring): the same packets, the same results."""

    def __init__(self) -> None:
        super().__init__()
        #: the last CRC computed per length: (register, bytes, CRC); the tick's read request is the same every tick
        self._last: dict[int, tuple[int, bytes, int]] = {}

    def updateCRC(self, crc_accum: int, data_blk_ptr: Sequence[int], data_blk_size: int) -> int:  # noqa: N802
        data = _as_bytes(data_blk_ptr, 0, data_blk_size) if data_blk_size >= 0 else None
        if data is None or not 0 <= crc_accum <= 0xFFFF:
            return super().updateCRC(crc_accum, data_blk_ptr, data_blk_size)
        last = self._last.get(data_blk_size)
        if last is not None and last[0] == crc_accum and last[1] == data:
            return last[2]
        crc = crc16(data, crc_accum)
        self._last[data_blk_size] = (crc_accum, data, crc)
        return crc

    def addStuffing(self, packet: list[int]) -> list[int]:  # noqa: N802
        # the SDK looks for FF FF FD ending at each byte of INST..PARAM, so from LEN_L on: packet[5 : LEN + 5]
        # (its copy holds TXPACKET_MAX_LEN bytes: a longer packet is the SDK's to refuse)
        length = packet[_LENGTH_L] | packet[_LENGTH_H] << 8
        ok = 2 <= length <= TXPACKET_MAX_LEN - 7
        scanned = _as_bytes(packet, _LENGTH_L, length + 7) if ok else None
        if scanned is None or _STUFF in scanned[:length]:
            return super().addStuffing(packet)
        return packet

    def removeStuffing(self, packet: list[int]) -> list[int]:  # noqa: N802
        # the SDK looks for FF FF FD FD from each byte of LEN_L on, its last FD up to CRC_L: packet[5 : LEN + 6]
        length = packet[_LENGTH_L] | packet[_LENGTH_H] << 8
        scanned = _as_bytes(packet, _LENGTH_L, length + 7) if length >= 2 else None
        if scanned is None or _STUFFED in scanned[: length + 1]:
            return super().removeStuffing(packet)
        return packet
