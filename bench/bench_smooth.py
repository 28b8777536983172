"""Benchmark: smooth motion (issue 14), before (velocity limit only, unfiltered targets) vs after (the
acceleration-limited profile and the zero-phase target filter), offline like ``retarget export``.

    python bench/bench_smooth.py                       # every clip in ../shared/bvh, both sides, wx250s + koch
    python bench/bench_smooth.py --clips motion_dance --arms wx250s --sides right
    RETARGET_SHARED_BVH=/data/bvh python bench/bench_smooth.py

Per clip, side and arm: ticks over the acceleration limit (collision-blocked ticks, an instant stop by the
collision check, counted apart), peak joint acceleration (rad/s^2), velocity-limited ticks, the redundant
joints' total travel (rad; forearm_roll + wrist_rotate on a 6-DOF arm), the tracking error p95 (mm, the
unfiltered mapped target to the commanded tool point) and the offline real-time factor.
Targets: 0 ticks over; peak acceleration >= 10x lower and velocity-limited ticks >= 5x fewer on
motion_dance; redundant travel <= 1 rad; tracking p95 <= 15 mm on motion_dance; real-time factor >= 100x.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))

import retarget  # noqa: E402
from retarget.arm import Arm  # noqa: E402
from retarget.control import ControlLoop, LoopConfig, TickRecord  # noqa: E402
from retarget.control.clock import VirtualClock  # noqa: E402
from retarget.mapping import Targets, retarget_targets  # noqa: E402
from retarget.mapping.config import MappingConfig  # noqa: E402
from retarget.mapping.filter import filter_targets  # noqa: E402

SHARED = Path(os.environ.get("RETARGET_SHARED_BVH", REPO.parent / "shared" / "bvh"))
REDUNDANT = {"forearm_roll", "wrist_rotate"}


def unlimited(arm: Arm) -> Arm:
    """``arm`` without an acceleration limit (the loop before issue 14)."""
    joints = tuple(dataclasses.replace(j, max_acceleration=1e12) for j in arm.joints)
    return dataclasses.replace(arm, joints=joints)


def run(arm: Arm, targets: Targets, clean: Targets) -> dict[str, float]:
    records: list[TickRecord] = []
    loop = ControlLoop(arm, targets, config=LoopConfig(), clock=VirtualClock(), on_tick=records.append)
    t0 = time.perf_counter()
    summary = loop.run(None, q_start=loop.initial_pose())
    wall = time.perf_counter() - t0
    q = np.array([r.q_cmd for r in records])
    blocked = np.array([r.blocked for r in records])
    rate = loop.config.rate
    v = np.diff(q, axis=0) * rate
    a = np.diff(v, axis=0) * rate
    over = np.any(np.abs(a) > arm.max_acceleration * (1 + 1e-6), axis=1)
    near_block = blocked[1:-1] | blocked[2:] | blocked[:-2]
    tool = np.array([arm.fk(x)[0][:3, 3] for x in q])
    goal, _, _ = clean.sample(np.array([r.clip_time for r in records]))
    err_mm = 1000 * np.linalg.norm(tool - goal, axis=1)
    redundant = [i for i, n in enumerate(arm.joint_names) if n in REDUNDANT]
    return {
        "over": int(np.sum(over & ~near_block)),
        "over_blocked": int(np.sum(over & near_block)),
        "peak_acc": float(np.abs(a).max()),
        "vel_limited": summary.velocity_limited_ticks,
        "redundant_rad": float(np.abs(np.diff(q[:, redundant], axis=0)).sum()) if redundant else 0.0,
        "track_p95_mm": float(np.percentile(err_mm, 95)),
        "rt_factor": summary.duration_s / wall,
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--clips", nargs="*", default=None, help="clip names (default: every *.bvh)")
    parser.add_argument("--arms", nargs="*", default=["wx250s", "koch"])
    parser.add_argument("--sides", nargs="*", default=["right", "left"])
    args = parser.parse_args()
    clips = sorted(SHARED.glob("*.bvh"))
    if args.clips:
        clips = [c for c in clips if c.stem in args.clips]
    print(
        f"{'clip':24s} {'arm':7s} {'side':5s} | before: peak acc, vel-lim, redund rad, p95 mm | "
        "after: over (blocked), peak acc, vel-lim, redund rad, p95 mm, RTF"
    )
    for clip in clips:
        motion = retarget.load_bvh(clip)
        for arm_name in args.arms:
            arm = retarget.load_arm(arm_name)
            for side in args.sides:
                config = MappingConfig.from_table(arm.mapping, overrides={"side": side})
                clean = retarget_targets(motion, arm, config)
                b = run(unlimited(arm), clean, clean)
                a = run(arm, filter_targets(clean), clean)
                print(
                    f"{clip.stem:24s} {arm_name:7s} {side:5s} | {b['peak_acc']:7.1f} {b['vel_limited']:5d} "
                    f"{b['redundant_rad']:6.2f} {b['track_p95_mm']:6.1f} | {a['over']:4d} ({a['over_blocked']:3d}) "
                    f"{a['peak_acc']:6.1f} {a['vel_limited']:4d} {a['redundant_rad']:6.2f} "
                    f"{a['track_p95_mm']:6.1f} {a['rt_factor']:6.0f}x",
                    flush=True,
                )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
