"""``UrlPortHandler.readPort`` waits for a port with a file descriptor to be readable instead of spinning: the SDK's
``rxPacket`` then reads the port a few times per packet, not thousands (the served simulator on a real clock, wire
model on, at 57600 baud so a ping and its status take 4.2 ms on the wire).  A ``socket://`` port is read, written
and drained on its socket, without pyserial's calls."""

from __future__ import annotations

import select
import socket
import time
from collections.abc import Callable, Iterator

import pytest
import serial
from dynamixel_sdk import COMM_RX_TIMEOUT, COMM_SUCCESS, PacketHandler

import sim
from drivers.port import UrlPortHandler, open_port
from retarget.control.clock import MonotonicClock, VirtualClock
from sim.server import PtyServer, SimServer, TcpServer
from tests.helpers import needs_pty


def _tcp(bus: sim.SimBus) -> tuple[SimServer, str]:
    server = TcpServer(bus)
    return server, server.url


def _pty(bus: sim.SimBus) -> tuple[SimServer, str]:
    server = PtyServer(bus)
    return server, server.path


@pytest.fixture(params=[pytest.param(_tcp, id="tcp"), pytest.param(_pty, id="pty", marks=[pytest.mark.pty, needs_pty])])
def served(request: pytest.FixtureRequest) -> Iterator[UrlPortHandler]:
    """A port on one servo (ID 1) at 57600 baud, served out of this thread on a real clock, wire model on (pyserial's
    ``socket://`` sleeps 0.3 s when it closes: one test per transport)."""
    make: Callable[[sim.SimBus], tuple[SimServer, str]] = request.param
    bus = sim.SimBus.from_ids([1], clock=MonotonicClock(), baud=57600, faults=sim.Faults(wire=True))
    server, where = make(bus)
    with server:
        port = open_port(where, 57600)
        try:
            yield port
        finally:
            port.closePort()


def _count_reads(port: UrlPortHandler) -> list[int]:
    """Spy on the port's ``readPort`` (what the SDK's ``rxPacket`` calls): the returned list grows by one per call."""
    calls: list[int] = []
    read = port.readPort

    def counted(length: int) -> bytes:
        calls.append(length)
        return read(length)

    port.readPort = counted  # type: ignore[method-assign]
    return calls


def test_a_reply_and_a_silence_are_waited_for_not_spun_on(served: UrlPortHandler) -> None:
    calls = _count_reads(served)
    model, result, error = PacketHandler(2.0).ping(served, 1)
    assert (result, error) == (COMM_SUCCESS, 0) and model > 0
    assert 1 <= len(calls) <= 4, calls  # the 11-byte head, then the rest (spinning: hundreds of calls)
    calls.clear()
    _, result, _ = PacketHandler(2.0).ping(served, 7)  # no servo 7: the SDK waits out its packet timeout
    assert result == COMM_RX_TIMEOUT
    assert 1 <= len(calls) <= 3, len(calls)  # spinning: thousands


def test_an_in_process_port_has_no_descriptor_and_reads_as_the_sdk_does() -> None:
    url = sim.attach(sim.SimBus.from_ids([1], clock=VirtualClock()))
    try:
        port = open_port(url, 1_000_000)
        try:
            assert port._fd is None
            assert PacketHandler(2.0).ping(port, 1)[1] == COMM_SUCCESS
        finally:
            port.closePort()
    finally:
        sim.unregister(url)


def _pyserial_calls_fail(port: UrlPortHandler) -> None:
    """Make the pyserial port's own read, write and drain raise: what still works does without them."""
    ser = port.ser
    assert ser is not None

    def refuse(*args: object) -> None:
        raise AssertionError("pyserial's own call was used")

    for name in ("read", "write", "reset_input_buffer"):
        setattr(ser, name, refuse)


@pytest.fixture
def raw_socket_port() -> Iterator[tuple[UrlPortHandler, socket.socket]]:
    """A ``socket://`` port on a loopback peer this test writes and reads itself: (the port, the peer's socket)."""
    with socket.create_server(("127.0.0.1", 0)) as listener:
        port = open_port(f"socket://127.0.0.1:{listener.getsockname()[1]}", 1_000_000)
        peer, _ = listener.accept()
    try:
        with peer:
            yield port, peer
    finally:
        port.closePort()


def test_a_socket_port_is_written_drained_and_read_on_its_socket(raw_socket_port) -> None:
    port, peer = raw_socket_port
    _pyserial_calls_fail(port)
    assert port.writePort([0xFF, 0xFF, 0xFD, 0x00, 0x01]) == 5
    assert peer.recv(16) == b"\xff\xff\xfd\x00\x01"

    late = b"\xff\xff\xfd\x00\x02junk" + b"\xff\xff\xfd\x00\x03"  # two late status packets' bytes
    peer.sendall(late)
    assert select.select([port._fd], [], [], 5.0)[0]
    port.clearPort()
    assert (port.stale_bytes, port.stale_packets) == (len(late), 2)
    port.setPacketTimeoutMillis(20)
    assert port.readPort(4) == b""  # drained: nothing until the timeout

    peer.sendall(b"abcdef")
    port.setPacketTimeoutMillis(2000)
    assert port.readPort(4) == b"abcd"
    assert port.readPort(10) == b"ef"  # what is there, as pyserial's read with timeout 0

    peer.close()
    with pytest.raises(serial.SerialException, match="socket disconnected"):
        port.readPort(4)


def test_a_socket_read_hands_out_what_it_took_beyond_the_ask_on_the_next_reads(raw_socket_port) -> None:
    port, peer = raw_socket_port
    _pyserial_calls_fail(port)
    port.setPacketTimeoutMillis(2000)
    peer.sendall(bytes(range(20)))
    assert select.select([port._fd], [], [], 5.0)[0]
    time.sleep(0.05)  # all 20 bytes in
    assert port.readPort(4) == bytes(range(4))
    peer.close()  # from here a read of the socket raises: the next reads are of what the first one took
    assert port.readPort(10) == bytes(range(4, 14))
    assert port.readPort(10) == bytes(range(14, 20))
    with pytest.raises(serial.SerialException, match="socket disconnected"):
        port.readPort(4)


def test_the_bytes_a_read_held_back_are_late_for_the_next_instruction(raw_socket_port) -> None:
    port, peer = raw_socket_port
    late = b"\xff\xff\xfd\x00\x02junk" + b"\xff\xff\xfd\x00\x03"
    peer.sendall(late)
    port.setPacketTimeoutMillis(2000)
    assert select.select([port._fd], [], [], 5.0)[0]
    time.sleep(0.05)
    assert port.readPort(3) == late[:3]
    port.clearPort()
    assert (port.stale_bytes, port.stale_packets) == (len(late) - 3, 1)  # the rest: one header left in it
    port.setPacketTimeoutMillis(20)
    assert port.readPort(4) == b""


@pytest.mark.parametrize("served", [pytest.param(_tcp, id="tcp")], indirect=True)
def test_the_sdk_pings_over_a_socket_port_without_pyserials_own_calls(served: UrlPortHandler) -> None:
    _pyserial_calls_fail(served)
    model, result, error = PacketHandler(2.0).ping(served, 1)
    assert (result, error) == (COMM_SUCCESS, 0) and model > 0
