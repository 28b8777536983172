"""The split position read (request_positions, then collect_positions) and the Link calls under it: the
instruction goes out at the request, the replies are taken at the collect, and nothing else may use the bus
in between.
"""

from __future__ import annotations

import numpy as np
import pytest

import sim
from drivers.comm import GroupRead, Link
from drivers.control_table import Instruction
from drivers.dynamixel_bus import DynamixelBus
from drivers.port import open_port
from retarget.errors import BusError
from tests.helpers import PRESENT, address

READS = (Instruction.SYNC_READ, Instruction.FAST_SYNC_READ)


def reads_sent(simbus: sim.SimBus) -> int:
    return sum(entry.instruction in READS for entry in simbus.log)


@pytest.fixture
def bus(arm, url, clock):
    bus = DynamixelBus(arm, url, clock=clock, shutdown="off", check_latency=False)
    bus.connect()
    yield bus
    bus.close()


def test_the_read_goes_out_at_the_request_and_is_taken_at_the_collect(bus, sim_bus, arm):
    rng = np.random.default_rng(3)
    for _ in range(5):
        goal = rng.uniform(bus.lower, bus.upper)
        bus.write_goals(goal)
        sim_bus.clock.advance(2.0)  # the servos get there
        before, ticks = reads_sent(sim_bus), bus.status().ticks
        bus.request_positions()
        assert reads_sent(sim_bus) == before + 1 and sim_bus.log[-1].instruction in READS
        assert bus.status().ticks == ticks  # not collected yet
        q = bus.collect_positions()
        assert reads_sent(sim_bus) == before + 1 and bus.status().ticks == ticks + 1
        assert q.shape == (arm.n_joints,) and q.dtype == np.float64
        np.testing.assert_allclose(q, goal, atol=2 * np.pi / 4096)
        np.testing.assert_array_equal(q, bus.read_positions())  # the same read, in one call


def test_exchange_is_collect_then_write_then_request(bus, sim_bus, arm):
    """The pipelined tick in one call: the last read's positions, this tick's SYNC_WRITE, the next read, in that
    order on the wire; and a collect that fails raises before the write goes out."""
    rng = np.random.default_rng(5)
    goal = rng.uniform(bus.lower, bus.upper)
    bus.write_goals(goal)
    sim_bus.clock.advance(2.0)
    bus.request_positions()
    n = len(sim_bus.log)
    q = bus.exchange(goal + 0.05)
    np.testing.assert_allclose(q, goal, atol=2 * np.pi / 4096)  # the read requested before the call
    sent = [e.instruction for e in list(sim_bus.log)[n:]]
    assert sent == [Instruction.SYNC_WRITE, sim_bus.log[n - 1].instruction]  # then the same read again
    bus.collect_positions()  # the read it started
    sim_bus.clock.advance(2.0)
    np.testing.assert_allclose(bus.read_positions(), goal + 0.05, atol=2 * np.pi / 4096)  # the goals it wrote
    n = len(sim_bus.log)
    with pytest.raises(BusError, match=r"no position read in flight: call request_positions\(\) first"):
        bus.exchange(goal)
    assert len(sim_bus.log) == n  # nothing went out


@pytest.mark.parametrize(
    "call",
    [
        pytest.param(lambda bus: bus.request_positions(), id="request-twice"),
        pytest.param(lambda bus: bus.read_positions(), id="read"),
        pytest.param(lambda bus: bus.write_goals(bus.arm.home), id="write"),
        pytest.param(lambda bus: bus.read_state(), id="read-state"),
        pytest.param(lambda bus: bus.set_torque(True), id="torque-on"),
        pytest.param(lambda bus: bus.read_gripper(), id="read-gripper"),
        pytest.param(lambda bus: bus.write_gripper(0.0), id="write-gripper"),
    ],
)
def test_nothing_else_uses_the_bus_while_a_read_is_in_flight(bus, call):
    bus.request_positions()
    with pytest.raises(BusError, match=r"a position read is in flight: call collect_positions\(\) first"):
        call(bus)
    bus.collect_positions()
    call(bus)  # and after the collect it works (a read left in flight is dropped by close)


def test_collect_without_a_request_is_an_error(bus):
    with pytest.raises(BusError, match=r"no position read in flight: call request_positions\(\) first"):
        bus.collect_positions()
    bus.request_positions()
    bus.collect_positions()
    with pytest.raises(BusError, match="no position read in flight"):
        bus.collect_positions()  # one collect per request


def test_torque_off_with_a_read_in_flight_is_refused_and_changes_nothing(bus, sim_bus, arm):
    bus.request_positions()
    with pytest.raises(BusError, match="a position read is in flight"):
        bus.set_torque(False)
    assert all(sim_bus.servo(i).get("Torque Enable") == 1 for i in arm.servo_ids)
    assert bus.status().retries == bus.status().errors == 0
    bus.collect_positions()


@pytest.mark.parametrize("shutdown", ["rest", "off"])
@pytest.mark.parametrize("fast", [True, False], ids=["fast-read", "plain-read"])
def test_close_with_a_read_in_flight_waits_for_its_replies(arm, clock, shutdown, fast):
    """On a half-duplex wire the shutdown's packets must not go out while the servos still answer the read (a
    collision), nor take its status packets for their own acknowledgements."""
    simbus = sim.SimBus.from_arm(arm, clock=clock, faults=sim.Faults(wire=True))
    url = sim.attach(simbus)
    try:
        bus = DynamixelBus(arm, url, clock=clock, shutdown=shutdown, fast_read=fast, check_latency=False)
        bus.connect()
        bus.write_goals(bus.read_positions() + 0.05)
        bus.request_positions()
        n = len(simbus.log)
        bus.close()
        assert simbus.collisions == []
        assert len(simbus.log) > n and all(simbus.servo(i).get("Torque Enable") == 0 for i in arm.servo_ids)
        with bus:  # and it connects again
            q = bus.read_positions()
        if shutdown == "rest":  # reached within the bus's rest tolerance (0.02 rad) before torque went off
            np.testing.assert_allclose(q, arm.rest, atol=0.03)
    finally:
        sim.unregister(url)


def test_a_lost_reply_of_a_pipelined_read_is_retried(bus, sim_bus):
    still = bus.read_positions()  # the servos hold where they are: every read must give these
    sim_bus.faults = sim.Faults(servos={3: sim.ReplyFaults(drop=0.3)}, seed=4)
    for _ in range(10):
        bus.request_positions()
        np.testing.assert_array_equal(bus.collect_positions(), still)
    assert bus.status().retries > 0 and bus.status().errors == 0


def test_a_silent_servo_fails_the_collect_by_its_id(bus, sim_bus):
    still = bus.read_positions()
    sim_bus.servo(4).unplug()
    for _ in range(bus.max_stale_ticks):  # stale: its last position stands in, the others are read
        bus.request_positions()
        np.testing.assert_array_equal(bus.collect_positions(), still)
    assert bus.status().worst_stale == bus.max_stale_ticks == 10
    bus.request_positions()
    with pytest.raises(BusError, match=r"^servo 4: no status packet \(Present Position\)") as info:
        bus.collect_positions()
    assert info.value.ids == (4,)
    with pytest.raises(BusError, match="bus is faulted"):
        bus.request_positions()
    sim_bus.servo(4).plug()  # so the fixture's close can turn its torque off


# ---------------------------------------------------------------------------------------------- Link


@pytest.fixture
def link(url):
    port = open_port(url, 1_000_000)
    yield Link(port, retries=1)
    port.closePort()


@pytest.mark.parametrize(
    ("requests", "fast"),
    [
        ({1: (PRESENT, 4), 2: (PRESENT, 4), 4: (PRESENT, 4)}, False),
        ({1: (PRESENT, 4), 2: (PRESENT, 4), 4: (PRESENT, 4)}, True),
        ({1: (PRESENT, 4), 2: (address("Present Temperature"), 1)}, False),
    ],
    ids=["sync", "fast-sync", "bulk"],
)
def test_send_then_receive_equals_one_group_read(link, sim_bus, requests, fast):
    sim_bus.servo(1).set_position(1234)
    read = link.send_group_read(GroupRead.plan(requests, fast=fast))
    assert read.sent and read.same == (len(set(requests.values())) == 1) and read.fast == (fast and read.same)
    split = link.receive_group_read(read, what="split")
    assert split == link.group_read(requests, fast=fast)
    assert int.from_bytes(split[1].data, "little") == 1234
    assert link.retry_count == 0


def test_a_read_whose_instruction_did_not_go_out_is_sent_again(link, sim_bus):
    link.port.is_using = True  # another transaction holds the port: the SDK refuses to send (COMM_PORT_BUSY)
    n = len(sim_bus.log)
    read = link.send_group_read(GroupRead.plan({1: (PRESENT, 4), 2: (PRESENT, 4)}))
    assert not read.sent and link.port.is_using  # its lock is left alone
    assert len(sim_bus.log) == n
    link.port.is_using = False  # that transaction ends
    replies = link.receive_group_read(read)
    assert sorted(replies) == [1, 2] and link.retry_count == 1
    assert [e.instruction for e in list(sim_bus.log)[n:]] == [Instruction.SYNC_READ]
