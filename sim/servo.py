"""One simulated Dynamixel X-series servo: control-table memory, access rules, motion, load and hardware errors.

The servo answers instruction-level calls (:meth:`SimServo.read`, :meth:`SimServo.write`, ...) with a
Protocol 2.0 error number and data; :class:`sim.bus.SimBus` turns those into packets.  The registers and
their defaults, ranges and access come from :mod:`drivers.control_table`.

Rules it follows, from the e-Manual:

* EEPROM items (address < 64) are writable only while Torque Enable is 0: Access error (7) otherwise.
  Read-only items and undefined addresses answer Access error; a write that covers part of an item answers
  Data Length error (5); a value outside an item's range answers Data Range (4); a Goal Position outside
  Min/Max Position Limit (position mode), a Goal Velocity beyond Velocity Limit, a Goal Current beyond
  Current Limit or a Goal PWM beyond PWM Limit answers Data Limit (6).  A failed write changes nothing.
* Present Position = Actual Position + Homing Offset.  Drive Mode bit 0 (reverse) mirrors the direction:
  the servo reports ``4096 - actual`` (the same within one turn as ``-actual``) so a reversed servo at the
  centre still reads 2048; goals, velocity and current are mirrored with it.
* Position modes (3, 4, 5) move toward Goal Position with the velocity-based trapezoid of Profile
  Velocity/Acceleration (0 = unlimited), or the time-based profile (Drive Mode bit 2) where they are
  times in ms.  The speed is capped by Velocity Limit and by the model's no-load speed.  Velocity mode (1)
  ramps Present Velocity to Goal Velocity under Profile Acceleration.  PWM (16), current (0) and
  current-based position (5) modes follow the no-load motor of :mod:`sim.physics`.  With torque off the
  motor does nothing; a hand may turn the horn (:meth:`SimServo.move_by_hand`).
* Present Current (Present Load on XL430) is the unloaded motor's: about zero at rest, growing with
  acceleration and velocity (:mod:`sim.physics`).  Temperature and input voltage are readable.
* Secondary ID, Protocol Type, the single-turn Homing Offset rule, Bus Watchdog and Indirect Data's inherited
  rules: :mod:`sim.rules` and :mod:`sim.watchdog`.
* A hardware error sets Hardware Error Status and the Alert bit (0x80) of every status packet.  If its bit
  is in the Shutdown mask, torque goes off and a write of Torque Enable = 1 is ignored until REBOOT.
* REBOOT resets the RAM area and clears hardware errors; FACTORY_RESET resets the table (0xFF all,
  0x01 all but ID, 0x02 all but ID and Baud Rate).

Motion is integrated lazily: every read and write first brings the servo to ``clock.now()`` (the bus also brings
every servo to each packet's time).  The Present items' bytes are computed only when something reads the memory
(a READ, a sync/bulk read, :meth:`SimServo.get`, :attr:`SimServo.memory`), for the state at the last update: the
bytes an eager computation on every update would have stored, at a fraction of the cost (a bus transaction
updates each servo several times and reads it at most once; ``tests/sim/test_replies_golden.py`` holds the replies
to their values before this was lazy).  A read of Present Position alone (the driver's position read, every tick)
computes that item only; ``tests/sim/test_fast_paths.py`` holds it to the whole block's bytes.
"""

from __future__ import annotations

import logging
import math
import struct
from collections import deque
from collections.abc import Mapping

from drivers.control_table import (
    ALERT_BIT,
    BAUD_CODES,
    BAUD_RATES,
    BROADCAST_ID,
    EEPROM_END,
    MODELS,
    PULSES_PER_REV,
    RETURN_DELAY_UNIT_S,
    RPM2_PER_ACCEL_UNIT,
    RPM_PER_VELOCITY_UNIT,
    VOLT_PER_UNIT,
    DriveMode,
    FactoryReset,
    HardwareError,
    Model,
    OperatingMode,
    Register,
    StatusError,
    common_register,
)
from drivers.control_table import model as lookup_model
from retarget.control.clock import Clock, MonotonicClock
from sim import rules
from sim.hand import HandPath, rate, smoothstep_path
from sim.obstacle import OVERLOAD_AFTER_S, OVERLOAD_SHARE, Obstacle
from sim.physics import PWM_FULL_SCALE, Motor
from sim.profile import Trajectory, ramp_profile, rest, time_profile, velocity_profile
from sim.servo_writes import WriteRules, register_struct
from sim.watchdog import WATCHDOG_ERROR, BusWatchdog

log = logging.getLogger(__name__)
_I32 = struct.Struct("<i")

PULSES_PER_S_PER_VELOCITY_UNIT = RPM_PER_VELOCITY_UNIT / 60.0 * PULSES_PER_REV  #: ~15.63
PULSES_PER_S2_PER_ACCEL_UNIT = RPM2_PER_ACCEL_UNIT / 3600.0 * PULSES_PER_REV  #: ~244.1
CLEAR_MULTI_TURN = bytes((0x01, 0x44, 0x58, 0x4C, 0x22))
_POSITION_MODES = (OperatingMode.POSITION, OperatingMode.EXTENDED_POSITION, OperatingMode.CURRENT_BASED_POSITION)

# Addresses of the items the servo reads and writes in its own memory on every update: the same on every X model
# (common_register checks that), as plain ints for the hot path.  "Present Current" is Present Load on XL430.
_MODEL_NUMBER = common_register("Model Number").address
_FIRMWARE_VERSION = common_register("Firmware Version").address
_ID = common_register("ID").address
_BAUD_RATE = common_register("Baud Rate").address
_RETURN_DELAY_TIME = common_register("Return Delay Time").address
_DRIVE_MODE = common_register("Drive Mode").address
_OPERATING_MODE = common_register("Operating Mode").address
_SECONDARY_ID = common_register("Secondary(Shadow) ID").address
_BUS_WATCHDOG = common_register("Bus Watchdog").address
_HOMING_OFFSET = common_register("Homing Offset").address
_MOVING_THRESHOLD = common_register("Moving Threshold").address
_SHUTDOWN = common_register("Shutdown").address
_TORQUE_ENABLE = common_register("Torque Enable").address
_STATUS_RETURN_LEVEL = common_register("Status Return Level").address
_REGISTERED_INSTRUCTION = common_register("Registered Instruction").address
_HARDWARE_ERROR_STATUS = common_register("Hardware Error Status").address
_GOAL_POSITION = common_register("Goal Position").address
_REALTIME_TICK = common_register("Realtime Tick").address
_MOVING = common_register("Moving").address
_MOVING_STATUS = common_register("Moving Status").address
_PRESENT_PWM = common_register("Present PWM").address
_PRESENT_CURRENT = common_register("Present Current").address
_PRESENT_VELOCITY = common_register("Present Velocity").address
_PRESENT_POSITION = common_register("Present Position").address
_VELOCITY_TRAJECTORY = common_register("Velocity Trajectory").address
_POSITION_TRAJECTORY = common_register("Position Trajectory").address
_PRESENT_INPUT_VOLTAGE = common_register("Present Input Voltage").address
_PRESENT_TEMPERATURE = common_register("Present Temperature").address
#: every Present item, Realtime Tick (120) to Present Temperature (146), back to back: one pack per refresh
_PRESENT_ITEMS = struct.Struct("<HBBhhiiiiHB")
_PRESENT_ORDER = (
    _REALTIME_TICK,
    _MOVING,
    _MOVING_STATUS,
    _PRESENT_PWM,
    _PRESENT_CURRENT,
    _PRESENT_VELOCITY,
    _PRESENT_POSITION,
    _VELOCITY_TRAJECTORY,
    _POSITION_TRAJECTORY,
    _PRESENT_INPUT_VOLTAGE,
    _PRESENT_TEMPERATURE,
)
if [a - _REALTIME_TICK for a in _PRESENT_ORDER] != [0, 2, 3, 4, 6, 8, 12, 16, 20, 24, 26]:  # pragma: no cover
    raise ImportError(f"Expected the Present items back to back from address 120, got {_PRESENT_ORDER}")
#: the goal item a Bus Watchdog trip zeroes, by Operating Mode
_MODE_GOAL: dict[int, str] = {
    OperatingMode.VELOCITY: "Goal Velocity",
    OperatingMode.PWM: "Goal PWM",
    OperatingMode.CURRENT: "Goal Current",
}
_REVERSE_BIT = int(DriveMode.REVERSE)  #: Drive Mode bit 0, as an int (an IntFlag operation costs a microsecond)
_TIME_BASED_BIT = int(DriveMode.TIME_BASED_PROFILE)  #: Drive Mode bit 2
_CURRENT_BASED_POSITION = int(OperatingMode.CURRENT_BASED_POSITION)
_PWM_MODE = int(OperatingMode.PWM)
_NONE = StatusError.NONE  #: as a constant: reading an Enum member costs ~0.1 us, and every read and write answers it

#: how to read a register's value from memory: ``(register_struct, address)``
_Reader = tuple[struct.Struct, int]


def _common_reader(name: str) -> _Reader:
    """The reader of item ``name``, the same on every model (address, size and sign; ImportError otherwise)."""
    regs = {(r.address, r.size, r.signed) for m in MODELS.values() if (r := m.registers.get(name)) is not None}
    st = register_struct(common_register(name))
    if len(regs) != 1 or st is None:  # pragma: no cover - the tables say otherwise
        raise ImportError(f"Expected {name!r} alike on every model, got (address, size, signed) {sorted(regs)}")
    return st, common_register(name).address


# what planning a move reads (every X model has these items, alike): read straight from memory, on every goal
_GOAL_POSITION_ITEM = _common_reader("Goal Position")
_VELOCITY_LIMIT_ITEM = _common_reader("Velocity Limit")
_PROFILE_VELOCITY_ITEM = _common_reader("Profile Velocity")
_PROFILE_ACCELERATION_ITEM = _common_reader("Profile Acceleration")
_READERS: dict[int, tuple[Mapping[str, Register], dict[str, _Reader]]] = {}


def _readers(regs: Mapping[str, Register]) -> dict[str, _Reader]:
    """``{name: reader}`` of the registers ``regs`` (one table per model, built once)."""
    hit = _READERS.get(id(regs))
    if hit is not None and hit[0] is regs:
        return hit[1]
    table = {}
    for name, reg in regs.items():
        st = register_struct(reg)
        if st is not None:
            table[name] = (st, reg.address)
    _READERS[id(regs)] = (regs, table)  # keeps regs alive, so its id is not reused
    return table


class SimServo(WriteRules):
    """A simulated servo of ``model`` with ID ``dxl_id``.

    ``position`` is the Present Position it starts at (pulses, with the default Drive Mode and Homing
    Offset).  ``baud`` (bps) and ``return_delay_time`` (2 us units) set those EEPROM items, which a real
    arm has already configured; everything else starts at the factory defaults.  ``boot_time`` is how long
    (s) it stays silent after REBOOT.
    """

    def __init__(
        self,
        model: Model | str,
        dxl_id: int = 1,
        *,
        clock: Clock | None = None,
        position: float = 2048.0,
        baud: int | None = None,
        return_delay_time: int | None = None,
        temperature: float = 32.0,
        boot_time: float = 0.0,
    ):
        self.model: Model = lookup_model(model) if isinstance(model, str | int) else model
        self.clock: Clock = clock if clock is not None else MonotonicClock()
        self.boot_time = float(boot_time)
        self._ambient = float(temperature)
        self._voltage = self.model.nominal_voltage
        self._mem = self.model.defaults()
        self._regs = self.model.registers
        self._readers = _readers(self._regs)
        self._shapes = {}
        self._no_load = self.model.no_load_rpm / 60.0 * PULSES_PER_REV  #: pulses/s
        self._motor = Motor.of(self.model)
        self._current_unit_ma = self.model.current_unit_ma
        self._stall_current = self.model.stall_current
        self._hand: HandPath | None = None  #: what a hand holds the horn at while torque is off
        self._fresh: float | None = None  #: clock time the Present items were last brought up to
        self._pending: float | None = None  #: clock time the Present items are due at, not yet computed (lazy)
        self._set("ID", dxl_id)
        if baud is not None:
            if baud not in BAUD_CODES:
                raise ValueError(f"Expected a Dynamixel baud rate {sorted(BAUD_CODES)}, got {baud}")
            self._set("Baud Rate", BAUD_CODES[baud])
        if return_delay_time is not None:
            self._set("Return Delay Time", return_delay_time)
        now = self.clock.now()
        self._t_origin = now
        self._t = now
        self._watchdog = BusWatchdog(now)
        self._init_goal_limits()
        self._trajectory: Trajectory = rest(float(position))  # physical (actual) pulses
        self._state = (float(position), 0.0, 0.0)  # actual p, v, a at self._t
        self._registered: tuple[int, bytes] | None = None
        self._scheduled_errors: list[tuple[float, int]] = []
        self._silent_until = -math.inf
        self._unplugged_at = math.inf
        #: (time, address, data) of the last accepted writes, oldest first
        self.writes: deque[tuple[float, int, bytes]] = deque(maxlen=10_000)
        self._set("Goal Position", int(self._present_from_actual(self._state[0])))
        self._indirect_used = False
        self._obstacle: Obstacle | None = None  #: a wall in the horn's way (sim.obstacle)
        self._push = 0.0  #: signed share of stall current pushing on the wall (actual frame), 0 when free
        self._push_since: float | None = None  #: clock time a push hard enough to overload began
        self.update()

    # ------------------------------------------------------------------ identity and wire settings

    def __repr__(self) -> str:
        return f"SimServo({self.model.name!r}, id={self.id})"

    @property
    def id(self) -> int:
        return self._mem[_ID]

    @property
    def baud(self) -> int:
        """The bps it listens at (Baud Rate item)."""
        return BAUD_RATES[self._mem[_BAUD_RATE]]

    @property
    def return_delay(self) -> float:
        """Seconds between the end of an instruction and the start of its status packet."""
        return self._mem[_RETURN_DELAY_TIME] * RETURN_DELAY_UNIT_S

    @property
    def status_return_level(self) -> int:
        return self._mem[_STATUS_RETURN_LEVEL]

    @property
    def secondary_id(self) -> int | None:
        """The ID it also obeys as a silent shadow (Secondary(Shadow) ID item), or None when that is off."""
        return rules.secondary_id(self._mem[_SECONDARY_ID])

    def hears(self, dxl_id: int) -> bool:
        """Whether an instruction packet for ``dxl_id`` is its own: its ID, its Secondary ID, or broadcast."""
        return dxl_id in (self._mem[_ID], BROADCAST_ID) or dxl_id == self.secondary_id

    def instruction_received(self, t: float) -> None:
        """An instruction packet it takes as its own arrived at clock time ``t``: restarts the Bus Watchdog interval.

        The bus calls this after bringing the servo up to ``t`` (so a watchdog due before ``t`` has tripped).
        """
        self._watchdog.packet(t)

    def packet_at(self, t: float, dxl_id: int, crc_ok: bool) -> None:
        """An instruction packet for ``dxl_id`` is on the wire at clock time ``t`` (its CRC good or not): brought up to
        ``t`` (a Bus Watchdog due before then trips on time), then :meth:`instruction_received` when it is its own."""
        self.update(t)
        if crc_ok and self.hears(dxl_id):
            self.instruction_received(t)

    @property
    def torque(self) -> bool:
        """Torque Enable, now."""
        self.update()
        return bool(self._mem[_TORQUE_ENABLE])

    @property
    def hardware_error(self) -> int:
        """Hardware Error Status, now."""
        self.update()
        return self._mem[_HARDWARE_ERROR_STATUS]

    def error_byte(self, error: int) -> int:
        """The ERR byte of a status packet: ``error`` plus the Alert bit while a hardware error is set."""
        return error | (ALERT_BIT if self._mem[_HARDWARE_ERROR_STATUS] else 0)

    @property
    def ambient_temperature(self) -> float:
        """degC the servo reads at rest (Present Temperature adds a little with load)."""
        return self._ambient

    @ambient_temperature.setter
    def ambient_temperature(self, value: float) -> None:
        self._ambient = float(value)
        self._fresh = None

    @property
    def input_voltage(self) -> float:
        """Volts, what Present Input Voltage reports."""
        return self._voltage

    @input_voltage.setter
    def input_voltage(self, value: float) -> None:
        self._voltage = float(value)
        self._fresh = None

    # ------------------------------------------------------------------ availability (faults)

    def unplug(self, at: float | None = None) -> None:
        """Stop answering from time ``at`` (default now), as if its cable were pulled."""
        self._unplugged_at = self.clock.now() if at is None else float(at)

    def plug(self) -> None:
        self._unplugged_at = math.inf

    def listening(self, now: float | None = None) -> bool:
        """False while unplugged or booting: the servo neither executes nor answers anything."""
        now = self.clock.now() if now is None else now
        return now < self._unplugged_at and now >= self._silent_until

    def schedule_hardware_error(self, bits: int | HardwareError, at: float) -> None:
        """Raise hardware error ``bits`` (HardwareError flags) at clock time ``at``."""
        self._scheduled_errors.append((float(at), int(bits)))
        self._scheduled_errors.sort()

    def trigger_hardware_error(self, bits: int | HardwareError) -> None:
        """Raise hardware error ``bits`` now: Alert bit, and torque off if ``bits & Shutdown``."""
        self.update()
        self._raise_hardware_error(int(bits))

    def _raise_hardware_error(self, bits: int) -> None:
        self._fresh = None
        self._mem[_HARDWARE_ERROR_STATUS] |= bits
        if bits & HardwareError.OVERHEATING:
            self.ambient_temperature = max(self.ambient_temperature, self._get("Temperature Limit") + 3)
        if bits & HardwareError.INPUT_VOLTAGE:
            self.input_voltage = self._get("Max Voltage Limit") * VOLT_PER_UNIT + 1.0
        if bits & self._mem[_SHUTDOWN] and self._mem[_TORQUE_ENABLE]:
            self._torque_off()
        log.info("servo %d: hardware error 0x%02x", self.id, bits)

    def block_at(self, present: float | None) -> None:
        """Put a wall at Present Position ``present`` (pulses), on the far side from where the horn is now
        (:mod:`sim.obstacle`); None removes it."""
        self.update()
        if present is None:
            self._obstacle = None
            return
        wall = self._actual_from_present(float(present))
        self._obstacle = Obstacle(wall, 1 if self._state[0] >= wall else -1)
        self._fresh = None

    # ------------------------------------------------------------------ raw register access (tests)

    def _get(self, name: str) -> int:
        reader = self._readers.get(name)
        if reader is None:
            reg = self._regs[name]
            return reg.decode(self._mem[reg.address : reg.end])
        st, address = reader
        value: int = st.unpack_from(self._mem, address)[0]
        return value

    def _set(self, name: str, value: int) -> None:
        reg = self._regs[name]
        self._mem[reg.address : reg.end] = reg.encode(int(value))

    def get(self, name: str) -> int:
        """The value of register ``name`` now (motion brought up to date)."""
        self.model.register(name)
        self.update()
        self._compute_pending()
        return self._get(name)

    def set(self, name: str, value: int) -> None:
        """Store ``value`` in register ``name`` bypassing every check (test setup; Present items are recomputed)."""
        self.model.register(name)
        self.update()
        self._set(name, value)
        self._fresh = None

    def set_position(self, present: float) -> None:
        """Teleport: make Present Position read ``present`` now, at rest."""
        self._fresh = None
        self.update()
        actual = self._actual_from_present(present)
        self._trajectory = rest(actual)
        self._state = (actual, 0.0, 0.0)
        self._fresh = None
        self.update()

    # ------------------------------------------------------------------ a hand on the horn

    def move_by_hand(self, path: HandPath | None) -> None:
        """A hand holds the horn from now on: ``path(t)`` is the Present Position (pulses) at clock time ``t`` (s).

        While torque is off Present Position follows the path, Present Velocity reports its derivative (0.229 rpm
        units) and Moving is 1 while that exceeds Moving Threshold, as when a limp joint is turned by hand.  With
        torque on the motor holds its own position and the path is ignored; the hand keeps holding, so when torque
        goes off again the horn follows the path from there.  ``None`` lets go: the horn stays where it was left.
        The path is in the reporting frame of the moment it is read (Homing Offset and Drive Mode applied).

        >>> from retarget.control.clock import VirtualClock
        >>> clock = VirtualClock()
        >>> servo = SimServo("XM430-W350", 1, clock=clock)
        >>> servo.move_by_hand(lambda t: 2048 + 100 * t)   # 100 pulses/s, from 2048 at t = 0
        >>> clock.advance(2.0)
        >>> servo.get("Present Position"), servo.get("Present Velocity"), servo.get("Moving")
        (2248, 6, 0)
        >>> servo.move_by_hand(None)                       # let go
        >>> clock.advance(1.0)
        >>> servo.get("Present Position"), servo.get("Present Velocity")
        (2248, 0)
        """
        self._fresh = None
        self.update()
        self._hand = path
        self._fresh = None
        self.update()

    def turn_by_hand(self, to: float, *, duration: float, now: float | None = None) -> float:
        """Turn the horn by hand from where it is to Present Position ``to`` (pulses) over ``duration`` s.

        A :func:`sim.hand.smoothstep_path` starting at clock time ``now`` (default the clock's now) from the present
        position; the hand then keeps holding it at ``to``.  Returns the clock time the turn ends.  Same rules as
        :meth:`move_by_hand` (no effect while torque is on).

        >>> from retarget.control.clock import VirtualClock
        >>> clock = VirtualClock()
        >>> servo = SimServo("XL430-W250", 1, clock=clock)
        >>> end = servo.turn_by_hand(3072, duration=1.0)
        >>> clock.advance(0.5)
        >>> servo.get("Present Position"), servo.get("Moving")   # half-way, at 1.5 x 1024 pulses/s
        (2560, 1)
        >>> clock.sleep_until(end)
        >>> servo.get("Present Position"), servo.get("Present Velocity"), servo.get("Moving")
        (3072, 0, 0)
        """
        t0 = self.clock.now() if now is None else float(now)
        self.update()
        start = self._present_from_actual(self._state[0])
        self.move_by_hand(smoothstep_path(t0=t0, start=start, end=float(to), duration=float(duration)))
        return t0 + float(duration)

    @property
    def memory(self) -> bytes:
        """A copy of the whole control table, up to date."""
        self.update()
        self._compute_pending()
        return bytes(self._mem)

    # ------------------------------------------------------------------ frames: actual <-> present

    @property
    def _reverse(self) -> bool:
        return bool(self._mem[_DRIVE_MODE] & _REVERSE_BIT)

    def _homing(self) -> int:
        """The Homing Offset in effect (an invalid one is ignored in position mode: :mod:`sim.rules`)."""
        offset: int = _I32.unpack_from(self._mem, _HOMING_OFFSET)[0]
        return rules.effective_homing_offset(offset, self._mem[_OPERATING_MODE]) if offset else 0

    def _present_from_actual(self, actual: float) -> float:
        return (PULSES_PER_REV - actual if self._reverse else actual) + self._homing()

    def _actual_from_present(self, present: float) -> float:
        p = present - self._homing()
        return PULSES_PER_REV - p if self._reverse else p

    # ------------------------------------------------------------------ motion

    def _mode(self) -> int:
        return self._mem[_OPERATING_MODE]

    def _vmax(self) -> float:
        """Pulses/s cap: Velocity Limit and the no-load speed."""
        no_load = self._no_load
        st, address = _VELOCITY_LIMIT_ITEM
        limit = st.unpack_from(self._mem, address)[0] * PULSES_PER_S_PER_VELOCITY_UNIT
        return min(no_load, limit) if limit > 0 else no_load

    def _plan_goal(self) -> None:
        now = self._t
        p, v, _ = self._state
        mem = self._mem
        goal = self._actual_from_present(_GOAL_POSITION_ITEM[0].unpack_from(mem, _GOAL_POSITION_ITEM[1])[0])
        vmax = self._vmax()
        pv = _PROFILE_VELOCITY_ITEM[0].unpack_from(mem, _PROFILE_VELOCITY_ITEM[1])[0]
        pa = _PROFILE_ACCELERATION_ITEM[0].unpack_from(mem, _PROFILE_ACCELERATION_ITEM[1])[0]
        if self._mem[_DRIVE_MODE] & _TIME_BASED_BIT:
            self._trajectory = time_profile(now, p, goal, pv / 1000.0, pa / 1000.0, vmax)
        else:
            if pv > 0:
                vmax = min(vmax, pv * PULSES_PER_S_PER_VELOCITY_UNIT)
            accel = pa * PULSES_PER_S2_PER_ACCEL_UNIT if pa > 0 else math.inf
            if self._mem[_OPERATING_MODE] == _CURRENT_BASED_POSITION:
                cap = self._motor.accel_cap(self._get("Goal Current"), self._get("Current Limit"))
                if cap <= 0:  # no current allowed: no torque to move with
                    self._trajectory = rest(p)
                    return
                accel = min(accel, cap)
            self._trajectory = velocity_profile(now, p, v, goal, vmax, accel)

    def _plan_pwm(self) -> None:
        """PWM mode: toward the no-load speed of the duty Goal PWM asks (within PWM Limit)."""
        p, v, _ = self._state
        limit = self._get("PWM Limit")
        target = self._motor.pwm_velocity(max(-limit, min(limit, self._get("Goal PWM"))))
        self._trajectory = ramp_profile(self._t, p, v, -target if self._reverse else target, self._motor.stall_accel)

    def _plan_current(self) -> None:
        """Current mode: Goal Current accelerates the unloaded rotor toward the no-load speed."""
        p, v, _ = self._state
        target, accel = self._motor.current_mode_target(self._get("Goal Current"))
        self._trajectory = ramp_profile(self._t, p, v, -target if self._reverse else target, accel)

    def _plan_mode(self) -> None:
        """Plan the motion the present Operating Mode and goals ask for (torque on)."""
        mode = self._mode()
        if mode == OperatingMode.VELOCITY:
            self._plan_velocity()
        elif mode == OperatingMode.PWM:
            self._plan_pwm()
        elif mode == OperatingMode.CURRENT:
            self._plan_current()

    def _plan_velocity(self) -> None:
        p, v, _ = self._state
        goal_v = self._get("Goal Velocity") * PULSES_PER_S_PER_VELOCITY_UNIT
        goal_v = max(-self._vmax(), min(self._vmax(), goal_v))
        if self._reverse:
            goal_v = -goal_v
        pa = self._get("Profile Acceleration")
        self._trajectory = ramp_profile(
            self._t, p, v, goal_v, pa * PULSES_PER_S2_PER_ACCEL_UNIT if pa > 0 else math.inf
        )

    def _torque_on(self) -> None:
        self._fresh = None
        self._mem[_TORQUE_ENABLE] = 1
        present = round(self._present_from_actual(self._state[0]))
        self._set("Goal Position", max(-1_048_575, min(1_048_575, present)))
        self._trajectory = rest(self._state[0])
        self._state = (self._state[0], 0.0, 0.0)
        self._plan_mode()

    def _torque_off(self) -> None:
        self._fresh = None
        self._mem[_TORQUE_ENABLE] = 0
        self._trajectory = rest(self._state[0])
        self._state = (self._state[0], 0.0, 0.0)
        if self._hand is not None:  # limp in a hand: the horn goes where the hand holds it
            self._state = self._hand_state(self._hand, self._t)

    def update(self, now: float | None = None) -> None:
        """Bring motion, faults, the Bus Watchdog and every Present item up to ``now`` (default ``clock.now()``).

        The Present items' bytes are computed when something reads them (:meth:`_compute_pending`), from the state
        as it stands at ``now``: the same bytes, without the cost on the many updates nothing reads after.
        """
        now = self.clock.now() if now is None else float(now)
        if now < self._t:
            now = self._t
        mem = self._mem
        if self._scheduled_errors or (mem[_TORQUE_ENABLE] and mem[_BUS_WATCHDOG]):
            self._run_due_events(now)
        if now == self._fresh:
            return  # nothing moved or changed since the last refresh
        if mem[_TORQUE_ENABLE] and self._obstacle is None:  # _advance's first case, inline (every packet, every servo)
            self._state = self._trajectory.state(now)
            self._t = now
        else:
            self._advance(now)
        if self._indirect_used:
            self._refresh_present(now)
        else:  # _refresh_present's lazy branch, inline: the bus updates every servo on every packet
            self._fresh = self._pending = now

    def _run_due_events(self, now: float) -> None:
        """Raise the hardware errors and trip the Bus Watchdog due by ``now``, in time order, advancing to each."""
        while True:
            due_error = self._scheduled_errors[0][0] if self._scheduled_errors else math.inf
            due_watchdog = self._watchdog.deadline(
                setting=self._mem[_BUS_WATCHDOG], torque=bool(self._mem[_TORQUE_ENABLE])
            )
            if min(due_error, due_watchdog) > now:
                break
            if due_error <= due_watchdog:
                at, bits = self._scheduled_errors.pop(0)
                self._advance(at)
                self._raise_hardware_error(bits)
            else:
                self._advance(due_watchdog)
                self._watchdog_trip()

    def _watchdog_trip(self) -> None:
        """Bus Watchdog timed out: stop at once where it is and hold; the item reads -1 (:mod:`sim.watchdog`)."""
        self._fresh = None
        p = self._state[0]
        self._trajectory = rest(p)
        self._state = (p, 0.0, 0.0)
        self._mem[_BUS_WATCHDOG] = WATCHDOG_ERROR
        self._set("Goal Position", max(-1_048_575, min(1_048_575, round(self._present_from_actual(p)))))
        goal = _MODE_GOAL.get(self._mode())
        if goal is not None:
            self._set(goal, 0)
        log.info("servo %d: bus watchdog tripped at t=%.3f s", self.id, self._t)

    def _hand_state(self, hand: HandPath, t: float) -> tuple[float, float, float]:
        """(actual p, v, a) of a horn the hand holds on ``hand`` at time ``t``."""
        v = rate(hand, t)
        return self._actual_from_present(hand(t)), -v if self._reverse else v, 0.0

    def _advance(self, now: float) -> None:
        if now < self._t:
            return
        if self._mem[_TORQUE_ENABLE]:
            self._state = self._trajectory.state(now)
            if self._obstacle is not None:
                self._push_on_wall(self._obstacle, now)
        elif self._hand is not None:
            self._state = self._hand_state(self._hand, now)
        elif self._state[1]:
            self._state = (self._state[0], 0.0, 0.0)  # let go: it stays where it was left
        self._t = now

    def _push_on_wall(self, wall: Obstacle, now: float) -> None:
        """Hold the horn at ``wall``; while the goal lies beyond it the motor pushes, and may overload."""
        p, v, a, touching = wall.clamp(*self._state)
        self._state = (p, v, a)
        goal = self._actual_from_present(self._get("Goal Position"))
        self._push = 0.0
        if touching and (goal - wall.actual) * wall.side < 0:
            if self._mode() == OperatingMode.CURRENT_BASED_POSITION:
                share = self._motor.current_share(min(abs(self._get("Goal Current")), self._get("Current Limit")))
            else:  # the position controller winds up to full output, capped only by PWM Limit
                share = min(1.0, self._get("PWM Limit") / PWM_FULL_SCALE)
            self._push = -wall.side * share
        if abs(self._push) < OVERLOAD_SHARE:
            self._push_since = None
        elif self._push_since is None:
            self._push_since = now
        elif now - self._push_since >= OVERLOAD_AFTER_S:
            self._push_since = None
            self._t = now
            self._raise_hardware_error(HardwareError.OVERLOAD)

    def _refresh_present(self, now: float) -> None:
        """The Present items are due at ``now`` (the state as it stands): computed when next read, at once when
        Indirect Data may mirror them.

        Between this call and the next read nothing the computation uses changes without a new call or ``_fresh``
        reset to None (which makes the read's :meth:`update` call it again), so the bytes are the ones an
        immediate computation would have stored.
        """
        self._fresh = now
        if self._indirect_used:
            self._pending = None
            self._compute_present(now)
        else:
            self._pending = now

    def _compute_pending(self) -> None:
        """Compute the Present items now if they are due (before anything reads the memory)."""
        if self._pending is not None:
            at, self._pending = self._pending, None
            self._compute_present(at)

    def _present(self, p: float) -> tuple[float, int]:
        """(Present Position unrounded, the item's value) of the actual position ``p`` (pulses)."""
        present = (PULSES_PER_REV - p if self._mem[_DRIVE_MODE] & _REVERSE_BIT else p) + self._homing()
        return present, max(-(2**31), min(2**31 - 1, round(present)))

    def _compute_present(self, now: float) -> None:
        """Store the Present items, Realtime Tick to Present Temperature, for the state at clock time ``now``."""
        mem = self._mem
        p, v, a = self._state
        torque = mem[_TORQUE_ENABLE]
        sign = -1.0 if mem[_DRIVE_MODE] & _REVERSE_BIT else 1.0
        present, position = self._present(p)
        moving_profile = bool(torque) and not self._trajectory.done(now)
        velocity_units = round(sign * v / PULSES_PER_S_PER_VELOCITY_UNIT)
        threshold = _I32.unpack_from(mem, _MOVING_THRESHOLD)[0]
        moving = 1 if moving_profile or abs(velocity_units) > threshold else 0
        goal = _I32.unpack_from(mem, _GOAL_POSITION)[0]
        in_position = not moving_profile and abs(goal - present) <= max(threshold, 1)
        moving_status = (
            (1 if in_position and torque else 0)
            | (2 if moving_profile else 0)
            | ((self._trajectory.shape & 3) << 4 if moving_profile else 0)
        )
        load = (self._push or self._motor.load_share(v, a)) * sign if torque else 0.0
        if self._current_unit_ma is None:
            current = round(max(-1.0, min(1.0, load)) * 1000)
        else:
            ma = load * self._stall_current * 1000.0
            current = max(-32768, min(32767, round(ma / self._current_unit_ma)))
        _PRESENT_ITEMS.pack_into(
            mem,
            _REALTIME_TICK,
            int((now - self._t_origin) * 1000.0) % 32768,
            moving,
            moving_status,
            self._present_pwm(sign * v) if torque else 0,
            current,
            velocity_units,
            position,
            velocity_units,  # Velocity Trajectory
            position,  # Position Trajectory
            max(0, min(65535, round(self._voltage / VOLT_PER_UNIT))),
            max(0, min(255, round(self._ambient + 4.0 * abs(load)))),
        )
        if self._indirect_used:
            for data_addr, target in rules.indirect_targets(self.model, mem).items():
                if 0 <= target < len(mem):
                    mem[data_addr] = mem[target]

    def _present_pwm(self, v: float) -> int:
        """Present PWM: Goal PWM in PWM mode, else the duty the unloaded motor needs at velocity ``v`` (reported)."""
        if self._mem[_OPERATING_MODE] == _PWM_MODE:
            limit = self._get("PWM Limit")
            return max(-limit, min(limit, self._get("Goal PWM")))
        return round(v / self._no_load * PWM_FULL_SCALE)

    # ------------------------------------------------------------------ instructions

    def ping(self) -> bytes:
        """The PING reply parameters: model number LSB, MSB, firmware version."""
        return bytes(self._mem[_MODEL_NUMBER : _MODEL_NUMBER + 2]) + bytes((self._mem[_FIRMWARE_VERSION],))

    def read(self, address: int, length: int) -> tuple[int, bytes]:
        """READ: ``(error, data)``; ``data`` is empty on error.

        A read of Present Position alone (the tick's position read) computes that item only: the other Present
        items stay due (:meth:`_compute_pending`), and are the bytes they would have been when something reads them.
        """
        self.update()
        if self._pending is not None:
            if _PRESENT_POSITION <= address and address + length <= _PRESENT_POSITION + 4:
                # Present Position alone, as _compute_present stores it; the other Present items stay due
                _I32.pack_into(self._mem, _PRESENT_POSITION, self._present(self._state[0])[1])
            else:
                self._compute_pending()
        if length <= 0:
            return StatusError.DATA_LENGTH, b""
        if address < 0 or address + length > len(self._mem):
            return StatusError.ACCESS, b""
        return _NONE, bytes(self._mem[address : address + length])

    def check_write(self, address: int, data: bytes) -> int:
        """The error a WRITE of ``data`` at ``address`` would answer (0 if it would succeed), changing nothing."""
        self.update()
        error, _ = self._validate(address, bytes(data))
        return error

    def write(self, address: int, data: bytes) -> int:
        """WRITE: validate every covered item, then store all and apply side effects; the error number."""
        self.update()
        data = bytes(data)
        # _validate's items alone while no Indirect Data is in use (the targets' rules are its own part)
        error, regs = self._validate(address, data) if self._indirect_used else self._validate_items(address, data)
        if error:
            return error
        self._apply(address, data, regs)
        return _NONE

    def reg_write(self, address: int, data: bytes) -> int:
        """REG_WRITE: validate now, execute on ACTION; sets Registered Instruction."""
        error = self.check_write(address, data)
        if error:
            return error
        self._registered = (address, bytes(data))
        self._mem[_REGISTERED_INSTRUCTION] = 1
        return StatusError.NONE

    def action(self) -> int:
        """ACTION: run the registered write; Instruction error when none is registered."""
        if self._registered is None:
            return StatusError.INSTRUCTION
        address, data = self._registered
        self._registered = None
        self._mem[_REGISTERED_INSTRUCTION] = 0
        return self.write(address, data)

    def reboot(self) -> None:
        """REBOOT (after its reply): RAM back to defaults, hardware error cleared, silent for ``boot_time``."""
        self._fresh = None
        self.update()
        defaults = self.model.defaults()
        self._mem[EEPROM_END:] = defaults[EEPROM_END:]
        self._registered = None
        self.ambient_temperature = min(self.ambient_temperature, 32.0)
        self.input_voltage = self.model.nominal_voltage
        self._torque_off()
        self._set("Goal Position", max(-1_048_575, min(1_048_575, round(self._present_from_actual(self._state[0])))))
        self._init_goal_limits()
        self._indirect_used = False
        self._silent_until = self._t + self.boot_time
        self.update()
        log.info("servo %d: rebooted", self.id)

    def factory_reset(self, option: int) -> int:
        """FACTORY_RESET with option 0xFF (all), 0x01 (keep ID) or 0x02 (keep ID and baud); the error number."""
        self._fresh = None
        if option not in tuple(FactoryReset):
            return StatusError.DATA_RANGE
        self.update()
        keep_id, keep_baud = self._mem[_ID], self._mem[_BAUD_RATE]
        self._mem[:] = self.model.defaults()
        if option in (FactoryReset.EXCEPT_ID, FactoryReset.EXCEPT_ID_AND_BAUD):
            self._mem[_ID] = keep_id
        if option == FactoryReset.EXCEPT_ID_AND_BAUD:
            self._mem[_BAUD_RATE] = keep_baud
        self._registered = None
        self._torque_off()
        self._set("Goal Position", round(self._present_from_actual(self._state[0])))
        self._init_goal_limits()
        self._indirect_used = False
        self.update()
        return StatusError.NONE

    def clear(self, params: bytes) -> int:
        """CLEAR 01 44 58 4C 22: reset the multi-turn count (Result Fail while moving)."""
        self._fresh = None
        if bytes(params) != CLEAR_MULTI_TURN:
            return StatusError.DATA_RANGE
        self.update()
        self._compute_pending()
        if self._mem[_MOVING]:
            return StatusError.RESULT_FAIL
        p = self._state[0] % PULSES_PER_REV
        self._trajectory = rest(p)
        self._state = (p, 0.0, 0.0)
        self._fresh = None
        self.update()
        return StatusError.NONE

    def _init_goal_limits(self) -> None:
        """Power-on RAM: Goal PWM = PWM Limit and Goal Current = Current Limit.

        What DYNAMIXEL Wizard shows on a fresh X-series servo, and what LeRobot's Koch gripper relies on (it sets
        current-based position mode and Current Limit, never Goal Current); not stated in the e-Manual (unverified).
        """
        self._set("Goal PWM", self._get("PWM Limit"))
        if "Current Limit" in self._regs:
            self._set("Goal Current", self._get("Current Limit"))
