"""Collision check speed, per bundled arm: one pose's full clearance check (``is_clear``, ``min_clearance``: every
pair plus the table, exact), every pair's distance (``distances``), a control tick's ``segment_clear`` (a small
step: two samples, the first remembered from the tick before), then wx250s with 0, 2 and 8 keep-out zones, and
a batch of poses.  Goal: <= 30 us median for wx250s's check.  Run: python bench/bench_collision.py

Each figure is the median wall time of single calls over a few poses (home and typical ones), and, in brackets,
the thread CPU time (best of a few batches: less sensitive to a busy machine)."""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable

import numpy as np

from retarget.arm.load import load_arm
from retarget.collision import Box, CollisionModel, Sphere, World

TYPICAL_DEG = [(0, 0, 0, 0, 0, 0), (30, -20, 20, 0, 30, 0), (-60, 10, -30, 45, 20, 90), (90, -40, 60, 0, -30, 0)]


def timed(fn: Callable[[np.ndarray], object], poses: list[np.ndarray], n: int = 600) -> str:
    """``median wall us (best cpu us)`` of ``fn`` over ``poses`` (``n`` calls each)."""
    wall = []
    cpu = float("inf")
    for q in poses:
        fn(q)
        for _ in range(n):
            t0 = time.perf_counter()
            fn(q)
            wall.append(time.perf_counter() - t0)
        for _ in range(3):
            c0 = time.thread_time()
            for _ in range(n // 3):
                fn(q)
            cpu = min(cpu, (time.thread_time() - c0) / (n // 3))
    return f"{statistics.median(wall) * 1e6:6.1f} ({cpu * 1e6:5.1f})"


def ticks(model: CollisionModel, q0: np.ndarray, n: int = 1500) -> str:
    """``segment_clear`` of a control loop's small steps (a slow sine sweep around ``q0``), per tick."""
    t = np.arange(n) * 0.01
    path = [q0 + np.radians(10) * np.sin(t[k] + np.arange(len(q0))) for k in range(n)]
    wall = []
    c0 = time.thread_time()
    for k in range(1, n):
        t0 = time.perf_counter()
        model.segment_clear(path[k - 1], path[k])
        wall.append(time.perf_counter() - t0)
    cpu = (time.thread_time() - c0) / (n - 1)
    return f"{statistics.median(wall) * 1e6:6.1f} ({cpu * 1e6:5.1f})"


def poses_of(arm_name: str) -> list[np.ndarray]:
    arm = load_arm(arm_name)
    qs = [np.radians(q[: arm.n_joints]) for q in TYPICAL_DEG] if arm.n_joints == 6 else [np.zeros(arm.n_joints)]
    return [np.clip(q, arm.lower, arm.upper) for q in qs] + [np.asarray(arm.home, dtype=np.float64)]


def main() -> None:
    print("us median wall (best cpu)      is_clear        min_clearance   distances       tick segment_clear")
    for name in ("wx250s", "vx300s", "px100", "omx", "koch"):
        arm = load_arm(name)
        model = CollisionModel.for_arm(arm)
        qs = poses_of(name)
        cols = [timed(model.is_clear, qs), timed(model.min_clearance, qs), timed(model.distances, qs, 200)]
        print(f"{name:8s} {len(model.pair_names):3d} pairs          " + "  ".join(cols) + "  " + ticks(model, qs[1]))
    arm = load_arm("wx250s")
    qs = poses_of("wx250s")
    for k in (0, 1, 4):
        zones = tuple(Box((0.3, 0.1 * i, 0.1), (0.05, 0.05, 0.05)) for i in range(k))
        zones += tuple(Sphere((0.3, -0.1 * i, 0.2), 0.05) for i in range(k))
        model = CollisionModel.for_arm(arm, world=World(keep_out=zones))
        cols = [timed(model.is_clear, qs), timed(model.min_clearance, qs), timed(model.distances, qs, 200)]
        print(f"wx250s + {2 * k} keep-outs: {len(model.pair_names):3d} pairs " + "  ".join(cols))
    model = CollisionModel.for_arm(arm)
    Q = np.random.default_rng(0).uniform(arm.lower, arm.upper, (1000, arm.n_joints))
    t0 = time.perf_counter()
    model.distances(Q)
    print(f"wx250s batch distances of 1000 poses: {(time.perf_counter() - t0) * 1e3:.1f} ms")


if __name__ == "__main__":
    main()
