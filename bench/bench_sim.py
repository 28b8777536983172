"""Simulator cost and the wire-time model.

1. Python overhead of one 6-servo control tick through dynamixel-sdk against the simulator, wire model off and
   Return Delay Time 0: GroupSyncWrite.txPacket (Goal Position, 4 bytes) + GroupSyncRead.txRxPacket (Present
   Position) or .fastSyncRead, over the in-process ``sim://`` port and over a pty served by ``sim.server``
   (the plain ``dynamixel_sdk.PortHandler``).  Real clock.
2. The wire-time model at 1 Mbps: the same tick on a VirtualClock bus with ``wire=1`` spends exactly the
   computed wire time (10 bits/byte, both directions, plus the Return Delay Time of each reply).
3. ``retarget sim``'s pty as a client sees it (informational): a PING round trip at 57600 baud through the plain
   ``PortHandler`` with the wire model (the CLI default) and without (``--no-wire``), against the computed wire
   time; and how many packets a client loses that writes then ``tcflush(TCOFLUSH)``es after a delay (pypot's
   pattern; a kernel race on ptys, see ``sim.server``), from a separate process.

Run: ``python bench/bench_sim.py [--ticks N]``.  Prints median and p95 per tick against TARGET_*.
"""

from __future__ import annotations

import argparse
import statistics
import time

from dynamixel_sdk import COMM_SUCCESS, GroupSyncRead, GroupSyncWrite, PacketHandler, PortHandler

import sim
from drivers.control_table import common_register
from drivers.port import UrlPortHandler  # the SDK port on any pyserial URL, as the driver opens it
from retarget.control.clock import MonotonicClock, VirtualClock
from sim.faults import Faults, wire_time
from sim.server import PtyServer

TARGET_INPROC_MS = 1.0  #: median tick over the in-process port (sync write + sync read, 6 servos)
TARGET_PTY_MS = 2.0  #: median tick over a pty
TARGET_WIRE_ERROR_US = 1.0  #: |modelled - computed| wire time per tick
IDS = tuple(range(1, 7))
GOAL, PRESENT = (common_register(n).address for n in ("Goal Position", "Present Position"))


def _stats(samples: list[float]) -> tuple[float, float]:
    ordered = sorted(samples)
    return statistics.median(ordered), ordered[int(0.95 * (len(ordered) - 1))]


def _tick_fn(port: PortHandler, *, fast: bool):
    ph = PacketHandler(2.0)
    write = GroupSyncWrite(port, ph, GOAL, 4)
    read = GroupSyncRead(port, ph, PRESENT, 4)
    for i in IDS:
        write.addParam(i, list((2048).to_bytes(4, "little")))
        read.addParam(i)
    receive = read.fastSyncRead if fast else read.txRxPacket

    def tick(k: int) -> None:
        goal = list((2048 + (k % 100)).to_bytes(4, "little"))
        for i in IDS:
            write.changeParam(i, goal)
        if write.txPacket() != COMM_SUCCESS or receive() != COMM_SUCCESS:
            raise RuntimeError("tick failed")
        read.getData(IDS[0], PRESENT, 4)

    return tick


def _time_ticks(tick, ticks: int) -> list[float]:
    for k in range(50):  # warm up
        tick(k)
    samples = []
    for k in range(ticks):
        t0 = time.perf_counter()
        tick(k)
        samples.append(time.perf_counter() - t0)
    return samples


def bench_inproc(ticks: int, *, fast: bool) -> list[float]:
    bus = sim.SimBus.from_ids(IDS, "XM430-W350", clock=MonotonicClock(), return_delay_time=0)
    url = sim.register("bench", bus)
    port = UrlPortHandler(url)
    port.openPort()
    try:
        return _time_ticks(_tick_fn(port, fast=fast), ticks)
    finally:
        port.closePort()
        sim.unregister("bench")


def bench_pty(ticks: int, *, fast: bool) -> list[float]:
    bus = sim.SimBus.from_ids(IDS, "XM430-W350", clock=MonotonicClock(), return_delay_time=0)
    with PtyServer(bus) as server:
        port = PortHandler(server.path)
        port.setBaudRate(1_000_000)
        try:
            return _time_ticks(_tick_fn(port, fast=fast), ticks)
        finally:
            port.closePort()


def wire_model(rdt: int, *, fast: bool) -> tuple[float, float]:
    """(modelled, computed) seconds of one tick at 1 Mbps with Return Delay Time ``rdt`` (2 us units)."""
    clock = VirtualClock()
    bus = sim.SimBus.from_ids(IDS, "XM430-W350", clock=clock, return_delay_time=rdt, faults=Faults(wire=True))
    port = UrlPortHandler(sim.register("wire", bus))
    port.openPort()
    try:
        tick = _tick_fn(port, fast=fast)
        tick(0)
        t0 = clock.now()
        tick(1)
        modelled = clock.now() - t0
    finally:
        port.closePort()
        sim.unregister("wire")
    n = len(IDS)
    write_bytes = 14 + n * 5  # header..LEN, INST, addr, len, (ID + 4 bytes) each, CRC
    read_request = 14 + n
    delay = rdt * 2e-6
    if fast:
        replies = wire_time(8 + n * (4 + 4), 1_000_000) + delay
    else:
        replies = n * (wire_time(15, 1_000_000) + delay)
    computed = wire_time(write_bytes, 1_000_000) + wire_time(read_request, 1_000_000) + replies
    return modelled, computed


def wire_real(ticks: int) -> list[float]:
    """Ticks on a real clock with the wire model on, RDT 250: the computed wire time plus Python overhead."""
    bus = sim.SimBus.from_ids(IDS, "XM430-W350", clock=MonotonicClock(), faults=Faults(wire=True))
    port = UrlPortHandler(sim.register("wire-real", bus))
    port.openPort()
    try:
        return _time_ticks(_tick_fn(port, fast=False), ticks)
    finally:
        port.closePort()
        sim.unregister("wire-real")


def pty_ping(wire: bool, pings: int) -> list[float]:
    """Real seconds per PING round trip at 57600 baud over a pty (plain PortHandler), RDT 250 (the factory value)."""
    bus = sim.SimBus.from_ids([1], "XL430-W250", clock=MonotonicClock(), baud=57600, faults=Faults(wire=wire))
    with PtyServer(bus) as server:
        port, ph = PortHandler(server.path), PacketHandler(2.0)
        port.setBaudRate(57600)
        try:
            samples = []
            for _ in range(pings):
                t0 = time.perf_counter()
                if ph.ping(port, 1)[1] != COMM_SUCCESS:
                    raise RuntimeError("ping failed")
                samples.append(time.perf_counter() - t0)
            return samples
        finally:
            port.closePort()


_FLUSH_CLIENT = """
import os, sys, termios, time, tty, select
fd = os.open(sys.argv[1], os.O_RDWR | os.O_NOCTTY)
tty.setraw(fd)
attrs = termios.tcgetattr(fd)
attrs[4] = attrs[5] = termios.B1000000
termios.tcsetattr(fd, termios.TCSANOW, attrs)
ping, gap, got = bytes.fromhex("fffffd0001030001194e"), float(sys.argv[3]), 0
for _ in range(int(sys.argv[2])):
    os.write(fd, ping)
    end = time.perf_counter() + gap
    while time.perf_counter() < end:
        pass
    termios.tcflush(fd, termios.TCOFLUSH)
    data, deadline = b"", time.monotonic() + 0.05
    while len(data) < 14 and time.monotonic() < deadline:
        if select.select([fd], [], [], 0.01)[0]:
            data += os.read(fd, 64)
    got += len(data) >= 14
print(got)
"""


def flush_loss(gap: float, packets: int) -> float:
    """Share of PINGs lost by a client (another process) that flushes its output ``gap`` s after each write."""
    import subprocess
    import sys

    bus = sim.SimBus.from_ids([1], "XL430-W250", clock=MonotonicClock(), return_delay_time=0)
    with PtyServer(bus) as server:
        out = subprocess.run([sys.executable, "-c", _FLUSH_CLIENT, server.path, str(packets), str(gap)],
                             capture_output=True, text=True, check=True).stdout  # fmt: skip
    return 1.0 - int(out) / packets


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--ticks", type=int, default=500, help="timed ticks per case (default 500)")
    args = parser.parse_args()
    ok = True
    print(f"6-servo tick (sync write + read), wire model off, RDT 0, {args.ticks} ticks, real clock")
    for name, fn, target in (("in-process", bench_inproc, TARGET_INPROC_MS), ("pty", bench_pty, TARGET_PTY_MS)):
        for fast in (False, True):
            median, p95 = _stats(fn(args.ticks, fast=fast))
            passed = median * 1e3 <= target
            ok &= passed
            label = f"{name} {'fast sync read' if fast else 'sync read'}"
            print(
                f"  {label:<28} median {median * 1e3:6.3f} ms  p95 {p95 * 1e3:6.3f} ms  "
                f"target median <= {target} ms  {'PASS' if passed else 'FAIL'}"
            )
    print("wire model at 1 Mbps (VirtualClock): modelled vs computed tick time")
    for rdt in (0, 250):
        for fast in (False, True):
            modelled, computed = wire_model(rdt, fast=fast)
            error_us = abs(modelled - computed) * 1e6
            passed = error_us <= TARGET_WIRE_ERROR_US
            ok &= passed
            label = f"RDT {rdt:>3} {'fast sync read' if fast else 'sync read'}"
            print(
                f"  {label:<28} modelled {modelled * 1e3:6.3f} ms  computed {computed * 1e3:6.3f} ms  "
                f"error {error_us:5.2f} us  target <= {TARGET_WIRE_ERROR_US} us  {'PASS' if passed else 'FAIL'}"
            )
    modelled, computed = wire_model(250, fast=False)
    median, p95 = _stats(wire_real(max(50, args.ticks // 5)))
    print(
        f"  real clock, RDT 250 sync read median {median * 1e3:6.3f} ms  p95 {p95 * 1e3:6.3f} ms  "
        f"(computed wire time {computed * 1e3:.3f} ms + Python overhead; informational)"
    )
    print("retarget sim's pty at 57600 baud (informational): PING round trip, plain PortHandler, RDT 250")
    computed = wire_time(10 + 14, 57600) + 250 * 2e-6
    for wire in (True, False):
        median, p95 = _stats(pty_ping(wire, max(20, args.ticks // 10)))
        label = "wire model (default)" if wire else "--no-wire"
        times = f"median {median * 1e3:6.3f} ms  p95 {p95 * 1e3:6.3f} ms"
        print(f"  {label:<28} {times}  (wire time {computed * 1e3:.3f} ms)")
    print("write then tcflush(TCOFLUSH) from another process (informational; a pty kernel race, see sim.server)")
    for gap in (0.0, 20e-6, 100e-6, 500e-6):
        print(f"  flush {gap * 1e6:5.0f} us after the write: {100 * flush_loss(gap, 200):5.1f} % of 200 PINGs lost")
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
