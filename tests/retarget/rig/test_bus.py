"""RigBus over the real driver: each arm of the wx250s-pair rig a DynamixelBus on its own in-process simulated bus.

What the arms' simulated servos hold is the truth: goal registers, torque, present positions, and the times the
simulated wires carried each packet.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from threading import Barrier
from typing import Any

import numpy as np
import pytest

import sim
from drivers import DynamixelBus
from drivers.units import pulses_to_rad
from retarget.control.bus import Bus, connected
from retarget.control.clock import Clock, MonotonicClock, VirtualClock
from retarget.errors import BusError
from retarget.rig import Rig, RigBus, load_rig
from sim.faults import Faults
from sim.protocol import Instruction
from tests.helpers import TORQUE, servo_angles, torques

NAMES = ("left", "right")


@pytest.fixture(scope="module")
def rig() -> Rig:
    return load_rig("wx250s-pair")


class Arms:
    """The rig's arms: per arm its simulated bus, its clock and its DynamixelBus (not connected)."""

    def __init__(self) -> None:
        self.sims: dict[str, sim.SimBus] = {}
        self.clocks: dict[str, Clock] = {}
        self.buses: dict[str, DynamixelBus] = {}
        self.urls: list[str] = []

    def angles(self, name: str) -> np.ndarray:
        """``(6,)`` rad: the joint angles the arm's primary servos' Present Position says."""
        return servo_angles(self.sims[name], self.buses[name].arm)

    def goals(self, name: str) -> np.ndarray:
        """``(6,)`` rad: the Goal Position of each joint's primary servo."""
        arm, simbus = self.buses[name].arm, self.sims[name]
        return np.array([pulses_to_rad(simbus.servo(j.servos[0].id).get("Goal Position")) for j in arm.joints])

    def advance(self, seconds: float) -> None:
        for clock in self.clocks.values():
            if isinstance(clock, VirtualClock):
                clock.advance(seconds)


@pytest.fixture
def make_arms(rig: Rig) -> Iterator[Callable[..., Arms]]:
    """``make_arms(shutdown=, faults={arm: Faults options}, clock=, wire=)``: each arm on its own VirtualClock by
    default (``clock``: one clock shared by both); every bus is closed and every simulated bus unregistered after."""
    made: list[Arms] = []

    def make(
        *, shutdown: str = "rest", faults: dict[str, dict[str, Any]] | None = None, clock: Clock | None = None,
        wire: bool = False,
    ) -> Arms:  # fmt: skip
        arms = Arms()
        for a in rig.arms:
            arms.clocks[a.name] = c = clock if clock is not None else VirtualClock()
            options = {"wire": wire, **(faults or {}).get(a.name, {})}
            arms.sims[a.name] = sim.SimBus.from_arm(a.arm, clock=c, faults=Faults.from_options(**options))
            arms.urls.append(sim.attach(arms.sims[a.name]))
            arms.buses[a.name] = DynamixelBus(a.arm, arms.urls[-1], shutdown=shutdown, clock=c, check_latency=False)
        made.append(arms)
        return arms

    yield make
    for arms in made:
        for bus in arms.buses.values():
            try:
                bus.close()
            except BusError:
                pass
        for url in arms.urls:
            sim.unregister(url)


def goals_for(arms: Arms) -> dict[str, np.ndarray]:
    """Distinct, reachable goals per arm, rad: near home, each joint and arm its own offset."""
    return {name: np.linspace(0.05, 0.3, 6) * (1 if name == "left" else -1) for name in NAMES}


# ------------------------------------------------------------------ joint order, splitting, reading


def test_joint_names_follow_the_rig_order_with_the_arm_as_prefix(make_arms):
    arms = make_arms()
    rig_bus = RigBus(arms.buses)
    joints = arms.buses["left"].joint_names
    assert rig_bus.joint_names == tuple(f"left/{j}" for j in joints) + tuple(f"right/{j}" for j in joints)
    assert rig_bus.n_joints == 12
    assert dict(rig_bus.slices) == {"left": slice(0, 6), "right": slice(6, 12)}
    assert isinstance(rig_bus, Bus)


def test_write_goals_splits_the_vector_per_arm_onto_each_arms_servos(make_arms):
    arms = make_arms()
    goals = goals_for(arms)
    with connected(RigBus(arms.buses)) as rig_bus:
        rig_bus.write_goals(np.concatenate([goals["left"], goals["right"]]))
        for name in NAMES:
            np.testing.assert_allclose(arms.goals(name), goals[name], atol=0.002)
        arms.advance(3.0)  # the servos get there
        present = rig_bus.read_positions()
        assert present.shape == (12,)
        np.testing.assert_allclose(present, np.concatenate([arms.angles(n) for n in NAMES]), atol=1e-9)
        np.testing.assert_allclose(present, np.concatenate([goals[n] for n in NAMES]), atol=0.01)


def test_pipelined_read_returns_both_arms_in_rig_order(make_arms):
    arms = make_arms()
    with connected(RigBus(arms.buses)) as rig_bus:
        rig_bus.write_goals(np.concatenate([goals_for(arms)[n] for n in NAMES]))
        arms.advance(3.0)
        rig_bus.request_positions()
        present = rig_bus.collect_positions()
        np.testing.assert_allclose(present, np.concatenate([arms.angles(n) for n in NAMES]), atol=1e-9)
        assert rig_bus.status().ticks == 1 and {n: s.ticks for n, s in rig_bus.statuses().items()} == {
            "left": 1,
            "right": 1,
        }


def test_exchange_collects_each_arm_then_sends_its_goals_and_next_read_arm_by_arm(make_arms):
    arms = make_arms()
    log: list[tuple[str, str, float, float]] = []
    rig_bus = RigBus({n: Recorder(n, arms.buses[n], log, Barrier(1)) for n in NAMES})
    goals = np.concatenate([goals_for(arms)[n] for n in NAMES])
    with connected(rig_bus):
        rig_bus.request_positions()
        before = np.concatenate([arms.angles(n) for n in NAMES])
        del log[:]
        present = rig_bus.exchange(goals)
        assert [(name, method) for name, method, *_ in log] == [("left", "exchange"), ("right", "exchange")]
        np.testing.assert_allclose(present, before, atol=1e-9)  # the reads requested before
        for name in NAMES:
            np.testing.assert_allclose(arms.goals(name), goals_for(arms)[name], atol=0.002)
        assert rig_bus.status().ticks == 1
        rig_bus.collect_positions()  # the reads it started
        with pytest.raises(ValueError, match=r"Expected finite goals in radians"):
            rig_bus.exchange(np.r_[goals[:11], np.inf])
        assert rig_bus.status().ticks == 2  # nothing was collected


@pytest.mark.parametrize("faulty", NAMES)
def test_an_exchange_that_fails_on_one_arm_gives_no_later_arm_its_goals_and_raises_naming_it(make_arms, faulty):
    """Servo 4 of one arm overloads: its collect raises, so it writes nothing; an arm before it in rig order already
    has its goals, an arm after it only collects (its read in flight is taken, no new goal goes out)."""
    arms = make_arms(shutdown="off", faults={faulty: {"hwerror": ["4:overload@5"]}})
    other = "left" if faulty == "right" else "right"
    with connected(RigBus(arms.buses)) as rig_bus:
        rig_bus.write_goals(np.zeros(12))
        arms.advance(6.0)  # past the fault's time
        rig_bus.request_positions()
        before = {n: arms.goals(n) for n in NAMES}
        ticks = arms.buses[other].status().ticks
        with pytest.raises(BusError, match=rf"^{faulty}: servo 4: hardware error: overload"):
            rig_bus.exchange(np.concatenate([goals_for(arms)[n] for n in NAMES]))
        assert arms.buses[other].status().ticks == ticks + 1  # its read was collected
        np.testing.assert_array_equal(arms.goals(faulty), before[faulty])
        if other == "left":  # before the faulty arm: it had its goals and its next read is in flight
            np.testing.assert_allclose(arms.goals("left"), goals_for(arms)["left"], atol=0.002)
        else:
            np.testing.assert_array_equal(arms.goals("right"), before["right"])


@pytest.mark.parametrize(
    "goals, match",
    [
        pytest.param(np.zeros(6), r"Expected goals of shape \(12,\) in radians \(left 6, right 6\), got shape \(6,\)",
                     id="one-arm"),
        pytest.param(np.r_[np.zeros(11), np.nan], r"Expected finite goals in radians", id="nan-on-the-right"),
    ],
)  # fmt: skip
def test_bad_goals_raise_before_any_arm_writes(make_arms, goals, match):
    arms = make_arms()
    with connected(RigBus(arms.buses)) as rig_bus:
        before = {n: arms.goals(n) for n in NAMES}
        with pytest.raises(ValueError, match=match):
            rig_bus.write_goals(goals)
        for name in NAMES:
            np.testing.assert_array_equal(arms.goals(name), before[name])


def test_set_torque_reaches_every_servo_of_both_arms(make_arms):
    arms = make_arms(shutdown="hold")
    with connected(RigBus(arms.buses)) as rig_bus:
        rig_bus.set_torque(False)
        assert all(v == 0 for n in NAMES for v in torques(arms.sims[n]).values())
        rig_bus.set_torque(True)
        assert all(v == 1 for n in NAMES for v in torques(arms.sims[n]).values())


# ------------------------------------------------------------------ the arms at the same time


def test_on_one_clock_a_rig_tick_takes_the_wire_time_of_one_arm_not_the_sum(make_arms):
    """Both simulated buses on ONE virtual clock, which moves only while a reply is awaited (wire model on): the
    clock time of a tick is the wire time it really took.  In turn, the two arms would take twice one's."""
    clock = VirtualClock()
    arms = make_arms(clock=clock, wire=True, shutdown="off")
    for bus in arms.buses.values():
        bus.connect()  # here, not in RigBus.connect's threads: the two arms share this clock
    rig_bus = RigBus(arms.buses)
    left, home = arms.buses["left"], np.zeros(12)

    def clock_time(tick: Callable[[], object]) -> float:
        t0 = clock.now()
        tick()
        return clock.now() - t0

    one = clock_time(lambda: (left.write_goals(home[:6]), left.read_positions()))
    in_turn = clock_time(lambda: [(b.write_goals(home[:6]), b.read_positions()) for b in arms.buses.values()])
    rig = clock_time(lambda: (rig_bus.write_goals(home), rig_bus.read_positions()))
    rig_bus.request_positions()
    pipelined = clock_time(rig_bus.collect_positions)
    rig_bus.request_positions()
    exchanged = clock_time(lambda: rig_bus.exchange(home))  # arm by arm: still one arm's wait, not two
    rig_bus.collect_positions()
    assert one > 0.001  # 1 Mbps: a sync write of 8 servos, a fast sync read and its replies, over 1 ms
    assert in_turn == pytest.approx(2 * one, rel=1e-6)
    assert rig == pytest.approx(one, rel=1e-6)
    assert 0 < pipelined < one
    assert exchanged == pytest.approx(pipelined, rel=1e-6)


class Recorder:
    """A Bus that passes every call to an arm's real bus and records when it ran: (arm, method, start, end).

    ``meet``: connect and close first wait there for the other arm's to start too (a BrokenBarrierError after
    ``timeout`` s when they run one after the other).
    """

    def __init__(self, name: str, bus: DynamixelBus, log: list[tuple[str, str, float, float]], meet: Barrier):
        self.name, self.bus, self.log, self.meet = name, bus, log, meet
        self.joint_names = bus.joint_names

    def _timed(self, method: str, *args: Any) -> Any:
        t0 = time.perf_counter()
        try:
            return getattr(self.bus, method)(*args)
        finally:
            self.log.append((self.name, method, t0, time.perf_counter()))

    def connect(self) -> None:
        self.meet.wait()
        self._timed("connect")

    def close(self) -> None:
        self.meet.wait()
        self._timed("close")

    def write_goals(self, q: np.ndarray) -> None:
        self._timed("write_goals", q)

    def read_positions(self) -> np.ndarray:
        return self._timed("read_positions")

    def request_positions(self) -> None:
        self._timed("request_positions")

    def collect_positions(self) -> np.ndarray:
        return self._timed("collect_positions")

    def exchange(self, q: np.ndarray) -> np.ndarray:
        return self._timed("exchange", q)

    def set_torque(self, enabled: bool) -> None:
        self._timed("set_torque", enabled)

    def status(self) -> Any:
        return self.bus.status()


def test_on_a_real_clock_both_arms_reads_are_in_flight_together_and_connect_and_close_run_at_once(make_arms):
    """Real clock, wire model on: in every tick each arm's read (its request's start to its collect's end)
    overlaps the other's; each arm's connect and close starts while the other's runs (they meet at a barrier)."""
    arms = make_arms(clock=MonotonicClock(), wire=True, shutdown="off")
    log: list[tuple[str, str, float, float]] = []
    meet = Barrier(2, timeout=10.0)
    rig_bus = RigBus({n: Recorder(n, arms.buses[n], log, meet) for n in NAMES})
    with connected(rig_bus):
        for _ in range(5):
            rig_bus.write_goals(np.zeros(12))
            rig_bus.read_positions()
    assert not any(s.connected for s in rig_bus.statuses().values())
    calls: dict[tuple[str, str], list[tuple[float, float]]] = {}
    for name, method, t0, t1 in log:
        calls.setdefault((name, method), []).append((t0, t1))
    assert [len(calls[n, "collect_positions"]) for n in NAMES] == [5, 5]
    for tick in range(5):
        reads = [(calls[n, "request_positions"][tick][0], calls[n, "collect_positions"][tick][1]) for n in NAMES]
        assert max(start for start, _ in reads) < min(end for _, end in reads), f"tick {tick}: reads in turn"
    assert not meet.broken


# ------------------------------------------------------------------ faults


@pytest.mark.parametrize("faulty", NAMES)
def test_a_hardware_error_on_one_arm_raises_naming_it_and_close_runs_both_shutdowns(make_arms, faulty):
    """Servo 4 (the elbow) of one arm overloads mid-run (the sim's hwerror fault); the tick's other arm still
    completes its read; close() then moves both arms to rest (the faulted joint excepted) and turns torque off."""
    arms = make_arms(shutdown="rest", faults={faulty: {"hwerror": ["4:overload@5"]}})
    rig_bus = RigBus(arms.buses)
    other = "left" if faulty == "right" else "right"
    rig_bus.connect()
    rig_bus.write_goals(np.concatenate([goals_for(arms)[n] for n in NAMES]))
    arms.advance(3.0)
    rig_bus.read_positions()
    ticks_before = arms.buses[other].status().ticks
    arms.advance(3.0)  # past the fault's time
    with pytest.raises(BusError, match=rf"^{faulty}: servo 4: hardware error: overload") as info:
        rig_bus.read_positions()
    assert info.value.ids == (4,)
    assert arms.buses[other].status().ticks == ticks_before + 1  # its read of that tick was collected
    assert rig_bus.status().hardware_errors == {4: (f"{faulty}: overload",)}
    assert rig_bus.statuses()[faulty].hardware_errors == {4: ("overload",)}
    moved = {n: arms.angles(n) for n in NAMES}
    rig_bus.close()
    rest = arms.buses[other].arm.rest
    np.testing.assert_allclose(arms.angles(other), rest, atol=0.03)
    elbow = 2
    keep = np.arange(6) != elbow
    np.testing.assert_allclose(arms.angles(faulty)[keep], rest[keep], atol=0.03)
    assert abs(arms.angles(faulty)[elbow] - moved[faulty][elbow]) < 0.03  # the faulted joint was not commanded
    assert all(v == 0 for n in NAMES for v in torques(arms.sims[n]).values())
    assert not rig_bus.status().connected


def test_a_failed_connect_of_one_arm_closes_the_other(make_arms):
    arms = make_arms(shutdown="off", faults={"right": {"unplug": ["9@0"]}})  # the right gripper never answers
    rig_bus = RigBus(arms.buses)
    on = TORQUE.to_bytes(2, "little") + b"\x01"
    with pytest.raises(BusError, match=r"^right: servo 9: no status packet from servo 9") as info:
        rig_bus.connect()
    assert info.value.ids == (9,)
    assert not arms.buses["left"].status().connected and not arms.buses["right"].status().connected
    torque_on = [e.id for e in arms.sims["left"].log if e.instruction == Instruction.WRITE and e.params == on]
    assert sorted(torque_on) == list(range(1, 10))  # left connected: torque on for its 9 servos ...
    assert all(v == 0 for v in torques(arms.sims["left"]).values())  # ... then closed: torque off


def test_close_closes_every_arm_when_one_fails_then_raises_and_is_safe_to_call_again(make_arms):
    arms = make_arms(shutdown="off")
    rig_bus = RigBus(arms.buses)
    rig_bus.connect()
    assert all(v == 1 for n in NAMES for v in torques(arms.sims[n]).values())
    arms.sims["left"].servo(9).unplug()  # the left gripper's torque off will get no reply
    with pytest.raises(BusError, match=r"^left: servo 9: could not turn torque off") as info:
        rig_bus.close()
    assert info.value.ids == (9,)
    assert all(v == 0 for v in torques(arms.sims["right"]).values())
    assert not any(s.connected for s in rig_bus.statuses().values())
    rig_bus.close()  # nothing left to close: no error
    assert not any(s.connected for s in rig_bus.statuses().values())


def test_a_rig_bus_needs_an_arm():
    with pytest.raises(ValueError, match="Expected the bus of at least one arm"):
        RigBus({})
