"""The wire model counts wire time only: the simulator's own processing overlaps with the bytes on the wire (a real
servo decodes while they arrive), so a reply's arrival is fixed by the instant its request was written, whatever the
simulator did afterwards.  A clock that moves on every read exposes any later clock read in the reply times.
"""

from __future__ import annotations

import pytest
import serial

import sim
from drivers.control_table import Instruction
from sim.faults import Faults, wire_time
from sim.protocol import build_instruction
from tests.helpers import GOAL, PRESENT

BAUD = 1_000_000
STEP = 1e-3  #: how far the clock moves on every read: far more than any wire time here


class SteppingClock:
    """Every ``now()`` is ``STEP`` later than the one before (as if each clock read took that long)."""

    def __init__(self) -> None:
        self.t = 0.0

    def now(self) -> float:
        self.t += STEP
        return self.t

    def sleep_until(self, t: float) -> None:
        self.t = max(self.t, t)


def u16(v: int) -> bytes:
    return v.to_bytes(2, "little")


def sync_write_goal(ids: range) -> bytes:
    return build_instruction(
        0xFE, Instruction.SYNC_WRITE, u16(GOAL) + u16(4) + b"".join(bytes([i]) + u16(2048) + u16(0) for i in ids)
    )


@pytest.mark.parametrize(
    "instruction, reply_length",
    [
        pytest.param(Instruction.SYNC_READ, 15, id="sync-read"),
        pytest.param(Instruction.FAST_SYNC_READ, 8 + 6 * 8, id="fast-sync-read"),
    ],
)
def test_reply_times_count_from_the_write_instant_only(instruction, reply_length):
    clock = SteppingClock()
    ids = range(1, 7)
    bus = sim.SimBus.from_ids(ids, "XM430-W350", clock=clock, return_delay_time=0, faults=Faults(wire=True))
    request = build_instruction(0xFE, instruction, u16(PRESENT) + u16(4) + bytes(ids))
    written = clock.t + STEP  # the first clock read inside feed: the instant the request is written
    replies = bus.feed(request)
    assert clock.t > written  # the simulator did read the clock again while it processed the request
    n = len(replies)
    assert n == (6 if instruction == Instruction.SYNC_READ else 1)
    assert all(len(r.data) == reply_length for r in replies)
    expected = [written + wire_time(len(request), BAUD) + (k + 1) * wire_time(reply_length, BAUD) for k in range(n)]
    assert [r.due for r in replies] == pytest.approx(expected, abs=1e-12)


def test_a_request_written_while_the_line_is_busy_waits_behind_it():
    clock = SteppingClock()
    ids = range(1, 7)
    bus = sim.SimBus.from_ids(ids, "XM430-W350", clock=clock, return_delay_time=0, faults=Faults(wire=True))
    goal = sync_write_goal(ids)
    read = build_instruction(0xFE, Instruction.FAST_SYNC_READ, u16(PRESENT) + u16(4) + bytes(ids))
    t_write = clock.t + STEP
    assert bus.feed(goal, now=t_write) == []
    # written 100 us later, while the 440 us sync write is still on the line: it goes out after it
    (reply,) = bus.feed(read, now=t_write + 100e-6)
    busy = wire_time(len(goal), BAUD)
    assert busy > 100e-6
    assert reply.due == pytest.approx(t_write + busy + wire_time(len(read) + len(reply.data), BAUD), abs=1e-12)


def test_the_port_hands_a_reply_over_at_its_due_time_not_before():
    port = serial.serial_for_url("sim://?ids=1-6&model=XM430-W350&rdt=0&wire=1&clock=virtual", baudrate=BAUD, timeout=0)
    clock = port.bus.clock
    read = build_instruction(0xFE, Instruction.FAST_SYNC_READ, u16(PRESENT) + u16(4) + bytes(range(1, 7)))
    port.write(read)
    due = wire_time(len(read) + 8 + 6 * 8, BAUD)
    clock.advance(due - 1e-6)  # the last byte is still on the wire
    assert port.in_waiting == 0
    clock.advance(2e-6)
    assert port.in_waiting == 8 + 6 * 8
    assert len(port.read(1000)) == 8 + 6 * 8
    port.close()


@pytest.mark.parametrize(
    ("after", "collides"),
    [
        pytest.param(-1e-6, True, id="while-the-reply-is-on-the-wire"),
        pytest.param(0.0, False, id="as-its-last-byte-arrives"),
    ],
)
def test_a_host_write_during_a_reply_is_a_collision(after, collides):
    ids = range(1, 7)
    bus = sim.SimBus.from_ids(ids, "XM430-W350", clock=SteppingClock(), return_delay_time=0, faults=Faults(wire=True))
    read = build_instruction(0xFE, Instruction.FAST_SYNC_READ, u16(PRESENT) + u16(4) + bytes(ids))
    goal = sync_write_goal(ids)
    (reply,) = bus.feed(read, now=0.0)
    assert bus.feed(goal, now=reply.due + after) == []
    assert [(e.instruction, e.id) for e in bus.collisions] == ([(Instruction.SYNC_WRITE, 0xFE)] if collides else [])
    # a host write right behind its own earlier write is no collision: the UART sends them one after the other
    bus.feed(goal, now=reply.due + 1.0)
    bus.feed(goal, now=reply.due + 1.0 + 1e-6)
    assert len(bus.collisions) == int(collides)


def test_without_the_wire_model_nothing_is_timed_so_nothing_collides():
    ids = range(1, 7)
    bus = sim.SimBus.from_ids(ids, "XM430-W350", clock=SteppingClock(), return_delay_time=0)
    read = build_instruction(0xFE, Instruction.FAST_SYNC_READ, u16(PRESENT) + u16(4) + bytes(ids))
    bus.feed(read, now=0.0)
    bus.feed(read, now=0.0)
    assert bus.collisions == []
