"""A rig's planned path proven before it plays: the arms' bounds segment by segment, and finding a move's segment."""

from __future__ import annotations

import math

import numpy as np
import pytest

from retarget.collision import CollisionModel
from retarget.rig import RigPlant, load_rig
from retarget.rig.check import RigGoalCheck, _fall
from retarget.rig.clearance import RigClearance
from retarget.rig.proof import (
    RigProof,
    _Measured,
    pair_falls,
    pairs_along,
    prove_apart,
    sample_step,
    sampled_along,
    travel_spread,
    whole_falls,
)


@pytest.fixture(scope="module")
def pair():
    rig = load_rig("wx250s-pair")
    return rig, RigPlant.of(rig), RigClearance(rig)


def near_the_other_arm(plant, between, rng):
    """A seeded pose with the waists turned toward each other and the arms 2-15 cm apart."""
    while True:
        q = rng.uniform(plant.lower, plant.upper) * 0.6
        q[0], q[6] = -np.pi / 2 + rng.normal(0, 0.3), np.pi / 2 + rng.normal(0, 0.3)
        if 0.02 < float(between.min_clearance(plant.split(q))) < 0.15:
            return q


def sampled_least(plant, between, a, b, n=65):
    """The least arm-against-arm clearance of ``n`` poses along ``a -> b`` (exact distances), metres."""
    s = np.linspace(0.0, 1.0, n)[:, None]
    return float(between.min_clearance(plant.split(a + s * (b - a))).min())


def test_every_segment_keeps_its_bound_and_some_nearly_reach_it(pair):
    """Seeded property of single moves near the other arm (one joint turned, a small move of all, a large one): the
    proof's bound is at most the least exact clearance sampled along the move, and somewhere the bound's fall
    from the start comes within 1.6x of the true one (a bound weakened by half fails)."""
    rig, plant, between = pair
    rng = np.random.default_rng(5)
    reached = 0.0
    for _ in range(40):
        a = near_the_other_arm(plant, between, rng)
        kind = rng.integers(3)
        dq = rng.normal(0, 0.03 if kind == 1 else 0.15, plant.n_joints)
        if kind == 0:
            dq = np.zeros(plant.n_joints)
            dq[rng.integers(plant.n_joints)] = rng.choice([-1, 1]) * rng.uniform(0.02, 0.3)
        low = prove_apart(between, np.array([a, a + dq]))[0]
        least = sampled_least(plant, between, a, a + dq)
        assert low <= least + 1e-12
        start = float(between.min_clearance(plant.split(a)))
        if start - low > 1e-3:
            reached = max(reached, (start - least) / (start - low))
    assert reached > 0.6


def test_each_pair_keeps_half_its_ends_clearances_less_half_its_fall(pair):
    """Seeded property of the proof's last step, pair by pair: along a move between two measured poses each pair
    keeps ``(d0 + d1 - fall) / 2`` (exact clearances densely sampled), and some pair's dip below its ends' mean
    comes within 10 % of ``fall / 2`` (a step weakened by more fails)."""
    rig, plant, between = pair
    rng = np.random.default_rng(17)
    spread = travel_spread(between)
    reached = 0.0
    for _ in range(24):
        a = rng.uniform(plant.lower, plant.upper) * 0.7
        b = a + rng.normal(0, rng.choice([0.05, 0.5]), plant.n_joints)
        at = _Measured(between, np.array([a, b]))
        at.measure(np.array([0, 1]))
        low = pairs_along(between, spread, at, np.array([0]), (b - a)[None])[0]
        s = np.linspace(0, 1, 129)[:, None]
        least = between.distances(plant.split(a + s * (b - a))).min(axis=0)
        assert np.all(least >= low - 1e-12)
        fall = np.minimum(pair_falls(between, spread, at.levers[:1], (b - a)[None]),
                          pair_falls(between, spread, at.levers[1:], (b - a)[None]))[0]  # fmt: skip
        dip = 0.5 * (at.gaps[0] + at.gaps[1]) - least
        big = fall > 1e-3
        reached = max(reached, float((dip[big] / (0.5 * fall[big])).max(initial=0.0)))
    assert reached > 0.9


def test_a_walk_near_the_other_arm_is_proven_where_it_is_clear(pair):
    """Seeded walk of small steps (the waists drifting toward each other, then away): every segment's bound keeps
    below its sampled least clearance; most are proven clear, and a segment that is not clear never is."""
    rig, plant, between = pair
    rng = np.random.default_rng(9)
    q = plant.home.copy()
    path = [q]
    for k in range(240):
        step = rng.normal(0, 0.01, plant.n_joints)
        drift = 0.006 if k < 120 else -0.01
        step[0] -= drift
        step[6] += drift
        q = np.clip(q + step, plant.lower, plant.upper)
        path.append(q)
    path = np.array(path)
    low = prove_apart(between, path)
    s = np.linspace(0.0, 1.0, 17)[None, :, None]
    along = (path[:-1, None] + s * (path[1:] - path[:-1])[:, None]).reshape(-1, plant.n_joints)
    least = between.min_clearance(plant.split(along)).reshape(len(low), -1).min(axis=1)
    assert np.all(low <= least + 1e-12)
    proven = low >= between.clearance
    assert proven.mean() > 0.7 and not proven[least < between.clearance].any()
    assert (least < between.clearance).any()  # the walk went into the other arm


def test_the_batch_bounds_are_the_tick_checks(pair):
    """The proof measures and bounds as the tick check does, in batches: each pose's clearances, levers and the
    whole rig's levers as :meth:`RigGoalCheck._measured`'s, the whole fall as ``_fall``'s and each pair's as
    ``_falls``' (whose own tests hold them to the exact clearances)."""
    rig, plant, between = pair
    models = {a.name: CollisionModel.for_arm(a.arm) for a in rig.arms}
    check = RigGoalCheck(plant, models, between, plant.home)
    rng = np.random.default_rng(21)
    poses = rng.uniform(plant.lower, plant.upper, (12, plant.n_joints)) * 0.7
    dq = rng.normal(0, 0.2, poses.shape)
    at = _Measured(between, poses)
    at.measure(np.arange(len(poses)))
    spread = travel_spread(between)
    i, j = between.pair_shapes
    falls = whole_falls(at.whole, spread[i].max(axis=0) + spread[j].max(axis=0), dq)
    pairs = pair_falls(between, spread, at.levers, dq)
    for k, q in enumerate(poses):
        _, gaps, least, levers, whole = check._measured(q)
        np.testing.assert_allclose(at.gaps[k], gaps, rtol=0, atol=1e-12)
        np.testing.assert_allclose(at.levers[k], levers, rtol=0, atol=1e-12)
        assert at.least[k] == pytest.approx(least, abs=1e-12)
        assert falls[k] == pytest.approx(_fall(whole, (q + dq[k]).tolist()), rel=1e-12)
        np.testing.assert_allclose(pairs[k], check._falls(levers, dq[k][:, None])[:, 0], rtol=1e-12)


def test_a_move_is_found_on_the_path_again_after_leaving_it(pair):
    rig, plant, between = pair
    path = plant.home + np.linspace(0.0, 0.2, 21)[:, None]
    proof = RigProof(path, {"left": np.arange(20.0)}, np.full(20, 0.5), between)
    segment = [proof.segment(path[k].tolist(), path[k + 1].tolist()) for k in range(5)]
    assert segment == [0, 1, 2, 3, 4]
    off = (path[6] + 0.003).tolist()
    assert proof.segment(path[5].tolist(), off) == -1  # a blocked tick's brake: not the path
    assert proof.segment(off, path[7].tolist()) == -1  # nor its way back
    assert proof.segment(path[9].tolist(), path[10].tolist()) == 9  # the path again, found by its end
    assert proof.segment(path[10].tolist(), (path[11] + 1e-11).tolist()) == 10  # within EPS of it
    assert proof.segment(path[11].tolist(), (path[12] + 1e-6).tolist()) == -1
    assert proof.segment(path[0].tolist(), path[1].tolist()) == 0  # played again
    slack = 2 * RigProof.EPS * float(between.motion.max())
    assert proof.apart[3] == pytest.approx(0.5 - slack, abs=1e-15) and proof.arms["left"][3] == 3.0
    assert len(proof) == 20 and proof.segment([math.nan] * 12, path[1].tolist()) == -1


def test_a_close_pass_is_sampled_finely_enough_that_no_dip_between_samples_exceeds_the_step(pair):
    """Seeded property of the proof's sampling of close passes (``sampled_along``, the tick check's way), on moves
    that pass the other arm closest near their middle: its figure is at most a :func:`sample_step` above the least
    of 257 exact poses along the move (a pair closes by no more than that between two samples), and not below it
    by more than those dense samples may miss.  Measuring the ends alone misses the dip on some of these moves."""
    rig, plant, between = pair
    rng = np.random.default_rng(11)
    spread, step = travel_spread(between), sample_step(between.clearance)
    ends_miss = 0
    for _ in range(12):
        middle = near_the_other_arm(plant, between, rng)
        half = rng.normal(0, 0.15, plant.n_joints)
        a, b = middle - half, middle + half
        at = _Measured(between, np.array([a, b]))
        at.measure(np.array([0, 1]))
        figure = float(sampled_along(between, spread, at, np.array([0]))[0])
        dense = sampled_least(plant, between, a, b, n=257)
        assert dense - step / 2 <= figure <= dense + step
        ends_miss += float(at.least.min()) > dense + step
    assert ends_miss >= 1


def test_a_close_pass_is_sampled_for_the_pairs_that_may_be_least_with_every_pairs_figure(pair):
    """Seeded property: ``sampled_along`` measures only the pairs that ``pairs_along`` leaves at or below the least of
    a segment's ends, and its figure is exactly that of every pair at the same samples (as many as the end's levers
    ask for), on moves past the other arm near their middle, some of whose least sample is a pair nearest at
    neither end (so a screen that kept only the ends' nearest pairs fails)."""
    rig, plant, between = pair
    rng = np.random.default_rng(37)
    spread, step = travel_spread(between), sample_step(between.clearance)
    poses = []
    for _ in range(16):
        middle, half = near_the_other_arm(plant, between, rng), rng.normal(0, 0.3, plant.n_joints)
        poses += [middle - half, middle + half]
    at = _Measured(between, np.array(poses))
    at.measure(np.arange(len(poses)))
    starts = np.arange(0, len(poses), 2)
    figures = sampled_along(between, spread, at, starts)
    elsewhere = 0  # moves whose least sample is a pair nearest at neither end
    for k, start in enumerate(starts):
        a, b = at.poses[start], at.poses[start + 1]
        fall = pair_falls(between, spread, at.levers[start + 1][None], (b - a)[None]).max()
        s = np.linspace(0.0, 1.0, max(2, math.ceil(fall / step) + 1))[:, None]
        every = between.distances(plant.split(a + s * (b - a)))
        assert figures[k] == every.min(), k
        nearest = np.unravel_index(every.argmin(), every.shape)[1]
        elsewhere += nearest not in (at.gaps[start].argmin(), at.gaps[start + 1].argmin())
    assert elsewhere >= 2


def test_poses_measured_for_their_least_are_measured_again_for_every_pair_when_asked(pair):
    """``_Measured``: a pose measured for its least alone (the proof's coarse levels) has no pair's clearance until
    asked for every pair; then each is ``distances``', and its least and levers stay as measured."""
    rig, plant, between = pair
    rng = np.random.default_rng(41)
    poses = rng.uniform(plant.lower, plant.upper, (6, plant.n_joints)) * 0.7
    at = _Measured(between, poses)
    at.measure(np.array([0, 2, 4]), every_pair=False)
    least, levers = at.least[[0, 2, 4]].copy(), at.levers[[0, 2, 4]].copy()
    assert np.isnan(at.gaps[[0, 2, 4]]).all() and at.done[[0, 2, 4]].all() and not at.full.any()
    at.measure(np.array([2, 3]))
    for k in (2, 3):
        np.testing.assert_array_equal(at.gaps[k], between.distances(plant.split(poses[k])))
        assert at.least[k] == at.gaps[k].min()
    np.testing.assert_array_equal(at.least[[0, 2, 4]], least)
    np.testing.assert_array_equal(at.levers[[0, 2, 4]], levers)
    assert at.full.tolist() == [False, False, True, True, False, False]
