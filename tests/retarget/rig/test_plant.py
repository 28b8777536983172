"""A rig's arms as one joint vector."""

from __future__ import annotations

import numpy as np
import pytest

from retarget.rig import RigPlant, load_rig


@pytest.mark.parametrize("name", ["aloha", "wx250s-pair"])
def test_the_plant_concatenates_every_arm_in_rig_order(name):
    rig = load_rig(name)
    plant = RigPlant.of(rig)
    assert plant.n_joints == sum(a.arm.n_joints for a in rig.arms)
    for a, part in zip(rig.arms, plant.slices, strict=True):
        np.testing.assert_array_equal(plant.lower[part], a.arm.lower)
        np.testing.assert_array_equal(plant.upper[part], a.arm.upper)
        np.testing.assert_array_equal(plant.max_velocity[part], a.arm.max_velocity)
        np.testing.assert_array_equal(plant.max_acceleration[part], a.arm.max_acceleration)
        np.testing.assert_array_equal(plant.rest[part], a.arm.rest)
        assert plant.joint_names[part] == tuple(f"{a.name}/{j}" for j in a.arm.joint_names)


def test_split_and_join_round_trip_single_poses_and_batches():
    plant = RigPlant.of(load_rig("wx250s-pair"))
    rng = np.random.default_rng(7)
    for shape in [(plant.n_joints,), (5, plant.n_joints)]:
        q = rng.uniform(-1, 1, shape)
        parts = plant.split(q)
        assert parts["left"].shape == shape[:-1] + (6,)
        np.testing.assert_array_equal(plant.join(parts), q)


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda p: p.split(np.zeros(5)), r"Expected poses of 12 joints, got shape \(5,\)"),
        (lambda p: p.join({"left": np.zeros(6)}), "Expected a pose for every arm of the rig, got none for right"),
    ],
    ids=["split-wrong-size", "join-missing-arm"],
)
def test_bad_vectors_are_refused(call, match):
    with pytest.raises(ValueError, match=match):
        call(RigPlant.of(load_rig("wx250s-pair")))
