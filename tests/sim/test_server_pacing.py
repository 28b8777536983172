"""The served simulator's pacing record (``SimServer.pacing``): every reply sent on a real clock is counted, the ones
that left more than ``LATE_S`` after their wire time as late, with the lateness's quantiles; a virtual clock keeps no
record.  Full garbage collections wait for the serving loop when it owns its process (``sim.pacing.Collections``).
No timed assertions: what the counts are, not how fast the machine was."""

from __future__ import annotations

import gc
import math
import socket
import sys
import threading
import time

import pytest

import sim
from retarget.control.clock import MonotonicClock, VirtualClock
from sim.pacing import LATE_S, Collections, Pacing
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


@pytest.mark.parametrize(
    ("lateness", "q", "within_us"),
    [
        pytest.param([0.0] * 9 + [0.4e-3], 0.5, 1.0, id="median-on-time"),
        pytest.param([0.0] * 9 + [0.4e-3], 1.0, 400.0, id="max-at-most-the-worst"),
        pytest.param([5e-6, 7.5e-6, 9e-6], 0.5, 8.0, id="1us-bins"),
        pytest.param([1.25e-3, 1.3e-3], 0.5, 1300.0, id="100us-bins"),
        pytest.param([1e-6, 0.25], 1.0, 250_000.0, id="beyond-100ms-the-worst"),
        pytest.param([-3e-6, -1e-6], 1.0, 1.0, id="early-counts-as-on-time"),
    ],
)
def test_pacing_quantiles_bound_the_lateness_to_its_bin(lateness, q, within_us):
    pacing = Pacing()
    for s in lateness:
        pacing.note(s)
    assert pacing.quantile(q) * 1e6 == pytest.approx(within_us)
    assert sorted(lateness)[math.ceil(q * len(lateness)) - 1] <= pacing.quantile(q)


def test_pacing_without_replies_has_no_quantiles_and_its_summary_none():
    assert math.isnan(Pacing().quantile(0.5))
    assert "median" not in Pacing(replies=3, late=0, worst=1e-4).summary()
    pacing = Pacing()
    pacing.note(2e-6)
    assert "(median 2 us, 99 % within 2 us, worst 2 us)" in pacing.summary()


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


def test_collections_take_full_collections_from_the_interpreter_and_give_them_back():
    before = gc.get_threshold()
    with Collections(enabled=True, every_s=10.0) as collections:
        assert gc.get_threshold()[:2] == before[:2] and gc.get_threshold()[2] > 10**6
        assert gc.get_freeze_count() > 0  # what existed before is frozen
        assert not collections.idle(0.0, quiet=True)  # no traffic since: nothing to collect
        collections.traffic()
        assert not collections.idle(1.0, quiet=False)  # steady traffic: counts from here
        assert not collections.idle(10.5, quiet=False)
        assert collections.idle(11.0, quiet=False) and collections.full == 1  # every_s later
        collections.traffic()
        assert collections.idle(11.1, quiet=True) and collections.full == 2  # a quiet spell after traffic
    assert gc.get_threshold() == before and gc.get_freeze_count() == 0


def test_disabled_collections_change_nothing():
    before = gc.get_threshold()
    with Collections(enabled=False) as collections:
        collections.traffic()
        assert gc.get_threshold() == before and not collections.idle(100.0, quiet=True)


class _Probe:
    """A hook that records the GC thresholds the serving loop runs under, then stops it."""

    def __init__(self, stop: threading.Event):
        self.stop, self.thresholds = stop, []

    def fds(self) -> list[int]:
        return []

    def due(self) -> float:
        return 0.0

    def service(self, ready: object, now: float) -> None:
        self.thresholds.append(gc.get_threshold())
        self.stop.set()


@pytest.mark.parametrize(("clock", "owns_gc"), [(MonotonicClock, True), (VirtualClock, False)], ids=["real", "virtual"])
def test_a_server_in_the_main_thread_on_a_real_clock_holds_full_collections(clock, owns_gc):
    before, stop = gc.get_threshold(), threading.Event()
    probe = _Probe(stop)
    server = TcpServer(sim.SimBus.from_ids([1], clock=clock()))
    server.add_hook(probe)
    try:
        server.serve_forever(stop)  # pytest runs this in the main thread
    finally:
        server.close()
    assert (probe.thresholds[0][2] > 10**6) is owns_gc
    assert gc.get_threshold() == before and gc.get_freeze_count() == 0


def test_a_server_in_a_thread_leaves_the_collector_alone():
    before, stop = gc.get_threshold(), threading.Event()
    probe = _Probe(stop)
    server = TcpServer(sim.SimBus.from_ids([1], clock=MonotonicClock()))
    server.add_hook(probe)
    with server:
        assert stop.wait(5.0)
    assert probe.thresholds and set(probe.thresholds) == {before}
