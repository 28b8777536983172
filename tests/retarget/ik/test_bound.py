"""ClearanceBound, its levers and its pieces: seeded properties that no bound ever exceeds the true clearance."""

from __future__ import annotations

import math

import numpy as np
import pytest

from retarget.arm.load import load_arm
from retarget.collision import Box, CollisionModel, Sphere, World
from retarget.collision.distance import point_box, point_segment
from retarget.collision.levers import pair_levers
from retarget.collision.pieces import Pieces
from retarget.ik.bound import ClearanceBound

ARMS = ["wx250s", "vx300s", "koch", "omx", "px100"]
ZONES = World(keep_out=(Sphere((0.3, 0.1, 0.2), 0.05), Box((0.2, -0.2, 0.1), (0.05, 0.05, 0.1))))


def _model(name: str, zones: bool) -> CollisionModel:
    return CollisionModel.for_arm(load_arm(name), world=ZONES if zones else None)


def _per_pair(bound: ClearanceBound, rows: np.ndarray, n_pairs: int) -> np.ndarray:
    """Each pair's bound: the least of its rows (its pieces, for a cut pair)."""
    out = np.full(n_pairs, math.inf)
    np.minimum.at(out, bound._pieces.pair_of, rows)
    return out


@pytest.mark.parametrize("zones", [False, True], ids=["table", "keep-outs"])
@pytest.mark.parametrize("name", ARMS)
def test_a_pair_never_closes_faster_than_its_levers(name, zones):
    """From any pose to any other, each pair's distance falls by at most its levers times the joints' moves (where
    it stays positive: a penetrating box pair's depth is a bound of nothing in particular)."""
    model = _model(name, zones)
    arm = model.arm
    levers = pair_levers(model)
    rng = np.random.default_rng(11)
    for _ in range(60):
        q0 = rng.uniform(arm.lower, arm.upper)
        for scale in (0.01, 0.1, 1.0):
            q1 = q0 + rng.normal(0.0, scale, arm.n_joints)
            bound = model.distances(q0) - levers @ np.abs(q1 - q0)
            d1 = model.distances(q1)
            positive = bound > 0
            assert np.all(bound[positive] <= d1[positive] + 1e-12)


def test_the_turntable_does_not_count_against_the_table_and_the_shoulder_axis_bounds_the_upper_arm():
    model = _model("wx250s", False)
    levers = pair_levers(model)
    names = model.pair_names
    assert np.all(levers[[i for i, n in enumerate(names) if n.endswith("/table")], 0] == 0.0)
    upper = levers[names.index("upper_arm/base")]
    # the waist by the base's corners about its own axis (not the upper arm's far end, 0.27 m); only two joints
    np.testing.assert_allclose(upper[:2], [math.hypot(0.0771, 0.0770), 0.1695], atol=2e-3)
    assert np.all(upper[2:] == 0.0)


@pytest.mark.parametrize("name", ["wx250s", "vx300s"])
def test_each_piece_is_at_most_as_far_as_a_brute_force_sample_of_it(name):
    """At the noted pose, each piece of a cut capsule is no farther than the least distance over 200 points
    sampled along it (to the other shape: a capsule's segment or a base box), less the pair's radii and nest."""
    model = _model(name, False)
    pieces = Pieces(model)
    assert pieces._cut, "the long links of this arm are cut"
    rng = np.random.default_rng(5)
    arm = model.arm
    for _ in range(30):
        q = rng.uniform(arm.lower, arm.upper) * 0.7
        rows = pieces.rows(q, model.pair_bounds(q, model.clearance + 0.01))
        rots, origins = model._frames(q[None])
        ends, _ = model.capsules(q)
        links = {link.name: i for i, link in enumerate(model.geometry.links)}
        cap = {i: c for c, i in enumerate(model._cap_ids)}
        for k, kk, kind, _, spans, span_rows in pieces._cut:
            u, v = sorted(model.pair_names[k].split("/"), key=lambda n: -model.geometry.links[links[n]].frame)
            a, b = ends[cap[links[u]]]  # u: the moving capsule (on the later frame)
            offset = model._one._py_off[kk]
            for (t0, t1), value in zip(spans, rows[span_rows], strict=True):
                t = np.linspace(t0, t1, 200)[:, None]
                pts = a + t * (b - a)
                if kind == 0:
                    oa, ob = ends[cap[links[v]]]
                    far = point_segment(pts, oa, ob)
                else:
                    box = model._box_ids.index(links[v])
                    frame = model._box_frame[box]
                    local = (pts - origins[0, frame]) @ rots[0, frame]
                    far = point_box(local, model._box_c[box], model._box_h[box])
                assert value <= float(far.min()) - offset + 1e-12


@pytest.mark.parametrize("zones", [False, True], ids=["table", "keep-outs"])
@pytest.mark.parametrize("name", ARMS)
def test_no_bound_exceeds_the_true_clearance_near_or_far_from_its_notes(name, zones):
    """Seeded: notes from pair_bounds (as the IK's guard and the goal check take them) or exact distances; every
    pair's bound from the last note, quick, lower_bound and quick_previous never exceed the true clearance."""
    model = _model(name, zones)
    arm = model.arm
    bound = ClearanceBound(model)
    rng = np.random.default_rng(3)
    n = len(model.pair_names)
    for i in range(80):
        ref = rng.uniform(arm.lower, arm.upper) * rng.choice([0.4, 1.0])
        bound.note(ref, model.pair_bounds(ref, model.clearance + 0.01) if i % 2 else model.distances(ref))
        for scale in (0.003, 0.03, 0.3):
            q = ref + rng.normal(0.0, scale, arm.n_joints)
            exact = model.distances(q)
            pairs = _per_pair(bound, bound.pairs_at(q), n)
            positive = pairs > 0
            assert np.all(pairs[positive] <= exact[positive] + 1e-12)
            least = float(exact.min())
            assert bound.quick(q) <= least + 1e-12
            assert bound.lower_bound(q) <= least + 1e-12
            assert bound.quick_previous(q) <= least + 1e-12


@pytest.mark.parametrize("name", ["wx250s", "koch"])
def test_the_segment_bound_never_exceeds_a_sampled_segment(name):
    model = _model(name, True)
    arm = model.arm
    bound = ClearanceBound(model)
    rng = np.random.default_rng(9)
    for _ in range(40):
        ref = rng.uniform(arm.lower, arm.upper) * 0.6
        bound.note(ref, model.distances(ref))
        q0 = ref + rng.normal(0.0, 0.02, arm.n_joints)
        q1 = q0 + rng.normal(0.0, 0.05, arm.n_joints)
        low = bound.segment_bound(q0, q1, bound.pairs_at(q0), bound.pairs_at(q1))
        samples = q0 + np.linspace(0.0, 1.0, 41)[:, None] * (q1 - q0)
        assert low <= float(model.distances(samples).min()) + 1e-12


def test_the_quick_bound_of_a_pose_is_kept_but_not_for_a_list_changed_since():
    model = _model("wx250s", False)
    bound = ClearanceBound(model)
    home = model.arm.home.tolist()
    bound.note(home, model.distances(model.arm.home))
    q = list(home)
    first = bound.quick(q)
    assert bound.quick(q) == first  # the same pose: the kept value
    q[1] += 0.3  # the caller changes its list: a new pose, a new (smaller) bound
    assert bound.quick(q) < first
    assert bound.quick(q) <= model.min_clearance(np.array(q)) + 1e-12


def test_the_screen_and_the_exact_bound_agree_at_the_note_and_both_bound_from_below():
    model = _model("wx250s", False)
    bound = ClearanceBound(model)
    q = np.array([0.3, -0.2, 0.3, 0.2, 0.5, 0.1])
    bound.note(q, model.distances(q))
    assert bound.quick(q) == pytest.approx(model.min_clearance(q), abs=1e-12)
    moved = (q + 0.05).tolist()
    assert bound._screened(bound._screen, moved) <= bound._low(bound.state, moved) + 1e-12


def test_bad_input_raises():
    model = _model("wx250s", False)
    bound = ClearanceBound(model)
    with pytest.raises(ValueError, match="Expected a note before rows_at_note"):
        bound.rows_at_note()
    assert bound.quick(model.arm.home) == -math.inf  # nothing noted yet
    bound.note(model.arm.home, model.distances(model.arm.home))
    with pytest.raises(ValueError, match="Expected 6 joint angles, got 1"):
        bound.quick([0.1])
    with pytest.raises(ValueError, match="Expected 6 joint angles, got 5"):
        bound.lower_bound([0.1] * 5)


def _table_distances(model: CollisionModel, slopes, poses: np.ndarray) -> np.ndarray:
    """``(n_poses, m)``: each table row's capsule's true table distance (its lower end's height less its radius)."""
    ends, radii = model.capsules(poses)  # (n_poses, n_caps, 2, 3)
    heights = ends[..., 2][:, slopes._caps]  # (n_poses, m, 2)
    out: np.ndarray = heights.min(axis=2) - radii[slopes._caps]
    return out


@pytest.mark.parametrize("name", ARMS)
def test_the_table_slope_bound_never_exceeds_a_sampled_segment_even_for_long_moves(name):
    """Seeded: from a note at a random pose, over straight segments of up to ~1 rad per joint, each table row's
    slope bound (its ends' heights, slopes and second-order term) is at most the capsule's true table distance at
    every one of 101 samples; and at the note itself it is exact.  Long moves are where the second-order term
    decides: without it, or without its cross terms, this fails."""
    model = _model(name, False)
    arm = model.arm
    bound = ClearanceBound(model)
    slopes = bound._slopes
    assert slopes.rows.size, "every bundled arm has capsules against the table"
    rng = np.random.default_rng(17)
    s = np.linspace(0.0, 1.0, 101)[:, None]
    for i in range(40):
        ref = rng.uniform(arm.lower, arm.upper) * rng.choice([0.5, 1.0])
        bound.note(ref, model.pair_bounds(ref, model.clearance + 0.01) if i % 2 else model.distances(ref))
        zero = np.zeros(arm.n_joints)
        at_note = slopes.heights(bound.state, zero, zero)
        np.testing.assert_allclose(at_note, _table_distances(model, slopes, ref[None])[0], atol=1e-12)
        for scale in (0.01, 0.1, 0.4, 1.0):
            q0 = ref + rng.normal(0.0, scale, arm.n_joints)
            q1 = ref + rng.normal(0.0, scale, arm.n_joints)
            low = slopes.heights(bound.state, q0 - ref, q1 - ref)
            true = _table_distances(model, slopes, q0 + s * (q1 - q0)).min(axis=0)
            assert np.all(low <= true + 1e-12)


@pytest.mark.parametrize(("name", "zones"), [("wx250s", False), ("wx250s", True), ("koch", False), ("omx", True)],
                         ids=["wx250s-table", "wx250s-keep-outs", "koch-table", "omx-keep-outs"])  # fmt: skip
def test_the_segment_low_bound_never_exceeds_a_sampled_segment(name, zones):
    """Seeded: ``segment_low`` (every row's concave bound, the table rows raised by their slopes) over a segment
    near a note never claims more clearance than 41 samples of it have (a penetrating pose: no positive claim),
    for a pose (both ends equal) as for a segment; and where the levers' sum falls short it often does better."""
    model = _model(name, zones)
    arm = model.arm
    bound = ClearanceBound(model)
    rng = np.random.default_rng(23)
    s = np.linspace(0.0, 1.0, 41)[:, None]
    sharper = 0
    for i in range(30):
        ref = rng.uniform(arm.lower, arm.upper) * rng.choice([0.4, 1.0])
        bound.note(ref, model.pair_bounds(ref, model.clearance + 0.01) if i % 2 else model.distances(ref))
        for scale in (0.003, 0.03, 0.3):
            q0 = ref + rng.normal(0.0, scale, arm.n_joints)
            q1 = q0 + rng.normal(0.0, scale, arm.n_joints)
            true = float(model.distances(q0 + s * (q1 - q0)).min())
            low = bound.segment_low(q0.tolist(), q1.tolist())
            assert low <= max(true, 0.0) + 1e-12
            pose = bound.segment_low(q0.tolist(), q0.tolist())
            assert pose <= max(float(model.distances(q0).min()), 0.0) + 1e-12
            linear = min(bound.quick(q0), bound.quick(q1))
            assert low >= linear - 1e-12  # never worse than the levers' bound
            sharper += low > linear + 1e-3
    if not zones and name == "wx250s":
        assert sharper >= 5


def _sampled(model: CollisionModel, q0: np.ndarray, q1: np.ndarray, n: int = 41) -> float:
    """The least clearance of ``n`` samples of the segment ``q0 -> q1``, at least 0 (a penetrating pose: no claim)."""
    s = np.linspace(0.0, 1.0, n)[:, None]
    return max(float(model.distances(q0 + s * (q1 - q0)).min()), 0.0)


@pytest.mark.parametrize(("name", "zones"), [("wx250s", False), ("wx250s", True), ("koch", False), ("omx", True)],
                         ids=["wx250s-table", "wx250s-keep-outs", "koch-table", "omx-keep-outs"])  # fmt: skip
def test_a_proven_segment_never_claims_more_than_a_sampled_segment(name, zones):
    """Seeded: notes recorded at random poses, then segments near them, each given a note index that is its own
    note's or one off it (prove tries the neighbours too): every segment's proven bound is at most the clearance
    of 41 samples of it, and the path's find returns it (less its margin) for exactly that move.  Both ends count:
    a bound from the end pose alone, or from the start alone, claims too much for some of these segments."""
    model = _model(name, zones)
    arm = model.arm
    bound = ClearanceBound(model)
    rng = np.random.default_rng(41)
    notes = bound.record()
    refs = []
    for i in range(12):
        ref = rng.uniform(arm.lower, arm.upper) * rng.choice([0.4, 1.0])
        bound.note(ref, model.pair_bounds(ref, model.clearance + 0.01) if i % 2 else model.distances(ref))
        refs.append(ref)
    starts, ends, index = [], [], []
    for k, ref in enumerate(refs):
        for scale in (0.01, 0.05, 0.2):
            near = ref + rng.normal(0.0, 0.2 * scale, arm.n_joints)
            far = near + rng.normal(0.0, scale, arm.n_joints)
            for q0, q1 in ((near, far), (far, near)):  # the note near the start, then near the end
                starts.append(q0)
                ends.append(q1)
                index.append(int(np.clip(k + rng.integers(-1, 2), 0, len(notes) - 1)))
    path = bound.prove(np.array(starts), np.array(ends), notes, np.array(index))
    assert bound.proven is path and len(path) == len(starts)
    proven = 0
    for q0, q1 in zip(starts, ends, strict=True):
        low = path.find(q0.tolist(), q1.tolist())
        assert low is not None
        assert low <= _sampled(model, q0, q1) + 1e-12
        proven += low >= model.clearance
    assert proven >= 6  # the bound claims something


def test_a_proven_path_answers_only_its_next_segment_and_only_within_eps():
    model = _model("wx250s", False)
    bound = ClearanceBound(model)
    home = model.arm.home
    notes = bound.record()
    bound.note(home, model.distances(home))
    steps = home + np.linspace(0.0, 0.05, 4)[:, None]  # 3 moves of 0.0167 rad per joint
    path = bound.prove(steps[:-1], steps[1:], notes, np.zeros(3, dtype=np.intp))
    a, b, c, d = (s.tolist() for s in steps)
    first = path.find(a, b)
    assert first is not None and first < model.min_clearance(home)
    assert path.find(c, d) is None  # neither the next segment (b -> c) nor the first
    off = [x + 1e-6 for x in c]
    assert path.find(b, off) is None  # beyond EPS: no answer, and the cursor stays
    assert path.find(b, [math.nan, *c[1:]]) is None
    assert path.find(b, c[:-1]) is None
    assert path.find(a, c) is None  # the right end, from elsewhere
    near = [x + 0.1 * path.EPS / len(c) for x in c]
    assert path.find(b, near) is not None  # within EPS: the segment's bound, less the margin
    assert path.find(np.array(c), np.array(d)) is not None  # (arrays as lists)
    assert path.find(c, d) is None  # past the end
    assert path.find(a, b) == first  # the path again, from its start
    assert not bound.record(False) and bound.record() == [bound.state]


def test_recall_bounds_from_the_best_kept_note_and_makes_it_the_last():
    """Seeded: more notes than are kept (the ring wraps); a pose near an early note that is still kept is bounded
    from it, never above its true clearance, and that note becomes the one quick bounds from; a pose near a note
    that fell out of the ring is not bounded from it."""
    from retarget.ik.bound import KEPT

    model = _model("wx250s", True)
    arm = model.arm
    bound = ClearanceBound(model)
    rng = np.random.default_rng(43)
    refs = [rng.uniform(arm.lower, arm.upper) * 0.5 for _ in range(KEPT + 8)]
    for ref in refs:
        bound.note(ref, model.distances(ref))
    recalled = 0
    for k, ref in enumerate(refs):
        q = ref + rng.normal(0.0, 0.002, arm.n_joints)
        true = max(model.min_clearance(q), 0.0)
        low = bound.recall(q)
        assert low <= true + 1e-12
        assert bound.quick(q) <= true + 1e-12
        if low >= model.clearance:
            recalled += 1
            assert np.array_equal(bound.state[0], refs[k]) or k < 8  # from its own note (while it is kept)
        if k < 8:  # fell out of the ring: bounded from another note, less than from its own
            assert low < model.min_clearance(ref) - 1e-6
    assert recalled >= KEPT // 2
