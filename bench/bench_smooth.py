"""Benchmark: smooth motion (issue 14), today (the loop before: velocity limit only, unfiltered targets) vs now
(the default loop exactly as ``retarget export CLIP --arm ARM --side SIDE`` builds it: the CLI's own
``offline_loop``, with whatever target filter and acceleration limit are the defaults), offline.

    python bench/bench_smooth.py                       # every clip in ../shared/bvh, both sides, wx250s + koch
    python bench/bench_smooth.py --clips motion_dance --arms wx250s --sides right
    python bench/bench_smooth.py --clips motion_dance --flags '--filter-cutoff 4'   # 'now' with export's flags
    RETARGET_SHARED_BVH=/data/bvh python bench/bench_smooth.py

Per clip, arm and side, today | now:
- ``over``: ticks whose joint acceleration exceeds the arm's ``max_acceleration`` (target 0); in brackets the
  ones next to a collision-blocked tick (the collision check's instant stop, counted apart);
- ``peak``: the peak joint acceleration, rad/s^2, besides those instant stops (target on motion_dance: 10x lower);
- ``vlim``: velocity-limited ticks (target: 5x fewer);
- ``redund``: the redundant joints' total travel, rad (forearm_roll + wrist_rotate on a 6-DOF arm; target <= 1);
- ``p95``: the tracking error p95, mm: the unfiltered mapped target to the commanded tool point (target on
  motion_dance <= 15, and nowhere worse than today);
- ``RTF``: the offline real-time factor of the run (clip seconds per wall second, single run).
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
from retarget.cli import build_parser  # noqa: E402
from retarget.cli.export import offline_loop  # noqa: E402
from retarget.control import ControlLoop, TickRecord  # noqa: E402
from retarget.mapping import Targets, retarget_targets  # noqa: E402
from retarget.mapping.config import MappingConfig  # noqa: E402

SHARED = Path(os.environ.get("RETARGET_SHARED_BVH", REPO.parent / "shared" / "bvh"))
REDUNDANT = {"forearm_roll", "wrist_rotate"}


def unlimited(arm: Arm) -> Arm:
    """``arm`` without an acceleration limit (the loop before issue 14)."""
    joints = tuple(dataclasses.replace(j, max_acceleration=1e12) for j in arm.joints)
    return dataclasses.replace(arm, joints=joints)


def unfiltered(motion: retarget.Motion, arm: Arm, side: str) -> Targets:
    """The clip's mapped targets without any filter (the tracking error's reference, and today's input)."""
    overrides: dict[str, object] = {"side": side}
    if "cutoff_hz" in {f.name for f in dataclasses.fields(MappingConfig)}:
        overrides["cutoff_hz"] = 0.0
    config = MappingConfig.from_table(arm.mapping, overrides=overrides)
    return retarget_targets(motion, arm, config)


def measure(loop: ControlLoop, arm: Arm, clean: Targets) -> dict[str, float]:
    """Run ``loop`` offline from its first pose (as export does) and measure it against ``arm``'s limits."""
    records: list[TickRecord] = []
    loop.on_tick = records.append
    q0 = loop.initial_pose()
    t0 = time.perf_counter()
    summary = loop.run(None, q_start=q0)
    wall = time.perf_counter() - t0
    q = np.array([q0, *(r.q_cmd for r in records)])
    blocked = np.array([False, *(r.blocked for r in records)])
    rate = loop.config.rate
    v = np.diff(q, axis=0) * rate
    a = np.diff(np.vstack([np.zeros(arm.n_joints), v]), axis=0) * rate  # from rest at the first pose
    over = np.any(np.abs(a) > arm.max_acceleration * (1 + 1e-6), axis=1)
    near_block = blocked[1:] | blocked[:-1]
    tool = np.array([arm.fk(x)[0][:3, 3] for x in q[1:]])
    goal, _, _ = clean.sample(np.array([r.clip_time for r in records]))
    err_mm = 1000 * np.linalg.norm(tool - goal, axis=1)
    redundant = [i for i, n in enumerate(arm.joint_names) if n in REDUNDANT]
    return {
        "over": int(np.sum(over & ~near_block)),
        "over_blocked": int(np.sum(over & near_block)),
        "peak": float(np.abs(a[~near_block]).max()),  # the collision check's instant stops apart
        "vlim": summary.velocity_limited_ticks,
        "redund": float(np.abs(np.diff(q[:, redundant], axis=0)).sum()) if redundant else 0.0,
        "p95": float(np.percentile(err_mm, 95)),
        "rtf": summary.duration_s / wall,
    }


def export_loop(clip: Path, arm_name: str, side: str, *flags: str) -> tuple[Arm, ControlLoop]:
    """The arm and the loop ``retarget export CLIP --arm ARM --side SIDE FLAGS`` builds (collision model included)."""
    argv = ["export", str(clip), "--arm", arm_name, "--side", side, "-o", os.devnull, *flags]
    inputs, loop = offline_loop(build_parser().parse_args(argv))
    return inputs.arm, loop


def today(clip: Path, arm_name: str, side: str, clean: Targets) -> dict[str, float]:
    """The loop before issue 14, as export ran it: unfiltered targets, no acceleration limit (the IK is today's
    tree's); measured against the arm's limits."""
    arm, loop = export_loop(clip, arm_name, side, "--no-filter")
    loop.arm = unlimited(arm)
    return measure(loop, arm, clean)


def now(clip: Path, arm_name: str, side: str, clean: Targets, flags: list[str]) -> dict[str, float]:
    """The default loop as ``retarget export`` builds it (with export's ``flags``, e.g. ``--filter-cutoff 4``)."""
    arm, loop = export_loop(clip, arm_name, side, *flags)
    return measure(loop, arm, clean)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--clips", nargs="*", default=None, help="clip names (default: every *.bvh)")
    parser.add_argument("--arms", nargs="*", default=["wx250s", "koch"])
    parser.add_argument("--sides", nargs="*", default=["right", "left"])
    parser.add_argument("--flags", default="", help="export flags for 'now', e.g. '--filter-cutoff 4'")
    args = parser.parse_args()
    clips = sorted(SHARED.glob("*.bvh"))
    if args.clips:
        clips = [c for c in clips if c.stem in args.clips]
    print(f"{'clip':18s} {'arm':6s} {'side':5s} | today: peak rad/s2, vlim, redund rad, p95 mm | "
          "now: over (blocked), peak rad/s2, vlim, redund rad, p95 mm, RTF")  # fmt: skip
    for clip in clips:
        motion = retarget.load_bvh(clip)
        for arm_name in args.arms:
            arm = retarget.load_arm(arm_name)
            for side in args.sides:
                clean = unfiltered(motion, arm, side)
                b = today(clip, arm_name, side, clean)
                a = now(clip, arm_name, side, clean, args.flags.split())
                print(
                    f"{clip.stem:18s} {arm_name:6s} {side:5s} | {b['peak']:6.1f} {b['vlim']:5d} {b['redund']:6.2f} "
                    f"{b['p95']:6.1f} | {a['over']:4d} ({a['over_blocked']:3d}) {a['peak']:6.1f} {a['vlim']:5d} "
                    f"{a['redund']:6.2f} {a['p95']:6.1f} {a['rtf']:5.0f}x",
                    flush=True,
                )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
