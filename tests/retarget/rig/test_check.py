"""The rig's goal check: each arm's own check, and the arms against each other on the pose and the path."""

from __future__ import annotations

import math

import numpy as np
import pytest

from retarget.collision import CollisionModel
from retarget.ik.bound import shared_bound
from retarget.rig import RigPlant, load_rig
from retarget.rig.check import RigGoalCheck, _fall
from retarget.rig.clearance import RigClearance
from retarget.rig.proof import RigProof, sample_step
from tests.helpers import brute_force_min_clearances, sampled_min_clearance


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


def random_move(rng, n):
    """A seeded joint move ``(n,)`` rad: one joint turned (the first-order bound's worst case), a small move of all,
    or a large one (where the second-order term counts)."""
    kind = rng.integers(3)
    if kind == 0:
        dq = np.zeros(n)
        dq[rng.integers(n)] = rng.choice([-1, 1]) * rng.uniform(0.01, 0.3)
        return dq
    return rng.normal(0, 0.05 if kind == 1 else 0.5, n)


def test_each_pair_closes_no_more_than_its_fall_and_nearly_as_much(pair):
    """Seeded property of the arm-against-arm bounds from a measured pose: no pair's exact clearance falls by more
    than its bound (``_falls`` with that pose's levers), nor by more than the whole rig's (``_fall``, every pair at
    once), and each comes within a few % of it somewhere (a bound weakened by more fails)."""
    rig, plant, models, between = pair
    check = RigGoalCheck(plant, models, between, plant.home)
    rng = np.random.default_rng(7)
    reached = whole_reached = 0.0
    for _ in range(300):
        q = rng.uniform(plant.lower, plant.upper) * 0.7
        ref = check._measured(q)
        gaps, levers, whole = ref[1], ref[3], ref[4]
        dq = random_move(rng, plant.n_joints)
        for s in (0.5, 1.0):
            fall = check._falls(levers, s * dq[:, None])[:, 0]
            closed = gaps - between.distances(plant.split(q + s * dq))
            assert np.all(closed <= fall + 1e-12)
            assert fall.max() <= _fall(whole, (q + s * dq).tolist()) + 1e-12
            big = fall > 1e-4
            reached = max(reached, float((closed[big] / fall[big]).max(initial=0.0)))
            whole_reached = max(whole_reached, fall.max() / _fall(whole, (q + s * dq).tolist()))
    assert reached > 0.95 and whole_reached > 0.999


def test_a_segment_keeps_half_its_ends_clearances_less_half_its_fall(pair):
    """Seeded property of the segment bound after a query: along a move whose ends were measured, each pair keeps
    ``(d0 + d1 - fall) / 2`` (exact clearances densely sampled), and some pair comes within 10 % of it."""
    rig, plant, models, between = pair
    check = RigGoalCheck(plant, models, between, plant.home)
    rng = np.random.default_rng(17)
    reached = 0.0
    for _ in range(150):
        a = rng.uniform(plant.lower, plant.upper) * 0.7
        b = a + random_move(rng, plant.n_joints)
        d0, end = check._measured(a)[1], check._measured(b)
        fall = check._falls(end[3], (a - b)[:, None])[:, 0]
        low = 0.5 * (d0 + end[1] - fall)
        s = np.linspace(0, 1, 201)[:, None]
        least = between.distances(plant.split(a + s * (b - a))).min(axis=0)
        assert np.all(least >= low - 1e-12)
        dip = 0.5 * (d0 + end[1]) - least  # how far the middle fell below the ends' mean
        big = fall > 1e-3
        reached = max(reached, float((dip[big] / (0.5 * fall[big])).max(initial=0.0)))
    assert reached > 0.9


def test_every_allowed_move_keeps_the_clearance_along_its_whole_path(pair):
    """Seeded property: a walk toward the other arm with a wide clearance (3 cm); every allowed move, sampled
    densely by the exact distances, keeps the clearance at its end and at least 3/4 of it between (the check's
    samples near a contact are half a clearance of travel apart)."""
    rig, plant, models, _ = pair
    between = RigClearance(rig, clearance=0.03)
    rng = np.random.default_rng(13)
    q = plant.home.copy()
    check = RigGoalCheck(plant, models, between, q)
    allowed = blocked = 0
    nearest = np.inf
    for _ in range(200):
        step = rng.normal(0, 0.06, plant.n_joints)
        step[0] -= 0.04  # drift the waists toward each other so that the arms meet
        step[6] += 0.04
        target = np.clip(q + step, plant.lower, plant.upper)
        if check.allows(q.tolist(), target.tolist()):
            allowed += 1
            s = np.linspace(0, 1, 25)[:, None]
            path = between.min_clearance(plant.split(q + s * (target - q)))
            assert path[-1] >= 0.03 - 1e-9 and path.min() >= 0.75 * 0.03 - 1e-9
            assert check.clearance <= path.min() + 1e-9  # the clearance reported is a lower bound
            q, nearest = target, min(nearest, float(path.min()))
        else:
            blocked += 1
    assert allowed > 50 and blocked >= 3 and nearest < 0.04  # the walk moved, and kept coming near the other arm


def proven_path(rig, plant, between, models, path):
    """The proof of ``path`` as a replay makes it: each arm's own bounds from notes of every pose of it (as an IK
    pass leaves them), and the arms apart."""
    own = {}
    for a, part in zip(rig.arms, plant.slices, strict=True):
        model = models[a.name]
        bound = shared_bound(model)
        notes = bound.record()
        index = []
        for k, q in enumerate(path[:, part]):
            bound.note(q, model.distances(q))
            if k:
                index.append(len(notes) - 1)
        own[a.name] = bound.prove(path[:-1, part], path[1:, part], notes, index).lows
    return RigProof.prove(between, path, own)


def test_a_proof_changes_no_decision_and_every_move_it_allows_is_clear(pair):
    """Seeded property: a planned path (the arms drift into each other and apart, the left one down into the table
    and up) proven ahead; a run along it (a few goals knocked off it, holding where a goal is blocked, back on the
    path after) is allowed and blocked move for move as by the same check without the proof (its own models: no
    shared bounds), and every move allowed keeps each arm off itself, the table and the other arm (brute force)."""
    rig, plant, _, between = pair
    rng = np.random.default_rng(23)
    q = plant.home.copy()
    path = [q]
    for k in range(140):
        step = rng.normal(0, 0.008, plant.n_joints)
        drift = 0.008 if k < 80 else -0.014
        step[0], step[6] = step[0] - drift, step[6] + drift
        down = 1 if 30 <= k < 60 else -1 if 60 <= k < 90 else 0  # the left shoulder and elbow down, then up
        step[1], step[2] = step[1] + down * 0.027, step[2] + down * 0.013
        q = np.clip(q + step, plant.lower, plant.upper)
        path.append(q)
    path = np.array(path)
    models = {a.name: CollisionModel.for_arm(a.arm) for a in rig.arms}
    proof = proven_path(rig, plant, between, models, path)
    plain = RigGoalCheck(plant, {a.name: CollisionModel.for_arm(a.arm) for a in rig.arms}, between, path[0])
    check = RigGoalCheck(plant, models, between, path[0], proof=proof)
    q, moves, blocked, found = path[0], [], 0, 0
    for k in range(1, len(path)):
        goal = path[k] + (rng.normal(0, 0.01, plant.n_joints) if rng.random() < 0.05 else 0.0)
        found += np.array_equal(q, path[k - 1]) and np.array_equal(goal, path[k])  # a move of the path
        allowed = check.allows(q.tolist(), goal.tolist())
        assert allowed == plain.allows(q.tolist(), goal.tolist()), k
        if allowed:
            moves.append((q, goal))
            q = goal
        else:
            blocked += 1
    assert blocked >= 5 and len(moves) > 70 and found > 70
    s = np.linspace(0.0, 1.0, 5)[:, None]
    along = np.concatenate([a + s * (b - a) for a, b in moves])
    for a, part in zip(rig.arms, plant.slices, strict=True):
        assert brute_force_min_clearances(a.arm, along[:, part]).min() > 0
    near = along[between.min_clearance(plant.split(along)) < 0.05]  # (the far poses are clear by centimetres)
    assert len(near) >= 5
    for x in near:
        assert sampled_min_clearance(rig, plant.split(x), spacing=0.01) > 0


def test_each_verdict_is_that_of_a_fresh_check_from_the_pose_held(pair):
    """Seeded property: along a walk into the other arm (a 3 cm clearance; a blocked goal followed by a shorter step
    from the pose held, as the loop brakes), the check allows and blocks each move exactly as a check started at
    the move's start does (its own models: no shared bounds, no recalled poses), whatever it measured before.  A
    goal the arms apart block leaves each arm's own check as it was (not to start again)."""
    rig, plant, models, _ = pair
    between = RigClearance(rig, clearance=0.03)
    fresh_models = {a.name: CollisionModel.for_arm(a.arm) for a in rig.arms}
    rng = np.random.default_rng(43)
    q = plant.home.copy()
    check = RigGoalCheck(plant, models, between, q)
    verdicts = {True: 0, False: 0}
    kept = 0
    for _ in range(160):
        step = rng.normal(0, 0.06, plant.n_joints)
        step[0], step[6] = step[0] - 0.04, step[6] + 0.04  # the waists drift toward each other
        for scale in (1.0, 0.3):  # a goal, and when it is blocked a shorter step from the pose held
            target = np.clip(q + scale * step, plant.lower, plant.upper)
            fresh = RigGoalCheck(plant, fresh_models, between, q)
            own = dict(check._checks)
            allowed = check.allows(q.tolist(), target.tolist())
            assert allowed == fresh.allows(q.tolist(), target.tolist())
            verdicts[allowed] += 1
            if allowed:
                q = target
                break
            if RigGoalCheck(plant, fresh_models, between, q)._segment_apart(q.tolist(), target.tolist()) < 0.03:
                assert not check._behind and all(check._checks[n] is own[n] for n in own)  # (as it was)
                kept += 1
    assert verdicts[True] > 60 and verdicts[False] >= 10 and kept >= 3


def test_a_sampled_move_has_the_figure_of_every_pair_sampled(pair):
    """Seeded property: a move past the other arm that the bounds leave short (from the start, then pair by pair
    from both ends' clearances) is sampled, and the check's figure is exactly the least of every pair at the same
    samples (as many as the end's levers ask for) and of the ends, though it measures only the pairs that may be the
    least; some of these moves' least sample is a pair nearest at neither end (so a screen that kept only the ends'
    nearest pairs fails)."""
    rig, plant, models, between = pair
    rng = np.random.default_rng(47)
    limit, sampled, elsewhere = between.clearance, 0, 0
    for _ in range(32):
        q = rng.uniform(plant.lower, plant.upper) * 0.6
        q[0], q[6] = -np.pi / 2 + rng.normal(0, 0.3), np.pi / 2 + rng.normal(0, 0.3)  # waists toward each other
        half = rng.normal(0, 0.3, plant.n_joints)
        a, b = q - half, q + half
        check = RigGoalCheck(plant, models, between, a)
        start, end = check._measured(a), check._measured(b)
        from_start = float((start[1] - check._falls(start[3], (b - a)[:, None])[:, 0]).min())
        fall = check._falls(end[3], (a - b)[:, None])[:, 0]
        if from_start >= limit or end[2] < limit or float((0.5 * (start[1] + end[1] - fall)).min()) >= limit:
            continue  # proven from the start, refused at its end, or proven from both ends: not sampled
        sampled += 1
        s = np.linspace(0.0, 1.0, max(2, math.ceil(float(fall.max()) / sample_step(limit)) + 1))[:, None]
        every = between.distances(plant.split(a + s * (b - a)))
        assert check._segment_apart(a.tolist(), b.tolist()) == min(float(every.min()), start[2], end[2])
        nearest = np.unravel_index(every.argmin(), every.shape)[1]
        elsewhere += nearest not in (start[1].argmin(), end[1].argmin())
    assert sampled >= 10 and elsewhere >= 2
