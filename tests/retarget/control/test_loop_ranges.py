"""Issue 16, item 10: every LoopConfig field has a documented range, and ``max_ticks`` bounds the lead-in too."""

from __future__ import annotations

import numpy as np
import pytest

from retarget.control.clock import VirtualClock
from retarget.control.loop import LoopConfig, TickRecord
from retarget.control.replay import ControlLoop, LeadIn
from retarget.errors import ConfigError
from tests.helpers import circle_targets


@pytest.mark.parametrize(
    ("field", "value", "match"),
    [
        ("rate", 1e6, r"^rate: Expected a tick rate from 1 to 1000 Hz \(got 1000000\.0\)$"),
        ("rate", 1e9, r"^rate: Expected a tick rate from 1 to 1000 Hz"),
        ("rate", 0.5, r"^rate: Expected a tick rate from 1 to 1000 Hz"),
        ("speed", 1e-6, r"^speed: Expected a speed from 0\.01 to 100 "),
        ("speed", 101.0, r"^speed: Expected a speed from 0\.01 to 100 "),
        ("velocity_scale", 1e-300, r"^velocity_scale: Expected a fraction from 0\.01 to 1 "),
        ("lead_in_speed", 1e-300, r"^lead_in_speed: Expected a joint speed from 0\.01 to 20 rad/s, or 0"),
        ("lead_in_speed", 21.0, r"^lead_in_speed: Expected a joint speed from 0\.01 to 20 rad/s"),
        ("ik_iterations", 10**6, r"^ik_iterations: Expected 1 to 1000 sweeps"),
        ("ik_tolerance", 1.0, r"^ik_tolerance: Expected a tolerance <= 0\.1 m"),
        ("progress_every", float("nan"), r"^progress_every: Expected a period > 0 s"),
    ],
)
def test_a_value_out_of_its_range_names_the_field(field, value, match):
    with pytest.raises(ConfigError, match=match) as info:
        LoopConfig(**{field: value})
    assert info.value.key == field


@pytest.mark.parametrize(
    "fields",
    [
        {"rate": 1.0},
        {"rate": 1000.0},
        {"speed": 0.01},
        {"speed": 100.0},
        {"velocity_scale": 0.01},
        {"lead_in_speed": 0.0},
        {"lead_in_speed": 0.01},
        {"lead_in_speed": 20.0},
        {"ik_iterations": 1000},
        {"ik_tolerance": 0.1},
    ],
)
def test_the_ends_of_the_ranges_are_accepted(fields):
    LoopConfig(**fields)


def test_max_ticks_bounds_the_lead_in(arm):
    """The slowest lead-in the ranges allow, with ``max_ticks=5``, ends after 5 lead-in and 5 clip ticks."""
    records: list[TickRecord] = []
    config = LoopConfig(max_ticks=5, velocity_scale=0.01, lead_in_speed=0.01)
    loop = ControlLoop(arm, circle_targets(arm), config=config, clock=VirtualClock(), on_tick=records.append)
    summary = loop.run(None, lead_in=True)
    lead = [r for r in records if r.lead_in]
    assert summary.ticks == 5 and summary.lead_in_ticks == len(lead) == 5 and len(records) == 10
    steps = np.abs(np.diff([arm.rest, *[r.q_cmd for r in records]], axis=0))
    assert np.all(steps <= arm.max_velocity * 0.01 / 100.0 + 1e-9)  # every tick within the velocity limit


def test_a_truncated_lead_in_follows_the_start_of_the_whole_plan():
    q_from, q_to = np.zeros(2), np.array([1.0, -2.0])
    plan = LeadIn.plan(q_from, q_to, speed=np.array([0.5, 0.5]), rate=100.0, target=np.zeros(3))
    cut = plan.truncated(5)
    assert cut.n_slots == 5 and cut.planned_slots == plan.n_slots > 5
    for k in range(5):  # slot -5 + k of the cut plan is slot -n + k of the whole one
        np.testing.assert_array_equal(cut.goal(-5 + k).q, plan.goal(-plan.n_slots + k).q)
    assert plan.truncated(plan.n_slots) is plan
