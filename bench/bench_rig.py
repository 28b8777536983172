"""The rig's composite bus (``retarget.rig.bus.RigBus``) against one arm's bus, on the simulator's wire-time model.

Two arms of the ``wx250s-pair`` rig (6 joints, 9 servos each: 2 shadows and the gripper), each on its own
in-process simulated bus at 1 Mbps (``sim://``, wire model on), each behind the real ``drivers.DynamixelBus``.
A tick is ``write_goals`` + ``read_positions`` (inline), or ``collect_positions`` + ``write_goals`` +
``request_positions`` (pipelined: what the control loop calls per tick, here with no compute in between).
Rates are the median tick's inverse.

1. Real clock: one arm's bus alone vs the RigBus over both, in both modes, the four cases measured in turns
   (interleaved blocks, best of ``--rounds``); the ratio checked against TARGET_RATIO is that of the mode
   :class:`~retarget.rig.RigReplay` runs by default (``pipeline=True``: pipelined).  With nothing computed between
   the calls, the two modes are the same calls in the same cyclic order (write A, write B, request A, request B,
   collect A, collect B, write A, ...), only cut into ticks at another place, so their rates may differ only by
   noise; an earlier version measured all inline figures first and all pipelined ones some seconds later, and on a
   shared machine read the load's drift as a gap between the modes (0.92 inline vs 0.79 pipelined).  What
   pipelining buys (the replies arrive while the loop computes the next tick) needs compute between the calls,
   which this bench leaves out: ``bench_replay.py`` measures it on the loop.  For comparison, the same ticks with
   each arm's calls in its own worker thread (the design RigBus does not use on its tick path: see its module
   docstring).
2. Wire time only: the same ticks with both simulated buses on ONE shared VirtualClock, which moves only while a
   reply is awaited: the rate the wires allow, host work excluded.  Shows the two arms' packets overlap.
3. Host CPU per tick (wire model off, real clock), and the simulator's share of it (time inside ``SimBus.feed``):
   in process, the simulated servos' Python runs on the host's interpreter, which the two arms share, so 1.
   measures the simulator more than the bus; with servos on their own wires the host does only the driver's part
   (the last line: 2.'s wire time plus that part, an estimate).  Last, what a call to each arm's worker thread
   and back costs (RigBus's workers, used for connect, close and set_torque) against a ThreadPoolExecutor.

Run: ``python bench/bench_rig.py [--ticks N] [--rounds R]`` (about 15 s with the defaults).  Exit status 1 when
the default mode's ratio in 1. misses TARGET_RATIO.
"""

from __future__ import annotations

import argparse
import inspect
import statistics
import time
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from functools import partial
from typing import Any

import numpy as np

import sim
from drivers import DynamixelBus
from retarget.control.clock import Clock, MonotonicClock, VirtualClock
from retarget.rig import RigReplay, load_rig
from retarget.rig.bus import RigBus
from sim.faults import Faults

TARGET_RATIO = 0.9  #: rig rate / one bus's rate, real clock, in the mode RigReplay runs by default
#: RigReplay's default tick mode (True: pipelined read-back), whose ratio is checked
DEFAULT_PIPELINE = bool(inspect.signature(RigReplay).parameters["pipeline"].default)
Tick = Callable[[int], None]


def _median_tick(tick: Tick, ticks: int, clock: Callable[[], float] = time.perf_counter) -> float:
    """Median seconds of one tick on ``clock`` over ``ticks`` ticks after a warm-up."""
    for k in range(30):
        tick(k)
    samples = []
    for k in range(ticks):
        t0 = clock()
        tick(k)
        samples.append(clock() - t0)
    return statistics.median(samples)


class _Timed:
    """Wraps ``SimBus.feed`` of some buses: the real seconds spent inside (the simulated servos' own work)."""

    def __init__(self, simbuses: list[sim.SimBus]):
        self.seconds = 0.0
        for simbus in simbuses:
            simbus.feed = self._timed(simbus.feed)

    def _timed(self, feed: Callable[..., Any]) -> Callable[..., Any]:
        def timed(*args: Any, **kwargs: Any) -> Any:
            t0 = time.perf_counter()
            try:
                return feed(*args, **kwargs)
            finally:
                self.seconds += time.perf_counter() - t0

        return timed


@contextmanager
def arms(*, wire: bool, shared_clock: Clock | None = None) -> Iterator[tuple[dict[str, DynamixelBus], _Timed]]:
    """The rig's arms, each a connected DynamixelBus on its own simulated bus (real clock, or ``shared_clock``);
    closed afterwards (shutdown OFF)."""
    rig = load_rig("wx250s-pair")
    urls, simbuses, buses = [], [], {}
    for rig_arm in rig.arms:
        clock = shared_clock if shared_clock is not None else MonotonicClock()
        simbuses.append(sim.SimBus.from_arm(rig_arm.arm, clock=clock, faults=Faults(wire=wire)))
        urls.append(sim.attach(simbuses[-1]))
        buses[rig_arm.name] = DynamixelBus(rig_arm.arm, urls[-1], shutdown="off", check_latency=False, clock=clock)
    try:
        for bus in buses.values():
            bus.connect()
        yield buses, _Timed(simbuses)
    finally:
        for bus in buses.values():
            bus.close()
        for url in urls:
            sim.unregister(url)


def _ticks(bus: Any, home: np.ndarray) -> tuple[Tick, Tick, Callable[[], None]]:
    """(inline tick, pipelined tick, end of the pipelined ticks) on ``bus``: small moves around ``home`` rad."""
    wiggle = 0.02 * np.sin(np.arange(200) * 0.1)
    in_flight = [False]

    def inline(k: int) -> None:
        bus.write_goals(home + wiggle[k % 200])
        bus.read_positions()

    def pipelined(k: int) -> None:
        if in_flight[0]:
            bus.collect_positions()
        bus.write_goals(home + wiggle[k % 200])
        bus.request_positions()
        in_flight[0] = True

    def end() -> None:
        if in_flight[0]:
            bus.collect_positions()
            in_flight[0] = False

    return inline, pipelined, end


def _rates(bus: Any, home: np.ndarray, ticks: int, clock: Callable[[], float] = time.perf_counter) -> list[float]:
    """[inline, pipelined] ticks per second on ``bus``."""
    inline, pipelined, end = _ticks(bus, home)
    out = [1.0 / _median_tick(inline, ticks, clock), 1.0 / _median_tick(pipelined, ticks, clock)]
    end()
    return out


def interleaved_rates(one: Any, one_home: np.ndarray, rig: Any, rig_home: np.ndarray, ticks: int,
                      rounds: int) -> tuple[list[float], list[float]]:  # fmt: skip
    """([inline, pipelined] of ``one``, the same of ``rig``) ticks per second, each the best of ``rounds`` blocks
    of ``ticks`` ticks: the four cases take turns block by block, in an order that alternates, so that a load the
    shared machine carries for a while falls on all of them alike (one block after the other, as ``_rates`` runs
    them, a pipelined figure measured in a busier second than its inline one differs for no reason of its own)."""
    cases = [(one, one_home, 0), (one, one_home, 1), (rig, rig_home, 0), (rig, rig_home, 1)]
    best = [0.0] * 4
    for r in range(rounds):
        for k in range(4) if r % 2 == 0 else reversed(range(4)):
            bus, home, mode = cases[k]
            modes = _ticks(bus, home)
            best[k] = max(best[k], 1.0 / _median_tick(modes[mode], ticks))
            modes[2]()
    return best[:2], best[2:]


def threaded_inline(rig_bus: RigBus, ticks: int) -> float:
    """Ticks/s of the inline tick with each arm's calls in its worker thread (RigBus's workers, private API)."""
    home = np.concatenate([b.arm.home for b in rig_bus.buses.values()])

    def tick(k: int) -> None:
        parts = rig_bus.split(home + 0.01 * (k % 2))
        rig_bus._run([partial(b.write_goals, parts[n]) for n, b in rig_bus.buses.items()])
        rig_bus._run([b.read_positions for b in rig_bus.buses.values()])

    try:
        return 1.0 / _median_tick(tick, ticks)
    finally:
        rig_bus._stop()


class _Idle:
    """A bus whose calls do nothing: what is left is the cost of getting a call to a thread and back."""

    joint_names = ("a", "b", "c", "d", "e", "f")

    def write_goals(self, q: np.ndarray) -> None: ...
    def read_positions(self) -> np.ndarray:
        return np.zeros(6)

    def request_positions(self) -> None: ...
    def collect_positions(self) -> np.ndarray:
        return np.zeros(6)


def handoff_us(ticks: int) -> tuple[float, float]:
    """(RigBus workers, ThreadPoolExecutor): median microseconds of one call to two idle buses' threads and back."""
    idle = [_Idle(), _Idle()]
    rig_bus = RigBus({"left": idle[0], "right": idle[1]})
    reads = [b.read_positions for b in idle]
    try:
        workers = _median_tick(lambda k: rig_bus._run(reads), ticks)
    finally:
        rig_bus._stop()
    with ThreadPoolExecutor(max_workers=2) as pool:
        pooled = _median_tick(lambda k: [f.result() for f in [pool.submit(r) for r in reads]], ticks)
    return 1e6 * workers, 1e6 * pooled


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--ticks", type=int, default=600, help="timed ticks per measurement (default 600)")
    parser.add_argument("--rounds", type=int, default=4, help="interleaved blocks per case in 1. (default 4)")
    args = parser.parse_args()
    n = args.ticks
    print("wx250s-pair: 2 arms x 9 servos, each arm on its own simulated bus at 1 Mbps")

    with arms(wire=True) as (buses, _):
        left, rig_bus = buses["left"], RigBus(buses)
        home = np.concatenate([b.arm.home for b in buses.values()])
        one, rig = interleaved_rates(left, left.arm.home, rig_bus, home, max(50, n // args.rounds), args.rounds)
        threads = threaded_inline(rig_bus, n)
    default = 1 if DEFAULT_PIPELINE else 0  #: the mode RigReplay runs by default: the figure checked
    print(f"1. real clock, wire model on, best of {args.rounds} interleaved blocks    inline    pipelined  (ticks/s)")
    print(f"   one arm's bus                                 {one[0]:8.0f}  {one[1]:8.0f}")
    print(f"   RigBus over both arms                         {rig[0]:8.0f}  {rig[1]:8.0f}")
    ratios = [r / o for r, o in zip(rig, one, strict=True)]
    ok = ratios[default] >= TARGET_RATIO
    print(f"   ratio                                         {ratios[0]:8.2f}  {ratios[1]:8.2f}")
    print(f"   checked: RigReplay's default, {('inline', 'pipelined')[default]}: ratio {ratios[default]:.2f} "
          f"(target >= {TARGET_RATIO:.2f})   {'ok' if ok else 'MISSED'}")  # fmt: skip
    print(f"   each arm in its own thread (not used)         {threads:8.0f}            ratio {threads / one[0]:.2f}")

    clock = VirtualClock()
    with arms(wire=True, shared_clock=clock) as (buses, _):
        left, rig_bus = buses["left"], RigBus(buses)
        one_v = _rates(left, left.arm.home, n // 4, clock.now)
        rig_v = _rates(rig_bus, np.concatenate([b.arm.home for b in buses.values()]), n // 4, clock.now)
    print("2. wire time only (one shared virtual clock)")
    print(f"   one arm's bus                                 {one_v[0]:8.0f}  {one_v[1]:8.0f}")
    print(f"   RigBus over both arms                         {rig_v[0]:8.0f}  {rig_v[1]:8.0f}"
          f"   ratio {rig_v[0] / one_v[0]:.2f}, {rig_v[1] / one_v[1]:.2f}")  # fmt: skip

    with arms(wire=False) as (buses, timed):
        left, rig_bus = buses["left"], RigBus(buses)
        home = np.concatenate([b.arm.home for b in buses.values()])
        cpu = []
        for bus, q in ((left, left.arm.home), (rig_bus, home)):
            inline, _, _ = _ticks(bus, q)
            inline(0)
            timed.seconds, t0 = 0.0, time.perf_counter()
            for k in range(n):
                inline(k)
            cpu.append(((time.perf_counter() - t0) / n, timed.seconds / n))
    print("3. host CPU per inline tick, wire model off, mean (ms)      total  simulator  driver+SDK")
    for name, (total, in_sim) in zip(("one arm's bus", "RigBus over both arms"), cpu, strict=True):
        print(f"   {name:40s}   {1e3 * total:8.2f}  {1e3 * in_sim:8.2f}  {1e3 * (total - in_sim):8.2f}")
    # servos on their own wires (hardware): the wire time of 2. plus the host's own work of 3., added up as if
    # none of it overlapped the wire (a floor for both rates)
    one_p, rig_p = (1.0 / (1.0 / one_v[0] + total - in_sim) for total, in_sim in cpu)
    print(f"   without the simulator's work (wire time + driver and SDK, not overlapped): one arm {one_p:.0f}, "
          f"rig {rig_p:.0f} ticks/s, ratio {rig_p / one_p:.2f}")  # fmt: skip

    rig_us, pool_us = handoff_us(n)
    print(f"   a call to two idle buses' threads and back: RigBus workers {rig_us:.0f} us, "
          f"ThreadPoolExecutor {pool_us:.0f} us")  # fmt: skip
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
