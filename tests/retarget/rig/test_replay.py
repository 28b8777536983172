"""Bimanual replay (dry runs): each arm follows its own hand, the hands' relation is kept, the arms never touch."""

from __future__ import annotations

import csv
import io

import numpy as np
import pytest

import retarget
from retarget.bvh.parse import DEMO_CLIP
from retarget.collision import CollisionModel
from retarget.control.clock import VirtualClock
from retarget.control.loop import LoopConfig
from retarget.control.plan import tool_task
from retarget.mapping import Targets, Workspace
from retarget.mapping.config import MappingConfig
from retarget.rig import RigReplay, RigTargets, load_rig, rig_targets
from retarget.rig.telemetry import RigTelemetry
from tests.helpers import SHARED_BVH, sampled_min_clearance

PUSH = SHARED_BVH / "push.bvh"
needs_push = pytest.mark.skipif(not PUSH.is_file(), reason=f"real BVH clips not found at {SHARED_BVH}")


def tool_in_world(rig_arm, q):
    """The tool point of ``q`` (rad) in the world, by the arm's own FK and the rig's placement (``(3,)`` m)."""
    return rig_arm.placement.to_world(rig_arm.arm.fk(q)[0][:3, 3])


def dry_run(rig, targets, **kwargs):
    models = {a.name: CollisionModel.for_arm(a.arm) for a in rig.arms}
    records = []
    replay = RigReplay(rig, targets, models=models, clock=VirtualClock(), on_tick=records.append, **kwargs)
    summary = replay.run(None, q_start=replay.initial_pose())
    return replay, summary, records


@needs_push
def test_each_arm_follows_its_own_hand_and_the_hands_keep_their_distance():
    rig = load_rig("aloha")
    targets = rig_targets(retarget.load_bvh(PUSH), rig)
    replay, summary, records = dry_run(rig, targets)
    assert summary.rig.ticks == len(records) == replay.n_slots
    times = np.array([r.clip_time for r in records])
    tools = {}
    for a in rig.arms:
        q = np.array([replay.arm_record(r, a.name).q_cmd for r in records])
        tools[a.name] = np.array([tool_in_world(a, x) for x in q])
        own = np.array([targets.arms[a.name].reference(times)]).reshape(-1, 3)
        own_world = a.placement.to_world(own)
        # each tool point is at its own hand's target, and far from the other hand's
        err = np.linalg.norm(tools[a.name] - own_world, axis=1)
        assert np.percentile(err, 95) < 0.03, a.name
        assert summary.arms[a.name].ik_converged_pct > 95
    left, right = rig.names
    hands = np.linalg.norm(
        rig[left].placement.to_world(targets.arms[left].reference(times))
        - rig[right].placement.to_world(targets.arms[right].reference(times)),
        axis=1,
    )
    robot = np.linalg.norm(tools[left] - tools[right], axis=1)
    assert np.median(np.abs(robot - hands)) < 0.02  # the tools' distance follows the hands' (scaled, clamped)
    for r in records[::3]:  # no contact between the arms, by the independent brute-force check
        poses = {a.name: replay.arm_record(r, a.name).q_cmd for a in rig.arms}
        assert sampled_min_clearance(rig, poses, spacing=0.01) > 0


def clap(rig, *, seconds=3.0, frame_time=1 / 30):
    """Both hands from 0.25 m out to the rig's middle line, 0.3 m ahead at 0.25 m height: a clap."""
    t = np.arange(0.0, seconds + 1e-9, frame_time)
    s = np.clip(t / (seconds - 1.0), 0.0, 1.0)[:, None]
    config = MappingConfig()
    arms, world = {}, {}
    for a, sign in zip(rig.arms, (1.0, -1.0), strict=True):
        y = a.placement.xyz[1]
        start = np.array([0.3, y - sign * 0.05, 0.25])
        end = np.array([0.3, 0.0, 0.25])
        world[a.name] = start + s * (end - start)
        arms[a.name] = Targets.from_raw(
            a.placement.to_base(world[a.name]), frame_time=frame_time, workspace=Workspace.for_arm(a.arm, config)
        )
    return RigTargets(arms=arms, world=world, scale=1.0, origin=np.zeros(3))


def test_hands_that_clap_stop_at_the_clearance():
    rig = load_rig("wx250s-pair")
    replay, summary, records = dry_run(rig, clap(rig))
    assert summary.rig.blocked_ticks > 0  # the goals into the other arm were not written
    assert summary.rig.min_clearance_mm >= 10.0 - 1e-6
    last = {a.name: replay.arm_record(records[-1], a.name).q_cmd for a in rig.arms}
    assert 0.0 < sampled_min_clearance(rig, last, spacing=0.004) < 0.04  # they came close, and stopped


def test_telemetry_has_each_arms_columns_and_their_tracking_error():
    rig = load_rig("wx250s-pair")
    targets = rig_targets(retarget.load_bvh(DEMO_CLIP), rig)
    replay = RigReplay(rig, targets, config=LoopConfig(max_ticks=30), clock=VirtualClock())
    text = io.StringIO()
    with RigTelemetry(text, replay) as telemetry:
        replay.on_tick = telemetry
        replay.run(None, q_start=replay.initial_pose())
    rows = list(csv.DictReader(io.StringIO(text.getvalue())))
    assert len(rows) == 30
    for a in rig.arms:
        for row in rows[::7]:
            q = np.array([float(row[f"{a.name}/{j}_cmd_rad"]) for j in a.arm.joint_names])
            mapped = targets.arms[a.name].reference(np.array([float(row["clip_time_s"])]))[0]
            expected = 1e3 * np.linalg.norm(a.arm.fk(q)[0][:3, 3] - mapped)
            assert float(row[f"{a.name}/tracking_mm"]) == pytest.approx(expected, abs=2e-3)
            assert row[f"{a.name}/waist_present_rad"] == ""  # a dry run reads nothing back


def test_the_lead_in_moves_every_arm_from_rest_to_the_clips_first_poses():
    rig = load_rig("wx250s-pair")
    targets = rig_targets(retarget.load_bvh(DEMO_CLIP), rig)
    models = {a.name: CollisionModel.for_arm(a.arm) for a in rig.arms}
    records = []
    replay = RigReplay(rig, targets, config=LoopConfig(end=0.05), models=models, clock=VirtualClock(),
                       on_tick=records.append)  # fmt: skip
    summary = replay.run(None, q_start=replay.plant.rest, lead_in=True)
    lead = [r for r in records if r.lead_in]
    assert summary.rig.lead_in_ticks == len(lead) > 10 and not any(r.blocked for r in records)
    np.testing.assert_allclose(lead[-1].q_cmd, replay.initial_pose(), atol=1e-6)  # arrived, every arm
    for r in lead[::5]:
        poses = {a.name: replay.arm_record(r, a.name).q_cmd for a in rig.arms}
        assert sampled_min_clearance(rig, poses, spacing=0.01) > 0


def test_the_plan_fits_each_arms_tool_point_in_its_own_rows_and_joints():
    """The rig's look-ahead task: block-diagonal Jacobians (an arm's joints move only its own tool point), each block
    the arm's own, and each arm's residual its tool point's distance from its target."""
    rig = load_rig("wx250s-pair")
    targets = rig_targets(retarget.load_bvh(DEMO_CLIP), rig)
    replay = RigReplay(rig, targets, config=LoopConfig(max_ticks=30), clock=VirtualClock())
    q = np.random.default_rng(3).uniform(replay.plant.lower, replay.plant.upper, (7, len(replay.plant.lower)))
    aims = np.random.default_rng(4).normal(0.3, 0.1, (7, 3 * len(rig.arms)))
    parts = [(a.arm.chain, part) for a, part in zip(rig.arms, replay.plant.slices, strict=True)]
    jacobians, residuals = tool_task(parts, q, aims)
    assert jacobians.shape == (7, 3 * len(rig.arms), q.shape[1]) and residuals.shape == (7, 3 * len(rig.arms))
    for k, (a, part) in enumerate(zip(rig.arms, replay.plant.slices, strict=True)):
        rows = slice(3 * k, 3 * k + 3)
        tool, own = a.arm.chain.tool_jacobians(q[:, part])
        np.testing.assert_array_equal(jacobians[:, rows, part], own)
        others = np.ones(q.shape[1], dtype=bool)
        others[part] = False
        assert not jacobians[:, rows][:, :, others].any()
        np.testing.assert_allclose(residuals[:, rows], tool - aims[:, rows])


def test_a_held_arm_has_no_task_on_its_held_ticks():
    """tool_task's ``held``: an arm's rows are zero on the ticks it is held (its IK stopped short of a collision),
    the other arm's rows and ticks as without it."""
    rig = load_rig("wx250s-pair")
    replay = RigReplay(rig, rig_targets(retarget.load_bvh(DEMO_CLIP), rig), config=LoopConfig(max_ticks=30),
                       clock=VirtualClock())  # fmt: skip
    q = np.random.default_rng(5).uniform(replay.plant.lower, replay.plant.upper, (6, len(replay.plant.lower)))
    aims = np.random.default_rng(6).normal(0.3, 0.1, (6, 3 * len(rig.arms)))
    parts = [(a.arm.chain, part) for a, part in zip(rig.arms, replay.plant.slices, strict=True)]
    held = np.zeros((6, 2), dtype=bool)
    held[[1, 4], 1] = True
    free_j, free_r = tool_task(parts, q, aims)
    jacobians, residuals = tool_task(parts, q, aims, held)
    assert not jacobians[[1, 4], 3:].any() and not residuals[[1, 4], 3:].any()
    free_j[[1, 4], 3:], free_r[[1, 4], 3:] = 0.0, 0.0
    np.testing.assert_array_equal(jacobians, free_j)
    np.testing.assert_array_equal(residuals, free_r)


def test_each_arms_ik_path_is_polished_so_its_joints_do_not_saw():
    """Each arm's IK pass (retarget.rig.replay.ArmPath.solve) takes one batched DLS step after its solves
    (retarget.control.polish): its tool points sit within microns of their targets instead of anywhere within the
    solver's 1 mm (the early-out's tick-to-tick sawtooth).  Measured on the demo clip, wx250s-pair: 0.2 mm p95
    before, 16 um now (the right arm; the left 1 um); commanded jerk RMS 815 rad/s^3 before, 229 now (aloha: 604,
    195)."""
    rig = load_rig("wx250s-pair")
    replay, summary, records = dry_run(rig, rig_targets(retarget.load_bvh(DEMO_CLIP), rig))
    for a in rig.arms:
        path = replay.paths[a.name]
        error = np.linalg.norm(a.arm.chain.tool_points(path.q) - path.targets, axis=1)
        assert float(np.percentile(error, 95)) < 0.05e-3, a.name
        assert float(path.error.max()) <= 1e-3  # the solver's own figures are kept
    q = np.array([r.q_cmd for r in records if not r.lead_in])
    jerk = np.diff(q, 3, axis=0) * replay.config.rate**3
    assert float(np.sqrt(np.mean(jerk**2))) < 400.0


def test_a_ball_in_an_arms_way_is_planned_around_without_a_blocked_goal():
    """The rig's plan keeps clear of each arm's world too (retarget.rig.keepclear): wx250s-pair on the demo clip with a
    5 cm ball in each arm's base frame at (0.28, -0.12, 0.40), in the right arm's way.  Measured: 101 blocked goals,
    stops at 169 rad/s^2 and the right arm 116 mm p95 off before; 0, 43 rad/s^2 and 59 mm now."""
    from retarget.collision import Sphere, World

    rig = load_rig("wx250s-pair")
    world = World(keep_out=(Sphere((0.28, -0.12, 0.40), 0.05),))
    models = {a.name: CollisionModel.for_arm(a.arm, world=world) for a in rig.arms}
    records = []
    replay = RigReplay(rig, rig_targets(retarget.load_bvh(DEMO_CLIP), rig), models=models, clock=VirtualClock(),
                       on_tick=records.append)  # fmt: skip
    replay.run(None, q_start=replay.initial_pose())
    assert sum(r.blocked for r in records) == 0
    q = np.array([r.q_cmd for r in records if not r.lead_in])
    accel = np.abs(np.diff(q, 2, axis=0)) * replay.config.rate**2
    assert np.all(accel <= replay.plant.max_acceleration * (1 + 1e-6))
    for a, part in zip(rig.arms, replay.plant.slices, strict=True):
        assert min(models[a.name].min_clearance(x) for x in q[::5, part]) >= models[a.name].clearance
