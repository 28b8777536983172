"""The pipelined read-back of the tick loop: the next tick computes while the last read-back is on the wire,
the wire carries the same packets in the same order, and every tick still gets its record.
"""

from __future__ import annotations

import numpy as np
import pytest

from drivers.control_table import Instruction
from retarget.control import ClipSource, ControlLoop, LoopConfig, TickRecord, run_on_bus, run_ticks
from retarget.control.bus import connected as connected_bus
from retarget.ik import CCDSolver
from tests.helpers import circle_targets, servo_angles, torque

READS = (Instruction.SYNC_READ, Instruction.FAST_SYNC_READ)


def replay(arm, sim_bus, *, pipeline: bool, **config):
    """Run the circle clip on a fresh simulated wx250s; (records, summary, the wire log as tuples)."""
    from drivers import DynamixelBus

    simbus, url, clock = sim_bus()
    records: list[TickRecord] = []
    loop = ControlLoop(
        arm,
        circle_targets(arm),
        config=LoopConfig(**config),
        clock=clock,
        on_tick=records.append,
        pipeline=pipeline,
    )
    with DynamixelBus(arm, url, clock=clock, shutdown="hold") as bus:
        summary = loop.run(bus)
    log = [(e.t, e.id, e.instruction, e.params) for e in simbus.log]
    return records, summary, log


@pytest.mark.parametrize("config", [{}, {"end": 0.5, "lead_in_speed": 0.0}], ids=["lead-in", "no-lead-in"])
def test_pipelined_and_in_tick_read_backs_are_the_same_run_on_the_wire(arm, sim_bus, config):
    piped, s1, wire1 = replay(arm, sim_bus, pipeline=True, **config)
    plain, s2, wire2 = replay(arm, sim_bus, pipeline=False, **config)
    assert wire1 == wire2  # every packet, its bytes and its time on the (virtual) wire
    assert [r.tick for r in piped] == [r.tick for r in plain] and len(piped) == s1.ticks + s1.lead_in_ticks
    for a, b in zip(piped, plain, strict=True):
        np.testing.assert_array_equal(a.q_cmd, b.q_cmd)
        np.testing.assert_array_equal(a.q_present, b.q_present)  # read at the same moment of the same tick
        assert a.bus_time > 0 and a.overrun == b.overrun and a.bus_retries == b.bus_retries == 0
    assert (s1.ticks, s1.lead_in_ticks, s1.ik_converged_pct) == (s2.ticks, s2.lead_in_ticks, s2.ik_converged_pct)
    # on the wire: write, read, write, read ... one of each per tick
    ticks = [ins for _, _, ins, _ in wire1 if ins == Instruction.SYNC_WRITE or ins in READS]
    run = ticks[-2 * len(piped) :]
    assert run == [Instruction.SYNC_WRITE, run[1]] * len(piped) and run[1] in READS


class Spy:
    """A clip source that notes, as each tick asks for its target, the reads sent and the reads collected."""

    def __init__(self, inner: ClipSource, simbus, bus):
        self.inner, self.simbus, self.bus = inner, simbus, bus
        self.seen: list[tuple[int, int]] = []  # (reads on the wire, reads collected) at each target_at
        self.finished = inner.finished
        self.start = inner.start

    def target_at(self, tick, t):
        self.seen.append((sum(e.instruction in READS for e in self.simbus.log), self.bus.status().ticks))
        return self.inner.target_at(tick, t)


@pytest.mark.parametrize(("pipeline", "in_flight"), [(True, 1), (False, 0)], ids=["pipelined", "in-tick-read"])
def test_the_next_tick_computes_while_the_read_back_is_on_the_wire(arm, sim_bus, pipeline, in_flight):
    from drivers import DynamixelBus

    simbus, url, clock = sim_bus()
    loop = ControlLoop(arm, circle_targets(arm), config=LoopConfig(end=0.3, lead_in_speed=0.0), clock=clock)
    with DynamixelBus(arm, url, clock=clock, shutdown="hold") as bus:
        spy = Spy(ClipSource(loop), simbus, bus)
        stats = run_ticks(arm, spy, CCDSolver(arm), config=loop.config, clock=clock, bus=bus, pipeline=pipeline)
    assert stats.ticks == len(spy.seen) == 31
    base = spy.seen[0][0] - spy.seen[0][1]  # reads of connect that no tick collects
    assert [sent - got - base for sent, got in spy.seen] == [0] + [in_flight] * 30


class Observing:
    def target_at(self, tick, t):
        return None

    def finished(self, tick):
        return tick >= 3

    def observe(self, tick, q_cmd, q_present):
        pass


def test_a_source_that_observes_is_not_pipelined(arm, sim_bus):
    from drivers import DynamixelBus

    _, url, clock = sim_bus()
    bus = DynamixelBus(arm, url, clock=clock)  # not connected: nothing is sent before the check
    with pytest.raises(ValueError, match=r"Expected a source without observe\(\) with pipeline=True"):
        run_ticks(arm, Observing(), CCDSolver(arm), config=LoopConfig(), clock=clock, bus=bus, pipeline=True)
    # a dry run has no read-back to pipeline
    stats = run_ticks(arm, Observing(), CCDSolver(arm), config=LoopConfig(), clock=clock, pipeline=True)
    assert stats.ticks == 3 and stats.holds == 3


@pytest.mark.parametrize("pipeline", [True, False], ids=["pipelined", "in-tick-read"])
def test_a_failing_callback_leaves_no_read_on_the_wire_under_the_shutdown(arm, sim_bus, pipeline):
    """The exception ends the run with a read-back in flight (pipelined): the bus's close waits for its replies
    before the rest move and the torque off, so nothing collides on the half-duplex wire."""
    from drivers import DynamixelBus

    simbus, url, clock = sim_bus()

    def on_tick(r: TickRecord) -> None:
        if r.tick == 30:
            raise RuntimeError("telemetry disk full")

    loop = ControlLoop(arm, circle_targets(arm), clock=clock, on_tick=on_tick, pipeline=pipeline)
    bus = DynamixelBus(arm, url, clock=clock, shutdown="rest")
    with pytest.raises(RuntimeError, match="telemetry disk full"):
        run_on_bus(loop, bus)
    assert simbus.collisions == [] and not bus.connected
    assert torque(simbus, arm) == [0] * 8
    np.testing.assert_allclose(servo_angles(simbus, arm), arm.rest, atol=0.06)


def test_ctrl_c_when_the_last_read_back_fails_still_records_the_tick(arm, sim_bus, caplog):
    """Ctrl-C (from a callback) with the last tick's read-back in flight and a servo gone: the tick is recorded
    without its present positions, the loop's series stay aligned, and the bus's shutdown names the servo."""
    from drivers import DynamixelBus
    from retarget.errors import BusError

    simbus, url, clock = sim_bus()
    records: list[TickRecord] = []

    def on_tick(r: TickRecord) -> None:
        records.append(r)
        if r.tick == 30:
            simbus.servo(4).unplug()  # after tick 31's read went out: tick 32's read gets no reply from it
        if r.tick == 31:
            raise KeyboardInterrupt

    config = LoopConfig(lead_in_speed=0.0)
    loop = ControlLoop(arm, circle_targets(arm), config=config, clock=clock, on_tick=on_tick)
    bus = DynamixelBus(arm, url, clock=clock, shutdown="rest", retries=0, max_stale_ticks=0)  # a miss raises
    stats = {}
    with pytest.raises(BusError, match=r"^servo 4: could not turn torque off"):
        with connected_bus(bus):
            stats["summary"] = loop.run(bus)
    summary = stats["summary"]
    assert summary.interrupted and summary.ticks == 33  # slots 0..32: 32's goals went out before the Ctrl-C
    assert [r.tick for r in records] == list(range(33))
    assert records[31].q_present is not None and records[32].q_present is None
    assert "tick 32: its read-back is lost: servo 4: no status packet" in caplog.text
    assert simbus.collisions == []
