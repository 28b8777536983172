"""Benchmark of the CCD IK solver on wx250s (or --arm), position to 1 mm.

Run: ``python bench/bench_ik.py [--arm wx250s] [--n 500] [--seed 0] [--dls-steps 8]`` (``--dls-steps 0``: CCD only,
the solver before issue 14)

Cases, each checked against the issue's targets:

- warm path: 500 targets along a smooth joint-space curve (about 4 mm per tick), each solve
  warm-started from the previous solution: median <= 0.06 ms, p95 <= 0.15 ms, 100 % converged,
  no joint moving more than 0.05 rad between consecutive solves;
- random targets: FK of 500 uniform random joint vectors inside the limits, each solved cold
  from home: >= 99.5 % converged, median <= 0.3 ms;
- safety: zero limit violations in every case, no NaN on unreachable targets;
- collisions on (``CCDSolver(collision=CollisionModel.for_arm(arm))``, the default clearance): the warm path
  again, median <= 0.08 ms, 100 % converged, every pose clear;
- the cost of one sweep and of the early-out (target already reached).

Times are ``time.perf_counter`` around each ``CCDSolver.solve`` call after a warm-up.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

import retarget
from retarget.collision import CollisionModel
from retarget.ik import CCDSolver


def smooth_path(arm: retarget.Arm, n: int, step: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """``(targets (n, 3), q (n, n_joints))``: FK of a smooth joint curve inside the limits, sampled uniformly in time.

    Each joint follows ``mid + k * amp * sin(2 pi f t + phase)`` (f = 1 or 2 cycles over the path), with ``k``
    scaled so that the tool moves ``step`` metres per tick on average.
    """
    rng = np.random.default_rng(seed)
    lo, hi = arm.lower, arm.upper
    mid = np.clip((lo + hi) / 2, lo + 0.4 * (hi - lo), hi - 0.4 * (hi - lo))
    amp = np.minimum(0.3 * (hi - lo) / 2, 1.0)
    freq = rng.integers(1, 3, arm.n_joints)
    phase = rng.uniform(0, 2 * np.pi, arm.n_joints)
    t = np.linspace(0.0, 1.0, n)[:, None]
    wave = np.sin(2 * np.pi * freq * t + phase)
    k = 1.0
    for _ in range(30):  # the mean step is close to linear in k
        q = mid + k * amp * wave
        targets = arm.chain.fk_batch(q)[:, :3, 3]
        mean = np.linalg.norm(np.diff(targets, axis=0), axis=1).mean()
        if abs(mean - step) < 1e-5:
            break
        k = min(k * step / mean, 1.0)
    return targets, q


def ms(values: list[float]) -> str:
    a = np.asarray(values) * 1e3
    return f"median {np.median(a):.4f} ms  p95 {np.percentile(a, 95):.4f} ms  max {a.max():.3f} ms"


def violations(arm: retarget.Arm, qs: np.ndarray) -> int:
    return int(np.sum((qs < arm.lower) | (qs > arm.upper)))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--arm", default="wx250s")
    parser.add_argument("--n", type=int, default=500)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--order", default=None, help="sweep order (default: the solver's)")
    parser.add_argument("--dls-steps", type=int, default=8, help="DLS steps before CCD (0: CCD only)")
    args = parser.parse_args()
    arm = retarget.load_arm(args.arm)
    dls = args.dls_steps
    solver = (
        CCDSolver(arm, tolerance=1e-3, dls_steps=dls)
        if args.order is None
        else CCDSolver(arm, order=args.order, dls_steps=dls)
    )
    print(
        f"arm {arm.name} ({arm.n_joints} joints), tolerance 1 mm, budget {solver.max_iterations} sweeps, "
        f"order {solver.order.value}, {dls} DLS steps first"
    )

    # -- warm path -----------------------------------------------------------------------------------------------
    targets, q_path = smooth_path(arm, args.n, 0.004, args.seed)
    steps = np.linalg.norm(np.diff(targets, axis=0), axis=1)
    for t in targets[:50]:  # warm-up
        solver.solve(t, q_path[0])
    times, qs, sweeps, conv = [], [], [], 0
    q = q_path[0].copy()
    for t in targets:
        t0 = time.perf_counter()
        r = solver.solve(t, q)
        times.append(time.perf_counter() - t0)
        q = r.q
        qs.append(q)
        sweeps.append(r.iterations)
        conv += r.converged
    qs = np.array(qs)
    dq = np.abs(np.diff(qs, axis=0)).max()
    path_dq = np.abs(np.diff(q_path, axis=0)).max()
    print(
        f"\nwarm path: {len(targets)} targets, {steps.mean() * 1e3:.1f} mm/tick mean ({steps.max() * 1e3:.1f} max), "
        f"the path itself moves a joint by <= {path_dq:.4f} rad/tick"
    )
    print(f"  time        {ms(times)}   target: median <= 0.06 ms, p95 <= 0.15 ms")
    print(f"  converged   {conv / len(targets):.1%}   target: 100%")
    print(f"  sweeps      median {np.median(sweeps):.0f}  p95 {np.percentile(sweeps, 95):.0f}  max {max(sweeps)}")
    print(f"  max |dq|    {dq:.4f} rad between consecutive solves   target: <= 0.05 rad")
    print(f"  limit violations {violations(arm, qs)}   target: 0")

    # -- the warm path with collisions on ---------------------------------------------------------------------------
    model = CollisionModel.for_arm(arm)
    safe = CCDSolver(arm, tolerance=1e-3, collision=model, dls_steps=dls)
    for t in targets[:50]:  # warm-up
        safe.solve(t, q_path[0])
    times, qs, conv, blocked = [], [], 0, 0
    q = q_path[0].copy()
    for t in targets:
        t0 = time.perf_counter()
        r = safe.solve(t, q)
        times.append(time.perf_counter() - t0)
        q = r.q
        qs.append(q)
        conv += r.converged
        blocked += r.blocked
    clear = int(np.sum(model.distances(np.array(qs)).min(axis=1) >= model.clearance))
    print(f"\nwarm path, collisions on (clearance {model.clearance * 1e3:g} mm, {len(model.pair_names)} pairs)")
    print(f"  time        {ms(times)}   target: median <= 0.08 ms")
    print(f"  converged   {conv / len(targets):.1%}   target: 100%   (blocked {blocked})")
    print(f"  clear poses {clear}/{len(targets)}   target: all")
    t0 = time.perf_counter()
    for _ in range(200):
        model.min_clearance(q)
    print(f"  one pose check (model.min_clearance): {(time.perf_counter() - t0) / 200 * 1e6:.1f} us")

    # -- random reachable targets, cold from home ----------------------------------------------------------------
    rng = np.random.default_rng(args.seed + 1)
    Q = rng.uniform(arm.lower, arm.upper, (args.n, arm.n_joints))
    rand_targets = arm.chain.fk_batch(Q)[:, :3, 3]
    times, qs, sweeps, restarts, conv = [], [], [], [], 0
    home = arm.home
    for t in rand_targets:
        t0 = time.perf_counter()
        r = solver.solve(t, home)
        times.append(time.perf_counter() - t0)
        qs.append(r.q)
        sweeps.append(r.iterations)
        restarts.append(r.restarts)
        conv += r.converged
    print(f"\nrandom reachable targets, cold from home: {args.n}")
    print(f"  time        {ms(times)}   target: median <= 0.3 ms")
    print(f"  converged   {conv / args.n:.1%}   target: >= 99.5%")
    print(f"  sweeps      median {np.median(sweeps):.0f}  p95 {np.percentile(sweeps, 95):.0f}  max {max(sweeps)}")
    print(f"  restarts    mean {np.mean(restarts):.2f}  max {max(restarts)}")
    print(f"  limit violations {violations(arm, np.array(qs))}   target: 0")

    # -- unreachable targets ---------------------------------------------------------------------------------------
    directions = rng.normal(size=(100, 3))
    far = directions / np.linalg.norm(directions, axis=1, keepdims=True) * (solver.reach * 2)
    bad = 0
    times = []
    for t in far:
        t0 = time.perf_counter()
        r = solver.solve(t, home)
        times.append(time.perf_counter() - t0)
        bad += (not np.all(np.isfinite(r.q))) or not math.isfinite(r.error) or violations(arm, r.q[None]) > 0
    print(f"\nunreachable targets (2x reach): 100   {ms(times)}   NaN or limit violations: {bad}   target: 0")

    # -- smoothness over more paths ------------------------------------------------------------------------------
    worst, worst_conv = 0.0, 0
    for seed in range(args.seed + 1, args.seed + 10):
        path, q_true = smooth_path(arm, args.n, 0.004, seed)
        q = q_true[0].copy()
        for t in path:
            r = solver.solve(t, q)
            worst = max(worst, float(np.abs(r.q - q).max()))
            worst_conv += r.converged
            q = r.q
    print(f"\n9 more smooth paths: converged {worst_conv / (9 * args.n):.1%}, worst |dq| {worst:.4f} rad/tick")

    # -- position + orientation (6-DOF arms) ----------------------------------------------------------------------
    if arm.n_joints >= 6:
        pose_solver = CCDSolver(arm, max_iterations=30, dls_steps=dls)
        poses = arm.chain.fk_batch(q_path)
        times, conv, worst = [], 0, 0.0
        q = q_path[0].copy()
        for T in poses:
            t0 = time.perf_counter()
            r = pose_solver.solve(T[:3, 3], q, T[:3, :3])
            times.append(time.perf_counter() - t0)
            worst = max(worst, float(np.abs(r.q - q).max()))
            conv += r.converged
            q = r.q
        print(f"\npose path (position 1 mm + orientation 0.01 rad), warm, budget 30 sweeps: {len(poses)}")
        print(f"  time        {ms(times)}")
        print(f"  converged   {conv / len(poses):.1%}   worst |dq| {worst:.4f} rad/tick")
        cold = CCDSolver(arm, max_iterations=300, dls_steps=dls)
        Qp = rng.uniform(arm.lower, arm.upper, (100, arm.n_joints))
        times, conv = [], 0
        for T in arm.chain.fk_batch(Qp):
            t0 = time.perf_counter()
            conv += cold.solve(T[:3, 3], home, T[:3, :3]).converged
            times.append(time.perf_counter() - t0)
        print(f"random poses, cold from home, budget 300 sweeps: 100   {ms(times)}   converged {conv}%")

    # -- cost of one sweep and of the early-out -----------------------------------------------------------------
    reps = 2000
    t_far = rand_targets[0]
    for order in ("base-first", "tip-first"):
        one = CCDSolver(arm, tolerance=1e-9, max_iterations=1, restarts=0, accel_ratio=0, order=order, dls_steps=0)
        for _ in range(200):
            one.solve(t_far, home)
        t0 = time.perf_counter()
        for _ in range(reps):
            one.solve(t_far, home)
        t_sweep = (time.perf_counter() - t0) / reps
        print(f"one solve of exactly one full {order} sweep (incl. call overhead): {t_sweep * 1e6:.1f} us")
    step = CCDSolver(arm, tolerance=1e-9, max_iterations=1, restarts=0, dls_steps=1)
    for _ in range(200):  # a warm-path tick: one DLS step, and no budget left for CCD
        step.solve(targets[1], q_path[0])
    t0 = time.perf_counter()
    for _ in range(reps):
        step.solve(targets[1], q_path[0])
    print(f"one solve of exactly one DLS step (incl. call overhead): {(time.perf_counter() - t0) / reps * 1e6:.1f} us")
    t_here = arm.fk(home)[0][:3, 3]
    t0 = time.perf_counter()
    for _ in range(reps):
        solver.solve(t_here, home)
    t_out = (time.perf_counter() - t0) / reps
    print(f"early-out (already within tolerance, 0 sweeps): {t_out * 1e6:.1f} us")


if __name__ == "__main__":
    main()
