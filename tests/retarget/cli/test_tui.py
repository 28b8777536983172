"""The interactive mode's testable core: key -> target (Jog), the newest-only key source, and a rig's keys (RigKeys:
Tab selects the arm the keys move, in the rig's world frame)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from retarget.cli.tui import KEYS, MAX_STEP, MIN_STEP, Action, Jog, KeySource, RigKeys
from retarget.control.clock import VirtualClock
from retarget.rig import Placement, RigGate, load_rig
from retarget.teleop.gate import TargetBounds, TargetGate


@pytest.fixture
def jog(arm):
    home = np.array([0.3, 0.0, 0.25])
    return Jog(target=home.copy(), home=home, bounds=TargetBounds.for_arm(arm), step=0.01)


@pytest.mark.parametrize(
    ("keys", "delta"),
    [
        ("w", (1, 0, 0)),
        ("UP", (1, 0, 0)),
        ("s", (-1, 0, 0)),
        ("DOWN", (-1, 0, 0)),
        ("a", (0, 1, 0)),
        ("LEFT", (0, 1, 0)),
        ("d", (0, -1, 0)),
        ("RIGHT", (0, -1, 0)),
        ("r", (0, 0, 1)),
        ("PGUP", (0, 0, 1)),
        ("f", (0, 0, -1)),
        ("PGDN", (0, 0, -1)),
    ],
    ids=lambda v: v if isinstance(v, str) else None,
)
def test_keys_nudge_one_axis(jog, keys, delta):
    before = jog.target.copy()
    assert jog.press(keys) is Action.MOVE
    np.testing.assert_allclose(jog.target - before, np.array(delta) * 0.01, atol=1e-15)


def test_every_mapped_key_moves_and_opposites_cancel(jog):
    rng = np.random.default_rng(1)
    start = jog.target.copy()
    keys = list(KEYS)
    presses = [keys[i] for i in rng.integers(0, len(keys), 200)]
    for k in presses:
        jog.press(k)
    expected = start + sum(np.eye(3)[KEYS[k][0]] * KEYS[k][1] * 0.01 for k in presses)
    np.testing.assert_allclose(jog.target, expected, atol=1e-12)  # nothing blocked this close to the centre


def test_step_size_doubles_halves_and_is_bounded(jog):
    assert jog.press("+") is Action.STEP and jog.step == pytest.approx(0.02)
    for _ in range(20):
        jog.press("+")
    assert jog.step == MAX_STEP
    for _ in range(40):
        jog.press("-")
    assert jog.step == MIN_STEP


def test_bounds_block_the_nudge(jog):
    jog.step = MAX_STEP
    for _ in range(3):
        jog.press("f")  # 0.25 -> 0.15 -> 0.05 -> -0.05 would be below the floor
    assert jog.target[2] == pytest.approx(0.05)
    assert jog.press("f") is Action.BLOCKED and "out_of_box" in jog.message
    assert jog.target[2] == pytest.approx(0.05)


def test_home_quit_and_unknown(jog):
    jog.press("w")
    assert jog.press("h") is Action.HOME
    np.testing.assert_allclose(jog.target, jog.home)
    assert jog.press("q") is Action.QUIT and jog.press("ESC") is Action.QUIT
    assert jog.press("z") is Action.NONE


def test_key_source_keeps_only_the_newest(arm, jog):
    clock = VirtualClock(2.0)
    src = KeySource(TargetGate(TargetBounds.for_arm(arm), clock=clock), jog)
    for _ in range(5):
        src.press("w")
    src.press("+")  # no new target
    (t,) = src.drain()
    np.testing.assert_allclose(t.position, [0.35, 0, 0.25])
    assert t.seq == 4 and t.received == 2.0 and src.dropped == 4
    assert not src.closed
    src.press("q")
    assert src.closed


@pytest.mark.parametrize(
    ("keys", "closure"),
    [("c", 1.0), ("o", 0.0), ("]", 0.1), ("]]]", 0.3), ("c[[", 0.8), ("[", 0.0), ("c]", 1.0)],
    ids=["close", "open", "step-up", "three-steps", "close-then-down", "floor-at-open", "ceiling-at-closed"],
)
def test_gripper_keys_set_the_gate_closure_and_never_move_the_target(arm, jog, keys, closure):
    gate = TargetGate(TargetBounds.for_arm(arm), clock=VirtualClock(0.0))
    src = KeySource(gate, jog)
    for key in keys:
        assert src.press(key) is Action.GRIPPER
    assert gate.gripper == pytest.approx(closure) and jog.gripper == pytest.approx(closure)
    assert src.drain() == [] and jog.message.startswith("gripper")


# ------------------------------------------------------------------ a rig's keys


def rig_keys(rig=None):
    rig = rig or load_rig("wx250s-pair")
    start = {a.name: a.placement.to_world([0.3, 0.0, 0.25]) for a in rig.arms}  # each in front of its base
    return RigKeys.for_gate(RigGate.for_rig(rig, clock=VirtualClock(1.0)), start=start, home=start), start


def test_tab_switches_the_arm_the_keys_move_and_the_other_stays():
    keys, start = rig_keys()
    assert keys.selected == "left"
    for key in ("w", "w", "r"):
        assert keys.press(key) is Action.MOVE
    assert keys.press("TAB") is Action.SELECT and keys.selected == "right"
    for key in ("a", "a", "a", "f"):
        assert keys.press(key) is Action.MOVE
    np.testing.assert_allclose(keys.jogs["left"].target, start["left"] + [0.02, 0, 0.01], atol=1e-12)
    np.testing.assert_allclose(keys.jogs["right"].target, start["right"] + [0, 0.03, -0.01], atol=1e-12)
    # what each follower gets: the newest target only, in its own base frame (the bases sit at y = +-0.3)
    (left,) = keys.sources["left"].drain()
    (right,) = keys.sources["right"].drain()
    np.testing.assert_allclose(left.position, [0.32, 0, 0.26], atol=1e-12)
    np.testing.assert_allclose(right.position, [0.3, 0.03, 0.24], atol=1e-12)
    assert keys.press("TAB") is Action.SELECT and keys.selected == "left"  # around again
    assert keys.press("BTAB") is Action.SELECT and keys.selected == "right"  # Shift-Tab: back


def test_rig_keys_move_in_the_world_frame_of_a_turned_arm():
    rig = load_rig("wx250s-pair")
    right = replace(rig.arms[1], placement=Placement((0.6, -0.3, 0.0), (0.0, 0.0, np.pi)))  # facing backward
    keys, start = rig_keys(replace(rig, arms=(rig.arms[0], right)))
    keys.press("TAB")
    keys.press("w")  # +x in the world: toward the right arm's base, its -x
    np.testing.assert_allclose(keys.jogs["right"].target, start["right"] + [0.01, 0, 0], atol=1e-12)
    (target,) = keys.sources["right"].drain()
    np.testing.assert_allclose(target.position, [0.29, 0, 0.25], atol=1e-12)


def test_rig_keys_share_the_step_block_in_each_arms_bounds_and_quit_every_arm():
    keys, start = rig_keys()
    assert keys.press("+") is Action.STEP
    keys.press("TAB")
    assert keys.jogs["right"].step == pytest.approx(0.02)
    keys.press("+")
    keys.press("+")
    keys.press("+")  # 0.16 m, capped at MAX_STEP
    assert {name: jog.step for name, jog in keys.jogs.items()} == {"left": MAX_STEP, "right": MAX_STEP}
    for _ in range(2):
        keys.press("f")  # 0.25 -> 0.15 -> 0.05 in the world (the bases are on the table: the same z)
    assert keys.press("f") is Action.BLOCKED and keys.message == "right: blocked: out_of_box"
    np.testing.assert_allclose(keys.jogs["right"].target, start["right"] + [0, 0, -0.2], atol=1e-12)
    assert keys.press("c") is Action.NONE and keys.sources["right"].gate.gripper is None  # no gripper on a rig
    assert keys.press("q") is Action.QUIT
    assert all(source.closed for source in keys.sources.values())
