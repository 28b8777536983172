"""A noisy bus: a group read keeps what came and asks again only the missing servos, parses past a corrupt
status packet, and a servo still silent after the retries goes stale (its last position) until the window.
Connect retries every write, Status Return Level included.
"""

from __future__ import annotations

import pytest
import serial

import sim
from drivers import units
from drivers.comm import GroupRead, Link
from drivers.control_table import Instruction
from drivers.port import UrlPortHandler, open_port
from retarget.errors import BusError
from sim.protocol import build_status
from tests.helpers import PRESENT, goal_writes, lossy_sdk_timeout, sync_read_ids


@pytest.fixture(autouse=True)
def _short_timeouts(monkeypatch: pytest.MonkeyPatch) -> None:
    lossy_sdk_timeout(monkeypatch)


@pytest.fixture
def link(url):
    port = open_port(url, 1_000_000)
    yield Link(port, retries=2)
    port.closePort()


# ---------------------------------------------------------------------------------------------- the Link


def test_a_retry_asks_only_the_servos_that_did_not_answer(link, sim_bus):
    sim_bus.faults = sim.Faults(servos={2: sim.ReplyFaults(drop=1.0)})
    n = len(sim_bus.log)
    requests = dict.fromkeys((1, 2, 3, 4), (PRESENT, 4))
    got = link.receive_group_read(link.send_group_read(GroupRead.plan(requests)), allow_missing=True)
    assert sorted(got) == [1, 3, 4]  # the first try's replies are kept
    # on the wire: the whole read once, then servo 2 alone for each retry
    assert sync_read_ids(list(sim_bus.log)[n:]) == [[1, 2, 3, 4], [2], [2]]
    assert link.retry_count == 2 and link.reply_loss(2) == (3, 3) and link.reply_loss(1) == (0, 1)


def test_replies_gathered_over_tries_make_one_complete_read(link, sim_bus):
    sim_bus.servo(3).set_position(1500)
    sim_bus.faults = sim.Faults(bus=sim.ReplyFaults(drop=0.3), seed=5)
    retried = 0
    for _ in range(10):
        n = len(sim_bus.log)
        got = link.group_read(dict.fromkeys((1, 2, 3, 4), (PRESENT, 4)), what="Present Position")
        assert list(got) == [1, 2, 3, 4] and int.from_bytes(got[3].data, "little") == 1500
        asked = sync_read_ids(list(sim_bus.log)[n:])
        assert asked[0] == [1, 2, 3, 4] and all(len(ids) < 4 for ids in asked[1:])  # no retry asks all four
        retried += len(asked) > 1
    assert retried > 0 and link.error_count == 0


def test_missing_after_every_retry_raises_naming_the_servo(link, sim_bus):
    sim_bus.faults = sim.Faults(servos={4: sim.ReplyFaults(drop=1.0)})
    with pytest.raises(BusError, match=r"^servo 4: no status packet \(positions\) at 1000000 baud after 3 tries$"):
        link.group_read(dict.fromkeys((1, 4), (PRESENT, 4)), what="positions")


def test_a_corrupt_reply_does_not_lose_the_replies_after_it(link, sim_bus):
    sim_bus.faults = sim.Faults(servos={2: sim.ReplyFaults(corrupt=1.0)})
    link.retries = 0
    got = link.receive_group_read(
        link.send_group_read(GroupRead.plan(dict.fromkeys((1, 2, 3), (PRESENT, 4)))), allow_missing=True
    )
    assert sorted(got) == [1, 3] and link.corrupt_count == 1


def test_collect_parses_past_a_bad_crc_on_the_wire():
    """Bytes on the wire: three status packets, the middle one with a flipped CRC bit, then a torn one."""
    port = UrlPortHandler("loop://")
    port.baudrate = 1_000_000
    assert port.setBaudRate(1_000_000)
    link = Link(port, retries=0)
    packets = [build_status(i, 0, (1000 + i).to_bytes(4, "little")) for i in (1, 2, 3)]
    packets[1] = packets[1][:-1] + bytes([packets[1][-1] ^ 0x01])
    wire = b"".join(packets) + build_status(4, 0, b"\x00\x00\x00\x00")[:8]  # servo 4's reply cut short
    assert isinstance(port.ser, serial.SerialBase)
    port.ser.write(wire)
    port.setPacketTimeout(4 * 15)
    got = link._collect(dict.fromkeys((1, 2, 3, 4), 4))
    assert {i: int.from_bytes(r.data, "little") for i, r in got.items()} == {1: 1001, 3: 1003}
    assert link.corrupt_count == 1
    port.closePort()


def test_status_return_level_write_is_retried_on_a_corrupt_reply(link, sim_bus):
    from drivers.control_table import common_register

    srl = common_register("Status Return Level")
    sim_bus.faults = sim.Faults(servos={1: sim.ReplyFaults(corrupt=0.5)}, seed=2)
    for _ in range(5):
        link.write_maybe_unacknowledged(1, srl, 2)
    assert link.retry_count > 0 and link.error_count == 0
    sim_bus.faults = sim.Faults(servos={1: sim.ReplyFaults(corrupt=1.0)})
    with pytest.raises(BusError, match=r"^servo 1: corrupt status packet writing Status Return Level = 2$"):
        link.write_maybe_unacknowledged(1, srl, 2)


def test_status_return_level_write_accepts_a_servo_that_never_answers(link, sim_bus):
    from drivers.control_table import common_register

    sim_bus.faults = sim.Faults(servos={1: sim.ReplyFaults(drop=1.0)})
    link.write_maybe_unacknowledged(1, common_register("Status Return Level"), 2)  # silent: level 0 or 1
    assert link.retry_count == 2 and link.error_count == 0


# ---------------------------------------------------------------------------------------------- the bus


def test_a_stale_servo_keeps_its_last_position_until_the_window(make_bus, url, sim_bus):
    bus = make_bus(url, retries=1, max_stale_ticks=4, shutdown="off")
    bus.connect()
    q0 = bus.read_positions()
    sim_bus.faults = sim.Faults(servos={1: sim.ReplyFaults(drop=1.0)})  # the waist's only servo
    writes = len(goal_writes(sim_bus))
    for k in range(4):
        bus.write_goals(q0)  # goals still go out: a sync write needs no reply
        sim_bus.servo(1).set_position(2048 + 100 * (k + 1))  # the waist moves, unseen
        sim_bus.servo(6).set_position(2048 + 100 * (k + 1))  # the forearm roll moves, seen
        q = bus.read_positions()
        assert q[0] == q0[0] and q[3] == pytest.approx(100 * (k + 1) * units.RAD_PER_PULSE)
    assert len(goal_writes(sim_bus)) == writes + 4
    status = bus.status()
    assert (status.stale_reads, status.stale_ticks, status.worst_stale, status.errors) == (4, 4, 4, 0)
    with pytest.raises(BusError, match=r"^servo 1: no status packet \(Present Position\).* 1: stale 5 reads in a row"):
        bus.read_positions()
    with pytest.raises(BusError, match="bus is faulted"):
        bus.write_goals(q0)
    sim_bus.faults = sim.Faults()  # so the fixture's close reaches every servo


def test_a_servo_that_answers_again_is_fresh_again(make_bus, url, sim_bus):
    bus = make_bus(url, retries=0, max_stale_ticks=2, shutdown="off")
    bus.connect()
    for _ in range(5):  # stale twice, fresh once: never more than 2 in a row
        sim_bus.faults = sim.Faults(servos={6: sim.ReplyFaults(drop=1.0)})
        bus.read_positions()
        bus.read_positions()
        sim_bus.faults = sim.Faults()
        bus.read_positions()
    assert (bus.status().stale_reads, bus.status().worst_stale, bus.status().errors) == (10, 2, 0)


def test_a_servo_stale_too_often_in_the_last_second_raises(make_bus, url, sim_bus):
    bus = make_bus(url, retries=0, max_stale_ticks=5, max_stale_fraction=0.2, dt=0.02, shutdown="off")
    bus.connect()
    assert bus.stale_window == 50
    with pytest.raises(BusError, match=r"^servo 7: .*stale 1 reads in a row, 11 of the last \d+ reads") as info:
        for _ in range(60):  # stale every other read: 11 of them pass 20 % of 50
            sim_bus.faults = sim.Faults(servos={7: sim.ReplyFaults(drop=1.0)})
            bus.read_positions()
            sim_bus.faults = sim.Faults()
            bus.read_positions()
    sim_bus.faults = sim.Faults()
    assert info.value.ids == (7,) and "11 of the last 21 reads (52%), 50% of 22 replies lost" in str(info.value)


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"max_stale_ticks": -1}, r"^Expected max_stale_ticks >= 0, got -1$"),
        ({"max_stale_fraction": 0.0}, r"^Expected max_stale_fraction in \(0, 1\], got 0.0$"),
        ({"max_stale_fraction": 1.5}, r"^Expected max_stale_fraction in \(0, 1\], got 1.5$"),
    ],
)
def test_bad_stale_options_raise(make_bus, url, options, message):
    with pytest.raises(ValueError, match=message):
        make_bus(url, **options)


@pytest.mark.parametrize("fault", ["drop", "corrupt"])
def test_connect_rides_through_lost_and_corrupt_replies(make_bus, url, sim_bus, fault):
    """Every write at connect is confirmed and retried: 10 seeded connects at 5 % all start."""
    for seed in range(10):
        sim_bus.faults = sim.Faults(bus=sim.ReplyFaults(**{fault: 0.05}), seed=seed)
        bus = make_bus(url, shutdown="off")
        bus.connect()
        assert bus.connected and bus.status().errors == 0
        sim_bus.faults = sim.Faults()
        bus.close()
    assert [e.instruction for e in sim_bus.log].count(Instruction.WRITE) > 0
