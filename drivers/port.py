"""A dynamixel-sdk ``PortHandler`` that opens any pyserial URL.

The SDK opens ``serial.Serial(port_name)``, which only knows device paths.  :class:`UrlPortHandler` changes
that one seam, ``setupPort``, to ``serial.serial_for_url``, so every packet still goes through the SDK's own
code and any of these work::

    /dev/ttyUSB0   COM3   socket://192.168.1.20:4000   rfc2217://host:port   sim://wx250s   sim://@name

``sim://`` URLs are served by the simulator package ``sim``; it is imported on first use, which registers the
URL handler with pyserial.  Open failures raise :class:`~retarget.errors.BusError`.

dynamixel-sdk ships no type hints: :class:`PortHandler` here is the SDK's class at run time, and for the type
checker a declaration of the part of it this package uses (the typed boundary to the SDK).

>>> port = open_port("sim://?ids=1&clock=virtual", 1_000_000)
>>> port.getBaudRate(), port.is_open
(1000000, True)
>>> port.closePort()
"""

from __future__ import annotations

import importlib
import logging
import select
import socket
from functools import partial
from typing import TYPE_CHECKING, Any

import serial
from serial.urlhandler import protocol_socket

from retarget.errors import BusError

if TYPE_CHECKING:

    class PortHandler:
        """``dynamixel_sdk.PortHandler`` as this package uses it (attributes and methods of SDK 3.7/3.8)."""

        port_name: str
        baudrate: int
        is_open: bool
        is_using: bool  #: a transaction holds the port (set by the packet handler, cleared on its end)
        ser: serial.SerialBase | None
        tx_time_per_byte: float  #: ms per byte on the wire

        # the SDK's camelCase method names
        def __init__(self, port_name: str) -> None: ...
        def openPort(self) -> bool: ...
        def closePort(self) -> None: ...
        def clearPort(self) -> None: ...
        def setBaudRate(self, baudrate: int) -> bool: ...
        def getBaudRate(self) -> int: ...
        def setupPort(self, cflag_baud: int) -> bool: ...
        def setPacketTimeout(self, packet_length: int) -> None: ...
        def setPacketTimeoutMillis(self, msec: float) -> None: ...
        def getTimeSinceStart(self) -> float: ...
        def readPort(self, length: int) -> bytes: ...
        def writePort(self, packet: list[int]) -> int: ...

        packet_timeout: float  #: ms this read waits (set by setPacketTimeout)

else:
    from dynamixel_sdk import PortHandler

log = logging.getLogger(__name__)

#: The baud rates the SDK accepts (``PortHandler.getCFlagBaud``).
SUPPORTED_BAUDS: tuple[int, ...] = (
    9600,
    19200,
    38400,
    57600,
    115200,
    230400,
    460800,
    500000,
    576000,
    921600,
    1000000,
    1152000,
    2000000,
    2500000,
    3000000,
    3500000,
    4000000,
)


def _register_url_handlers(port_name: str) -> None:
    """Import ``sim`` for a ``sim://`` URL: importing it registers the scheme with pyserial.

    By name, not an import statement: the driver does not depend on the simulator, only a ``sim://`` URL does.
    """
    if port_name.startswith("sim://"):
        try:
            importlib.import_module("sim")
        except ImportError as exc:  # pragma: no cover - sim ships with retarget
            raise BusError(f"cannot open {port_name!r}: the simulator package 'sim' is not importable ({exc})") from exc


def _no_delay(ser: serial.SerialBase) -> None:
    """TCP_NODELAY on a ``socket://`` port (pyserial leaves Nagle on).

    Without it a SYNC_WRITE (no reply) followed by a READ is the classic write-write-read pattern: the READ
    waits for the ACK of the first segment, which the peer delays ~40 ms, past the SDK's 34 ms timeout.
    """
    sock = getattr(ser, "_socket", None)
    if isinstance(sock, socket.socket) and sock.family in (socket.AF_INET, socket.AF_INET6):
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)


def _file_descriptor(ser: serial.SerialBase) -> int | None:
    """The port's file descriptor to wait on (a device or ``socket://``); None for a port without one."""
    try:
        fd = ser.fileno()  # io.RawIOBase's raises io.UnsupportedOperation (an OSError and a ValueError)
    except (OSError, ValueError, AttributeError):
        return None
    return fd if isinstance(fd, int) else None


def _plain_socket(ser: serial.SerialBase) -> socket.socket | None:
    """The connected socket of a pyserial ``socket://`` port (non-blocking, pyserial opens it so), read and written
    directly by :class:`UrlPortHandler`; None for any other port (``rfc2217://`` has a socket too, under a protocol
    of its own)."""
    sock = getattr(ser, "_socket", None)
    return sock if type(ser) is protocol_socket.Serial and isinstance(sock, socket.socket) else None


def _recv(sock: socket.socket, length: int) -> bytes:
    """Up to ``length`` bytes the socket has now (b"" for none), as pyserial's ``read`` would return them; a closed
    connection raises ``serial.SerialException``, as there."""
    try:
        data = sock.recv(length)
    except (BlockingIOError, InterruptedError):
        return b""
    except OSError as exc:
        raise serial.SerialException(f"read failed: {exc}") from exc
    if not data:
        raise serial.SerialException("socket disconnected")
    return data


_HEADER = b"\xff\xff\xfd\x00"  #: the start of every Protocol 2.0 packet


class UrlPortHandler(PortHandler):
    """``dynamixel_sdk.PortHandler`` opened through ``serial.serial_for_url``; everything else is the SDK's.

    Four additions, all on the SDK's own calls:

    * ``clearPort`` (the SDK calls it before every instruction it sends) counts what it drops: bytes already
      waiting then are replies that came after their transaction's timeout, late by definition
      (:attr:`stale_packets`, :attr:`stale_bytes`);
    * ``setPacketTimeout`` also tells a port that models time (the simulator's ``sim://`` on a virtual clock)
      how long this read waits, so a reply due later is not delivered to it, as on a real port;
    * ``readPort`` waits for a port with a file descriptor to be readable instead of spinning (see it);
    * on a ``socket://`` port, ``clearPort``, ``readPort`` and ``writePort`` use the socket directly: pyserial's
      calls add a ``select`` to every read, write and drain (three per call of ``clearPort``, two per read, one per
      write; measured on the 2-core VM, ``bench/bench_rig.py``'s tick: 280 -> 257 us of driver CPU per arm).  A read
      takes what the socket has (the SDK asks a status packet's first 11 bytes, then the rest) and hands out the
      bytes beyond what was asked on the next reads, without a ``select`` and a ``recv`` each: the same bytes in the
      same order; ``clearPort`` drops them with the socket's.
    """

    stale_packets = 0  #: late status packets dropped before an instruction (a partial one counts as one)
    _fd: int | None = None  #: the open port's file descriptor, for readPort's wait; None: it has none
    _socket: socket.socket | None = None  #: a ``socket://`` port's socket, read and written directly
    _held = b""  #: bytes a read of the socket took beyond what it was asked, for the next reads
    stale_bytes = 0  #: the bytes they had

    def clearPort(self) -> None:  # noqa: N802 - the SDK's name
        ser: Any = self.ser  # a pyserial port of any class (the stubs' SerialBase lacks the input-buffer calls)
        if ser is None:
            return
        if self._socket is not None:
            late, self._held = self._held, b""
            # anything waiting (bytes, or the peer's end)?  A select costs a third of a recv that fails (EAGAIN)
            if select.select([self._socket], [], [], 0)[0]:
                late += b"".join(iter(partial(_recv, self._socket, 4096), b""))
        else:
            waiting = ser.in_waiting
            late = ser.read(waiting) if waiting else b""
        if late:
            self.stale_bytes += len(late)
            self.stale_packets += max(1, late.count(_HEADER))
            log.debug("dropped %d late bytes before an instruction", len(late))
        if self._socket is None:
            ser.reset_input_buffer()

    def writePort(self, packet: list[int]) -> int:  # noqa: N802 - the SDK's name
        """The SDK's ``writePort``; on a ``socket://`` port one ``send``, and pyserial's write only for what the socket
        did not take at once."""
        if self._socket is None:
            return super().writePort(packet)
        data = bytes(packet)
        try:
            sent = self._socket.send(data)
        except (BlockingIOError, InterruptedError):
            sent = 0
        except OSError as exc:
            raise serial.SerialException(f"write failed: {exc}") from exc
        if sent < len(data):
            assert self.ser is not None
            self.ser.write(data[sent:])
        return len(data)

    def setPacketTimeout(self, packet_length: int) -> None:  # noqa: N802 - the SDK's name
        super().setPacketTimeout(packet_length)
        window = getattr(self.ser, "reply_window", None)
        if window is not None:
            window(self.packet_timeout / 1000.0)

    def setPacketTimeoutMillis(self, msec: float) -> None:  # noqa: N802 - the SDK's name
        super().setPacketTimeoutMillis(msec)
        window = getattr(self.ser, "reply_window", None)
        if window is not None:
            window(self.packet_timeout / 1000.0)

    def readPort(self, length: int) -> bytes:  # noqa: N802 - the SDK's name
        """The SDK's ``readPort``, but on a port with a file descriptor (a device path, ``socket://``) it first
        waits for the port to be readable, at most until the packet timeout.

        The SDK's ``rxPacket`` calls ``readPort`` in a loop until the packet is whole or the timeout passed, and the
        port is opened with ``timeout=0``: while the reply is on the wire it spins, a full core of Python holding
        the GIL (measured on a 2-core VM, ``bench/bench_rig.py``: 2.1 ms of CPU per 2.2 ms tick, 0.3 ms with the
        wait).  ROBOTIS made the same change in the C++ SDK (DynamixelSDK#694: ``poll()`` in ``readPort``).  Bytes
        already there are read at once; a timed-out read returns what it has, as before.  Ports without a file
        descriptor (the in-process ``sim://``, whose reads model the wire themselves) are read as the SDK does.
        """
        ser: Any = self.ser
        held = self._held
        if held and length > 0:  # the socket's bytes the last read took beyond what it was asked
            self._held = held[length:]
            return held[:length]
        if self._fd is not None:
            left = min(self.packet_timeout, self.packet_timeout - self.getTimeSinceStart())  # ms
            if left > 0:
                select.select([self._fd], [], [], left / 1000.0)
        if self._socket is not None:
            data = _recv(self._socket, 4096 if length > 0 else length)  # (the SDK never asks for nothing)
            if len(data) > length:
                self._held = data[length:]
                return data[:length]
            return data
        out: bytes = ser.read(length)
        return out

    def setupPort(self, cflag_baud: int) -> bool:  # noqa: N802 - the SDK's name
        if self.is_open:
            self.closePort()
        _register_url_handlers(self.port_name)
        try:
            self.ser = serial.serial_for_url(
                self.port_name,
                baudrate=self.baudrate,
                bytesize=serial.EIGHTBITS,
                parity=serial.PARITY_NONE,
                stopbits=serial.STOPBITS_ONE,
                timeout=0,
            )
        except (serial.SerialException, OSError, ValueError) as exc:
            raise BusError(f"cannot open port {self.port_name!r} at {self.baudrate} baud: {exc}") from exc
        _no_delay(self.ser)
        self._fd = _file_descriptor(self.ser)
        self._socket = _plain_socket(self.ser)
        self._held = b""
        self.is_open = True
        self.ser.reset_input_buffer()
        self.tx_time_per_byte = (1000.0 / self.baudrate) * 10.0
        return True

    def closePort(self) -> None:  # noqa: N802 - the SDK's name
        if self.ser is not None:
            self.ser.close()
        self._fd = None
        self._socket = None
        self._held = b""
        self.is_open = False
        self.is_using = False


def open_port(port: str, baud: int) -> UrlPortHandler:
    """Open ``port`` (a device path or pyserial URL) at ``baud`` bps (one of :data:`SUPPORTED_BAUDS`).

    Returns the open SDK port handler; raises ``BusError`` naming the port on failure.
    """
    if baud not in SUPPORTED_BAUDS:
        known = ", ".join(map(str, SUPPORTED_BAUDS))
        raise BusError(f"baud rate {baud} is not supported by dynamixel-sdk; use one of {known}")
    handler = UrlPortHandler(port)
    handler.baudrate = baud
    if not handler.setBaudRate(baud):  # pragma: no cover - the whitelist above matches the SDK's
        raise BusError(f"cannot open port {port!r} at {baud} baud")
    log.debug("opened %s at %d baud", port, baud)
    return handler
