"""The gripper on the real driver against the simulated bus: configured in current-based position mode (5) with
the arm file's current limit, it closes on an object (a ``block`` wall in the sim) and holds it at that current
without overloading; in plain position mode (3) the same close pushes at stall and the watch reports Overload.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import retarget
import sim
from drivers import DynamixelBus, control_table
from drivers.control_table import OperatingMode
from drivers.control_table import model as lookup_model
from drivers.gripper import gripper_registers
from retarget.arm.model import MAX_CURRENT_LIMIT_MA, Arm
from retarget.control.clock import VirtualClock
from retarget.errors import BusError, ConfigError

BLOCK = 1900  #: pulses: the object, between the vx300s gripper's centre (2048) and its closed limit (1779)


def _connect(arm: Arm, *, block: int | None = None) -> tuple[DynamixelBus, sim.SimBus, VirtualClock, str]:
    clock = VirtualClock()
    simbus = sim.SimBus.from_arm(arm, clock=clock)
    assert arm.gripper is not None
    if block is not None:
        simbus.servo(arm.gripper.servo.id).block_at(block)
    url = sim.attach(simbus)
    bus = DynamixelBus(arm, url, clock=clock, shutdown="off", dt=0.01, check_latency=False)
    bus.connect()
    return bus, simbus, clock, url


def _close_on_block(arm: Arm, seconds: float) -> tuple[BusError | None, dict[str, int]]:
    """Close the gripper fully onto the wall at BLOCK and tick (position reads, the gripper watched) ``seconds``;
    (the run's BusError or None, the gripper servo's registers at the end, before the bus closes)."""
    assert arm.gripper is not None
    bus, simbus, clock, url = _connect(arm, block=BLOCK)
    error: BusError | None = None
    try:
        bus.write_gripper(arm.gripper.angle(1.0))
        for _ in range(round(seconds / 0.01)):
            clock.sleep_until(clock.now() + 0.01)
            bus.read_positions()
    except BusError as exc:
        error = exc
    finally:
        servo = simbus.servo(arm.gripper.servo.id)
        names = ("Present Position", "Present Current", "Hardware Error Status", "Torque Enable")
        registers = {name: servo.get(name) for name in names}
        bus.close()
        sim.unregister(url)
    return error, registers


@pytest.mark.parametrize(
    ("name", "mode", "limits"),
    [
        pytest.param("vx300s", OperatingMode.CURRENT_BASED_POSITION, {"Current Limit": 242}, id="vx300s-650mA"),
        pytest.param("omx", OperatingMode.CURRENT_BASED_POSITION, {"Current Limit": 200}, id="omx-538mA"),
        pytest.param("koch", OperatingMode.CURRENT_BASED_POSITION, {"Current Limit": 500}, id="koch-500mA"),
        pytest.param("wx250s", OperatingMode.POSITION, {"PWM Limit": 250}, id="wx250s-pwm"),
        pytest.param("px100", OperatingMode.POSITION, {"PWM Limit": 250}, id="px100-pwm"),
    ],
)
def test_connect_configures_the_gripper_from_the_arm_file(name, mode, limits):
    arm = retarget.load_arm(name)
    assert arm.gripper is not None
    bus, simbus, _, url = _connect(arm)
    try:
        servo = simbus.servo(arm.gripper.servo.id)
        assert servo.get("Operating Mode") == mode
        for reg, value in limits.items():
            assert servo.get(reg) == value
        if mode == OperatingMode.CURRENT_BASED_POSITION:
            assert servo.get("Goal Current") == limits["Current Limit"]
        joint = simbus.servo(arm.joints[0].servos[0].id)
        assert joint.get("Operating Mode") == OperatingMode.POSITION  # the joints stay in position mode
    finally:
        bus.close()
        sim.unregister(url)


def test_mode_5_holds_the_object_at_the_current_limit_without_overload():
    arm = retarget.load_arm("vx300s")
    assert arm.gripper is not None
    error, registers = _close_on_block(arm, 3.0)
    assert error is None
    assert registers["Present Position"] == BLOCK  # stopped at the object, short of the closed limit
    assert registers["Hardware Error Status"] == 0
    assert registers["Torque Enable"] == 1
    # pushing (toward lower pulses) at the limit: 242 units x 2.69 mA = 651 mA
    assert registers["Present Current"] == -242


def test_mode_5_telemetry_reads_the_current_at_the_limit():
    arm = retarget.load_arm("vx300s")
    assert arm.gripper is not None
    bus, simbus, clock, url = _connect(arm, block=BLOCK)
    try:
        bus.write_gripper(arm.gripper.angle(1.0))
        clock.sleep_until(clock.now() + 1.0)
        state = bus.read_state()
        k = state.ids.index(arm.gripper.servo.id)
        assert abs(state.current[k]) == pytest.approx(0.651, abs=0.003)
        assert bus.read_gripper() == pytest.approx(
            (BLOCK - 2048) * 2 * np.pi / 4096, abs=1e-6
        )  # offset 0: 2048 is 0 rad
    finally:
        bus.close()
        sim.unregister(url)


def test_plain_position_mode_overloads_on_the_same_object():
    arm = retarget.load_arm("vx300s")
    assert arm.gripper is not None
    plain = dataclasses.replace(arm, gripper=dataclasses.replace(arm.gripper, current_limit=None))
    error, registers = _close_on_block(plain, 3.0)
    assert error is not None
    assert "overload" in str(error) and "9" in str(error)
    assert registers["Hardware Error Status"] == 0x20
    assert registers["Present Position"] == BLOCK


def test_current_limit_needs_current_sensing():
    arm = retarget.load_arm("wx250s")
    assert arm.gripper is not None
    g = dataclasses.replace(arm.gripper, current_limit=500.0)
    with pytest.raises(ConfigError, match=r"gripper\.current_limit.*XL430-W250"):
        gripper_registers(g, lookup_model("XL430-W250"))


def test_current_limit_above_the_model_maximum():
    arm = retarget.load_arm("vx300s")
    assert arm.gripper is not None
    g = dataclasses.replace(arm.gripper, current_limit=5000.0)
    with pytest.raises(ConfigError, match="Expected at most 3209 mA"):
        gripper_registers(g, lookup_model("XM430-W350"))


def test_set_gripper_writes_on_the_tick_path_and_reads_at_the_watch_rate():
    arm = retarget.load_arm("vx300s")
    assert arm.gripper is not None
    bus, simbus, clock, url = _connect(arm, block=BLOCK)
    servo = simbus.servo(arm.gripper.servo.id)
    try:
        assert bus.gripper_reading() is not None and np.isnan(bus.gripper_reading().command)  # type: ignore[union-attr]
        before = servo.get("Goal Position")
        bus.set_gripper(1.0)
        assert servo.get("Goal Position") == before  # stored, not sent
        for _ in range(100):  # 1 s at 100 Hz: the watch rate is every 20 reads
            clock.sleep_until(clock.now() + 0.01)
            bus.read_positions()
        assert servo.get("Goal Position") == 1779  # the closed (lower) limit
        reading = bus.gripper_reading()
        assert reading is not None and reading.command == 1.0
        assert reading.angle == pytest.approx((BLOCK - 2048) * 2 * np.pi / 4096)
        assert reading.current == pytest.approx(-0.651, abs=0.003)
        writes = [w for w in servo.writes if w[1] == 116]
        bus.set_gripper(1.002)  # within the deadband: clipped to 1.0 anyway, nothing new is written
        bus.set_gripper(0.999)
        bus.read_positions()
        assert [w for w in servo.writes if w[1] == 116] == writes
        with pytest.raises(ValueError, match="finite gripper closure"):
            bus.set_gripper(float("nan"))
    finally:
        bus.close()
        sim.unregister(url)


@pytest.mark.parametrize("name", sorted(control_table.MODELS), ids=str)
def test_the_arm_readers_current_limits_are_the_register_tables(name: str) -> None:
    model = control_table.model(name)
    top = model.register("Current Limit").maximum if model.current_unit_ma else None
    expected = None if top is None else top * model.current_unit_ma
    assert MAX_CURRENT_LIMIT_MA[name] == (None if expected is None else pytest.approx(expected))
