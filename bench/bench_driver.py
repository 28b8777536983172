"""Driver overhead: one control tick (write goals + read positions) through DynamixelBus vs raw dynamixel-sdk.

Both sides talk to the same in-process simulated WidowX-250 6DOF (``sim://wx250s``: 6 joints, 8 joint servos
with the two shadows) through the same port class, so the difference is the driver's own Python work:
clamping, step limiting, encoding, per-ID status collection and decoding.

    raw:    GroupSyncWrite.changeParam x8 + txPacket, then GroupSyncRead.fastSyncRead (or txRxPacket) + getData x8
    driver: DynamixelBus.write_goals(q) then DynamixelBus.read_positions()

Run: ``python bench/bench_driver.py [--ticks N]``.  Prints median and p95 per tick and the overhead ratio,
checked against TARGET_RATIO.

Then the read rate on a noisy bus: the same driver tick (write_goals + read_positions) with 5 % of the replies
lost (``drop=0.05``, seeded), relative to none.  A lost reply costs the SDK's reply timeout in real time, as on a
real port (``2 x LATENCY_TIMER + 2`` ms, 34 ms with the SDK's 16 ms), and only the missing servos are asked again;
a servo still silent goes stale for the tick instead of ending the run.  Informational (no target): the ratio is
set by the SDK's timeout, not by the driver.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np
from dynamixel_sdk import COMM_SUCCESS, GroupSyncRead, GroupSyncWrite, PacketHandler

from drivers.control_table import common_register
from drivers.dynamixel_bus import DynamixelBus
from drivers.port import open_port
from retarget.arm.load import load_arm
from retarget.control.bus import ShutdownMode

TARGET_RATIO = 1.5  #: the driver may cost at most this many times the raw SDK calls per tick
URL = "sim://wx250s?rdt=0"  #: Return Delay Time 0 on both sides, as the driver configures it
TORQUE, GOAL, PRESENT = (common_register(n).address for n in ("Torque Enable", "Goal Position", "Present Position"))


def _stats(samples: list[float]) -> tuple[float, float]:
    ordered = sorted(samples)
    return statistics.median(ordered), ordered[int(0.95 * (len(ordered) - 1))]


def bench_raw(arm, ticks: int, *, fast: bool) -> list[float]:
    ids = [s.id for j in arm.joints for s in j.servos]
    port = open_port(URL, arm.baud)
    ph = PacketHandler(2.0)
    try:
        for i in ids:  # torque on, or the goals go nowhere
            ph.write1ByteTxRx(port, i, TORQUE, 1)
        writer = GroupSyncWrite(port, ph, GOAL, 4)
        reader = GroupSyncRead(port, ph, PRESENT, 4)
        for i in ids:
            writer.addParam(i, [0, 8, 0, 0])
            reader.addParam(i)
        times = []
        rng = np.random.default_rng(0)
        for _ in range(ticks):
            goal = 2048 + rng.integers(-200, 200, size=len(ids))
            t0 = time.perf_counter()
            for i, g in zip(ids, goal, strict=True):
                writer.changeParam(i, list(int(g).to_bytes(4, "little", signed=True)))
            writer.txPacket()
            result = reader.fastSyncRead() if fast else reader.txRxPacket()
            if result != COMM_SUCCESS:
                raise RuntimeError(ph.getTxRxResult(result))
            _ = [reader.getData(i, PRESENT, 4) for i in ids]
            times.append(time.perf_counter() - t0)
        for i in ids:
            ph.write1ByteTxRx(port, i, TORQUE, 0)
        return times
    finally:
        port.closePort()


def bench_driver(arm, ticks: int, *, fast: bool) -> list[float]:
    bus = DynamixelBus(arm, URL, shutdown=ShutdownMode.OFF, fast_read=fast, check_latency=False)
    times = []
    rng = np.random.default_rng(0)
    with bus:
        for _ in range(ticks):
            q = rng.uniform(-0.3, 0.3, size=arm.n_joints)
            t0 = time.perf_counter()
            bus.write_goals(q)
            bus.read_positions()
            times.append(time.perf_counter() - t0)
    return times


def bench_loss(arm, ticks: int, *, drop: float) -> tuple[float, int, int]:
    """Reads per second (wall clock) of ``ticks`` driver ticks with ``drop`` of the replies lost, the retries and
    the stale reads."""
    url = f"{URL}&drop={drop}&seed=1" if drop else URL
    bus = DynamixelBus(arm, url, shutdown=ShutdownMode.OFF, check_latency=False)
    rng = np.random.default_rng(0)
    with bus:
        start = bus.status()
        t0 = time.perf_counter()
        for _ in range(ticks):
            bus.write_goals(rng.uniform(-0.3, 0.3, size=arm.n_joints))
            bus.read_positions()
        elapsed = time.perf_counter() - t0
        end = bus.status()
    return ticks / elapsed, end.retries - start.retries, end.stale_reads - start.stale_reads


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ticks", type=int, default=2000)
    args = parser.parse_args()
    arm = load_arm("wx250s")
    n_servos = sum(len(j.servos) for j in arm.joints)
    print(f"{arm.name}: {arm.n_joints} joints, {n_servos} joint servos, {args.ticks} ticks, in-process {URL}")
    worst = 0.0
    for fast in (True, False):
        label = "FAST_SYNC_READ" if fast else "SYNC_READ"
        bench_raw(arm, 200, fast=fast)  # warm up
        bench_driver(arm, 200, fast=fast)
        raw_med, raw_p95 = _stats(bench_raw(arm, args.ticks, fast=fast))
        drv_med, drv_p95 = _stats(bench_driver(arm, args.ticks, fast=fast))
        ratio = drv_med / raw_med
        worst = max(worst, ratio)
        print(f"  {label:<15} raw sdk  median {raw_med * 1e6:7.1f} us  p95 {raw_p95 * 1e6:7.1f} us")
        print(f"  {label:<15} driver   median {drv_med * 1e6:7.1f} us  p95 {drv_p95 * 1e6:7.1f} us  ratio {ratio:.2f}")
    verdict = "ok" if worst <= TARGET_RATIO else "OVER TARGET"
    print(f"overhead ratio (driver / raw, median per tick): worst {worst:.2f}, target <= {TARGET_RATIO}: {verdict}")
    loss_ticks = max(200, args.ticks // 4)
    clean, _, _ = bench_loss(arm, loss_ticks, drop=0.0)
    noisy, retries, stale = bench_loss(arm, loss_ticks, drop=0.05)
    print(
        f"  read rate, {loss_ticks} ticks: no loss {clean:7.0f} reads/s; 5% loss {noisy:7.0f} reads/s "
        f"({noisy / clean:.1%} of no loss; {retries} retries, {stale} stale reads, 0 errors)"
    )
    return 0 if worst <= TARGET_RATIO else 1


if __name__ == "__main__":
    raise SystemExit(main())
