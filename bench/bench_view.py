"""Benchmark of the views: ``retarget view --record`` on a real clip (whole process time, file size), and the
cost per tick of a live ``--record`` on the simulated bus at 100 Hz in real time (tick, compute and bus time,
overruns, with and without the view).

    python bench/bench_view.py [--clip /work/shared/bvh/motion_dance.bvh] [--ticks 500]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
CLIP = Path(os.environ.get("RETARGET_SHARED_BVH", REPO.parent / "shared" / "bvh")) / "motion_dance.bvh"


def retarget(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "retarget", *args], capture_output=True, text=True, check=True)


def bench_record(clip: Path) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "view.rrd"
        t0 = time.perf_counter()
        retarget("view", str(clip), "--record", str(out))
        elapsed = time.perf_counter() - t0
        print(f"view --record {clip.name}: {elapsed:.2f} s whole process, {out.stat().st_size / 1e6:.2f} MB")


def bench_live(ticks: int) -> None:
    args = ["replay", "--port", "sim://wx250s", "--max-ticks", str(ticks), "--json", "--lead-in", "0",
            "--shutdown", "hold"]  # fmt: skip
    with tempfile.TemporaryDirectory() as tmp:
        for label, extra in (("without view", []), ("with --record", ["--record", str(Path(tmp) / "live.rrd")])):
            s = json.loads(retarget(*args, *extra).stdout)
            print(f"replay 100 Hz sim, {ticks} ticks, {label}: tick p50 {s['tick_ms_p50']:.2f} ms p99 "
                  f"{s['tick_ms_p99']:.2f} ms, compute p50 {s['compute_ms_p50']:.2f} ms, bus p50 {s['bus_ms_p50']:.2f} "
                  f"ms, overruns {s['overruns']}")  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--clip", type=Path, default=CLIP)
    parser.add_argument("--ticks", type=int, default=500)
    args = parser.parse_args()
    if args.clip.exists():
        bench_record(args.clip)
    else:
        print(f"skipped view --record: no {args.clip}")
    bench_live(args.ticks)


if __name__ == "__main__":
    main()
