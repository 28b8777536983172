"""DynamixelBus against the simulated wx250s: registers read back from the simulated servos, not from the driver."""

from __future__ import annotations

import dataclasses
import math
import re

import numpy as np
import pytest

import retarget
import sim
from drivers import units
from drivers.control_table import EEPROM_END, HardwareError
from drivers.dynamixel_bus import DynamixelBus, Profile, plan_servos
from retarget.arm.config import list_arms
from retarget.control.bus import Bus, ShutdownMode
from retarget.errors import BusError, ConfigError
from tests.helpers import goal_writes, torques


def expected_limits(lower: float, upper: float, offset: int = 0) -> tuple[int, int]:
    lo = math.ceil(2048 + offset + lower / units.RAD_PER_PULSE - 1e-6)
    hi = math.floor(2048 + offset + upper / units.RAD_PER_PULSE + 1e-6)
    return max(lo, 0), min(hi, 4095)


# ---------------------------------------------------------------------------------------------- connect


def test_implements_the_bus_protocol(make_bus, url):
    assert isinstance(make_bus(url), Bus)


def test_connect_configures_every_servo_then_enables_torque(make_bus, transport_url, sim_bus, arm):
    bus = make_bus(transport_url, shutdown=ShutdownMode.HOLD)
    bus.connect()
    for j, joint in enumerate(arm.joints):
        for s in joint.servos:
            servo = sim_bus.servo(s.id)
            lo, hi = expected_limits(joint.lower, joint.upper, s.offset)
            assert servo.get("Operating Mode") == 3, s.id
            assert servo.get("Drive Mode") == (1 if s.direction < 0 else 0), s.id
            assert (servo.get("Min Position Limit"), servo.get("Max Position Limit")) == (lo, hi), s.id
            assert servo.get("Velocity Limit") == 131, s.id  # pi rad/s, as Interbotix configures it
            assert servo.get("Profile Velocity") == 131, s.id
            assert servo.get("Return Delay Time") == 0, s.id  # factory 250
            assert servo.get("Homing Offset") == 0, s.id
            assert servo.get("Torque Enable") == 1, s.id
            assert lo <= servo.get("Goal Position") <= hi, (s.id, j)
    gripper = sim_bus.servo(arm.gripper.servo.id)
    assert (gripper.get("Min Position Limit"), gripper.get("Max Position Limit")) == expected_limits(
        arm.gripper.lower, arm.gripper.upper
    )
    assert gripper.get("Torque Enable") == 1
    # enabling torque did not move anything: every joint still reads its starting (rest) pose
    np.testing.assert_allclose(bus.read_positions(), arm.rest, atol=units.RAD_PER_PULSE)
    status = bus.status()
    assert (status.stale_reads, status.errors) == (0, 0)  # no stale reply was left behind
    if transport_url.startswith("sim://"):  # in process, replies are immediate: a clean bus needs no retry
        assert status.retries == 0  # (a loaded machine may delay a pty's or a socket's reply past the timeout)
    bus.close()  # before the pty/TCP server goes away


def test_eeprom_is_written_only_when_it_differs(make_bus, url, sim_bus):
    make_bus(url, shutdown=ShutdownMode.HOLD).connect()
    make_bus(url, shutdown=ShutdownMode.OFF).close()  # nothing: never connected
    for servo in sim_bus.servos:
        servo.writes.clear()
    second = make_bus(url, shutdown=ShutdownMode.HOLD)
    second.connect()  # servos already configured and torque on: no EEPROM write, no torque off
    for servo in sim_bus.servos:
        eeprom = [(address, data) for _, address, data in servo.writes if address < EEPROM_END]
        assert eeprom == [], servo.id
        assert servo.get("Torque Enable") == 1


def test_time_based_profile_sets_drive_mode_bit2(make_bus, url, sim_bus):
    make_bus(url, profile=Profile.TIME, dt=0.02).connect()
    shoulder, shadow = sim_bus.servo(2), sim_bus.servo(3)
    assert (shoulder.get("Drive Mode"), shadow.get("Drive Mode")) == (4, 5)
    assert shoulder.get("Profile Velocity") == 20  # ms: one tick
    assert shoulder.get("Profile Acceleration") == 5


def test_wrong_models_fail_before_any_torque(make_bus, arm, clock):
    wrong = sim.SimBus.from_ids(range(1, 10), "XL430-W250", clock=clock)  # the arm wants XM430-W350 on 1..7
    url = sim.register("drivers-wrong-models", wrong)
    try:
        bus = make_bus(url)
        expected = r"servo 1 is XL430-W250 \(1060\), the arm expects XM430-W350 \(1020\)"
        with pytest.raises(BusError, match=expected) as info:
            bus.connect()
        assert info.value.ids == (1, 2, 3, 4, 5, 6, 7)
        assert "\n" not in str(info.value)
        assert set(torques(wrong).values()) == {0}
        assert all(len(s.writes) == 0 for s in wrong.servos)  # nothing was written at all
        assert not bus.connected
    finally:
        sim.unregister(url)


def test_missing_servos_are_named_with_a_hint(make_bus, arm, clock):
    partial = sim.SimBus.from_arm(arm, clock=clock)
    partial.servo(4).unplug()
    partial.servo(5).unplug()
    url = sim.register("drivers-missing", partial)
    try:
        bus = make_bus(url, retries=0)
        with pytest.raises(BusError, match=r"no status packet from servo 4, 5 at 1000000 baud.*check the baud rate"):
            bus.connect()
        assert set(torques(partial).values()) == {0}
        assert not bus.connected
    finally:
        sim.unregister(url)


def test_wrong_baud_names_every_servo(make_bus, url, arm):
    bus = make_bus(url, baud=57600, retries=0)
    with pytest.raises(BusError, match=r"no status packet from servo 1, 2, 3, 4, 5, 6, 7, 8, 9 at 57600 baud"):
        bus.connect()


def test_unknown_port_is_a_bus_error(make_bus):
    with pytest.raises(BusError, match=r"cannot open port '/dev/does-not-exist'"):
        make_bus("/dev/does-not-exist").connect()


# ---------------------------------------------------------------------------------------------- goals


def test_goals_round_trip_through_the_servos_seeded(make_bus, transport_url, sim_bus, arm, clock):
    bus = make_bus(transport_url, shutdown=ShutdownMode.OFF)
    bus.connect()
    rng = np.random.default_rng(42)
    for _ in range(5):
        q = rng.uniform(bus.lower, bus.upper)
        bus.write_goals(q)
        bus.read_positions()  # a reply: over a pty or TCP the server has now taken the goal, at this clock time
        clock.advance(5.0)  # long enough for any move at pi rad/s
        np.testing.assert_allclose(bus.read_positions(), q, atol=units.RAD_PER_PULSE / 2 + 1e-9)
    bus.close()  # before the pty/TCP server goes away


def test_shadows_are_mirrored_in_the_same_sync_write(make_bus, url, sim_bus, clock):
    bus = make_bus(url, shutdown=ShutdownMode.OFF)
    bus.connect()
    q = np.array([0.3, 0.5, -0.7, 0.2, 0.4, -0.1])
    bus.write_goals(q)
    last = goal_writes(sim_bus)[-1]
    assert sorted(last) == [1, 2, 3, 4, 5, 6, 7, 8]  # shadows 3 and 5 in the same packet
    assert last[2] == last[3] == units.rad_to_pulses(0.5) and last[4] == last[5] == units.rad_to_pulses(-0.7)
    clock.advance(5.0)
    for primary, shadow in ((2, 3), (4, 5)):
        p, s = sim_bus.servo(primary), sim_bus.servo(shadow)
        assert s.get("Drive Mode") & 1 == 1 and p.get("Drive Mode") & 1 == 0
        assert s.get("Present Position") == p.get("Present Position")  # the shaft turned the other way


@pytest.mark.parametrize("scale", [1.5, 10.0, -10.0], ids=["just-over", "far-over", "far-under"])
def test_limits_are_clamped_before_the_wire(make_bus, url, sim_bus, arm, scale):
    bus = make_bus(url, shutdown=ShutdownMode.OFF)
    bus.connect()
    q = np.where(scale > 0, arm.upper, arm.lower) * abs(scale) + np.sign(scale) * 1.0
    bus.write_goals(q)
    plans = {p.id: p for p in plan_servos(arm)}
    writes = goal_writes(sim_bus)
    assert writes
    for packet in writes:
        for dxl_id, ticks in packet.items():
            assert plans[dxl_id].min_pulse <= ticks <= plans[dxl_id].max_pulse, (dxl_id, ticks)
    for servo in sim_bus.servos:
        assert servo.get("Min Position Limit") <= servo.get("Goal Position") <= servo.get("Max Position Limit")


def test_step_limit_from_max_velocity(make_bus, url, sim_bus, arm):
    dt = 0.02
    bus = make_bus(url, dt=dt, shutdown=ShutdownMode.OFF)
    bus.connect()
    start = bus.read_positions()
    bus.write_goals(start + 1.0)  # one radian on every joint, in one tick
    first = goal_writes(sim_bus)[-1]
    max_ticks = arm.max_velocity[0] * dt / units.RAD_PER_PULSE
    for joint_index, dxl_id in enumerate((1, 2, 4, 6, 7, 8)):
        before = units.rad_to_pulses(start[joint_index])
        assert abs(first[dxl_id] - before) <= math.ceil(max_ticks), dxl_id
    bus.write_goals(start + 1.0)  # the next tick takes the next step
    assert goal_writes(sim_bus)[-1][1] > first[1]


@pytest.mark.parametrize(
    ("q", "message"),
    [
        (np.zeros(5), r"Expected goals of shape \(6,\) in radians, got shape \(5,\)"),
        (np.array([0, 0, math.nan, 0, 0, 0]), r"Expected finite goals"),
    ],
    ids=["shape", "nan"],
)
def test_bad_goals_are_refused(make_bus, url, q, message):
    bus = make_bus(url, shutdown=ShutdownMode.OFF)
    bus.connect()
    with pytest.raises(ValueError, match=message):
        bus.write_goals(q)


def test_torque_on_again_does_not_jump(make_bus, url, sim_bus, clock):
    bus = make_bus(url, shutdown=ShutdownMode.OFF)
    bus.connect()
    bus.set_torque(False)
    sim_bus.servo(1).set_position(2500)  # pushed by hand while limp
    bus.set_torque(True)
    assert sim_bus.servo(1).get("Goal Position") == 2500
    assert torques(sim_bus)[1] == 1


def test_gripper_is_clamped_and_read_back(make_bus, url, sim_bus, arm, clock):
    bus = make_bus(url, shutdown=ShutdownMode.OFF)
    bus.connect()
    bus.write_gripper(10.0)
    clock.advance(5.0)
    assert bus.read_gripper() == pytest.approx(arm.gripper.upper, abs=units.RAD_PER_PULSE)
    assert sim_bus.servo(9).get("Goal Position") == sim_bus.servo(9).get("Max Position Limit")


# ---------------------------------------------------------------------------------------------- faults


def test_dropped_replies_are_retried(make_bus, arm, clock):
    lossy = sim.SimBus.from_arm(arm, clock=clock, faults=sim.Faults(bus=sim.ReplyFaults(drop=0.05), seed=3))
    url = sim.register("drivers-lossy", lossy)
    try:
        bus = make_bus(url, retries=6, shutdown=ShutdownMode.OFF)
        bus.connect()
        for _ in range(15):
            bus.write_goals(np.zeros(6))
            clock.advance(0.02)
            assert bus.read_positions().shape == (6,)
        status = bus.status()
        assert status.retries > 0 and status.errors == 0 and status.ticks == 15
    finally:
        sim.unregister(url)


@pytest.mark.parametrize("fast_read", [True, False], ids=["fast-sync-read", "sync-read"])
@pytest.mark.parametrize("max_stale", [0, 3], ids=["no-stale", "stale-3"])
def test_unplugged_servo_raises_naming_it(make_bus, url, sim_bus, fast_read, max_stale):
    bus = make_bus(url, retries=1, fast_read=fast_read, shutdown=ShutdownMode.OFF, max_stale_ticks=max_stale)
    bus.connect()
    before = bus.read_positions()
    sim_bus.servo(5).unplug()  # a shadow (elbow): its primary 4 still gives the joint's angle
    for k in range(max_stale):  # its last reading stands in, marked stale, for max_stale_ticks reads
        np.testing.assert_array_equal(bus.read_positions(), before)
        assert (bus.status().stale_reads, bus.status().worst_stale) == (k + 1, k + 1)
    with pytest.raises(BusError, match=r"^servo 5: no status packet \(Present Position\) at 1000000 baud") as info:
        bus.read_positions()
    assert info.value.ids == (5,)
    if max_stale:
        expected = r"5: stale 4 reads in a row, 4 of the last 5 reads \(80%\), \d+% of \d+ replies lost"
        assert re.search(expected, str(info.value))
    assert bus.status().errors == 1
    with pytest.raises(BusError, match="faulted"):  # no more goals after an unrecoverable fault
        bus.write_goals(np.zeros(6))
    with pytest.raises(BusError, match=r"^servo 5: could not turn torque off$"):  # the others did
        bus.close()
    assert not bus.connected
    assert {i: t for i, t in torques(sim_bus).items() if i != 5} == dict.fromkeys((1, 2, 3, 4, 6, 7, 8, 9), 0)


def test_hardware_error_is_reported_by_name(make_bus, url, sim_bus):
    bus = make_bus(url, shutdown=ShutdownMode.OFF)
    bus.connect()
    sim_bus.servo(4).trigger_hardware_error(HardwareError.OVERLOAD | HardwareError.OVERHEATING)
    expected = r"^servo 4: hardware error: overheating, overload; .*power-cycle it or reboot it"
    with pytest.raises(BusError, match=expected) as info:
        bus.read_positions()
    assert info.value.ids == (4,)
    assert bus.status().hardware_errors == {4: ("overheating", "overload")}
    with pytest.raises(BusError, match="faulted"):
        bus.write_goals(np.zeros(6))


def test_recover_reboots_and_configures_again(make_bus, url, sim_bus, clock):
    bus = make_bus(url, recover=True, shutdown=ShutdownMode.OFF)
    bus.connect()
    servo = sim_bus.servo(6)
    servo.trigger_hardware_error(HardwareError.OVERLOAD)
    assert servo.get("Torque Enable") == 0  # the servo shut itself down
    q = bus.read_positions()  # rebooted, configured, torque back on
    assert q.shape == (6,)
    assert servo.get("Hardware Error Status") == 0 and servo.get("Torque Enable") == 1
    assert servo.get("Return Delay Time") == 0 and servo.get("Velocity Limit") == 131
    assert bus.status().hardware_errors == {}


def test_recover_gives_up_after_three_reboots(make_bus, url, sim_bus):
    bus = make_bus(url, recover=True, shutdown=ShutdownMode.OFF)
    bus.connect()
    servo = sim_bus.servo(6)
    for _ in range(3):
        servo.trigger_hardware_error(HardwareError.OVERLOAD)
        bus.read_positions()
    servo.trigger_hardware_error(HardwareError.OVERLOAD)
    with pytest.raises(BusError, match=r"^servo 6: hardware error: overload; still failing after 3 reboots"):
        bus.read_positions()


# ---------------------------------------------------------------------------------------------- shutdown


@pytest.mark.parametrize("profile", [Profile.VELOCITY, Profile.TIME], ids=["velocity-profile", "time-profile"])
def test_close_rest_moves_to_rest_then_torque_off(make_bus, url, sim_bus, arm, clock, profile):
    bus = make_bus(url, shutdown=ShutdownMode.REST, profile=profile, dt=0.02)
    bus.connect()
    for _ in range(200):  # stream the arm to home, 4 s at 50 Hz
        bus.write_goals(arm.home)
        clock.advance(0.02)
    np.testing.assert_allclose(bus.read_positions(), arm.home, atol=0.002)
    t0 = clock.now()
    bus.close()
    # it waited on the bus clock, and the move was no faster than the safe speed
    farthest = float(np.max(np.abs(arm.rest - arm.home)))
    assert clock.now() - t0 >= (farthest - bus.rest_tolerance) / bus.rest_speed
    assert set(torques(sim_bus).values()) == {0}
    # with torque off nothing moves: the present position is where the servos were when torque went off
    for joint, rest in zip(arm.joints, arm.rest, strict=True):
        for s in joint.servos:
            present = units.pulses_to_rad(sim_bus.servo(s.id).get("Present Position"))
            assert present == pytest.approx(rest, abs=bus.rest_tolerance + units.RAD_PER_PULSE), s.id


@pytest.mark.parametrize(("mode", "torque"), [(ShutdownMode.OFF, 0), (ShutdownMode.HOLD, 1)], ids=["off", "hold"])
def test_close_off_and_hold(make_bus, url, sim_bus, mode, torque):
    bus = make_bus(url, shutdown=mode)
    bus.connect()
    bus.write_goals(np.zeros(6))
    before = len(goal_writes(sim_bus))
    bus.close()
    assert len(goal_writes(sim_bus)) == before  # no goal after close began
    assert set(torques(sim_bus).values()) == {torque}


def test_context_manager_runs_the_shutdown(make_bus, url, sim_bus):
    with make_bus(url, shutdown="off") as bus:
        assert bus.connected and set(torques(sim_bus).values()) == {1}
    assert not bus.connected and set(torques(sim_bus).values()) == {0}


def test_ctrl_c_still_turns_torque_off(make_bus, url, sim_bus):
    bus = make_bus(url, shutdown=ShutdownMode.OFF)
    with pytest.raises(KeyboardInterrupt), bus:
        bus.link.port.is_using = True  # as if Ctrl-C hit inside an SDK transaction
        raise KeyboardInterrupt
    assert set(torques(sim_bus).values()) == {0}


def test_closed_bus_refuses_calls(make_bus, url):
    bus = make_bus(url, shutdown=ShutdownMode.OFF)
    for call in (bus.read_positions, lambda: bus.write_goals(np.zeros(6)), lambda: bus.set_torque(True)):
        with pytest.raises(BusError, match="not connected"):
            call()
    bus.connect()
    bus.read_positions()
    bus.close()
    bus.close()  # idempotent
    with pytest.raises(BusError, match="not connected"):
        bus.read_positions()
    assert bus.status().connected is False
    assert bus.status().ticks == 1  # counters stay readable after close


# ---------------------------------------------------------------------------------------------- options


@pytest.mark.parametrize(
    ("options", "error", "message"),
    [
        ({"retries": -1}, ValueError, "Expected retries >= 0"),
        ({"return_delay_us": 600}, ValueError, r"Expected return_delay_us in 0\.\.508"),
        ({"dt": 0.0}, ValueError, "Expected dt > 0"),
        ({"shutdown": "sleep"}, ValueError, "'sleep' is not a valid ShutdownMode"),
    ],
    ids=["retries", "return-delay", "dt", "shutdown"],
)
def test_bad_options(arm, options, error, message):
    with pytest.raises(error, match=message):
        DynamixelBus(arm, "sim://wx250s", **options)


def test_unknown_servo_model_is_a_config_error(arm):
    import dataclasses

    joint = dataclasses.replace(arm.joints[0], servos=(dataclasses.replace(arm.joints[0].servos[0], model="AX-12A"),))
    bad = dataclasses.replace(arm, joints=(joint, *arm.joints[1:]))
    with pytest.raises(ConfigError, match=r"joints\[0\]\.servos\[0\]\.model"):
        DynamixelBus(bad, "sim://wx250s")


def test_fault_options_in_the_url_hardware_error_at_connect(arm):
    """The simulator's own URL options (its own virtual clock): a servo already in overload fails connect."""
    bus = DynamixelBus(arm, "sim://wx250s?clock=virtual&hwerror=7:overload@0", check_latency=False)
    with pytest.raises(BusError, match=r"^servo 7: hardware error: overload; ") as info:
        bus.connect()
    assert info.value.ids == (7,)
    assert not bus.connected


def test_fault_options_in_the_url_dropped_replies(arm):
    bus = DynamixelBus(
        arm, "sim://wx250s?clock=virtual&drop=0.03&seed=11", retries=6, shutdown="off", check_latency=False
    )
    with bus:
        for _ in range(10):
            bus.read_positions()
        assert bus.status().retries > 0 and bus.status().errors == 0


def test_torque_on_is_all_or_nothing(make_bus, url, sim_bus):
    bus = make_bus(url, retries=0, shutdown=ShutdownMode.HOLD)
    bus.connect()
    bus.set_torque(False)
    sim_bus.servo(4).set("Status Return Level", 1)  # acts on writes but never answers them
    with pytest.raises(BusError, match=r"^servo 4: no status packet writing Torque Enable = 1$"):
        bus.set_torque(True)
    assert set(torques(sim_bus).values()) == {0}  # servos 1-3 were enabled, then turned off again


def test_read_state_reports_health_in_si_units(make_bus, url, sim_bus, arm):
    bus = make_bus(url, shutdown=ShutdownMode.OFF)
    bus.connect()
    sim_bus.servo(8).ambient_temperature = 55.0
    state = bus.read_state()
    assert state.ids == (1, 2, 3, 4, 5, 6, 7, 8, 9)
    np.testing.assert_allclose(state.position[[0, 1, 3, 5, 6, 7]], arm.rest, atol=units.RAD_PER_PULSE)
    assert state.position[2] == state.position[1]  # the shoulder shadow reads as its joint
    xm = slice(0, 7)  # XM430-W350: current, 12 V; XL430-W250 (8, 9): load, 11.1 V
    assert np.all(np.isfinite(state.current[xm])) and np.all(np.isnan(state.load[xm]))
    assert np.all(np.isnan(state.current[7:])) and np.all(np.isfinite(state.load[7:]))
    np.testing.assert_allclose(state.voltage, [12.0] * 7 + [11.1] * 2)
    assert state.temperature[7] >= 55 and state.temperature[0] < 55
    np.testing.assert_allclose(state.velocity, 0.0)


def test_shadow_disagreeing_with_its_primary_keeps_torque_off(make_bus, url, sim_bus):
    sim_bus.servo(3).set_position(sim_bus.servo(3).get("Present Position") + 300)  # drive mode still 0 here
    bus = make_bus(url)
    with pytest.raises(
        BusError, match=r"^servo 3: shadow servo disagrees with its joint \(servo 3 reads [+-]0\.\d+ rad"
    ):
        bus.connect()
    assert set(torques(sim_bus).values()) == {0} and not bus.connected


def test_eeprom_change_on_a_servo_under_torque_turns_it_off_first(make_bus, url, sim_bus, caplog):
    make_bus(url, shutdown=ShutdownMode.HOLD).connect()
    sim_bus.servo(2).set("Return Delay Time", 250)  # torque is on: a plain write would be an access error
    with caplog.at_level("WARNING", logger="drivers.dynamixel_bus"):
        make_bus(url, shutdown=ShutdownMode.HOLD).connect()
    assert sim_bus.servo(2).get("Return Delay Time") == 0 and sim_bus.servo(2).get("Torque Enable") == 1
    assert "servo 2: turning torque off to write its EEPROM settings" in caplog.text


@pytest.mark.parametrize("level", [0, 1], ids=["ping-only", "reads-only"])
def test_status_return_level_is_restored(make_bus, url, sim_bus, level):
    sim_bus.servo(4).set("Status Return Level", level)
    make_bus(url, shutdown=ShutdownMode.OFF).connect()
    assert sim_bus.servo(4).get("Status Return Level") == 2 and sim_bus.servo(4).get("Torque Enable") == 1


@pytest.mark.parametrize("name", list_arms())
def test_every_bundled_arm_connects_moves_and_rests(name, clock):
    arm = retarget.load_arm(name)
    simulated = sim.SimBus.from_arm(arm, clock=clock)
    url = sim.register(f"drivers-arm-{name}", simulated)
    try:
        with DynamixelBus(arm, url, clock=clock, check_latency=False) as bus:
            bus.write_goals(arm.home)
            clock.advance(10.0)
            np.testing.assert_allclose(
                bus.read_positions(), np.clip(arm.home, bus.lower, bus.upper), atol=units.RAD_PER_PULSE
            )
            assert bus.status().retries == 0
        assert set(torques(simulated).values()) == {0}
    finally:
        sim.unregister(url)


def test_step_limit_starts_from_the_clamped_goal(make_bus, url, sim_bus, arm):
    """With ``dt`` set the step limit walks from the last goal *after* the joint clamp: a waist held at +20 rad
    for 400 ticks stays at its upper limit, so asking for the start pose again moves the goal back one step at
    the next tick (without the clamp the last goal ran to 12.6 rad and the wire stayed pinned at the top tick
    for about 300 ticks while the caller believed the arm was coming back)."""
    dt = 0.01
    bus = make_bus(url, dt=dt, shutdown=ShutdownMode.OFF)
    bus.connect()
    start = bus.read_positions()
    far = start.copy()
    far[0] = 20.0
    for _ in range(400):
        bus.write_goals(far)
    top = plan_servos(arm)[0].max_pulse  # the waist's upper limit, +pi, on the servo's last tick
    assert goal_writes(sim_bus)[-1][1] == top == 4095 and bus.upper[0] == units.pulses_to_rad(top)
    step = arm.max_velocity[0] * dt  # 20.5 ticks
    for k in range(1, 4):
        bus.write_goals(start)
        assert goal_writes(sim_bus)[-1][1] == units.rad_to_pulses(bus.upper[0] - k * step), k
    assert goal_writes(sim_bus)[-1][1] == 4095 - 61  # three steps of 20.5 ticks back


def test_a_shadow_with_another_offset_narrows_its_joint(make_bus, clock, arm):
    """A shadow whose zero offset moves its tick range 250 ticks past 4095: the joint's range is what both
    servos can reach, so at the joint's upper limit the primary stops 250 ticks short of its own limit and the
    two servos get the same angle (clipping ticks per servo alone would send the primary 250 ticks further
    than its shadow: the two would fight, overloaded)."""
    shoulder = arm.joints[1]
    primary, shadow = shoulder.servos
    offset = 4095 + 250 - int(units.rad_to_pulses(shoulder.upper))  # shadow's tick at the arm's upper limit: 4345
    moved = dataclasses.replace(shoulder, servos=(primary, dataclasses.replace(shadow, offset=offset)))
    shifted = dataclasses.replace(arm, joints=(arm.joints[0], moved, *arm.joints[2:]))
    plans = {p.id: p for p in plan_servos(shifted)}
    assert plans[3].max_pulse == 4095 and plans[2].max_pulse == units.rad_to_pulses(shoulder.upper)
    simulated = sim.SimBus.from_arm(shifted, clock=clock)
    name = f"drivers-shadow-offset-{id(simulated)}"
    try:
        bus = make_bus(sim.register(name, simulated), arm=shifted, shutdown=ShutdownMode.OFF)
        bus.connect()
        assert bus.upper[1] == pytest.approx(shoulder.upper - 250 * units.RAD_PER_PULSE, abs=units.RAD_PER_PULSE)
        q = bus.read_positions()
        for far in (shoulder.upper, shoulder.upper + 1.0):
            q[1] = far
            bus.write_goals(q)
            last = goal_writes(simulated)[-1]
            assert (last[2], last[3]) == (plans[2].max_pulse - 250, 4095), far
        q[1] = shoulder.lower + 0.1  # inside both ranges: the same angle, each on its own zero
        bus.write_goals(q)
        last = goal_writes(simulated)[-1]
        assert last[2] == units.rad_to_pulses(q[1]) and last[3] == units.rad_to_pulses(q[1], offset=offset)
        bus.close()
    finally:
        sim.unregister(name)
