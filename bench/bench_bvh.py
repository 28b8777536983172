"""Benchmark: parse + all-frame FK of a real clip, against the 30 ms target (and pybvh if installed).

    python bench/bench_bvh.py                      # ../shared/bvh/motion_dance.bvh, 21 runs
    python bench/bench_bvh.py --runs 50 clip.bvh
    RETARGET_SHARED_BVH=/data/bvh python bench/bench_bvh.py

Each run reads the file from disk, parses it and computes ``positions()``
(all joints, all frames) from scratch.  pybvh (``pip install pybvh==0.9.0``,
not a dependency) is timed in the same process on the same file, its
positions compared with ours, and the ratio printed.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))

from retarget.bvh import load_bvh  # noqa: E402

TARGET_MS = 30.0
DEFAULT = Path(os.environ.get("RETARGET_SHARED_BVH", REPO.parent / "shared" / "bvh")) / "motion_dance.bvh"


def timed(fn, runs: int, warmup: int = 2) -> tuple[list[float], object]:
    result = None
    for _ in range(warmup):
        result = fn()
    times = []
    for _ in range(runs):
        t0 = time.perf_counter()
        result = fn()
        times.append((time.perf_counter() - t0) * 1e3)
    return times, result


def summary(times: list[float]) -> str:
    q = np.percentile(times, [50, 95])
    return f"median {q[0]:7.2f} ms   p95 {q[1]:7.2f} ms   min {min(times):7.2f} ms"


def ours(path: Path):
    motion = load_bvh(path)
    return motion, motion.positions()


def split(path: Path, runs: int) -> None:
    parse, _ = timed(lambda: load_bvh(path), runs)
    motion = load_bvh(path)

    def fk():
        motion._cached_pose = None  # drop the cache: time the FK itself
        return motion.positions()

    fk_times, _ = timed(fk, runs)
    print(f"  parse only   {summary(parse)}")
    print(f"  FK only      {summary(fk_times)}")


def pybvh_run(path: Path):
    import pybvh

    clip = pybvh.read_bvh_file(path)
    return clip, pybvh.frames_to_node_positions(clip)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("clip", nargs="?", type=Path, default=DEFAULT)
    parser.add_argument("--runs", type=int, default=21)
    args = parser.parse_args()
    if not args.clip.exists():
        print(f"bench_bvh: {args.clip} not found (set RETARGET_SHARED_BVH or pass a clip)", file=sys.stderr)
        return 2
    size = args.clip.stat().st_size / 1e6
    times, (motion, positions) = timed(lambda: ours(args.clip), args.runs)
    print(f"{args.clip.name}: {size:.2f} MB, {motion.n_frames} frames, {motion.n_joints} joints, {args.runs} runs")
    print(f"retarget parse+FK {summary(times)}   target < {TARGET_MS:.0f} ms median")
    split(args.clip, args.runs)
    median = statistics.median(times)
    ok = median < TARGET_MS
    print(f"target parse+FK < {TARGET_MS:.0f} ms median: {'PASS' if ok else 'FAIL'} ({median:.2f} ms)")
    try:
        import pybvh  # noqa: F401
    except ImportError:
        print("pybvh not installed (pip install pybvh==0.9.0 to compare)")
    else:
        read, clip = timed(lambda: pybvh.read_bvh_file(args.clip), max(5, args.runs // 3), warmup=1)
        fk, ref = timed(lambda: pybvh.frames_to_node_positions(clip), max(5, args.runs // 3), warmup=1)
        joints = [i for i, node in enumerate(clip.nodes) if not node.is_end_site()]
        ref = np.asarray(ref)[:, joints]
        err = float(np.abs(ref - positions).max() / np.abs(ref).max())
        both = statistics.median(read) + statistics.median(fk)
        print(f"pybvh read        {summary(read)}")
        print(f"pybvh FK          {summary(fk)}")
        ratio = both / median
        print(f"pybvh parse+FK    median {both:7.2f} ms")
        print(f"target >= 4x faster than pybvh: {'PASS' if ratio >= 4 else 'FAIL'} ({ratio:.1f}x in this run)")
        print(f"target positions equal pybvh's to 1e-9: {'PASS' if err <= 1e-9 else 'FAIL'} (max rel. diff {err:.1e})")
        ok = ok and err <= 1e-9 and ratio >= 4
    print("all targets met" if ok else "some target missed")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
