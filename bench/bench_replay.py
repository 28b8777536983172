"""Benchmark of retargeting and the control loop, checked against the issue's targets.

Run: ``python bench/bench_replay.py [--clip PATH] [--repeat 5] [--bus-ticks 2000]``

1. Offline retargeting of ``../shared/bvh/motion_dance.bvh`` (15.6 s of motion) to wx250s without a
   bus: the mapping of every frame plus the dry-run loop at 100 Hz (IK warm-started, velocity limits).
   Target: <= 0.16 s in total (>= 100x real time), IK converged on every reachable (unclamped) tick,
   per-tick compute p99 <= 1 ms.  BVH parsing is reported beside it (its own bench is bench_bvh.py).
   Then ``retarget export`` with collisions on (the default clearance: targets pushed out of blocked zones,
   every IK pose verified, every tick's segment checked), both sides, the whole command run in process
   (``retarget.cli.main``, best of ``--repeat``): target >= 100x real time, zero goals within the clearance;
   and the export cases that must not get slower (:data:`EXPORT_CASES`).
2. The loop on the simulated bus at 1 Mbps with the wire-time model on, 6 servos (the Koch arm:
   5 joints + gripper), Return Delay Time 0.  The wire-limited tick rate is measured on a virtual clock
   with the loop unpaced (the simulator advances the clock by exactly the wire time of each packet,
   nothing else); then the loop runs on the real clock at that rate (``--rate`` = the wire-limited
   rate: a tick that overruns skips slots, as in any real run, and the joints keep their per-tick
   velocity limit at that rate) and the median real period between ticks is compared with the
   wire-limited one (the median, because the machine is shared).  The loop is ControlLoop's default, with
   the pipelined read-back; the same run without it (``pipeline=False``) is printed beside it.
   Target: >= 90 % of the wire-limited tick rate.
3. Safety over every clip in ../shared/bvh and both sides (export-style dry runs on wx250s): commanded
   angles outside the limits and velocity-limit violations.  Target: zero.

Times are ``time.perf_counter``; each case is warmed up once, medians over ``--repeat`` runs.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from pathlib import Path

import numpy as np

import retarget
import sim
from drivers import DynamixelBus
from retarget.control import ControlLoop, LoopConfig, TickRecord
from retarget.control.clock import MonotonicClock, VirtualClock
from retarget.mapping import retarget_targets
from retarget.mapping.config import MappingConfig, Side

REPO = Path(__file__).resolve().parent.parent
SHARED = Path(os.environ.get("RETARGET_SHARED_BVH", REPO.parent / "shared" / "bvh"))


def check(ok: bool) -> str:
    return "OK  " if ok else "MISS"


def row(label: str, value: str, target: str, ok: bool) -> None:
    print(f"   {label:<34} {value:<22} target {target:<20} {check(ok)}")


#: ``retarget export`` cases that must not get slower (clip, arm, side), timed beside the issue's target
EXPORT_CASES = (
    ("motion_walk.bvh", "wx250s", "left"),
    ("push.bvh", "koch", "right"),
    ("motion_dance.bvh", "koch", "right"),
)


def export_command(clip: Path, arm: str, side: str, repeat: int) -> tuple[list[float], str]:
    """``retarget export CLIP --arm ARM --side SIDE -o FILE`` run in process (``retarget.cli.main``: argument
    parsing, BVH parse, mapping, collision model, IK pass, plan, loop, CSV), ``repeat`` times after a warm-up:
    the real seconds of each run and the command's summary line (stderr)."""
    import contextlib
    import io
    import tempfile

    from retarget.cli import main as cli

    seconds = []
    with tempfile.TemporaryDirectory() as tmp:
        argv = ["export", str(clip), "--arm", arm, "--side", side, "-o", str(Path(tmp) / "out.csv")]
        for i in range(repeat + 1):
            err = io.StringIO()
            t0 = time.perf_counter()
            with contextlib.redirect_stderr(err):
                code = cli(argv)
            if i:
                seconds.append(time.perf_counter() - t0)
            if code:
                raise SystemExit(f"bench_replay: retarget export failed: {err.getvalue().strip()}")
    return seconds, err.getvalue().strip()


def offline_collisions(clip: Path, repeat: int) -> None:
    """Case 1 with collisions on: ``retarget export`` of both sides, the whole command in process, then the loop's
    figures (least clearance written, blocked goals) from the library, as export runs it (look-ahead plan from the
    first target's IK); then the export cases that must not get slower."""
    from retarget.collision import CollisionModel

    arm = retarget.load_arm("wx250s")
    motion = retarget.load_bvh(clip)
    model = CollisionModel.for_arm(arm)
    print(f"1b. retarget export {clip.name} --arm wx250s, collisions on (clearance {model.clearance * 1e3:g} mm), "
          f"the whole command in process, best of {repeat}")  # fmt: skip
    for side in (Side.RIGHT, Side.LEFT):
        seconds, _ = export_command(clip, "wx250s", side.value, repeat)
        best, factor = min(seconds), motion.duration / min(seconds)
        median = statistics.median(seconds)
        row(f"{side.value}: whole command", f"{best * 1e3:.0f} ms = {factor:.0f}x", ">= 100x real time", factor >= 100)
        print(f"   ({side.value}: median {median * 1e3:.0f} ms = {motion.duration / median:.0f}x)")
        targets = retarget_targets(motion, arm, MappingConfig(side=side), collision=model)
        loop = ControlLoop(arm, targets, config=LoopConfig(collision=model), clock=VirtualClock())
        s = loop.run(None, q_start=loop.initial_pose())
        least, limit = s.min_clearance_mm, model.clearance * 1e3
        ok = least is not None and least >= limit
        row(f"{side.value}: least clearance written", f"{least:.1f} mm", f">= {limit:g} mm", ok)
        print(
            f"   (IK {s.ik_converged_pct:.1f}% converged, {s.ik_blocked_ticks} ticks stopped short by a collision; "
            f"{s.blocked_ticks} goals blocked; {s.pushed_targets} targets pushed out; "
            f"compute p99 {s.compute_ms_p99:.2f} ms)"
        )
    print("   export cases that must not get slower (whole command, best of the runs):")
    for name, arm_name, side_name in EXPORT_CASES:
        path = clip.parent / name
        if not path.is_file():
            print(f"   {name}: not found, skipped")
            continue
        seconds, _ = export_command(path, arm_name, side_name, repeat)
        duration = retarget.load_bvh(path).duration
        print(f"   {name} --arm {arm_name} --side {side_name}: {min(seconds) * 1e3:.0f} ms = "
              f"{duration / min(seconds):.0f}x real time")  # fmt: skip


def offline(clip: Path, repeat: int) -> None:
    arm = retarget.load_arm("wx250s")
    parse = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        motion = retarget.load_bvh(clip)
        motion.positions()
        parse.append(time.perf_counter() - t0)
    totals, mapping, summaries = [], [], []
    for i in range(repeat + 1):
        t0 = time.perf_counter()
        targets = retarget_targets(motion, arm)
        t1 = time.perf_counter()
        summary = ControlLoop(arm, targets, clock=VirtualClock(), clip_name=clip.name).run(None)
        t2 = time.perf_counter()
        if i:  # the first run is the warm-up
            totals.append(t2 - t0)
            mapping.append(t1 - t0)
            summaries.append(summary)
    total = statistics.median(totals)
    s = summaries[0]
    # IK convergence on the reachable ticks: every tick's target is inside the workspace after clamping, so all
    conv = min(x.ik_converged_pct for x in summaries)
    p99 = max(x.compute_ms_p99 for x in summaries)
    duration = motion.duration
    print(f"1. offline retargeting, {clip.name} ({motion.n_frames} frames, {duration:.1f} s) -> wx250s, no bus")
    print(f"   BVH parse + FK (not counted)       median {statistics.median(parse) * 1e3:.1f} ms")
    print(f"   mapping, all frames                median {statistics.median(mapping) * 1e3:.1f} ms")
    row(f"mapping + loop, {s.ticks} ticks", f"{total * 1e3:.1f} ms", "<= 160 ms", total <= 0.16)
    row("real-time factor", f"{duration / total:.0f}x", ">= 100x", duration / total >= 100)
    row("IK converged", f"{conv:.1f} %", "100 %", conv == 100)
    row("per-tick compute p99", f"{p99:.3f} ms", "<= 1 ms", p99 <= 1)
    print(
        f"   (ik error median {s.ik_error_median_mm:.2f} mm, p95 {s.ik_error_p95_mm:.2f} mm; "
        f"{s.ik_sweeps_mean:.1f} sweeps/tick; clamped {s.clamped_ticks}, velocity-limited {s.velocity_limited_ticks})"
    )


def on_bus(clip: Path, ticks: int) -> None:
    arm = retarget.load_arm("koch")
    motion = retarget.load_bvh(clip)
    targets = retarget_targets(motion, arm)
    # The servos start on the first target, so the bench measures the clip loop alone: no lead-in
    # (lead_in_speed=0; its ticks would be counted apart from the clip's anyway).  The wire time is measured
    # unpaced on the virtual clock, where only the wire moves time: at the loop's top rate (1 kHz) every tick of
    # this bus (about 1.06 ms of wire time) overruns its slot, so the loop never sleeps (checked below).
    unpaced = LoopConfig(rate=LoopConfig.RATE_RANGE[1], loop=True, max_ticks=ticks, lead_in_speed=0.0)
    q0 = ControlLoop(arm, targets, config=unpaced).initial_pose()

    def run(clock, config: LoopConfig, *, pipeline: bool = True) -> tuple[float, np.ndarray, np.ndarray, int]:
        """(clock seconds of the run, real period of each tick, real bus time of each tick, ticks)."""
        simbus = sim.SimBus.from_arm(arm, clock=clock, pose=q0, return_delay_time=0, faults=sim.Faults(wire=True))
        url = sim.attach(simbus)
        bus = DynamixelBus(arm, url, clock=clock, shutdown="hold", return_delay_us=0)
        stamps: list[float] = []
        bus_s: list[float] = []

        def on_tick(r: TickRecord) -> None:
            stamps.append(time.perf_counter())
            bus_s.append(r.bus_time)

        loop = ControlLoop(arm, targets, config=config, clock=clock, on_tick=on_tick, pipeline=pipeline)
        try:
            bus.connect()
            try:
                c0 = clock.now()
                summary = loop.run(bus)
                c1 = clock.now()
            finally:
                bus.close()
        finally:
            sim.unregister(url)
        computes.append(summary.compute_ms_p50 / 1e3)
        return (c1 - c0), np.diff(stamps), np.asarray(bus_s), summary.ticks

    computes: list[float] = []
    run(VirtualClock(), unpaced)  # warm-up
    virtual, _, _, n = run(VirtualClock(), unpaced)
    wire_period = virtual / n
    if wire_period <= 1.0 / unpaced.rate:
        print(
            f"   note: the wire time per tick is below the loop's top rate's slot; {wire_period * 1e3:.3f} ms is paced"
        )
    at_wire_rate = LoopConfig(rate=1.0 / wire_period, loop=True, max_ticks=ticks, lead_in_speed=0.0)
    _, periods, bus_s, n_real = run(MonotonicClock(), at_wire_rate)
    period = float(np.median(periods))
    summary_compute = computes[-1]
    _, periods_off, _, _ = run(MonotonicClock(), at_wire_rate, pipeline=False)
    period_off = float(np.median(periods_off))
    ratio = wire_period / period
    print(f"2. loop on the simulated bus: koch ({len(arm.servo_ids)} servos), 1 Mbps, wire model on, RDT 0")
    print(f"   wire time per tick (virtual clock)  {wire_period * 1e3:.3f} ms = {1 / wire_period:.0f} ticks/s")
    row(
        f"real clock, --rate {1 / wire_period:.0f}, {n_real} ticks: median period",
        f"{period * 1e3:.3f} ms = {1 / period:.0f}/s",
        ">= 90 % of wire rate",
        ratio >= 0.9,
    )
    print(
        f"   = {ratio * 100:.1f} % of the wire-limited rate; mean period {np.mean(periods) * 1e3:.3f} ms "
        f"(load spikes)\n   bus calls median {np.median(bus_s) * 1e3:.3f} ms (write, request and collect of the "
        f"read-back); loop compute median {summary_compute * 1e3:.3f} ms\n"
        f"   without the pipelined read-back (pipeline=False): median period {period_off * 1e3:.3f} ms = "
        f"{wire_period / period_off * 100:.1f} % of the wire-limited rate"
    )


def safety() -> None:
    arm = retarget.load_arm("wx250s")
    clips = sorted(SHARED.glob("*.bvh"))
    outside = violations = ticks = 0
    vmax = arm.max_velocity / 100.0
    for clip in clips:
        motion = retarget.load_bvh(clip)
        for side in (Side.LEFT, Side.RIGHT):
            targets = retarget_targets(motion, arm, MappingConfig(side=side))
            q: list[np.ndarray] = []

            def keep(r: TickRecord, q: list[np.ndarray] = q) -> None:
                q.append(r.q_cmd)

            ControlLoop(arm, targets, clock=VirtualClock(), on_tick=keep).run(None)
            Q = np.array(q)
            ticks += len(Q)
            outside += int(np.count_nonzero((Q < arm.lower) | (Q > arm.upper)))
            violations += int(np.count_nonzero(np.abs(np.diff(Q, axis=0)) > vmax + 1e-12))
    print(f"3. safety: {len(clips)} clips x 2 sides, {ticks} ticks on wx250s")
    row("commanded angles outside limits", str(outside), "0", outside == 0)
    row("velocity-limit violations", str(violations), "0", violations == 0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--clip", type=Path, default=SHARED / "motion_dance.bvh")
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--bus-ticks", type=int, default=2000)
    parser.add_argument("--skip-bus", action="store_true")
    parser.add_argument("--export-only", action="store_true", help="only case 1b: retarget export, collisions on")
    args = parser.parse_args()
    if not args.clip.is_file():
        raise SystemExit(f"bench_replay: clip not found: {args.clip} (set RETARGET_SHARED_BVH)")
    if args.export_only:
        offline_collisions(args.clip, args.repeat)
        return
    offline(args.clip, args.repeat)
    offline_collisions(args.clip, args.repeat)
    if not args.skip_bus:
        on_bus(args.clip, args.bus_ticks)
    safety()


if __name__ == "__main__":
    main()
