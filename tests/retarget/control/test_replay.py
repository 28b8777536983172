"""The control loop on synthetic targets: dry runs, then runs on the simulated bus through the real driver."""

from __future__ import annotations

import math

import numpy as np
import pytest

import retarget
from retarget.control import ControlLoop, JointGoal, LoopConfig, TickRecord, run_on_bus, run_ticks
from retarget.control.clock import VirtualClock
from retarget.errors import ConfigError
from retarget.ik import IKResult
from retarget.mapping import Targets
from retarget.mapping.config import MappingConfig
from tests.helpers import circle_targets, servo_angles, torque


def run(arm, targets, **config):
    records: list[TickRecord] = []
    loop = ControlLoop(arm, targets, config=LoopConfig(**config), clock=VirtualClock(), on_tick=records.append)
    summary = loop.run(None)
    return loop, summary, records


def test_dry_run_follows_the_targets_within_limits(arm):
    targets = circle_targets(arm)
    loop, summary, records = run(arm, targets)
    assert summary.ticks == len(records) == 201  # 2 s at 100 Hz, both ends included
    assert summary.dry_run and not summary.interrupted
    q = np.array([r.q_cmd for r in records])
    assert np.all(q >= arm.lower) and np.all(q <= arm.upper)
    steps = np.abs(np.diff(q, axis=0))
    assert np.all(steps <= arm.max_velocity / 100 + 1e-12)
    # after the lead-in from the rest pose, the commanded pose tracks the target to IK tolerance
    tool = np.array([arm.fk(qi)[0][:3, 3] for qi in q])
    tracking = np.linalg.norm(tool - np.array([r.target for r in records]), axis=1)
    settled = ~np.array([r.velocity_limited for r in records])
    settled[: np.argmax(settled)] = False
    assert np.median(tracking[settled]) < 1.5e-3
    assert summary.ik_converged_pct > 95
    assert all(r.q_present is None for r in records)


def test_ticks_are_resampled_by_linear_interpolation(arm):
    targets = circle_targets(arm)
    _, _, records = run(arm, targets, rate=50.0)
    for r in records[:: len(records) // 7]:
        f = r.clip_time / targets.frame_time
        i = min(int(f), targets.n_frames - 2)
        w = f - i
        expected = targets.raw[i] * (1 - w) + targets.raw[i + 1] * w
        np.testing.assert_allclose(r.target, expected, atol=1e-12)
        assert r.time == pytest.approx(r.tick / 50.0)


@pytest.mark.parametrize(
    ("config", "ticks", "first", "last"),
    [
        ({}, 201, 0.0, 2.0),
        ({"speed": 2.0}, 101, 0.0, 2.0),
        ({"speed": 0.5}, 401, 0.0, 2.0),
        ({"start": 0.5, "end": 1.5}, 101, 0.5, 1.5),
        ({"end": 10.0}, 201, 0.0, 2.0),  # an end past the clip stops at the clip's end
        ({"rate": 30.0}, 61, 0.0, 2.0),
    ],
    ids=["default", "speed2", "speed-half", "window", "end-past-clip", "rate30"],
)
def test_window_speed_and_rate(arm, config, ticks, first, last):
    _, summary, records = run(arm, circle_targets(arm), **config)
    assert summary.ticks == ticks
    assert records[0].clip_time == pytest.approx(first)
    assert records[-1].clip_time == pytest.approx(last)


def test_loop_wraps_until_max_ticks(arm):
    _, summary, records = run(arm, circle_targets(arm), loop=True, max_ticks=450, start=0.5, end=1.5)
    assert summary.ticks == 450
    clip = np.array([r.clip_time for r in records])
    assert clip.min() == pytest.approx(0.5) and clip.max() < 1.5
    assert np.count_nonzero(np.diff(clip) < 0) == 4  # 100 ticks per lap


def test_stop_flag_ends_the_run_at_a_tick_boundary(arm):
    records: list[TickRecord] = []
    loop = ControlLoop(arm, circle_targets(arm), clock=VirtualClock())

    def on_tick(r: TickRecord) -> None:
        records.append(r)
        if r.tick == 9:
            loop.stop()

    loop.on_tick = on_tick
    summary = loop.run(None)
    assert summary.interrupted and summary.ticks == len(records) == 10


def test_keyboard_interrupt_inside_a_tick_ends_the_run(arm):
    def on_tick(r: TickRecord) -> None:
        if r.tick == 4:
            raise KeyboardInterrupt

    loop = ControlLoop(arm, circle_targets(arm), clock=VirtualClock(), on_tick=on_tick)
    summary = loop.run(None)
    assert summary.interrupted and summary.ticks == 5


class SlowClock(VirtualClock):
    """A virtual clock on which every tick's work takes ``work`` seconds.

    The loop reads the clock once at the start, then once at the end of each tick.
    """

    def __init__(self, work: float):
        super().__init__()
        self.work = work
        self.reads = 0

    def now(self) -> float:
        self.reads += 1
        if self.reads > 1:
            self.advance(self.work)
        return super().now()


def test_overruns_are_counted_and_skip_slots_instead_of_drifting(arm):
    clock = SlowClock(work=0.025)  # 2.5 slots of work per tick at 100 Hz
    records: list[TickRecord] = []
    loop = ControlLoop(arm, circle_targets(arm), clock=clock, on_tick=records.append)
    summary = loop.run(None)
    assert summary.overruns == summary.ticks > 0
    assert summary.skipped_ticks > 0
    # ticks stay on the 100 Hz grid and cover the clip in about its real duration: no accumulated delay
    assert all(r.time == pytest.approx(r.tick / 100) for r in records)
    assert records[-1].tick >= 190
    assert all(r.overrun for r in records)
    # the velocity limit scales with the slots that passed
    q = np.array([r.q_cmd for r in records])
    slots = np.diff([r.tick for r in records])
    assert np.all(np.abs(np.diff(q, axis=0)) <= arm.max_velocity * (slots[:, None] / 100) + 1e-12)


def test_start_pose_is_the_rest_pose_or_given(arm):
    _, _, records = run(arm, circle_targets(arm), max_ticks=1)
    first = records[0].q_cmd
    assert np.all(np.abs(first - arm.rest) <= arm.max_velocity / 100 + 1e-12)
    loop = ControlLoop(arm, circle_targets(arm), clock=VirtualClock())
    q0 = loop.initial_pose()
    got: list[TickRecord] = []
    loop.on_tick = got.append
    loop.run(None, q_start=q0)
    assert not got[0].velocity_limited
    # on target at once, within what a start at rest on a circle already moving costs the plan (measured 1.3 mm)
    assert np.linalg.norm(arm.fk(got[0].q_cmd)[0][:3, 3] - got[0].target) <= 2e-3
    with pytest.raises(ValueError, match=r"Expected a start pose of shape \(6,\), got \(3,\)"):
        loop.run(None, q_start=np.zeros(3))


def test_velocity_scale_caps_every_step(arm):
    _, summary, records = run(arm, circle_targets(arm), velocity_scale=0.25)
    q = np.array([r.q_cmd for r in records])
    assert np.all(np.abs(np.diff(q, axis=0)) <= 0.25 * arm.max_velocity / 100 + 1e-12)
    assert summary.velocity_limited_ticks > 0


class OutOfLimitsSolver:
    """A test double of the IK solver whose answers lie 0.5 rad beyond every joint limit: past the upper
    limits for the first ``turn`` calls, past the lower ones after (the real solver clamps its own answers,
    so only a double shows whether the loop clamps what it is given)."""

    def __init__(self, arm, turn: int):
        self.high, self.low, self.turn, self.calls = arm.upper + 0.5, arm.lower - 0.5, turn, 0

    def solve(self, target, seed, rotation=None) -> IKResult:
        self.calls += 1
        q = self.high if self.calls <= self.turn else self.low
        return IKResult(q=q.copy(), error=0.0, iterations=1, converged=True)


class Beyond:
    """A target source: a point target every tick (``joint_goal=False``), or a :class:`JointGoal` 0.5 rad
    beyond the limits (upper ones for the first ``turn`` ticks, then lower)."""

    def __init__(self, arm, turn: int, *, joint_goal: bool):
        self.arm, self.turn, self.joint_goal = arm, turn, joint_goal

    def target_at(self, tick, t):
        point = np.array([0.3, 0.0, 0.2])
        if not self.joint_goal:
            return point, None, False
        q = self.arm.upper + 0.5 if tick < self.turn else self.arm.lower - 0.5
        return JointGoal(q, point)

    def finished(self, tick):
        return False


@pytest.mark.parametrize("joint_goal", [False, True], ids=["ik-solution", "joint-goal"])
def test_goals_beyond_the_limits_are_clamped_by_the_loop(arm, joint_goal):
    """Every commanded pose stays within [lower, upper] when the goal lies beyond them, and a joint driven
    past a limit rests exactly on it (it does not creep beyond by one step per tick)."""
    turn, n = 250, 500  # 250 ticks of pi/100 rad: every joint reaches its upper limit, then its lower one
    solver = OutOfLimitsSolver(arm, turn)
    records: list[TickRecord] = []
    stats = run_ticks(
        arm,
        Beyond(arm, turn, joint_goal=joint_goal),
        solver,
        config=LoopConfig(max_ticks=n),
        clock=VirtualClock(),
        on_tick=records.append,
    )
    assert len(records) == n and solver.calls == (0 if joint_goal else n)
    q = np.array([r.q_cmd for r in records])
    assert np.all(q >= arm.lower) and np.all(q <= arm.upper)
    np.testing.assert_array_equal(q[turn - 1], arm.upper)  # reached and held on the limit, not beyond
    np.testing.assert_array_equal(q[-1], arm.lower)
    np.testing.assert_array_equal(stats.q_cmd, arm.lower)


@pytest.mark.parametrize(
    ("seconds_per_tick", "reported"),
    [(0.25, [0, 4, 8, 12, 16]), (0.0, [0]), (0.4, [0, 3, 6, 9, 12, 15, 18]), (1.0, list(range(20)))],
    ids=["every-4th-tick", "time-stands-still", "uneven", "every-tick"],
)
def test_progress_is_paced_by_its_time_source(arm, seconds_per_tick, reported):
    """``on_progress`` gets the first tick, then the first tick at least ``progress_every`` seconds of
    ``progress_time`` after the last report (a fake time source here: one read per tick)."""
    reads: list[float] = []

    def fake_time() -> float:
        reads.append(round(len(reads) * seconds_per_tick, 9))
        return reads[-1]

    got: list[TickRecord] = []
    loop = ControlLoop(
        arm,
        circle_targets(arm),
        config=LoopConfig(max_ticks=20, progress_every=1.0),
        clock=VirtualClock(),
        on_progress=got.append,
        progress_time=fake_time,
    )
    loop.run(None)
    assert len(reads) == 20 and [r.tick for r in got] == reported


def test_summary_counts_and_percentiles(arm):
    _, summary, records = run(arm, circle_targets(arm))
    d = summary.to_dict()
    assert d["ticks"] == len(records)
    assert d["velocity_limited_ticks"] == sum(r.velocity_limited for r in records)
    assert d["clamped_ticks"] == 0
    assert d["ik_error_max_mm"] == pytest.approx(max(r.ik_error for r in records) * 1e3, abs=1e-4)
    assert d["run_time_s"] == pytest.approx(len(records) / 100)
    assert d["duration_s"] == pytest.approx(len(records) / 100)
    assert d["frames"] == 61
    text = summary.format()
    assert "dry run" in text and "201 ticks at 100 Hz" in text and "overruns 0" in text


def test_clamped_targets_are_flagged(arm):
    targets = circle_targets(arm)
    far = targets.raw.copy()
    far[20:30] = [2.0, 0.0, 0.3]  # out of reach
    targets = Targets.from_raw(far, frame_time=targets.frame_time, workspace=targets.workspace)
    _, summary, records = run(arm, targets)
    assert summary.clamped_ticks == sum(r.clamped for r in records) > 0
    for r in records:
        assert np.linalg.norm(r.target - targets.workspace.center) <= targets.workspace.r_max + 1e-9


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"rate": 0.0}, r"rate: Expected a tick rate > 0 Hz \(got 0.0\)"),
        ({"rate": math.inf}, r"rate: Expected a tick rate"),
        ({"speed": -1.0}, r"speed: Expected a speed > 0"),
        ({"start": -0.5}, r"start: Expected a start time >= 0 s"),
        ({"start": 1.0, "end": 1.0}, r"end: Expected an end time after start \(1 s\)"),
        ({"max_ticks": 0}, r"max_ticks: Expected at least 1 tick"),
        ({"velocity_scale": 1.5}, r"velocity_scale: Expected a fraction in \(0, 1\]"),
        ({"ik_iterations": 0}, r"ik_iterations: Expected at least 1 sweep"),
        ({"ik_tolerance": 0.0}, r"ik_tolerance: Expected a tolerance > 0 m"),
    ],
    ids=["rate0", "rate-inf", "speed", "start", "end", "max-ticks", "velocity-scale", "ik-iterations", "ik-tol"],
)
def test_bad_loop_config(kwargs, match):
    with pytest.raises(ConfigError, match=match):
        LoopConfig(**kwargs)


def test_start_after_the_clip_is_an_error(arm):
    with pytest.raises(ConfigError, match=r"start: Expected a start time before the clip's end \(2 s\)"):
        ControlLoop(arm, circle_targets(arm), config=LoopConfig(start=5.0), clock=VirtualClock())


def test_orientation_targets_reach_the_solver(arm):
    targets = circle_targets(arm)
    down = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])  # tool x pointing down
    rotations = np.broadcast_to(down, (targets.n_frames, 3, 3)).copy()
    targets = Targets.from_raw(
        targets.raw,
        frame_time=targets.frame_time,
        workspace=targets.workspace,
        config=MappingConfig(orientation_weight=1.0),
        rotations=rotations,
    )
    loop = ControlLoop(arm, targets, clock=VirtualClock())
    q0 = loop.initial_pose()
    records: list[TickRecord] = []
    loop.on_tick = records.append
    loop.run(None, q_start=q0)
    R = arm.fk(records[-1].q_cmd)[0][:3, :3]
    assert np.degrees(np.arccos(np.clip((np.trace(R.T @ down) - 1) / 2, -1, 1))) < 5


# --------------------------------------------------------------------------------------------- on the simulated bus


def test_run_on_the_simulated_bus_reaches_the_solved_angles(arm, sim_bus):
    from drivers import DynamixelBus

    simbus, url, clock = sim_bus()
    records: list[TickRecord] = []
    loop = ControlLoop(arm, circle_targets(arm), config=LoopConfig(end=1.0), clock=clock, on_tick=records.append)
    summary = run_on_bus(loop, DynamixelBus(arm, url, clock=clock, shutdown="hold"))
    # on a bus the lead-in from the rest pose runs first; its ticks are reported apart from the clip's
    lead = [r for r in records if r.lead_in]
    assert records[: len(lead)] == lead and len(lead) == summary.lead_in_ticks > 0
    records = records[len(lead) :]
    assert summary.ticks == len(records) == 101 and not summary.dry_run
    assert summary.bus_errors == 0 and summary.overruns == 0
    # the present positions read back each tick follow the goals
    last = records[-1]
    assert last.q_present is not None
    assert np.max(np.abs(last.q_present - last.q_cmd)) < 0.1
    assert all(r.bus_time > 0 for r in records)
    # HOLD keeps torque on at the last goal: the servos settle on the last solved angles
    clock.advance(1.0)
    np.testing.assert_allclose(servo_angles(simbus, arm), last.q_cmd, atol=2 * 2 * np.pi / 4096)
    assert torque(simbus, arm) == [1] * 8


@pytest.mark.parametrize(
    ("pipeline", "ticks"),
    [(False, 31), (True, 32)],  # pipelined, tick 30's record comes once tick 31's goals went out: 31 is counted
    ids=["in-tick-read", "pipelined"],
)
def test_ctrl_c_in_a_tick_stops_and_the_bus_shuts_down_at_rest(arm, sim_bus, pipeline, ticks):
    from drivers import DynamixelBus

    simbus, url, clock = sim_bus()
    seen: list[int] = []

    def on_tick(r: TickRecord) -> None:
        seen.append(r.tick)
        if r.tick == 30:
            raise KeyboardInterrupt

    loop = ControlLoop(arm, circle_targets(arm), clock=clock, on_tick=on_tick, pipeline=pipeline)
    bus = DynamixelBus(arm, url, clock=clock, shutdown="rest")
    summary = run_on_bus(loop, bus)
    assert summary.interrupted and summary.ticks == ticks
    assert seen[-(ticks - 29) :] == list(range(29, ticks))  # every tick whose goals went out has its record
    assert not bus.connected
    assert torque(simbus, arm) == [0] * 8
    np.testing.assert_allclose(servo_angles(simbus, arm), arm.rest, atol=0.06)


def test_dropped_replies_are_retried_and_counted(arm, sim_bus):
    import sim
    from drivers import DynamixelBus

    simbus, url, clock = sim_bus(bus=sim.ReplyFaults(drop=0.01), seed=3)
    records: list[TickRecord] = []
    loop = ControlLoop(arm, circle_targets(arm), config=LoopConfig(end=0.5), clock=clock, on_tick=records.append)
    summary = run_on_bus(loop, DynamixelBus(arm, url, clock=clock, shutdown="off"))
    assert summary.bus_retries > 0 and summary.bus_errors == 0
    assert sum(r.bus_retries for r in records) <= summary.bus_retries


def test_an_unplugged_servo_raises_and_the_bus_is_closed(arm, sim_bus):
    from drivers import DynamixelBus

    simbus, url, clock = sim_bus(unplug={4: 0.3})
    bus = DynamixelBus(arm, url, clock=clock, shutdown="off", retries=1)
    loop = ControlLoop(arm, circle_targets(arm), clock=clock)
    with pytest.raises(retarget.BusError, match=r"servo 4\b"):
        run_on_bus(loop, bus)
    assert not bus.connected


def test_a_stop_before_the_first_tick_gives_an_empty_summary(arm):
    loop = ControlLoop(arm, circle_targets(arm), clock=VirtualClock())
    loop.stop()
    summary = loop.run(None)
    assert summary.interrupted and summary.ticks == 0
    assert summary.ik_converged_pct == 0.0 and summary.tick_ms_max == 0.0 and summary.duration_s == 0.0
    assert "0 ticks" in summary.format()


# --------------------------------------------------------------------------------------------- the lead-in


def rest_as_read(arm) -> np.ndarray:
    """The rest pose as the driver reads it back from the simulated servos (whole position ticks), radians."""
    from drivers.units import pulses_to_rad, rad_to_pulses

    offsets = np.array([j.servos[0].offset for j in arm.joints])
    directions = np.array([j.servos[0].direction for j in arm.joints])
    pulses = rad_to_pulses(arm.rest, offset=offsets, direction=directions)
    return pulses_to_rad(pulses, offset=offsets, direction=directions)


def split_lead_in(records: list[TickRecord]) -> tuple[list[TickRecord], list[TickRecord]]:
    """(lead-in records, clip records); the lead-in's come first."""
    n = sum(r.lead_in for r in records)
    assert all(r.lead_in for r in records[:n]) and not any(r.lead_in for r in records[n:])
    return records[:n], records[n:]


@pytest.mark.parametrize("speed", [0.5, 0.2, 10.0], ids=["default", "slow", "capped-by-max-velocity"])
def test_lead_in_on_the_bus_moves_to_the_first_pose_within_its_speed_then_plays_the_clip(arm, sim_bus, speed):
    from drivers import DynamixelBus

    simbus, url, clock = sim_bus()
    records: list[TickRecord] = []
    config = LoopConfig(end=1.0, lead_in_speed=speed)
    loop = ControlLoop(arm, circle_targets(arm), config=config, clock=clock, on_tick=records.append)
    q1 = loop.initial_pose()
    q0 = rest_as_read(arm)  # the start pose
    summary = run_on_bus(loop, DynamixelBus(arm, url, clock=clock, shutdown="hold"))
    lead, clip = split_lead_in(records)
    n = len(lead)
    assert n == summary.lead_in_ticks > 0 and summary.lead_in_s == pytest.approx(n / 100)
    # slots -n .. -1 before the clip's clock starts, the clip waiting at its start, no IK
    assert [r.tick for r in lead] == list(range(-n, 0))
    assert all(r.time == pytest.approx(r.tick / 100) and r.clip_time == 0.0 for r in lead)
    assert all(r.ik_sweeps == 0 and not r.velocity_limited and r.q_present is not None for r in lead)
    np.testing.assert_allclose(lead[0].target, circle_targets(arm).raw[0], atol=1e-12)  # heading for the first
    # from the servos' start pose (rest) no joint moves faster than the lead-in speed (capped by max velocity)
    cap = np.minimum(speed, arm.max_velocity)
    q = np.array([q0, *(r.q_cmd for r in lead)])
    steps = np.abs(np.diff(q, axis=0))
    assert np.all(steps <= cap / 100 + 1e-12)
    assert np.max(steps / cap) * 100 > 0.95  # ...and not much slower: the peak is the speed
    # it ends on the first target's solution before clip tick 0, which starts there without a jump
    np.testing.assert_allclose(lead[-1].q_cmd, q1, atol=1e-12)
    assert clip[0].tick == 0 and clip[0].time == 0.0 and not clip[0].velocity_limited
    assert np.all(np.abs(clip[0].q_cmd - q1) <= arm.max_acceleration / 100**2 + 1e-12)  # from rest: one tick's accel
    assert np.max(np.abs(lead[-1].q_present - q1)) < 0.05  # the servos followed
    # the clip's stats are the clip's
    assert summary.ticks == len(clip) == 101 and summary.duration_s == pytest.approx(1.01)
    assert summary.run_time_s == pytest.approx(1.01)
    assert summary.velocity_limited_ticks == sum(r.velocity_limited for r in clip)
    assert summary.ik_error_max_mm == pytest.approx(max(r.ik_error for r in clip) * 1e3)
    assert "lead-in to the clip's first pose: " in summary.format()
    assert f"{n} ticks (before the clip" in summary.format()


def test_no_lead_in_at_speed_0_goes_to_the_first_pose_at_full_speed(arm, sim_bus):
    """Today's start, kept with lead_in_speed=0: the first ticks speed up from rest at each joint's acceleration
    limit, to its max velocity."""
    from drivers import DynamixelBus

    simbus, url, clock = sim_bus()
    records: list[TickRecord] = []
    loop = ControlLoop(
        arm, circle_targets(arm), config=LoopConfig(end=1.0, lead_in_speed=0), clock=clock, on_tick=records.append
    )
    q0 = rest_as_read(arm)
    summary = run_on_bus(loop, DynamixelBus(arm, url, clock=clock, shutdown="hold"))
    assert summary.lead_in_ticks == 0 and summary.lead_in_s == 0.0 and summary.ticks == len(records) == 101
    assert records[0].tick == 0 and not any(r.lead_in for r in records)
    signed = np.diff(np.array([q0, *(r.q_cmd for r in records)]), axis=0)
    steps = np.abs(signed)
    accel = arm.max_acceleration / 100.0**2  # rad per slot^2
    np.testing.assert_allclose(steps[0].max(), accel.max(), rtol=1e-9)  # from rest: one slot's acceleration
    assert np.all(np.abs(np.diff(signed, axis=0)) <= accel * (1 + 1e-9))  # never more
    assert np.max(steps / arm.max_velocity) * 100 == pytest.approx(1.0)  # up to full speed
    assert not records[0].velocity_limited and summary.velocity_limited_ticks > 10
    assert "lead-in" not in summary.format()


def test_a_dry_run_has_no_lead_in_unless_asked(arm):
    loop = ControlLoop(arm, circle_targets(arm), config=LoopConfig(end=1.0), clock=VirtualClock())
    assert loop.run(None).lead_in_ticks == 0
    records: list[TickRecord] = []
    loop.on_tick = records.append
    summary = loop.run(None, lead_in=True)  # a preview from the rest pose
    lead, clip = split_lead_in(records)
    assert len(lead) == summary.lead_in_ticks > 0 and summary.ticks == len(clip) == 101
    np.testing.assert_allclose(lead[-1].q_cmd, loop.initial_pose(), atol=1e-12)
    assert np.all(lead[0].q_present is None for r in lead)
    # and a start pose already on the first pose needs none
    assert loop.run(None, q_start=loop.initial_pose(), lead_in=True).lead_in_ticks == 0


def test_max_ticks_counts_the_clips_ticks(arm):
    records: list[TickRecord] = []
    loop = ControlLoop(arm, circle_targets(arm), config=LoopConfig(max_ticks=5), clock=VirtualClock())
    loop.on_tick = records.append
    summary = loop.run(None, lead_in=True)
    lead, clip = split_lead_in(records)
    # max_ticks bounds the lead-in too (a run's length is what the user asked for): its first 5 slots, then the clip
    assert summary.ticks == len(clip) == 5 and len(lead) == summary.lead_in_ticks == 5


def test_a_stop_during_the_lead_in_ends_the_run_with_no_clip_ticks(arm):
    records: list[TickRecord] = []
    loop = ControlLoop(arm, circle_targets(arm), clock=VirtualClock())

    def on_tick(r: TickRecord) -> None:
        records.append(r)
        if len(records) == 10:
            loop.stop()

    loop.on_tick = on_tick
    summary = loop.run(None, lead_in=True)
    assert summary.interrupted and summary.ticks == 0 and summary.lead_in_ticks == 10
    assert all(r.lead_in for r in records) and summary.lead_in_s == pytest.approx(0.1)
    assert summary.duration_s == 0.0 and summary.run_time_s == 0.0 and summary.real_time_factor == 0.0


def test_ctrl_c_during_the_lead_in_shuts_the_bus_down_at_rest(arm, sim_bus):
    from drivers import DynamixelBus

    simbus, url, clock = sim_bus()

    records: list[TickRecord] = []

    def on_tick(r: TickRecord) -> None:
        records.append(r)
        if len(records) == 100:
            raise KeyboardInterrupt

    loop = ControlLoop(arm, circle_targets(arm), config=LoopConfig(lead_in_speed=0.1), clock=clock, on_tick=on_tick)
    bus = DynamixelBus(arm, url, clock=clock, shutdown="rest")
    summary = run_on_bus(loop, bus)
    # the 100th record comes (pipelined) once tick 101's goals went out: both count, and both have a record
    assert summary.interrupted and summary.ticks == 0 and summary.lead_in_ticks == 101
    assert len(records) == 101 and all(r.lead_in for r in records)
    assert not bus.connected
    assert torque(simbus, arm) == [0] * 8
    np.testing.assert_allclose(servo_angles(simbus, arm), arm.rest, atol=0.06)


def test_overruns_during_the_lead_in_skip_slots_and_keep_the_speed(arm):
    clock = SlowClock(work=0.025)
    records: list[TickRecord] = []
    loop = ControlLoop(arm, circle_targets(arm), config=LoopConfig(lead_in_speed=0.5), clock=clock)
    loop.on_tick = records.append
    summary = loop.run(None, lead_in=True)
    lead, clip = split_lead_in(records)
    assert len(lead) == summary.lead_in_ticks > 10 and clip
    assert all(r.time == pytest.approx(r.tick / 100) for r in records)  # on the grid, before and after slot 0
    assert all(r.overrun for r in lead) and summary.overruns == len(clip)  # the clip's overruns only
    q = np.array([arm.rest, *(r.q_cmd for r in lead)])
    slots = np.diff([lead[0].tick - 1, *(r.tick for r in lead)])
    assert slots[0] == 1 and np.all(slots[1:] >= 2)  # 2.5 slots of work per tick
    assert np.all(np.abs(np.diff(q, axis=0)) <= 0.5 * slots[:, None] / 100 + 1e-12)


class StallClock(VirtualClock):
    """A virtual clock that jumps ``stall`` seconds once, at its first reading at or after ``at``: a bus call
    stalled inside a tick (retries after a lost status packet, a USB hiccup).  Shared with the simulator, so
    the servos live through the stall too."""

    def __init__(self, *, at: float, stall: float):
        super().__init__()
        self.at, self.stall, self.stalled = at, stall, False

    def now(self) -> float:
        if not self.stalled and self._t >= self.at:
            self.stalled = True
            self._t += self.stall
        return self._t


@pytest.mark.parametrize(
    ("lead_in_speed", "at"), [(0.0, 1.0), (0.5, 0.3)], ids=["stall-in-the-clip", "stall-in-the-lead-in"]
)
def test_a_stalled_bus_call_does_not_let_the_goals_jump(arm, lead_in_speed, at):
    """0.3 s stall in one tick: the loop skips the missed slots (no drift) but every goal stays within one
    slot of ``velocity_scale x max_velocity`` of the last (of ``lead_in_speed`` in the lead-in), so the arm
    lags and catches up within the limit (the goals once jumped by the whole stall's travel, 30 x the limit,
    and the servos ran at full speed).
    The servos' read-back obeys it too: the present positions, over 10 ticks, move no faster than the limit
    (timed by the clock at each read-back), give or take one tick's step (with its Profile Velocity at the
    joint's full speed a servo runs each step in a burst just after the write, so a read may come before or
    after it) and 2 position ticks of quantisation."""
    import sim
    from drivers import DynamixelBus

    scale, rate = 0.2, 100.0
    clock = StallClock(at=at, stall=0.3)
    simbus = sim.SimBus.from_arm(arm, clock=clock, faults=sim.Faults(wire=True))
    url = sim.attach(simbus)
    records: list[tuple[TickRecord, float]] = []
    config = LoopConfig(rate=rate, velocity_scale=scale, lead_in_speed=lead_in_speed)
    loop = ControlLoop(arm, circle_targets(arm), config=config, clock=clock)
    loop.on_tick = lambda r: records.append((r, clock.now()))  # now: just after the read-back
    try:
        summary = run_on_bus(loop, DynamixelBus(arm, url, clock=clock, shutdown="hold"))
    finally:
        sim.unregister(url)
    ticks = np.array([r.tick for r, _ in records])
    gaps = np.diff(ticks)
    k = int(np.argmax(gaps))
    assert clock.stalled and gaps[k] >= 25 and records[k][0].overrun and np.all(np.delete(gaps, k) == 1)
    assert records[k][0].lead_in == (lead_in_speed > 0) and summary.ticks > 100  # stalled where meant, ran on
    q = np.array([r.q_cmd for r, _ in records])
    limit = scale * arm.max_velocity / rate  # rad per tick, whatever slots passed
    # the lead-in's ticks: its own speed (0.5 rad/s, below the scaled 0.63 rad/s), after the stall too
    limits = np.array([np.full(6, lead_in_speed / rate) if r.lead_in else limit for r, _ in records[1:]])
    assert np.all(np.abs(np.diff(q, axis=0)) <= limits * (1 + 1e-9) + 1e-12)
    # and the acceleration limit: a step differs from the last by at most one slot's acceleration per slot passed;
    # the missed slots braked the arm to rest, so right after the stall it moved on by exactly one slot's worth
    accel = arm.max_acceleration / rate**2  # rad per slot^2
    steps = np.diff(q, axis=0)
    assert np.all(np.abs(np.diff(steps, axis=0)) <= accel * gaps[1:, None] * (1 + 1e-9) + 1e-12)
    after = np.abs(q[k + 1] - q[k])
    assert np.all(after <= accel + 1e-12) and np.any(np.isclose(after, accel, rtol=1e-9, atol=0))
    if lead_in_speed:  # and still arrived: the arm caught up with the plan as it slowed down
        np.testing.assert_allclose(records[summary.lead_in_ticks - 1][0].q_cmd, loop.initial_pose(), atol=1e-12)
    present = np.array([r.q_present for r, _ in records])
    read_at = np.array([t for _, t in records])
    moved = np.abs(present[10:] - present[:-10])
    allowed = scale * arm.max_velocity * (read_at[10:] - read_at[:-10])[:, None] + limit + 2 * 2 * np.pi / 4096
    assert np.all(moved <= allowed)


@pytest.mark.parametrize("seed", range(5))
def test_lead_in_plan_property(seed):
    """Random moves: every step within speed/rate per joint, the last goal exact, and one slot fewer would not do."""
    from retarget.control import LeadIn

    rng = np.random.default_rng(seed)
    for _ in range(50):
        n_joints = int(rng.integers(1, 8))
        q0, q1 = rng.uniform(-3, 3, (2, n_joints))
        speed = rng.uniform(0.05, 3.0, n_joints)
        rate = float(rng.choice([30.0, 100.0, 500.0]))
        plan = LeadIn.plan(q0, q1, speed=speed, rate=rate, target=np.zeros(3))
        n = plan.n_slots
        q = np.array([q0, *(plan.goal(k).q for k in range(-n, 0))])
        assert np.all(np.abs(np.diff(q, axis=0)) <= speed / rate + 1e-12)
        np.testing.assert_array_equal(q[-1], q1)
        # minimal: with n - 1 slots the raised cosine's largest step would be too fast for the slowest joint
        worst = np.max(np.abs(q1 - q0) / speed) * rate  # slots at constant speed
        if worst <= 1:
            assert n == 0
        else:
            assert n >= 2 and np.sin(np.pi / (2 * (n - 1))) * worst > 1
    still = LeadIn.plan(np.zeros(3), np.full(3, 1e-4), speed=np.full(3, 0.5), rate=100.0, target=np.zeros(3))
    assert still.n_slots == 0  # within one step at the speed: no lead-in
    one = LeadIn.plan(np.zeros(2), np.array([1.0, -0.25]), speed=np.full(2, 0.5), rate=100.0, target=np.zeros(3))
    assert one.n_slots == 315  # ceil(pi / (2 asin(1 / 200))): about pi/2 x the 2 s at constant speed
    mid = one.goal(-158).q  # the middle of the move, at half way
    np.testing.assert_allclose(mid, [0.5, -0.125], atol=1e-2)


@pytest.mark.parametrize("value", [-0.1, math.nan, math.inf], ids=["negative", "nan", "inf"])
def test_bad_lead_in_speed(value):
    with pytest.raises(ConfigError, match=r"lead_in_speed: Expected a joint speed >= 0 rad/s \(0: no lead-in\)"):
        LoopConfig(lead_in_speed=value)
