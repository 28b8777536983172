"""The served simulator's pacing record (``SimServer.pacing``): every reply sent on a real clock is counted, the ones
that left more than ``LATE_S`` after their wire time as late; a virtual clock keeps no record.  No timed
assertions: what the counts are, not how fast the machine was."""

from __future__ import annotations

import math
import socket
import sys
import time

import pytest

import sim
from retarget.control.clock import MonotonicClock, VirtualClock
from sim.pacing import LATE_S, Pacing
from sim.protocol import PacketParser, build_instruction
from sim.server import TcpServer

PING = 0x01


@pytest.mark.parametrize(
    ("lateness", "late", "worst"),
    [
        pytest.param([-1e-5, 2e-5], 0, 2e-5, id="on-time"),
        pytest.param([1e-4, LATE_S, 3e-3, 1e-3], 2, 3e-3, id="two-late"),
    ],
)
def test_pacing_counts_replies_and_the_late_ones(lateness, late, worst):
    pacing = Pacing()
    for s in lateness:
        pacing.note(s)
    assert (pacing.replies, pacing.late, pacing.worst) == (len(lateness), late, worst)
    assert pacing.summary().startswith(f"{len(lateness)} replies, {late} (")


@pytest.mark.parametrize(("clock", "counted"), [(MonotonicClock, 3), (VirtualClock, 0)], ids=["real", "virtual"])
def test_a_served_bus_records_the_replies_it_paced_on_a_real_clock(clock, counted):
    bus = sim.SimBus.from_ids([1, 2], clock=clock(), faults=sim.Faults(wire=True))
    with TcpServer(bus) as server:
        with socket.create_connection(server.address, timeout=5) as client:  # (pyserial's socket:// sleeps on close)
            for dxl_id in (1, 2, 1):
                client.sendall(build_instruction(dxl_id, PING))
                status = b""
                while len(status) < 14:
                    status += client.recv(14 - len(status))
                assert [p.id for p in PacketParser().feed(status)] == [dxl_id]
        assert server.pacing.replies == counted
        assert 0 <= server.pacing.late <= counted


class _Stall:
    """A hook that holds the serving thread ``seconds`` once, right after the server's first reply went out."""

    def __init__(self, server: TcpServer, seconds: float):
        self.server, self.seconds, self.done = server, seconds, False

    def fds(self) -> list[int]:
        return []

    def due(self) -> float:
        return math.inf

    def service(self, ready: object, now: float) -> None:
        if self.server.pacing.replies == 1 and not self.done:
            self.done = True
            time.sleep(self.seconds)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="kernel receive timestamps: Linux")
def test_over_tcp_an_instruction_is_timed_from_its_arrival_not_from_when_a_busy_server_reads_it():
    clock = MonotonicClock()
    bus = sim.SimBus.from_ids([1], clock=clock, faults=sim.Faults(wire=True))
    server = TcpServer(bus)
    server.add_hook(_Stall(server, 0.2))
    with server, socket.create_connection(server.address, timeout=5) as client:
        client.sendall(build_instruction(1, PING))
        assert len(client.recv(14)) == 14  # the server now stalls for 0.2 s
        sent = clock.now()
        client.sendall(build_instruction(1, PING))  # arrives while the server is busy
        status = b""
        while len(status) < 14:
            status += client.recv(14 - len(status))
    # the bus took the second ping as on the wire from its arrival (its log time is the end of its bytes), not
    # from when the server got round to reading it 0.2 s later
    assert bus.log[-1].t - sent < 0.1, bus.log[-1].t - sent
