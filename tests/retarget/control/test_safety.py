"""GoalCheck (the tick loop's last word before a write): its answers match brute force, and a goal that is itself
within the clearance is refused without sampling the segment."""

from __future__ import annotations

import numpy as np
import pytest

from retarget import load_arm
from retarget.collision import CollisionModel
from retarget.control.safety import GoalCheck
from tests.helpers import brute_force_min_clearances


@pytest.fixture
def wx():
    return load_arm("wx250s")


def test_a_goal_inside_an_obstacle_is_refused_without_sampling(wx, monkeypatch):
    model = CollisionModel.for_arm(wx)
    check = GoalCheck(model, wx.home)
    goal = wx.home.copy()
    goal[1], goal[2] = 1.6, 0.2  # the shoulder down: the gripper into the table
    assert brute_force_min_clearances(wx, goal[None])[0] < model.clearance

    def no_sampling(*_):
        raise AssertionError("the segment was sampled")

    monkeypatch.setattr(check, "_segment_clear", no_sampling)
    before = check.clearance
    assert not check.allows(wx.home.tolist(), goal.tolist())
    assert check.clearance == before  # a blocked goal is not written: the clearance of the pose held


def test_goal_check_answers_agree_with_sampled_segments_along_a_seeded_walk(wx):
    """Seeded random walk of goals near the table and the base: each answer is True exactly when 101 samples of
    the segment keep the clearance (up to segments that graze it: those are skipped), and an accepted segment's
    reported clearance is at most the sampled one."""
    model = CollisionModel.for_arm(wx)
    rng = np.random.default_rng(31)
    q = wx.home.copy()
    check = GoalCheck(model, q)
    s = np.linspace(0.0, 1.0, 101)[:, None]
    answers = []
    for _ in range(100):
        goal = np.clip(q + rng.normal(0.0, 0.08, wx.n_joints) + [0.0, 0.03, 0.0, 0.0, 0.0, 0.0], wx.lower, wx.upper)
        true = float(brute_force_min_clearances(wx, q + s * (goal - q)).min())
        ok = check.allows(q.tolist(), goal.tolist())
        if abs(true - model.clearance) > 2e-3:
            assert ok == (true >= model.clearance)
        if ok:
            assert check.clearance <= true + 1e-9
            q = goal
        answers.append(ok)
    assert 10 < sum(answers) < 100  # both answers were exercised
