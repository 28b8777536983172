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


def test_a_proven_move_is_taken_without_a_query_and_any_other_move_is_checked(wx, monkeypatch):
    """A planned path proven ahead (ClearanceBound.prove): the check takes each proven move's bound (no query, no
    sampling); a move that is not the next proven segment, or one whose bound falls short, is checked as ever."""
    from retarget.ik.bound import shared_bound

    model = CollisionModel.for_arm(wx)
    bound = shared_bound(model)
    notes = bound.record()
    bound.note(wx.home, model.distances(wx.home))
    path = wx.home + np.linspace(0.0, 0.04, 5)[:, None] * [1.0, 0.5, -0.5, 0.0, 0.3, 0.0]
    goal = wx.home.copy()
    goal[1], goal[2] = 1.6, 0.2  # the gripper into the table
    starts = np.vstack([path[:-1], path[-1:]])
    ends = np.vstack([path[1:], goal[None]])  # the last "segment" runs into the table: its bound falls short
    proven = bound.prove(starts, ends, notes, np.zeros(len(starts), dtype=np.intp))
    check = GoalCheck(model, path[0])

    def no_query(*_):
        raise AssertionError("queried")

    monkeypatch.setattr(model, "pair_bounds", no_query)
    monkeypatch.setattr(check, "_segment_clear", no_query)
    for q0, q1 in zip(path[:2], path[1:3], strict=True):
        assert check.allows(q0.tolist(), q1.tolist())
        assert model.clearance <= check.clearance <= brute_force_min_clearances(wx, q1[None])[0]
    monkeypatch.undo()
    assert not check.allows(path[2].tolist(), goal.tolist())  # not the next proven move: checked, refused
    assert check.allows(path[2].tolist(), path[3].tolist())  # the next one still is
    assert check.allows(path[3].tolist(), path[4].tolist())
    assert proven._low[-1] < model.clearance  # the move into the table: proven short of the clearance, so ...
    assert not check.allows(path[4].tolist(), goal.tolist())  # ... checked as ever, and refused
