"""Mapped targets are pushed out of the collision model's blocked zones, and counted."""

from __future__ import annotations

import numpy as np

from retarget.collision import CollisionModel, Sphere, World
from retarget.mapping import Targets, Workspace


def test_targets_in_a_keep_out_are_pushed_out_and_counted(arm):
    model = CollisionModel.for_arm(arm, world=World(keep_out=(Sphere((0.3, 0.0, 0.2), 0.05),)))
    t = np.linspace(0.0, 1.0, 41)
    raw = np.stack([0.3 + 0 * t, -0.15 + 0.3 * t, 0.2 + 0 * t], axis=-1)  # a line through the ball's centre
    plain = Workspace.for_arm(arm)
    targets = Targets.from_raw(raw, frame_time=0.05, workspace=plain.with_blocked(model))
    inside = np.linalg.norm(raw - [0.3, 0.0, 0.2], axis=1) < 0.05 + model.clearance
    np.testing.assert_array_equal(targets.pushed, inside)
    assert targets.n_pushed == int(inside.sum()) > 0 and np.all(targets.clamped[inside])
    assert min(model.point_margin(p) for p in targets.positions) >= model.clearance - 1e-9
    np.testing.assert_array_equal(targets.positions[~inside], raw[~inside])  # the others untouched
    # sampled between frames, and one at a time: the same zones, the same push
    positions, _, moved = targets.sample(np.linspace(0.0, 2.0, 201))
    assert min(model.point_margin(p) for p in positions) >= model.clearance - 1e-9 and moved.any()
    one, flag = targets.at(1.0)  # the middle frame: the ball's centre
    assert flag and model.point_margin(one) >= model.clearance - 1e-9
    np.testing.assert_allclose(one, positions[100])
    free = Targets.from_raw(raw, frame_time=0.05, workspace=plain)
    assert free.n_pushed == 0 and not free.clamped.any()  # without the model: nothing blocked


def test_targets_below_the_table_are_lifted_clear(arm):
    model = CollisionModel.for_arm(arm)
    workspace = Workspace(center=np.array([0.0, 0.0, 0.11]), r_min=0.05, r_max=0.6, floor=-1.0).with_blocked(model)
    points, moved = workspace.clamp(np.array([[0.3, 0.0, -0.02], [0.3, 0.0, 0.2]]))
    np.testing.assert_array_equal(moved, [True, False])
    assert points[0, 2] >= model.clearance - 1e-12 and np.allclose(points[1], [0.3, 0.0, 0.2])
