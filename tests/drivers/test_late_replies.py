"""Late replies (issue 16, item 3): a status packet that comes after its transaction's timeout is never taken
for a later transaction's reply.  It is dropped before the next instruction or discarded by the matching (ID,
expected set, length), and counted in ``Link.late_packets``; the servo's read counts as missing (stale, then a
BusError under ``max_stale_ticks``).  Over a pty on a real clock, and in process on a virtual clock, where the
simulator now times a reply out as a real port does instead of waiting out its delay.
"""

from __future__ import annotations

import dynamixel_sdk.port_handler
import pytest

import sim
from drivers.comm import GroupRead, Link
from drivers.dynamixel_bus import DynamixelBus
from drivers.port import open_port
from retarget.control.clock import MonotonicClock, VirtualClock
from retarget.errors import BusError
from sim.server import PtyServer
from tests.helpers import PRESENT, lossy_sdk_timeout, needs_pty

#: The SDK's LATENCY_TIMER (ms) over the pty: a reply window of 2 x 20 + 2 = 42 ms (plus the bytes' time)
PTY_LATENCY_TIMER_MS = 20
#: servo 3's delay over the pty: past one window, inside the next ones (where it used to be taken)
PTY_DELAY_MS = 70


def _read(link: Link, ids: tuple[int, ...]) -> dict[int, int]:
    read = GroupRead.plan(dict.fromkeys(ids, (PRESENT, 4)))
    got = link.receive_group_read(link.send_group_read(read), allow_missing=True)
    return {i: int.from_bytes(r.data, "little") for i, r in got.items()}


# ---------------------------------------------------------------------------------------------- over a pty


@pytest.mark.pty
@needs_pty
def test_over_a_pty_a_late_reply_is_never_the_next_reads_answer(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(dynamixel_sdk.port_handler, "LATENCY_TIMER", PTY_LATENCY_TIMER_MS)
    bus = sim.SimBus.from_ids([1, 2, 3], "XM430-W350", clock=MonotonicClock(), return_delay_time=0)
    bus.faults = sim.Faults(servos={3: sim.ReplyFaults(delay=PTY_DELAY_MS / 1000)})
    with PtyServer(bus).start() as server:
        port = open_port(server.path, 1_000_000)
        try:
            link = Link(port, retries=3)
            for _ in range(3):
                # each try's reply from servo 3 lands in a later try's window: before, it was taken as that one's
                assert sorted(_read(link, (1, 2, 3))) == [1, 2]
            assert link.late_count > 0  # discarded by the matching, not only dropped before an instruction
            assert link.late_packets >= link.late_count
            # the delay ends: the answer is the servo's position now, not a late reply still on its way
            bus.faults = sim.Faults()
            bus.servo(3).set_position(1234)
            assert _read(link, (1, 2, 3))[3] == 1234
        finally:
            port.closePort()


@pytest.mark.pty
@needs_pty
def test_over_a_pty_a_late_servo_goes_stale_then_raises(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(dynamixel_sdk.port_handler, "LATENCY_TIMER", PTY_LATENCY_TIMER_MS)
    simbus = sim.SimBus.from_arm("wx250s", clock=MonotonicClock())
    with PtyServer(simbus).start() as server:
        bus = DynamixelBus("wx250s", server.path, shutdown="off", retries=2, max_stale_ticks=2, check_latency=False)
        with bus:
            bus.read_positions()
            simbus.faults = sim.Faults(servos={2: sim.ReplyFaults(delay=PTY_DELAY_MS / 1000)})
            bus.read_positions()
            bus.read_positions()
            assert bus.status().stale_reads >= 2 and bus.status().errors == 0
            with pytest.raises(BusError, match=r"servo 2\b"):
                bus.read_positions()
            link = bus._link or bus._last_link
            assert link is not None and link.late_packets > 0
            simbus.faults = sim.Faults()


# ---------------------------------------------------------------------------------------------- in process


def test_on_a_virtual_clock_a_reply_later_than_the_timeout_is_not_waited_for(monkeypatch: pytest.MonkeyPatch) -> None:
    lossy_sdk_timeout(monkeypatch)
    port = open_port("sim://?ids=1-3&model=XM430-W350&rdt=0&delay_ms=3:50&clock=virtual", 1_000_000)
    try:
        link = Link(port, retries=3)
        clock = port.ser.bus.clock  # type: ignore[union-attr]
        assert isinstance(clock, VirtualClock)
        t0 = clock.now()
        assert sorted(_read(link, (1, 2, 3))) == [1, 2]
        assert clock.now() - t0 < 0.010  # the read timed out: it did not jump the clock 50 ms to the reply
        assert link.late_packets == 0  # the four late replies are still on the wire
        clock.sleep_until(t0 + 0.060)  # they arrive: the next instruction drops them
        port.ser.bus.faults = sim.Faults()  # type: ignore[union-attr]
        assert sorted(_read(link, (1, 2, 3))) == [1, 2, 3]
        assert port.stale_packets == 4 and link.late_packets == 4
    finally:
        port.closePort()


def test_on_a_virtual_clock_late_replies_inside_a_window_are_discarded(monkeypatch: pytest.MonkeyPatch) -> None:
    """Late replies that land in a later read's window, before the servo's own reply, are not taken for it."""
    lossy_sdk_timeout(monkeypatch)
    simbus = sim.SimBus.from_ids([1, 2, 3], "XM430-W350", clock=VirtualClock(), return_delay_time=250)
    url = sim.attach(simbus)
    port = open_port(url, 1_000_000)
    try:
        link = Link(port, retries=3)
        simbus.servo(3).set_position(1000)
        simbus.faults = sim.Faults(servos={3: sim.ReplyFaults(delay=0.050)})
        t0 = simbus.clock.now()
        # 4 tries, each timed out (the clock goes to the end of its window): servo 3's first reply is due at
        # t0 + 51.5 ms (Return Delay Time 500 us after servos 1 and 2, + 50 ms), the next ones after
        assert sorted(_read(link, (1, 2, 3))) == [1, 2]
        simbus.faults = sim.Faults()
        simbus.servo(3).set_position(2000)
        simbus.clock.sleep_until(t0 + 0.0513)  # the next read's window: late replies before servo 3's own
        got = _read(link, (1, 2, 3))
        assert sorted(got) == [1, 2, 3] and got[3] == 2000  # not 1000, from a late reply
        assert link.late_count >= 1 and link.late_packets >= link.late_count
    finally:
        port.closePort()
        sim.unregister(url)


def test_a_late_servo_goes_stale_then_raises_in_process(url: str, sim_bus: sim.SimBus, monkeypatch) -> None:
    lossy_sdk_timeout(monkeypatch)
    bus = DynamixelBus("wx250s", url, shutdown="off", retries=1, max_stale_ticks=1)
    with bus:
        bus.read_positions()
        sim_bus.faults = sim.Faults(servos={4: sim.ReplyFaults(delay=0.050)})
        bus.read_positions()
        assert bus.status().stale_reads == 1
        with pytest.raises(BusError, match=r"servo 4\b"):
            bus.read_positions()
        sim_bus.faults = sim.Faults()
