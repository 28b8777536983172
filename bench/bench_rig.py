"""The rig's composite bus (``retarget.rig.bus.RigBus``) against one arm's bus, on the simulator's wire-time model.

Two arms of the ``wx250s-pair`` rig (6 joints, 9 servos each: 2 shadows and the gripper), each on its own
simulated bus at 1 Mbps with the wire model on, each behind the real ``drivers.DynamixelBus``.  A tick is
``write_goals`` + ``read_positions`` (inline), or ``exchange`` (pipelined: collect, write, request, what the control
loop calls per tick, here with no compute in between; RigBus goes arm by arm in it).  Rates are the median tick's
inverse.  The target (issue 19): the rig's rate at least TARGET_RATIO of one bus's, for "two 6-servo arms": so 1. runs
again as 1b. on ``bench/koch-pair.toml`` (two Koch arms, 5 joints and the gripper, 6 servos each), checked too.

1. Out of process, real clock (the figure checked): ``retarget sim --rig wx250s-pair`` serves each arm's bus from
   its own process, replies paced in real time by their wire time (``sim.server``), and the driver opens the ports
   as it opens a real adapter: the shape of a real rig, each arm's servos on their own wire, none of their work in
   the driver's interpreter.  Loopback TCP by default (``--transport pty``: ptys): there the simulator times each
   instruction from the kernel's receive time, so a simulator process the shared machine kept waiting does not
   move its wire later (on a pty, from when it read it).  One arm's bus alone vs the RigBus over both, both modes,
   the four cases in turns (interleaved blocks, best of ``--rounds``); the ratio checked is that of the mode
   :class:`~retarget.rig.RigReplay` runs by default (``pipeline=True``).  On one arm the two modes are the same
   calls in the same cyclic order, only cut into ticks at another place, so their rates differ only by noise (an
   earlier version measured them seconds apart and read the load's drift as a gap).  On the rig they differ: inline,
   every arm's write, then every arm's request, then every arm's collect; pipelined (``RigBus.exchange``) arm by arm,
   each arm's collect, write and request together, so an arm's next write waits for no other arm's host work.  Before
   that (every arm's collect, then every arm's write, then every request) the pipelined ratio was 0.84-0.93 on this
   2-core VM; arm by arm 0.97-1.03 (five runs; the rig at 91 % of the wire-limited rate of 3.), on ptys 1.02.  With
   ``--rig``, a pair of 6-servo arms (two ``koch``, 5 joints and the gripper each, in a rig file): 0.95 and 0.99, the
   rig at 83-88 % of the wire-limited rate (943 ticks/s: shorter packets, so the host's share is larger).  Also: the
   share of the wire-limited rate (3.) reached; the fastest tenth of the inline ticks (the ticks the machine's other
   load disturbed least); the mean tick, the CPU per tick of the driver (this process) and of each arm's simulator
   process, and the cores they kept busy; how punctually each simulator sent its replies (``SimServer.pacing``: how
   many left later than 0.5 ms, i.e. the machine did not keep real time, the median and
   99th percentile lateness, the worst).  What limits 1. here: the scheduler's placement more than CPU.  Per tick
   each arm's simulator process takes ~0.5-0.6 ms of CPU, ~0.3 of it the servos' Python (``SimBus.feed``: on a warm
   cache the SYNC_WRITE of 8 goals ~115 us, the FAST_SYNC_READ ~75 us; ~1.5 x that between ticks, caches cold), the
   rest two or three wake-ups (each instruction; the timer 100 us before the reply, ~35 us of CPU each on this VM),
   the spin, the send and the loop; the driver ~0.2 ms per arm (its Python ~55 us of it on a warm cache, the rest the
   socket calls, the wake-ups they cause and cold caches).  Before the arm-by-arm exchange a rig tick was one arm's
   plus the second arm's collect, plus what the driver loses when a simulator its write or read request woke takes its
   core: Linux puts a socket's wake-up on the waker's CPU when the waker runs alone there, and a simulator's reply
   pulls the driver onto
   that simulator's CPU, so the next write to it lands there too and preempts the driver (``perf sched``, 1 s of
   pipelined rig ticks: preempted by a simulator 0.17-0.22 times per tick before the simulators' speed-up, 0.42-0.44
   after, 75-85 -> 140-150 ms of waiting per second: the leaner simulators now sleep between an arm's SYNC_WRITE and
   its read request, which the rig sends ~0.3 ms apart, and each wake-up is one more chance).  Diagnosis only (not
   something to ship): with the simulators kept off the driver's CPU (taskset) the pipelined ratio is 0.94-0.95 now,
   0.89-0.93 before.  Measured with the other workers' load (load average 0.4-1.5, 10 runs each, interleaved with
   the tree before the simulators' and the driver's speed-up, medians): CPU per rig tick driver 0.52 -> 0.51 ms,
   simulators 0.67 -> 0.59 ms each (one arm: driver 0.26 -> 0.23, simulator 0.69 -> 0.55 ms); in process (4.) the
   simulator 0.40-0.58 -> 0.26-0.28 ms, the driver and SDK 0.12-0.17 -> 0.09-0.11 ms per arm tick; one arm's
   pipelined rate 588 -> 626 ticks/s, the rig's 523 -> 523: ratio 0.89 -> 0.84 pipelined (0.80-0.97; 1 of 10 runs
   >= 0.90 either way), 0.91 -> 0.885 inline; replies later than 0.5 ms 0.2-1.9 % both.  Earlier: the simulator's
   garbage collections wait for idle moments and the driver uses its socket directly (CPU per rig tick driver 0.64 ->
   0.50 ms, simulators 1.52 -> 1.37 ms; the worst late reply 18-30 ms -> 2-8 ms).  Tried and left out: ``SPIN_S`` 40 us
   (median reply 17-20 us late, no CPU saved; 0 was worse still); the simulator yielding its core (``sched_yield``)
   on packets nobody answers (inline ratio +0.02-0.10, pipelined unchanged at moderate load, one arm's replies more
   often late); SCHED_BATCH simulators (best blocks 0.90-0.93, but 42-48 % of replies late under the other workers'
   load); the simulator deferring a SYNC_WRITE until the read request after it or 250 us (the write's preemption of
   the driver moves to the request: rig unchanged); ``epoll`` in the simulator (its millisecond timeouts make
   replies late).
2. In process, for comparison (``sim://``, the figure checked before): both simulated buses run in the driver's
   own interpreter, so the simulated servos' Python (~0.27 ms per arm per tick, 4.) competes with the driver for the
   GIL and the rig's ticks pay for both arms' simulators in turn; that measures the simulator more than the bus,
   hence the check on 1.  Also the same ticks with each arm's calls in its own worker thread (the design RigBus
   does not use on its tick path: see its module docstring).
3. Wire time only: the same ticks with both simulated buses on ONE shared VirtualClock, which moves only while a
   reply is awaited: the rate the wires allow, host work excluded.  Shows the two arms' packets overlap.
4. Host CPU per tick in process (wire model off, real clock), and the simulator's share of it (time inside
   ``SimBus.feed``), with an estimate without the simulator (3.'s wire time plus the driver's part).  Last, what a
   call to each arm's worker thread and back costs (RigBus's workers, used for connect, close and set_torque)
   against a ThreadPoolExecutor.

Run: ``python bench/bench_rig.py [--ticks N] [--rounds R] [--transport tcp|pty] [--rig NAME|FILE]
[--six-servo-rig NAME|FILE]`` (about 35 s with the defaults).
Exit status 1 when the default mode's ratio in 1. or 1b. misses TARGET_RATIO.
"""

from __future__ import annotations

import argparse
import inspect
import os
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from functools import partial
from pathlib import Path
from typing import IO, Any

import numpy as np

import sim
from drivers import DynamixelBus
from retarget.control.clock import Clock, MonotonicClock, VirtualClock
from retarget.rig import RigReplay, load_rig
from retarget.rig.bus import RigBus
from sim.faults import Faults

FAST_QUANTILE = 0.1  #: 1.'s second figure: the rates of the fastest tenth of the ticks
TARGET_RATIO = 0.9  #: rig rate / one bus's rate, out of process, real clock, in RigReplay's default mode
#: the issue's "two 6-servo arms": two Koch arms (bench_rig.py checks 1. on it too)
SIX_SERVO_RIG = Path(__file__).resolve().parent / "koch-pair.toml"
#: RigReplay's default tick mode (True: pipelined read-back), whose ratio is checked
DEFAULT_PIPELINE = bool(inspect.signature(RigReplay).parameters["pipeline"].default)
Tick = Callable[[int], None]


def _median_tick(
    tick: Tick, ticks: int, clock: Callable[[], float] = time.perf_counter, *, quantile: float = 0.5
) -> float:
    """Median seconds of one tick on ``clock`` over ``ticks`` ticks after a warm-up (``quantile``: another one,
    e.g. 0.1 for the fastest tenth's bound)."""
    for k in range(30):
        tick(k)
    samples = []
    for k in range(ticks):
        t0 = clock()
        tick(k)
        samples.append(clock() - t0)
    if quantile == 0.5:
        return statistics.median(samples)
    return float(np.quantile(samples, quantile))


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
def arms(rig_name: str, *, wire: bool, shared_clock: Clock | None = None
         ) -> Iterator[tuple[dict[str, DynamixelBus], _Timed]]:  # fmt: skip
    """The rig's arms, each a connected DynamixelBus on its own simulated bus (real clock, or ``shared_clock``);
    closed afterwards (shutdown OFF)."""
    rig = load_rig(rig_name)
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


@contextmanager
def served_arms(rig_name: str, transport: str) -> Iterator[tuple[dict[str, DynamixelBus], list[int], IO[str]]]:
    """The rig's arms served by ``retarget sim --rig`` (one process per arm, wire model on, real clock) on ptys or
    loopback TCP, each a connected DynamixelBus on its port: (buses, the arm processes' pids, the server's stderr,
    a file read once it stopped).  Closed and stopped afterwards (shutdown OFF)."""
    where_tcp = ["--tcp", "127.0.0.1:0"] if transport == "tcp" else []
    err = tempfile.TemporaryFile("w+")  # a file, not a pipe: a chatty server never blocks on it
    argv = [sys.executable, "-m", "retarget", "sim", "--rig", rig_name, *where_tcp]
    server = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=err, text=True)
    buses: dict[str, DynamixelBus] = {}
    try:
        assert server.stdout is not None
        rig = load_rig(rig_name)
        ports = dict(server.stdout.readline().strip().partition("=")[::2] for _ in rig.arms)
        for rig_arm in rig.arms:
            port = ports[rig_arm.name]
            buses[rig_arm.name] = DynamixelBus(rig_arm.arm, port, shutdown="off", check_latency=False)
        for bus in buses.values():
            bus.connect()
        yield buses, _children(server.pid, len(ports)), err
    finally:
        for bus in buses.values():
            bus.close()
        server.terminate()
        server.wait(timeout=10)
        err.seek(0)


def _children(pid: int, n: int) -> list[int]:
    """The ``n`` child processes of ``pid`` (Linux /proc; empty where it cannot be read)."""
    children = Path(f"/proc/{pid}/task/{pid}/children")
    for _ in range(100):
        try:
            pids = [int(p) for p in children.read_text().split()]
        except OSError:
            return []
        if len(pids) >= n:
            return pids
        time.sleep(0.02)
    return []


def _cpu_seconds(pid: int) -> float:
    """CPU seconds (user + system) process ``pid`` used so far (Linux /proc); nan where it cannot be read."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rpartition(")")[2].split()
    except OSError:
        return float("nan")
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def cpu_per_tick(tick: Tick, ticks: int, pids: list[int]) -> tuple[float, float, list[float]]:
    """(wall seconds per tick, this process's CPU seconds per tick, each of ``pids``' CPU seconds per tick), means
    over ``ticks`` ticks."""
    before, c0, t0 = [_cpu_seconds(p) for p in pids], time.process_time(), time.perf_counter()
    for k in range(ticks):
        tick(k)
    wall, driver = (time.perf_counter() - t0) / ticks, (time.process_time() - c0) / ticks
    return wall, driver, [(_cpu_seconds(p) - b) / ticks for p, b in zip(pids, before, strict=True)]


def _ticks(bus: Any, home: np.ndarray) -> tuple[Tick, Tick, Callable[[], None]]:
    """(inline tick, pipelined tick, end of the pipelined ticks) on ``bus``: small moves around ``home`` rad."""
    wiggle = 0.02 * np.sin(np.arange(200) * 0.1)
    in_flight = [False]

    def inline(k: int) -> None:
        bus.write_goals(home + wiggle[k % 200])
        bus.read_positions()

    def pipelined(k: int) -> None:  # as the control loop's PipelinedReadBack
        if in_flight[0]:
            bus.exchange(home + wiggle[k % 200])
            return
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
                      rounds: int, quantile: float = 0.5) -> tuple[list[float], list[float]]:  # fmt: skip
    """([inline, pipelined] of ``one``, the same of ``rig``) ticks per second, each the best of ``rounds`` blocks
    of ``ticks`` ticks: the four cases take turns block by block, in an order that alternates, so that a load the
    shared machine carries for a while falls on all of them alike (one block after the other, as ``_rates`` runs
    them, a pipelined figure measured in a busier second than its inline one differs for no reason of its own).
    A block's rate is its median tick's inverse (``quantile``: that of another quantile of its ticks)."""
    cases = [(one, one_home, 0), (one, one_home, 1), (rig, rig_home, 0), (rig, rig_home, 1)]
    best = [0.0] * 4
    for r in range(rounds):
        for k in range(4) if r % 2 == 0 else reversed(range(4)):
            bus, home, mode = cases[k]
            modes = _ticks(bus, home)
            best[k] = max(best[k], 1.0 / _median_tick(modes[mode], ticks, quantile=quantile))
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

    def exchange(self, q: np.ndarray) -> np.ndarray:
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


def _print_rates(title: str, one: list[float], rig: list[float]) -> list[float]:
    """Print one arm's and the rig's [inline, pipelined] rates and their ratios; returns the ratios."""
    print(f"{title:62s}inline    pipelined  (ticks/s)")
    print(f"   one arm's bus                                 {one[0]:8.0f}  {one[1]:8.0f}")
    print(f"   RigBus over both arms                         {rig[0]:8.0f}  {rig[1]:8.0f}")
    ratios = [r / o for r, o in zip(rig, one, strict=True)]
    print(f"   ratio                                         {ratios[0]:8.2f}  {ratios[1]:8.2f}")
    return ratios


def out_of_process(
    rig_name: str, transport: str, ticks: int, rounds: int
) -> tuple[list[float], list[float], list[str], str]:
    """1.: ([inline, pipelined] of one arm, the same of the rig), the CPU lines, the servers' pacing lines."""
    with served_arms(rig_name, transport) as (buses, pids, err):
        left, rig_bus = buses["left"], RigBus(buses)
        home = np.concatenate([b.arm.home for b in buses.values()])
        one, rig = interleaved_rates(left, left.arm.home, rig_bus, home, max(50, ticks // rounds), rounds)
        fast = interleaved_rates(left, left.arm.home, rig_bus, home, max(50, ticks // rounds), 2, FAST_QUANTILE)
        cpu = [  # inline only: a pipelined tick's length depends on where the last one cut, its quantiles do not
            f"   the fastest tenth of the inline ticks (their {FAST_QUANTILE:.0%} quantile, best of 2): one arm "
            f"{fast[0][0]:.0f}, rig {fast[1][0]:.0f} ticks/s, ratio {fast[1][0] / fast[0][0]:.2f} (the ticks other "
            "load disturbed least)",
            "   1.'s inline ticks, means (ms):     tick  driver    simulators     cores busy",
        ]
        for name, bus, q in (("one arm's bus", left, left.arm.home), ("RigBus over both arms", rig_bus, home)):
            wall, driver, servers = cpu_per_tick(_ticks(bus, q)[0], ticks // 2, pids)
            sims = ", ".join(f"{1e3 * c:.2f}" for c in servers) or "n/a"
            busy = (driver + sum(servers)) / wall  # cores kept busy on average
            cpu.append(f"   {name:34s}{1e3 * wall:6.2f}  {1e3 * driver:6.2f}    {sims:12s}   {busy:4.2f}")
    pacing = [line.strip() for line in err.read().splitlines() if "replies" in line]
    return one, rig, cpu, "\n".join(f"   {line}" for line in pacing)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--ticks", type=int, default=600, help="timed ticks per measurement (default 600)")
    parser.add_argument("--rounds", type=int, default=4, help="interleaved blocks per case in 1. and 2. (default 4)")
    parser.add_argument("--transport", choices=("pty", "tcp"), default="tcp", help="1.'s ports (default tcp)")
    parser.add_argument("--rig", default="wx250s-pair", help="a bundled rig or a rig file (default wx250s-pair)")
    parser.add_argument("--six-servo-rig", default=str(SIX_SERVO_RIG), metavar="NAME|FILE",
                        help="1. again on this rig, checked too ('': not; default bench/koch-pair.toml)")  # fmt: skip
    args = parser.parse_args()
    n = args.ticks
    load = ", ".join(f"{x:.1f}" for x in os.getloadavg())
    print(f"{os.cpu_count()} cores, load average {load}; each arm on its own simulated bus at 1 Mbps")
    default = 1 if DEFAULT_PIPELINE else 0  #: the mode RigReplay runs by default: the figure checked
    ok = True
    for k, rig_name in enumerate(r for r in (args.rig, args.six_servo_rig) if r):
        servos = ", ".join(f"{a.name} {a.arm.name} {len(a.arm.servo_ids)}" for a in load_rig(rig_name).arms)
        one_r, rig_r, cpu_r, pacing_r = out_of_process(rig_name, args.transport, n, args.rounds)
        print(f"1{'b' if k else ''}. {Path(rig_name).stem}, servos per arm: {servos}")
        ratios = _print_rates(f"   out of process ({args.transport}), wire model in real time, best of {args.rounds}",
                              one_r, rig_r)  # fmt: skip
        ok = ok and ratios[default] >= TARGET_RATIO
        print(f"   checked: RigReplay's default, {('inline', 'pipelined')[default]}: ratio {ratios[default]:.2f} "
              f"(target >= {TARGET_RATIO:.2f})   {'ok' if ratios[default] >= TARGET_RATIO else 'MISSED'}")  # fmt: skip
        if k == 0:
            one_o, rig_o, cpu_o, pacing = one_r, rig_r, cpu_r, pacing_r  # 2.-4. are on --rig

    with arms(args.rig, wire=True) as (buses, _):
        left, rig_bus = buses["left"], RigBus(buses)
        home = np.concatenate([b.arm.home for b in buses.values()])
        one, rig = interleaved_rates(left, left.arm.home, rig_bus, home, max(50, n // args.rounds), args.rounds)
        threads = threaded_inline(rig_bus, n)
    _print_rates(f"2. in process (sim://), for comparison, best of {args.rounds}", one, rig)
    print(f"   each arm in its own thread (not used)         {threads:8.0f}            ratio {threads / one[0]:.2f}")

    clock = VirtualClock()
    with arms(args.rig, wire=True, shared_clock=clock) as (buses, _):
        left, rig_bus = buses["left"], RigBus(buses)
        one_v = _rates(left, left.arm.home, n // 4, clock.now)
        rig_v = _rates(rig_bus, np.concatenate([b.arm.home for b in buses.values()]), n // 4, clock.now)
    print("3. wire time only (one shared virtual clock)")
    print(f"   one arm's bus                                 {one_v[0]:8.0f}  {one_v[1]:8.0f}")
    print(f"   RigBus over both arms                         {rig_v[0]:8.0f}  {rig_v[1]:8.0f}"
          f"   ratio {rig_v[0] / one_v[0]:.2f}, {rig_v[1] / one_v[1]:.2f}")  # fmt: skip
    print(f"   1. reached: one arm {one_o[default] / one_v[default]:.0%}, rig {rig_o[default] / rig_v[default]:.0%} "
          "of the wire-limited rate")  # fmt: skip
    print("\n".join(cpu_o))
    print(pacing or "   (no pacing record from the simulator)")

    with arms(args.rig, wire=False) as (buses, timed):
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
    print("4. in process: host CPU per inline tick, wire model off, mean (ms)   total  simulator  driver+SDK")
    for name, (total, in_sim) in zip(("one arm's bus", "RigBus over both arms"), cpu, strict=True):
        print(f"   {name:40s}   {1e3 * total:8.2f}  {1e3 * in_sim:8.2f}  {1e3 * (total - in_sim):8.2f}")
    # servos on their own wires (hardware): the wire time of 3. plus the host's own work of 4., added up as if
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
