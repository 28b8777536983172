"""The Koch follows a human arm clear of itself and the table (issue 14): its arm file's ``[mapping]`` puts the hand
where its collision model (``[collision]``) lets the IK reach it, and an export keeps every commanded pose clear."""

from __future__ import annotations

import os

import numpy as np
import pytest

from retarget import load_arm
from retarget.cli import build_parser
from retarget.cli.export import offline_loop
from retarget.collision import CollisionModel
from retarget.ik import CCDSolver
from retarget.mapping.config import MappingConfig
from retarget.mapping.workspace import ik_weights
from tests.helpers import brute_force_min_clearances, shared_clip_params, t_pose, targets_of

#: columns of tests.helpers' CMU skeleton (``t_pose``): each arm joint's Z, X, Y rotation (degrees); an arm at 0 is
#: held out sideways (a T-pose), Z turns it down or up, Y forward or back
ARM, FOREARM = {"right": 27, "left": 15}, {"right": 30, "left": 18}
POSES = {  # (upper arm Z, Y; forearm Y), the right arm's; the left arm's mirrored
    "hanging": (90, 0, 0),  # a hanging arm: the hand lowest, in front of the robot (was within the jaw of the table)
    "forward": (0, 90, 0),
    "hand-in-front": (90, 0, 90),  # elbow bent, forearm forward
    "hand-behind": (90, 0, -90),  # elbow bent, forearm back: the hand beside the robot's own shoulder
    "raised": (-90, 0, 0),
    "out": (0, 0, 0),
}


def human_pose(side: str, pose: str) -> np.ndarray:
    """One frame ``(1, n_channels)`` of the CMU skeleton with the ``side`` arm in ``pose``."""
    z, y, fy = POSES[pose]
    sign = 1.0 if side == "right" else -1.0
    frames = t_pose(1)
    frames[0, ARM[side]] = sign * z
    frames[0, ARM[side] + 2] = sign * y
    frames[0, FOREARM[side] + 2] = sign * fy
    return frames


@pytest.mark.parametrize("side", ["right", "left"])
@pytest.mark.parametrize("pose", list(POSES))
def test_the_koch_reaches_a_mapped_human_pose_from_home_clear_of_itself_and_the_table(side, pose):
    arm = load_arm("koch")
    config = MappingConfig.from_table(arm.mapping, path=arm.source, overrides={"side": side})
    model = CollisionModel.for_arm(arm)
    solver = CCDSolver(arm, weights=ik_weights(arm, config), collision=model)
    target = targets_of(human_pose(side, pose), arm, config).positions[0]
    result = solver.solve(target, arm.home)
    assert result.converged and not result.blocked, (pose, target, result)
    assert brute_force_min_clearances(arm, result.q[None])[0] >= model.clearance  # checked independently


def test_a_hanging_arm_maps_in_front_of_the_koch_well_above_the_table():
    arm = load_arm("koch")
    pivot = arm.fk(arm.home)[1][1]  # the shoulder_lift joint
    hanging = targets_of(human_pose("right", "hanging"), arm, MappingConfig.from_table(arm.mapping)).positions[0]
    raised = targets_of(human_pose("right", "raised"), arm, MappingConfig.from_table(arm.mapping)).positions[0]
    assert hanging[2] > 0.08  # the jaw pointing down stays clear of the table
    assert pivot[0] - hanging[0] > 0.1  # ahead of the shoulder (the Koch's forward is -x), not folded beside it
    assert raised[2] - hanging[2] > 0.15  # and the motion keeps its range: 0.36 of the reach per human arm length


@pytest.mark.parametrize("side", ["right", "left"])
@pytest.mark.parametrize("clip", shared_clip_params())
def test_a_koch_export_of_a_shared_clip_reaches_every_target_with_every_pose_clear(clip, side):
    argv = ["export", str(clip), "--arm", "koch", "--side", side, "--end", "4", "-o", os.devnull]
    inputs, loop = offline_loop(build_parser().parse_args(argv))
    q_cmd: list[np.ndarray] = []
    loop.on_tick = lambda r: q_cmd.append(r.q_cmd)
    summary = loop.run(None, q_start=loop.initial_pose())
    assert summary.blocked_ticks == 0 and summary.ik_blocked_ticks == 0
    assert summary.ik_converged_pct == 100.0  # every (filtered) target reached, within the IK tolerance
    clearances = brute_force_min_clearances(inputs.arm, np.array(q_cmd))  # checked independently of the model
    assert clearances.min() >= inputs.collision.clearance
