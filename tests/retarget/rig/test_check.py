"""The rig's goal check: each arm's own check, and the arms against each other on the pose and the path."""

from __future__ import annotations

import numpy as np
import pytest

from retarget.collision import CollisionModel
from retarget.rig import RigPlant, load_rig
from retarget.rig.check import RigGoalCheck
from retarget.rig.clearance import RigClearance
from tests.helpers import sampled_min_clearance


@pytest.fixture(scope="module")
def pair():
    rig = load_rig("wx250s-pair")
    plant = RigPlant.of(rig)
    models = {a.name: CollisionModel.for_arm(a.arm) for a in rig.arms}
    return rig, plant, models, RigClearance(rig)


def arms_touching(rig, plant, between, rng):
    """A seeded pose of both arms that is clear of each arm's own model but puts the arms within the clearance
    of each other (found by reaching both arms toward the middle)."""
    while True:
        q = rng.uniform(plant.lower, plant.upper) * 0.6
        parts = plant.split(q)
        parts["left"][0], parts["right"][0] = -np.pi / 2, np.pi / 2  # waists turned toward each other
        q = plant.join(parts)
        if between.min_clearance(plant.split(q)) < 0:
            return q


def test_a_move_into_the_other_arm_is_blocked_and_the_held_pose_stays_checked(pair):
    rig, plant, models, between = pair
    check = RigGoalCheck(plant, models, between, plant.home)
    touching = arms_touching(rig, plant, between, np.random.default_rng(3))
    assert sampled_min_clearance(rig, plant.split(touching)) < 0  # the independent check agrees
    assert not check.allows(plant.home.tolist(), touching.tolist())
    assert check.allows(plant.home.tolist(), plant.rest.tolist())  # the held pose's moves still go


def test_a_path_through_the_other_arm_is_blocked_though_both_ends_are_clear(pair):
    rig, plant, models, between = pair
    rng = np.random.default_rng(5)
    touching = arms_touching(rig, plant, between, rng)
    parts = plant.split(touching)
    # swing the left waist from one side of the contact to the other: both ends clear, the middle not
    for swing in np.linspace(0.2, 1.5, 27):
        a, b = touching.copy(), touching.copy()
        a[0], b[0] = parts["left"][0] - swing, parts["left"][0] + swing
        ends_clear = all(between.min_clearance(plant.split(x)) > 0.02 for x in (a, b))
        if ends_clear and all(models[n].is_clear(plant.split(x)[n]) for x in (a, b) for n in rig.names):
            break
    else:
        pytest.skip("no clear pair of ends found for this seed")
    check = RigGoalCheck(plant, models, between, a)
    assert not check.allows(a.tolist(), b.tolist())


def test_every_allowed_move_of_a_random_walk_keeps_the_arms_apart(pair):
    """Seeded property: a walk of random steps, each allowed or not by the check; every allowed move is sampled
    densely by the independent brute-force function, which never sees the arms overlap."""
    rig, plant, models, between = pair
    rng = np.random.default_rng(11)
    q = plant.home.copy()
    check = RigGoalCheck(plant, models, between, q)
    allowed = blocked = 0
    nearest = np.inf
    for _ in range(150):
        step = rng.normal(0, 0.08, plant.n_joints)
        step[0] -= 0.05  # drift the waists toward each other so that the arms meet
        step[6] += 0.05
        target = np.clip(q + step, plant.lower, plant.upper)
        if check.allows(q.tolist(), target.tolist()):
            allowed += 1
            for s in np.linspace(0, 1, 5)[1:]:
                assert sampled_min_clearance(rig, plant.split(q + s * (target - q)), spacing=0.01) > -1e-3
            q = target
            nearest = min(nearest, float(between.min_clearance(plant.split(q))))
        else:
            blocked += 1
    assert allowed > 20 and blocked >= 1 and nearest < 0.05  # the walk moved, and came near the other arm
