"""Benchmark of teleop's hot paths, checked against targets.

Run: ``python bench/bench_teleop.py [--repeat 5]``

1. The target gate (parse + bounds + stamp) on valid lines and on seeded garbage: messages per second.
   Target: >= 20,000/s each, so a flood of garbage cannot starve the control loop's core.
2. A dry-run teleop session on wx250s (no bus): a one-shot move, then holding still.  Per-tick compute
   of the moving ticks and of the held ticks.  Target: held ticks run 0 IK sweeps and cost <= 50 us p50
   (the IK early-out makes holding free); moving ticks p99 <= 1 ms.

Times are ``time.perf_counter``; each case is warmed up once, medians over ``--repeat`` runs.
"""

from __future__ import annotations

import argparse
import logging
import random
import statistics
import time

import numpy as np

import retarget
from retarget.control import LoopConfig, TickRecord
from retarget.control.clock import VirtualClock
from retarget.teleop import Follower, run_teleop
from retarget.teleop.gate import TargetBounds, TargetGate
from retarget.teleop.sources import Source


def check(ok: bool) -> str:
    return "OK  " if ok else "MISS"


def row(label: str, value: str, target: str, ok: bool) -> None:
    print(f"   {label:<34} {value:<22} target {target:<20} {check(ok)}")


def garbage(n: int) -> list[bytes]:
    rng = random.Random(1)
    out = []
    for i in range(n):
        k = i % 4
        if k == 0:
            out.append(b"!" + bytes(rng.randrange(256) for _ in range(rng.randrange(40))))
        elif k == 1:
            out.append(b"nan 0 0.2")
        elif k == 2:
            out.append(b'{"x": 0.3, "y": ')
        else:
            out.append(b"1e9 0 0.2")
    return out


def gate_rate(messages: list[bytes], repeat: int) -> float:
    logging.getLogger("retarget.teleop.gate").setLevel(logging.ERROR)  # measure parsing, not logging
    arm = retarget.load_arm("wx250s")
    rates = []
    for _ in range(repeat + 1):
        gate = TargetGate(TargetBounds.for_arm(arm), clock=VirtualClock())
        t0 = time.perf_counter()
        for m in messages:
            gate.accept(m)
        rates.append(len(messages) / (time.perf_counter() - t0))
    return statistics.median(rates[1:])


def session(repeat: int) -> tuple[list[list[float]], list[list[float]], int]:
    """Per-tick compute (ms) of the moving and the held ticks of a 6 s dry run, and the most sweeps of a held one."""
    arm = retarget.load_arm("wx250s")
    moving_ms, held_ms, held_sweeps = [], [], 0
    for _ in range(repeat + 1):
        clock = VirtualClock()
        gate = TargetGate(TargetBounds.for_arm(arm), clock=clock)
        source = Source(gate)  # open: the run holds after reaching the target until max_ticks
        source.feed("0.3 0.1 0.25")
        follower = Follower(arm, source, clock=clock, rate=100.0)
        records: list[TickRecord] = []
        result = run_teleop(arm, follower, config=LoopConfig(max_ticks=600), clock=clock, on_tick=records.append)
        end = result.visits[-1].tick
        moving_ms.append([r.compute_time * 1e3 for r in records if r.tick <= end])
        held_ms.append([r.compute_time * 1e3 for r in records if r.tick > end])
        held_sweeps = max(held_sweeps, max(r.ik_sweeps for r in records if r.tick > end))
    return moving_ms[1:], held_ms[1:], held_sweeps


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()

    print("1. target gate: parse + bounds + stamp")
    valid = [f"{0.3 + 1e-4 * (i % 100):.4f} 0.05 0.2".encode() for i in range(20000)]
    rate = gate_rate(valid, args.repeat)
    row("valid lines", f"{rate:,.0f} msg/s", ">= 20,000 msg/s", rate >= 20000)
    rate = gate_rate(garbage(20000), args.repeat)
    row("garbage (rejected, counted)", f"{rate:,.0f} msg/s", ">= 20,000 msg/s", rate >= 20000)

    print("2. dry-run teleop on wx250s: a one-shot move, then holding")
    moving, held, sweeps = session(args.repeat)
    p99 = statistics.median(float(np.percentile(m, 99)) for m in moving)
    p50 = statistics.median(float(np.percentile(m, 50)) for m in moving)
    row("moving ticks compute p50 / p99", f"{p50:.3f} / {p99:.3f} ms", "p99 <= 1 ms", p99 <= 1.0)
    h50 = statistics.median(float(np.percentile(h, 50)) for h in held)
    row(f"held ticks ({len(held[0])}) compute p50", f"{h50 * 1e3:.1f} us", "<= 50 us", h50 <= 0.05)
    row("held ticks IK sweeps (max)", f"{sweeps}", "0", sweeps == 0)


if __name__ == "__main__":
    main()
