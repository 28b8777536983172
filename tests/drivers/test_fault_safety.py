"""Safety of the shutdown and reconnect paths against the simulated wx250s (review findings, regression tests).

* REST after a hardware error: the healthy joints go to rest, the faulted joint is not commanded, then torque off.
* Reconnecting to an arm left holding: a servo whose EEPROM must change is limp only for its own writes.
* The hold goal at torque on is the single-turn reading (Present Position counts turns while torque is off).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import sim
from drivers import units
from drivers.control_table import HardwareError, Instruction
from drivers.dynamixel_bus import Profile, hold_pulse, hold_tick
from retarget.arm import Arm
from retarget.control.bus import ShutdownMode
from retarget.errors import BusError
from tests.helpers import GOAL, TORQUE, torques

SHOULDER, ELBOW, WRIST_ROTATE = 1, 2, 5  # joint indices of the wx250s


def goal_ids_after(sim_bus: sim.SimBus, start: int) -> set[int]:
    """IDs that got a Goal Position (SYNC_WRITE or WRITE) in the simulated wire's log from entry ``start`` on."""
    ids: set[int] = set()
    for entry in list(sim_bus.log)[start:]:
        p = entry.params
        if entry.instruction == Instruction.SYNC_WRITE and int.from_bytes(p[0:2], "little") == GOAL:
            size = int.from_bytes(p[2:4], "little")
            ids |= {p[4 + k] for k in range(0, len(p) - 4, size + 1)}
        elif entry.instruction == Instruction.WRITE and int.from_bytes(p[0:2], "little") == GOAL:
            ids.add(entry.id)
    return ids


def joint_angle(sim_bus: sim.SimBus, dxl_id: int) -> float:
    return float(units.pulses_to_rad(sim_bus.servo(dxl_id).get("Present Position")))


def to_home(bus, arm: Arm, clock) -> None:
    for _ in range(200):  # stream the arm to home, 4 s at 50 Hz
        bus.write_goals(arm.home)
        clock.advance(0.02)
    np.testing.assert_allclose(bus.read_positions(), arm.home, atol=0.002)


# ---------------------------------------------------------------------------------------------- REST after a fault


@pytest.mark.parametrize("profile", [Profile.VELOCITY, Profile.TIME], ids=["velocity-profile", "time-profile"])
@pytest.mark.parametrize("seen", [True, False], ids=["raised-before-close", "found-by-close"])
def test_rest_after_an_overload_moves_the_healthy_joints_then_torque_off(
    make_bus, url, sim_bus, arm, clock, caplog, seen, profile
):
    bus = make_bus(url, shutdown=ShutdownMode.REST, dt=0.02, profile=profile)
    bus.connect()
    to_home(bus, arm, clock)
    sim_bus.servo(8).trigger_hardware_error(HardwareError.OVERLOAD)  # the (unloaded) wrist_rotate servo
    if seen:
        with pytest.raises(BusError, match=r"^servo 8: hardware error: overload; "):
            bus.read_positions()
    mark, t0 = len(sim_bus.log), clock.now()
    with caplog.at_level("WARNING", logger="drivers.dynamixel_bus"):
        bus.close()
    assert "could not move" not in caplog.text
    assert "not moving wrist_rotate to rest (faulted servo 8)" in caplog.text
    # the arm did not drop: every healthy joint went to rest at the safe speed, on the bus clock
    farthest = float(np.max(np.abs(arm.rest - arm.home)))
    assert clock.now() - t0 >= (farthest - bus.rest_tolerance) / bus.rest_speed
    for j, joint in enumerate(arm.joints):
        if j != WRIST_ROTATE:
            for s in joint.servos:
                assert joint_angle(sim_bus, s.id) == pytest.approx(
                    arm.rest[j], abs=bus.rest_tolerance + units.RAD_PER_PULSE
                ), s.id
    assert 8 not in goal_ids_after(sim_bus, mark)  # the faulted servo was not commanded
    assert goal_ids_after(sim_bus, mark) == {1, 2, 3, 4, 5, 6, 7}
    assert set(torques(sim_bus).values()) == {0}  # then torque off everywhere
    assert bus.status().hardware_errors == {8: ("overload",)}


@pytest.mark.parametrize("faulted", [2, 3], ids=["shoulder-primary", "shoulder-shadow"])
def test_rest_after_a_shoulder_fault_leaves_the_shoulder_alone(make_bus, url, sim_bus, arm, clock, caplog, faulted):
    """A joint with a faulted servo is not commanded: its healthy servo is never asked to move the joint alone."""
    bus = make_bus(url, shutdown=ShutdownMode.REST, dt=0.02)
    bus.connect()
    to_home(bus, arm, clock)
    sim_bus.servo(faulted).trigger_hardware_error(HardwareError.OVERLOAD)
    assert sim_bus.servo(faulted).get("Torque Enable") == 0  # its Shutdown mask cut its torque
    with pytest.raises(BusError, match=rf"^servo {faulted}: hardware error: overload; "):
        bus.read_positions()
    assert sim_bus.servo(5 - faulted).get("Torque Enable") == 1  # its partner holds the shoulder alone
    mark = len(sim_bus.log)
    with caplog.at_level("WARNING", logger="drivers.dynamixel_bus"):
        bus.close()
    assert "could not move" not in caplog.text
    assert f"not moving shoulder to rest (faulted servo {faulted})" in caplog.text
    assert goal_ids_after(sim_bus, mark) == {1, 4, 5, 6, 7, 8}  # nothing for servo 2 or 3
    # the healthy one held the shoulder through the whole move: no Torque Enable write before the last read
    entries = list(sim_bus.log)[mark:]
    reads = [k for k, e in enumerate(entries) if e.instruction in (Instruction.SYNC_READ, Instruction.FAST_SYNC_READ)]
    torque_writes = [k for k, _, v in torque_timeline(sim_bus, mark) if v is not None]
    assert len(reads) > 10 and torque_writes and min(torque_writes) - mark > max(reads)
    for s in (2, 3):  # still at home: neither moved
        assert joint_angle(sim_bus, s) == pytest.approx(arm.home[SHOULDER], abs=units.RAD_PER_PULSE), s
    for j, joint in enumerate(arm.joints):
        if j != SHOULDER:
            for s in joint.servos:
                assert joint_angle(sim_bus, s.id) == pytest.approx(
                    arm.rest[j], abs=bus.rest_tolerance + units.RAD_PER_PULSE
                ), s.id
    assert set(torques(sim_bus).values()) == {0}


def test_a_fault_during_the_rest_move_freezes_that_joint_only(make_bus, url, sim_bus, arm, clock, caplog):
    bus = make_bus(url, shutdown=ShutdownMode.REST, dt=0.02)
    bus.connect()
    to_home(bus, arm, clock)
    t0 = clock.now()
    sim_bus.servo(4).schedule_hardware_error(HardwareError.OVERLOAD, at=t0 + 0.5)  # the elbow, 0.5 s into the move
    with caplog.at_level("WARNING", logger="drivers.dynamixel_bus"):
        bus.close()
    assert "could not move" not in caplog.text
    assert "elbow stops where it is" in caplog.text
    assert bus.status().hardware_errors == {4: ("overload",)}
    # the elbow stopped 0.5 s into the move at the rest speed (in 0.229 rpm units), which it reached at its
    # max_acceleration (the rest move's Profile Acceleration, in 214.577 rev/min^2 units): speed^2 / 2a behind a
    # jump to speed; its healthy shadow stopped with it, at most one wait (0.05 s) later
    speed = float(units.velocity_units_to_rad_s(units.rad_s_to_velocity_units(bus.rest_speed)))
    accel = float(units.accel_units_to_rad_s2(units.rad_s2_to_accel_units(arm.joints[ELBOW].max_acceleration)))
    travel = 0.5 * speed - speed**2 / (2 * accel)
    assert joint_angle(sim_bus, 4) == pytest.approx(travel, abs=units.RAD_PER_PULSE)
    assert travel <= joint_angle(sim_bus, 5) <= travel + 0.05 * speed + units.RAD_PER_PULSE
    for j, joint in enumerate(arm.joints):
        if j != ELBOW:
            for s in joint.servos:
                assert joint_angle(sim_bus, s.id) == pytest.approx(
                    arm.rest[j], abs=bus.rest_tolerance + units.RAD_PER_PULSE
                ), s.id
    assert set(torques(sim_bus).values()) == {0}


def test_a_silent_joint_servo_turns_torque_off_at_once(make_bus, url, sim_bus, arm, clock, caplog):
    """Without a joint's reading the arm cannot be watched: no rest move, torque off on every servo that answers."""
    bus = make_bus(url, shutdown=ShutdownMode.REST, dt=0.02, retries=1)
    bus.connect()
    to_home(bus, arm, clock)
    sim_bus.servo(4).unplug()
    mark = len(sim_bus.log)
    with (
        caplog.at_level("ERROR", logger="drivers.dynamixel_bus"),
        pytest.raises(BusError, match=r"^servo 4: could not turn torque off"),
    ):
        bus.close()
    assert "could not move wx250s to its rest pose: servo 4: no status packet" in caplog.text
    assert goal_ids_after(sim_bus, mark) == set()
    assert {i: t for i, t in torques(sim_bus).items() if i != 4} == dict.fromkeys((1, 2, 3, 5, 6, 7, 8, 9), 0)
    assert not bus.connected


# ---------------------------------------------------------------------------------------------- reconnect, holding


def torque_timeline(sim_bus: sim.SimBus, start: int) -> list[tuple[int, int, int | None]]:
    """``(log index, target ID, Torque Enable value or None)`` of every unicast instruction from ``start`` on."""
    out = []
    for k, entry in enumerate(list(sim_bus.log)[start:], start):
        if entry.id == 0xFE:
            continue
        value = None
        if entry.instruction == Instruction.WRITE and int.from_bytes(entry.params[0:2], "little") == TORQUE:
            value = entry.params[2]
        out.append((k, entry.id, value))
    return out


def test_reconnect_to_a_holding_arm_keeps_the_shoulder_limp_only_for_its_own_eeprom(
    make_bus, url, sim_bus, arm, clock, caplog
):
    first = make_bus(url, shutdown=ShutdownMode.HOLD)
    first.connect()
    first.close()
    assert set(torques(sim_bus).values()) == {1}  # left holding
    shoulder = dataclasses.replace(arm.joints[SHOULDER], max_velocity=np.radians(120.0))
    edited = dataclasses.replace(arm, joints=(arm.joints[0], shoulder, *arm.joints[2:]))
    before = {s.id: s.get("Present Position") for s in sim_bus.servos}
    mark = len(sim_bus.log)
    with caplog.at_level("WARNING", logger="drivers.dynamixel_bus"):
        make_bus(url, arm=edited, shutdown=ShutdownMode.HOLD).connect()
    timeline = torque_timeline(sim_bus, mark)
    offs = [(k, i) for k, i, v in timeline if v == 0]
    assert [i for _, i in offs] == [2, 3]  # only the shoulder's servos went limp, one after the other
    on = {s.id: True for s in sim_bus.servos}
    for _, dxl_id, value in timeline:
        if value is not None:
            on[dxl_id] = bool(value)
        assert on[2] or on[3], "both shoulder servos limp at once"
    for k_off, dxl_id in offs:
        k_on = next(k for k, i, v in timeline if k > k_off and i == dxl_id and v == 1)
        window = {i for k, i, _ in timeline if k_off < k < k_on}
        assert window == {dxl_id}, f"servo {dxl_id}'s torque-off window holds instructions to {window - {dxl_id}}"
    assert set(torques(sim_bus).values()) == {1}
    velocity_limit = int(units.rad_s_to_velocity_units(np.radians(120.0)))
    assert sim_bus.servo(2).get("Velocity Limit") == velocity_limit == sim_bus.servo(3).get("Velocity Limit")
    after = {s.id: s.get("Present Position") for s in sim_bus.servos}
    assert after == before  # nothing moved
    for dxl_id in (2, 3):
        assert (
            f"servo {dxl_id}: turning torque off to write its EEPROM settings (Velocity Limit 131 -> {velocity_limit})"
            in caplog.text
        )


# ---------------------------------------------------------------------------------------------- hold goal, multi-turn


@pytest.mark.parametrize(
    ("present", "expected", "lo", "hi"),
    [
        (4196, 100, 0, 4095),
        (-100, 3996, 0, 4095),
        (2500, 2500, 0, 4095),
        (4096 + 2048, 2048, 820, 3345),
        (8191, 3345, 820, 3345),
        (-4096 + 500, 820, 820, 3345),
    ],
    ids=["past-180", "below-0", "in-range", "one-turn-over", "wrapped-then-clipped-high", "wrapped-then-clipped-low"],
)
def test_hold_pulse_wraps_before_clipping(present, expected, lo, hi):
    assert hold_pulse(present, lo, hi) == expected
    assert hold_tick is hold_pulse  # the first release's name


@pytest.mark.parametrize(
    ("servos", "present", "expected"),
    [((1,), 4196, 100), ((1,), -100, 3996), ((2, 3), 4096 + 2100, 2100), ((9,), 4096 + 2000, 2000)],
    ids=["waist-past-180", "waist-below-0", "shoulder-a-turn-over", "gripper-a-turn-over"],
)
def test_torque_on_holds_the_single_turn_position(make_bus, url, sim_bus, servos, present, expected):
    """Present Position counts turns while torque is off; the hold goal is the reading modulo 4096."""
    bus = make_bus(url, shutdown=ShutdownMode.OFF)
    bus.connect()
    bus.set_torque(False)
    for dxl_id in servos:  # turned by hand while limp
        sim_bus.servo(dxl_id).set_position(present)
    mark = len(sim_bus.log)
    bus.set_torque(True)
    goals: dict[int, int] = {}
    for entry in list(sim_bus.log)[mark:]:
        p = entry.params
        if int.from_bytes(p[0:2], "little") != GOAL:
            continue
        if entry.instruction == Instruction.SYNC_WRITE:
            for k in range(4, len(p), 5):
                goals[p[k]] = int.from_bytes(p[k + 1 : k + 5], "little", signed=True)
        elif entry.instruction == Instruction.WRITE:
            goals[entry.id] = int.from_bytes(p[2:6], "little", signed=True)
    assert {i: goals[i] for i in servos} == dict.fromkeys(servos, expected)
    assert all(torques(sim_bus)[i] == 1 for i in servos)
