"""The Dynamixel servo bus of one arm, on dynamixel-sdk: :class:`DynamixelBus` implements ``retarget.bus.Bus``.

Lifecycle (explicit, also as a context manager)::

    with DynamixelBus(retarget.load_arm("wx250s"), "/dev/ttyUSB0") as bus:   # connect(): check, configure, torque on
        q = bus.read_positions()                                            # (6,) rad
        bus.write_goals(q_next)                                             # clamped, step-limited, one sync write
    # close(): stop goals, shutdown per ShutdownMode (rest pose, then torque off), release the port

connect():
  1. open the port (any pyserial URL) at the arm's baud; on Linux check the FTDI latency timer;
  2. PING every configured ID (joints, shadows, gripper), compare model numbers with the arm description and
     raise ONE BusError naming every missing ID and wrong model, before anything is written;
  3. configure each servo with torque off (EEPROM is only writable then), writing only values that differ:
     Operating Mode = position, Drive Mode (bit 0 = the servo's direction, so shadows mirror their primary;
     bit 2 = time-based profile when chosen), Homing Offset = 0, Max/Min Position Limit from the joint limits
     (the servo's own second line of defence), Velocity Limit, Return Delay Time; then Profile Acceleration and
     Profile Velocity (RAM);
     Status Return Level goes back to 2 first, so every write is acknowledged;
     a servo found under torque (an arm left holding by shutdown HOLD) whose EEPROM must change goes limp only
     for its own EEPROM writes: torque off, write, Goal Position = where it is, torque on (a warning names the
     servo and the registers); a shadow never goes limp together with its primary;
  4. check every shadow reads the same angle as its primary (else they would fight under torque), set each
     Goal Position to its joint's present angle (so enabling torque does not jump), then torque on, all or
     nothing.  Present Position read with torque off counts whole turns; torque on in position mode resets it
     into 0..4095 (e-Manual, Present Position(132)), so the hold goal is the reading modulo 4096
     (:func:`hold_pulse`).

Faults: a position read keeps the replies that came and asks again (``retries`` times per tick) only the servos
still missing; a servo still silent after that is *stale* for the tick: its last position stands in, counted in
:meth:`DynamixelBus.status` (``stale_reads``, ``worst_stale``).  A servo stale for more than ``max_stale_ticks``
reads in a row, or for more than ``max_stale_fraction`` of the reads in the last second, or silent in any other
transaction after its retries, or raising a hardware alert, makes the bus refuse further goals and raises
BusError naming it (and, for staleness, the loss rate seen); close() (or leaving the ``with`` block) then runs
the shutdown sequence.  ``recover=True`` instead reboots an alerting servo and configures it again (at most 3
times each).  Shutdown REST after a hardware error: joints with a faulted servo are not commanded, the others go
to rest, then torque goes off everywhere; a silent joint servo turns torque off at once (see ``_move_to_rest``).
The servos outside the position read (the gripper) are watched: a PING each every ``watch_period`` (0.2 s), before
a position read's request, so a hardware error or a missing servo there ends the run the same way.

Direction is applied by the servo (Drive Mode bit 0), as Interbotix does: every servo of a joint gets the same
register value ``2048 + offset + q / RAD_PER_PULSE`` in the same SYNC_WRITE and a reversed servo turns its shaft
the other way.  Position limits (pulses) are therefore computed in that register space for every servo.

Units: joint angles in radians, speeds in rad/s, times in seconds; register values in the e-Manual's units
(positions in pulses, 4096 per turn).  "Tick" is one control cycle (a write_goals and a read_positions).
"""

from __future__ import annotations

import logging
import math
import struct
from collections import deque
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from types import TracebackType

import numpy as np

from drivers import units
from drivers.comm import GroupRead, Link, StatusPacket
from drivers.control_table import MODEL_BY_NUMBER, VOLT_PER_UNIT, common_register, hardware_error_names
from drivers.gripper import GripperChannel, GripperReading
from drivers.latency import check_latency_timer
from drivers.port import open_port
from drivers.servo_plan import MAX_PROFILE_MS, Profile, ServoPlan, ServoSettings, plan_servos
from drivers.watchdog import HostWatchdog
from retarget.arm.load import load_arm
from retarget.arm.model import Arm
from retarget.control.bus import BusStatus, ShutdownMode, close_after_failure
from retarget.control.clock import Clock, MonotonicClock
from retarget.errors import BusError

log = logging.getLogger(__name__)

#: EEPROM block read once per servo at connect: Return Delay Time (9) .. Min Position Limit (52..55).
_EEPROM_START = common_register("Return Delay Time").address
_EEPROM_END = common_register("Min Position Limit").end
#: RAM block of read_state: Present Current/Load (126) .. Present Temperature (146), the same on every X model.
_STATE_START = common_register("Present Current").address  # XL430-W250 has Present Load at that address
_STATE_END = common_register("Present Temperature").end
_MAX_RECOVERIES = 3  #: reboots per servo and connect before a hardware error is final (recover=True)
#: the registers every servo gets in one SYNC_WRITE: the same address and size on every X model
_GOAL_POSITION = common_register("Goal Position")
_PROFILE_ACCELERATION = common_register("Profile Acceleration")
_PROFILE_VELOCITY = common_register("Profile Velocity")


@dataclass(frozen=True)
class ServoState:
    """One read of every servo's health, in ``DynamixelBus.servos`` order.  Arrays are ``(n_servos,) float64``."""

    ids: tuple[int, ...]
    position: np.ndarray  #: rad, in the servo's joint frame (2048 + offset = 0 rad)
    velocity: np.ndarray  #: rad/s
    current: np.ndarray  #: A; NaN for models that report load instead (XL430)
    load: np.ndarray  #: fraction of the maximum, -1..1; NaN for models that report current
    voltage: np.ndarray  #: V
    temperature: np.ndarray  #: degC

    @classmethod
    def decode(cls, servos: Sequence[ServoPlan], replies: Mapping[int, StatusPacket]) -> ServoState:
        n = len(servos)
        pos, vel, cur, load, volt, temp = (np.full(n, np.nan) for _ in range(6))
        for k, s in enumerate(servos):
            data = replies[s.id].data

            def field(name: str, _s: ServoPlan = s, _data: bytes = data) -> int:
                reg = _s.model.register(name)
                return reg.decode(_data[reg.address - _STATE_START : reg.end - _STATE_START])

            pos[k] = units.pulses_to_rad(field("Present Position"), offset=s.offset)
            vel[k] = units.velocity_units_to_rad_s(field("Present Velocity"))
            if s.model.current_unit_ma is None:
                load[k] = field("Present Load") / 1000.0
            else:
                cur[k] = field("Present Current") * s.model.current_unit_ma / 1000.0
            volt[k] = field("Present Input Voltage") * VOLT_PER_UNIT
            temp[k] = field("Present Temperature")
        return cls(tuple(s.id for s in servos), pos, vel, cur, load, volt, temp)


class DynamixelBus:
    """The servos of one arm on one Dynamixel bus.  See the module docstring for what connect() does.

    Nothing is opened or sent until :meth:`connect` (or ``with``); the constructor only checks its arguments
    (ValueError) and plans every servo from the arm description (ConfigError).  Bus failures raise BusError
    naming the servos.

    Arguments (all tuning knobs keyword-only):
        arm: the arm description (``retarget.load_arm``), or the name or path it loads from.
        port: a device path or pyserial URL (``/dev/ttyUSB0``, ``COM3``, ``socket://h:p``, ``sim://wx250s``);
            required, there is no default port.
        baud: the bus baud rate, bps; default: the arm's.
        shutdown: what close() does with the arm (HOLD, REST then torque off, OFF).
        retries: repeats of a failed transaction before it raises (per tick); a position read repeats only for
            the servos that did not answer.
        max_stale_ticks: a position read may miss a servo after its retries: its last position stands in,
            marked stale, for at most this many reads in a row; one more raises BusError.  0 = a missed read
            raises at once.
        max_stale_fraction: BusError too when a servo was stale in more than this fraction of the position reads
            of the last second (``1 / dt`` reads; 100 without ``dt``).  1.0 turns this check off.
        return_delay_us: Return Delay Time written at connect (0..508 us, 2 us steps; servo default 500).
        profile: velocity- or time-based servo profile.
        profile_velocity: rad/s cap of the servo's own profile (VELOCITY); default each joint's max velocity;
            0 = no cap.
        profile_acceleration: rad/s^2 (VELOCITY); default per joint ``servo_plan.servo_acceleration``: its
            ``max_acceleration``, or ``max_velocity / (2 dt)`` where that is more (so the servo's profile trails the
            loop's goals by at most one tick's travel); 0 = unlimited.  The rest move on close uses the joint's
            ``max_acceleration`` itself.
        profile_time: seconds per move (TIME); default ``dt`` or 0.1 s.  The ramp is a quarter of it.
        dt: the control tick period in seconds; when set, write_goals limits every joint's step per call to
            ``max_velocity * dt`` (from the arm description).  ``step_limit=False`` turns that off.
        rest_speed: rad/s of the move to the rest pose on close (REST).
        rest_timeout: seconds to wait for the rest pose before torque goes off anyway.
        rest_tolerance: rad; the rest pose counts as reached when every joint is this close.
        shadow_tolerance: rad; torque stays off when a shadow servo reads further than this from its primary.
        recover: on a hardware error, reboot the servo and configure it again instead of raising.
        watchdog: seconds (0.02..2.54, rounded up to 20 ms; at least 3 ticks of ``dt``): arm every servo's Bus
            Watchdog with the first goal, so the arm stops within that time when the host stops talking (a killed
            process, a pulled cable) instead of finishing its last move; see :mod:`drivers.watchdog`.  None: off.
        watch_period: seconds between the watch reads of the servos outside the position read (the gripper):
            a PING of each (presence, and the Alert bit of a hardware error) before every
            ``max(1, round(watch_period / dt))``-th position read (``dt`` 0.01 s when unset), and before every
            one while one of them is missing.  Default 0.2 s.
        fast_read: FAST_SYNC_READ for positions: True, False, or None = when every servo's firmware has it.
        check_latency: check (and lower) the FTDI latency timer of a /dev/ttyUSBn port.
        clock: the clock for waits (the REST move); a shared ``VirtualClock`` in tests.

    On the simulated arm (``sim://wx250s``: every servo of the WidowX-250 at its rest pose; ``clock=virtual``
    makes waiting for a reply cost no real time)::

        >>> bus = DynamixelBus("wx250s", "sim://wx250s?clock=virtual", shutdown="off")
        >>> with bus:                                  # connect: ping, configure, torque on
        ...     q = bus.read_positions()               # (6,) rad, from the primary servos
        ...     bus.write_goals(q + 0.05)              # one SYNC_WRITE, clamped to the joint limits
        >>> bool(np.allclose(q, bus.arm.rest, atol=0.002)), bus.status().ticks, bus.connected
        (True, 1, False)
    """

    def __init__(
        self,
        arm: Arm | str,
        port: str,
        *,
        baud: int | None = None,
        shutdown: ShutdownMode | str = ShutdownMode.REST,
        retries: int = 3,
        max_stale_ticks: int = 10,
        max_stale_fraction: float = 0.5,
        return_delay_us: int = 0,
        profile: Profile | str = Profile.VELOCITY,
        profile_velocity: float | None = None,
        profile_acceleration: float | None = None,
        profile_time: float | None = None,
        dt: float | None = None,
        step_limit: bool = True,
        rest_speed: float = 0.5,
        rest_timeout: float = 10.0,
        rest_tolerance: float = 0.02,
        shadow_tolerance: float = 0.1,
        recover: bool = False,
        watchdog: float | None = None,
        watch_period: float | None = None,
        fast_read: bool | None = None,
        check_latency: bool = True,
        clock: Clock | None = None,
    ):
        if isinstance(arm, str):
            arm = load_arm(arm)
        self.arm = arm
        self.port_name = port
        self.baud = int(baud if baud is not None else arm.baud)
        self.shutdown_mode = ShutdownMode(shutdown)
        self.profile = Profile(profile)
        if retries < 0:
            raise ValueError(f"Expected retries >= 0, got {retries}")
        if not 0 <= return_delay_us <= 508:
            raise ValueError(f"Expected return_delay_us in 0..508, got {return_delay_us}")
        if dt is not None and not dt > 0:
            raise ValueError(f"Expected dt > 0 seconds, got {dt}")
        if not rest_speed > 0:
            raise ValueError(f"Expected rest_speed > 0 rad/s, got {rest_speed}")
        if max_stale_ticks < 0:
            raise ValueError(f"Expected max_stale_ticks >= 0, got {max_stale_ticks}")
        if not 0.0 < max_stale_fraction <= 1.0:
            raise ValueError(f"Expected max_stale_fraction in (0, 1], got {max_stale_fraction}")
        if watch_period is not None and not (math.isfinite(watch_period) and watch_period > 0):
            raise ValueError(f"Expected watch_period > 0 seconds, got {watch_period}")
        self.retries = retries
        self.max_stale_ticks = int(max_stale_ticks)
        self.max_stale_fraction = float(max_stale_fraction)
        #: reads in the window of max_stale_fraction: one second of ticks
        self.stale_window = max(1, round(1.0 / dt)) if dt is not None else 100
        self.watch_period = 0.2 if watch_period is None else float(watch_period)
        #: position reads between two watch reads of the servos outside the position read (the gripper)
        self.watch_ticks = max(1, round(self.watch_period / (dt if dt is not None else 0.01)))
        self.settings = ServoSettings(
            profile=self.profile,
            profile_velocity=profile_velocity,
            profile_acceleration=profile_acceleration,
            profile_time=profile_time,
            dt=dt,
            return_delay_us=return_delay_us,
        )
        self.dt = dt
        self.step_limit = step_limit
        self.rest_speed = rest_speed
        self.rest_timeout = rest_timeout
        self.rest_tolerance = rest_tolerance
        self.shadow_tolerance = shadow_tolerance
        self.recover = recover
        self.fast_read = fast_read
        self.check_latency = check_latency
        self.clock: Clock = clock if clock is not None else MonotonicClock()

        self.servos = plan_servos(arm)
        self._watchdog = None if watchdog is None else HostWatchdog(watchdog, [s.id for s in self.servos], dt=dt)
        self._joint_servos = tuple(s for s in self.servos if s.role != "gripper")
        self._gripper = next((s for s in self.servos if s.role == "gripper"), None)
        #: the gripper's goal and readings on the tick path (set_gripper); None without a gripper
        self._gripper_channel = (
            GripperChannel(self.arm.gripper, self._gripper, read_every=self.watch_ticks)
            if self._gripper is not None and self.arm.gripper is not None
            else None
        )
        self._primary_index = np.array(
            [next(i for i, s in enumerate(self._joint_servos) if s.joint == j and s.role == "primary")
             for j in range(arm.n_joints)]
        )  # fmt: skip
        js = self._joint_servos
        self._servo_joint = np.array([s.joint for s in js])
        self._position_requests = {s.id: (s.model.register("Present Position").address, 4) for s in js}
        #: the Present Position read planned once, plain and FAST_SYNC_READ (indexed by ``_use_fast``)
        self._position_reads = (
            GroupRead.plan(self._position_requests),
            GroupRead.plan(self._position_requests, fast=True),
        )
        self._state_requests = {s.id: (_STATE_START, _STATE_END - _STATE_START) for s in self.servos}
        #: the servos the position read leaves out (the gripper): the watch PINGs them (presence, Alert bit)
        self._watched = tuple(s.id for s in self.servos if s.id not in self._position_requests)
        self._servo_offset = np.array([s.offset for s in js], dtype=np.int64)
        # the joint range every servo of the joint can reach: the intersection over its servos
        lower = np.full(arm.n_joints, -np.inf)
        upper = np.full(arm.n_joints, np.inf)
        for s in js:
            lower[s.joint] = max(lower[s.joint], float(units.pulses_to_rad(s.min_pulse, offset=s.offset)))
            upper[s.joint] = min(upper[s.joint], float(units.pulses_to_rad(s.max_pulse, offset=s.offset)))
        self.lower = np.maximum(lower, arm.lower)  #: (n_joints,) rad, the clamp of write_goals
        self.upper = np.minimum(upper, arm.upper)
        self.max_step = arm.max_velocity * dt if dt is not None and step_limit else None
        self._max_step = None if self.max_step is None else tuple(self.max_step.tolist())
        # the tick path (write_goals, read_positions) works on plain floats: numpy costs more than the math
        # on a handful of values, and every microsecond there is a microsecond the wire sits idle
        self._goal_shape = (arm.n_joints,)
        self._clamp = tuple(zip(self.lower.tolist(), self.upper.tolist(), strict=True))  #: per joint (lo, hi) rad
        self._goal_plan = tuple(
            (s.id, s.joint, units.CENTER_PULSE + s.offset, s.min_pulse, s.max_pulse) for s in js
        )  #: per joint servo: ID, joint, pulse of 0 rad, position limits (pulses)
        self._goal_packing = struct.Struct("<" + "Bi" * len(js))  #: SYNC_WRITE params: ID, signed 4-byte LE goal
        self._primary_plan = tuple(
            (js[k].id, units.CENTER_PULSE + js[k].offset) for k in self._primary_index
        )  #: per joint: its primary servo's ID and pulse of 0 rad

        self._link: Link | None = None
        self._last_link: Link | None = None  #: keeps the counters readable after close
        self._torque = False
        self._faulted: str | None = None
        self._last_goal: list[float] | None = None  #: rad per joint, the goals last sent
        self._ticks = 0  #: control cycles (position reads) since connect
        self._hardware_errors: dict[int, tuple[str, ...]] = {}
        self._recoveries: dict[int, int] = {}  #: servo ID -> reboots since connect
        self._firmware: dict[int, int] = {}
        self._use_fast = False
        self._pending: GroupRead | None = None  #: a position read sent by request_positions, not yet collected
        self._last_replies: dict[int, StatusPacket] | None = None  #: the last reply of every joint servo
        self._stale_run: dict[int, int] = {}  #: servo ID -> stale reads in a row, now (absent: 0)
        self._stale_history: dict[int, deque[int]] = {}  #: servo ID -> the ticks it was stale in, last second
        self._watch_run: dict[int, int] = {}  #: watched servo ID -> watch reads it missed in a row, now
        self._watch_history: dict[int, deque[int]] = {}  #: watched servo ID -> the ticks it was missed in
        self._reset_stale()

    # ------------------------------------------------------------------ Bus protocol

    @property
    def joint_names(self) -> tuple[str, ...]:
        return self.arm.joint_names

    @property
    def connected(self) -> bool:
        return self._link is not None

    @property
    def link(self) -> Link:
        """The open link, for one transaction; BusError when not connected or while a position read is in flight."""
        if self._link is None:
            raise BusError(f"not connected (port {self.port_name}): call connect() first")
        if self._pending is not None:
            raise BusError("a position read is in flight: call collect_positions() first")
        return self._link

    def __enter__(self) -> DynamixelBus:
        if not self.connected:
            self.connect()
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        if exc is None:
            self.close()
        else:  # a failing shutdown must not mask the error that ended the block
            close_after_failure(self)

    def __repr__(self) -> str:
        state = "connected" if self.connected else "closed"
        return f"DynamixelBus({self.arm.name!r}, {self.port_name!r}, baud={self.baud}, {state})"

    def connect(self) -> None:
        """Open, check every servo, configure them with torque off, then enable torque.  See the module docstring."""
        if self.connected:
            return
        port = open_port(self.port_name, self.baud)
        self._link = self._last_link = Link(port, retries=self.retries)
        self._faulted = None
        self._hardware_errors = {}
        self._recoveries = {}
        self._ticks = 0
        self._reset_stale()
        try:
            if self.check_latency:
                check_latency_timer(self.port_name)
            self._check_servos()
            for s in self.servos:
                self._configure(s)
            self.set_torque(True)
        except BaseException:
            # set_torque is all or nothing, so no servo is left under torque but those found holding (HOLD): they
            # keep holding where they are; just free the port
            port.closePort()
            self._link = None
            raise
        log.info(
            "connected %s on %s at %d baud (%d servos)", self.arm.name, self.port_name, self.baud, len(self.servos)
        )

    def close(self) -> None:
        """Stop goals, run the shutdown sequence (HOLD / REST then torque off / OFF), release the port.  Idempotent."""
        link = self._link
        if link is None:
            return
        interrupted: KeyboardInterrupt | None = None
        if self._pending is not None:  # a read whose replies may still be on the wire: nothing goes out before them
            try:
                link.drain(self._pending)
            except KeyboardInterrupt as exc:
                interrupted = exc
            self._pending = None
        link.release()  # a Ctrl-C inside the SDK leaves the port marked busy
        try:
            if self._watchdog is not None:
                self._watchdog.disarm(link)  # the shutdown sequence may pause; a tripped servo takes goals again
            if self._torque and self.shutdown_mode is ShutdownMode.REST:
                try:
                    self._move_to_rest()
                except (BusError, OSError) as exc:
                    log.error("could not move %s to its rest pose: %s", self.arm.name, exc)
                except KeyboardInterrupt as exc:  # a second Ctrl-C cuts the rest move short, never the torque off
                    log.warning("rest move interrupted: torque off now")
                    link.release()
                    interrupted = exc
            if self.shutdown_mode is not ShutdownMode.HOLD:
                self._torque_off_all()
        finally:
            link.port.closePort()
            self._link = None
            self._torque = False
            self._last_goal = None
            log.info("closed %s (%s)", self.port_name, self.shutdown_mode.value)
        if interrupted is not None:
            raise interrupted

    def status(self) -> BusStatus:
        """Counters since the last connect (still readable after close)."""
        link = self._link or self._last_link
        return BusStatus(
            connected=self._link is not None,
            ticks=self._ticks,
            retries=0 if link is None else link.retry_count,
            errors=0 if link is None else link.error_count,
            hardware_errors=dict(self._hardware_errors),
            stale_reads=self._stale_reads,
            stale_ticks=self._stale_ticks,
            worst_stale=self._worst_stale,
            late_packets=0 if link is None else link.late_packets,
            reboots=sum(self._recoveries.values()),
        )

    def read_positions(self) -> np.ndarray:
        """Present joint angles ``(n_joints,) float64`` radians, from the primary servos.

        One SYNC_READ (FAST_SYNC_READ when available) of every joint servo (shadows too, so their alerts are
        seen); the servos that did not answer are asked again, ``retries`` times.  A servo still silent then
        keeps its last position, marked stale (see ``max_stale_ticks``); BusError naming it once it was stale
        for too long.  A servo with its
        Alert bit set is reported by its hardware error names (or rebooted and configured again with
        ``recover=True``).
        """
        self.request_positions()
        return self.collect_positions()

    def request_positions(self) -> None:
        """Send the position read of :meth:`read_positions` and return at once; :meth:`collect_positions` ends it.

        The status packets come in while the caller computes (the control loop solves the next tick meanwhile),
        so the wire is not idle during host work.  Until then no other call may use the bus (BusError).
        """
        link = self._require_active()  # also refuses a second request before the first is collected
        if self._watched and (self._watch_run or self._ticks % self.watch_ticks == self.watch_ticks - 1):
            self._watch(link)  # before the request: nothing may use the bus between it and its collect
        if self._gripper_channel is not None:
            self._gripper_channel.service(link)  # a changed gripper goal; its state at the watch's rate
        self._pending = link.send_group_read(self._position_reads[self._use_fast])

    def collect_positions(self) -> np.ndarray:
        """Present joint angles ``(n_joints,) float64`` radians of the read :meth:`request_positions` sent.

        Failures, retries and alerts as :meth:`read_positions`.
        """
        link = self._link
        if self._pending is None or link is None:
            raise BusError("no position read in flight: call request_positions() first")
        replies = self._receive_joint_replies(link, stale_ok=True)
        self._ticks += 1
        return np.array(
            [
                (int.from_bytes(replies[dxl_id].data, "little", signed=True) - zero) * units.RAD_PER_PULSE
                for dxl_id, zero in self._primary_plan
            ]
        )

    def exchange(self, q: np.ndarray) -> np.ndarray:
        """One pipelined tick: :meth:`collect_positions`, then :meth:`write_goals` ``(q)`` and
        :meth:`request_positions`; returns the collected positions ``(n_joints,) float64`` radians.  A failed
        collect raises before the write."""
        present = self.collect_positions()
        self.write_goals(q)
        self.request_positions()
        return present

    def read_state(self) -> ServoState:
        """Health of every servo (gripper included) in one group read of Present Load/Current .. Temperature.

        Slower than read_positions (24 bytes per servo): call it at a few hertz for telemetry, not every tick.
        """
        link = self._require_active()
        replies = link.group_read(self._state_requests, fast=self._use_fast, what="present state")
        self._raise_alerts()
        return ServoState.decode(self.servos, replies)

    def write_goals(self, q: np.ndarray) -> None:
        """Send goal angles ``(n_joints,) float64`` radians in ONE SYNC_WRITE to every joint servo (shadows included).

        Each goal is clamped to the joint limits first, then (with ``dt``) to ``max_velocity * dt`` from the
        previous goal, then encoded per servo and clipped to that servo's position limits.
        """
        link = self._require_active()
        q = np.asarray(q, dtype=np.float64)
        if q.shape != self._goal_shape:
            raise ValueError(f"Expected goals of shape ({self.arm.n_joints},) in radians, got shape {q.shape}")
        values = q.tolist()
        if not all(map(math.isfinite, values)):
            raise ValueError(f"Expected finite goals in radians, got {q}")
        goal = [lo if v < lo else hi if v > hi else v for v, (lo, hi) in zip(values, self._clamp, strict=True)]
        last = self._last_goal
        if self._max_step is not None and last is not None:
            goal = [
                p + (m if v - p > m else -m if v - p < -m else v - p)
                for v, p, m in zip(goal, last, self._max_step, strict=True)
            ]
        if self._watchdog is not None:
            self._watchdog_tick(link)
        self._send_goals(link, goal)
        self._last_goal = goal

    def set_torque(self, enabled: bool) -> None:
        """Torque on or off for every servo of the arm (gripper included).

        Turning it on first sets every Goal Position to the present position, so nothing jumps.
        """
        link = self.link
        if not enabled:
            self._torque_off_all()
            return
        if self._faulted:
            raise BusError(f"bus is faulted ({self._faulted}); close it and connect again")
        # with torque off Present Position counts turns (a joint turned by hand past 180 deg reads 4196); torque on
        # in position mode resets it into 0..4095 (e-Manual, Present Position(132)): hold the single-turn angle
        pulses = self._read_joint_pulses(check_active=False) % units.PULSES_PER_REV
        self._check_shadows(pulses)
        # what a stale read falls back on until every servo answered a tick: the single-turn reading
        self._last_replies = {
            dxl_id: StatusPacket(dxl_id, 0, int(p).to_bytes(4, "little", signed=True))
            for dxl_id, p in zip(self._position_requests, pulses.tolist(), strict=True)
        }
        primary = self._primary_index
        q = np.clip(units.pulses_to_rad(pulses[primary], offset=self._servo_offset[primary]), self.lower, self.upper)
        self._send_goals(link, q.tolist())  # every servo of a joint gets its primary's angle, as write_goals will
        if self._gripper is not None:
            g = self._gripper
            p = units.signed32(link.read_register(g.id, g.model.register("Present Position")))
            link.write_register(g.id, g.model.register("Goal Position"), hold_pulse(p, g.min_pulse, g.max_pulse))
        turned_on: list[ServoPlan] = []
        try:
            for s in self.servos:
                turned_on.append(s)  # before the write: a servo may act on it and still lose its reply
                link.write_register(s.id, s.model.register("Torque Enable"), 1)
        except BaseException:
            for s in turned_on:  # all or nothing: an arm half under torque is worse than a limp one
                try:
                    link.write_register(s.id, s.model.register("Torque Enable"), 0)
                except BusError as exc:
                    log.error("torque off after a failed torque on: %s", exc)
            raise
        self._torque = True
        self._last_goal = q.tolist()

    # ------------------------------------------------------------------ gripper

    def read_gripper(self) -> float:
        """Present gripper shaft angle, radians (its own READ)."""
        g = self._require_gripper()
        pulses = units.signed32(self.link.read_register(g.id, g.model.register("Present Position")))
        self._raise_alerts()
        return float(units.pulses_to_rad(pulses, offset=g.offset))

    def write_gripper(self, angle: float) -> None:
        """Gripper goal, radians of the servo shaft, clamped to the gripper limits (its own WRITE)."""
        g = self._require_gripper()
        link = self._require_active()
        if not math.isfinite(angle):
            raise ValueError(f"Expected a finite gripper angle in radians, got {angle}")
        goal = int(np.clip(units.rad_to_pulses(angle, offset=g.offset), g.min_pulse, g.max_pulse))
        link.write_register(g.id, g.model.register("Goal Position"), goal)
        self._raise_alerts()

    # ------------------------------------------------------------------ internals

    def _watchdog_tick(self, link: Link) -> None:
        """Arm the Bus Watchdog with the first goal; later, a BusError if a host silence let it stop the servos."""
        watchdog, now = self._watchdog, self.clock.now()
        assert watchdog is not None
        if not watchdog.armed:
            watchdog.arm(link, now)
        try:
            watchdog.check(link, now)
        except BusError as exc:
            self._faulted = str(exc)
            raise
        watchdog.talked(now)

    def _require_active(self) -> Link:
        link = self.link
        if self._faulted:
            raise BusError(f"bus is faulted ({self._faulted}); no more goals are sent: close it")
        return link

    def set_gripper(self, closure: float) -> None:
        """Gripper goal as closure 0 (open) .. 1 (closed) of its limits (``[gripper] closed``): stored, and written
        on the tick path (before the next position read, when it moved by more than 0.5 %), not now."""
        if self._gripper_channel is None:
            raise BusError(f"arm {self.arm.name!r} has no gripper")
        self._gripper_channel.set(closure)

    def gripper_reading(self) -> GripperReading | None:
        """The gripper's last command and reading (read every ``watch_period`` once set_gripper was called)."""
        return None if self._gripper_channel is None else self._gripper_channel.reading

    def _require_gripper(self) -> ServoPlan:
        if self._gripper is None:
            raise BusError(f"arm {self.arm.name!r} has no gripper")
        return self._gripper

    def _send_goals(self, link: Link, goal: Sequence[float]) -> None:
        """One SYNC_WRITE of Goal Position: each servo gets its joint's ``goal`` (rad, finite), encoded as
        ``round(2048 + offset + q / RAD_PER_PULSE)`` (as ``units.rad_to_pulses``) and clipped to its position limits."""
        values: list[int] = []
        for dxl_id, joint, zero, lo, hi in self._goal_plan:
            p = round(zero + goal[joint] / units.RAD_PER_PULSE)
            values += (dxl_id, lo if p < lo else hi if p > hi else p)
        link.sync_write_param(_GOAL_POSITION.address, _GOAL_POSITION.size, list(self._goal_packing.pack(*values)))

    def _check_shadows(self, pulses: np.ndarray) -> None:
        """Refuse torque when a shadow disagrees with its primary: under torque the two would fight (overload)."""
        q = units.pulses_to_rad(pulses, offset=self._servo_offset)
        q_primary = q[self._primary_index][self._servo_joint]
        off = np.abs((q - q_primary + np.pi) % (2.0 * np.pi) - np.pi)  # on the circle: 4095 and 1 are 2 pulses apart
        bad = [s for s, d in zip(self._joint_servos, off, strict=True) if d > self.shadow_tolerance]
        if bad:
            detail = ", ".join(
                f"servo {s.id} reads {float(q[i] - q_primary[i]):+.3f} rad from its primary"
                for i, s in enumerate(self._joint_servos)
                if s in bad
            )
            raise BusError(
                f"shadow servo disagrees with its joint ({detail}); under torque they would fight: check the horn "
                "and the servo's offset in the arm description",
                ids=[s.id for s in bad],
            )

    def _read_joint_pulses(self, *, check_active: bool = True) -> np.ndarray:
        """Present Position of every joint servo ``(n_joint_servos,) int64`` pulses, in ``_joint_servos`` order."""
        replies = self._read_joint_replies(check_active=check_active)
        return np.array(
            [int.from_bytes(replies[dxl_id].data, "little", signed=True) for dxl_id in self._position_requests],
            dtype=np.int64,
        )

    def _read_joint_replies(self, *, check_active: bool = True) -> dict[int, StatusPacket]:
        """Present Position replies of every joint servo (shadows too, so their alerts are seen), by ID."""
        link = self._require_active() if check_active else self.link
        self._pending = link.send_group_read(self._position_reads[self._use_fast])
        return self._receive_joint_replies(link)

    def _receive_joint_replies(self, link: Link, *, stale_ok: bool = False) -> dict[int, StatusPacket]:
        """The replies of the position read in flight (``_pending``).  It stays in flight when a Ctrl-C cuts
        this short, so that close() waits for its replies before it sends anything.

        ``stale_ok`` (the tick path): a servo still silent after the retries gets its last reply instead, marked
        stale (:meth:`_note_stale`), while ``max_stale_ticks`` allows it."""
        pending = self._pending
        if pending is None:  # pragma: no cover - every caller sent the read first
            raise BusError("no position read in flight")
        stale_ok = stale_ok and self.max_stale_ticks > 0 and self._last_replies is not None
        try:
            replies = link.receive_group_read(pending, what="Present Position", allow_missing=stale_ok)
        except BusError as exc:
            self._pending = None
            self._faulted = str(exc)
            raise
        self._pending = None
        if len(replies) < len(pending.ids):
            replies = self._note_stale(link, pending.ids, replies)
        elif self._stale_run:
            self._stale_run.clear()
        if stale_ok:
            self._last_replies = replies
        if self._use_fast and link.fast_failures >= 3:
            log.warning("FAST_SYNC_READ failed 3 times in a row: using plain SYNC_READ from now on")
            self._use_fast = False
        if link.alerts:
            self._raise_alerts()
        return replies

    def _watch(self, link: Link) -> None:
        """The watch: a PING of every servo outside the position read (the gripper).

        Its status packet carries the Alert bit, as every one does: a hardware error is handled as in a position
        read (BusError naming the servo and the alert, or a reboot with ``recover=True``).  A servo still silent
        after the retries is watched again before every position read, one try each (so a servo that is gone
        costs one timeout per tick, not ``retries + 1``, and the stop comes within a second), and faults the bus
        once it was missed for too long, by the position reads' rule (more than ``max_stale_ticks`` watch reads
        in a row, or ``max_stale_fraction`` of the last second's ticks)."""
        run = self._watch_run
        replies = {i for i in self._watched if (link.ping_once(i) if i in run else link.ping(i)) is not None}
        history = self._watch_history
        too_long: list[int] = []
        for dxl_id in self._watched:
            if dxl_id in replies:
                run.pop(dxl_id, None)
                continue
            missed_too_long = self._count_miss(run, history, dxl_id)
            log.debug("tick %d: watched servo %d silent (%d in a row)", self._ticks, dxl_id, run[dxl_id])
            if missed_too_long:
                too_long.append(dxl_id)
        if too_long:
            parts = [
                f"{i}: missed {run[i]} watch reads in a row, {len(history[i])} in the last second" for i in too_long
            ]
            limit = f"more than {self.max_stale_ticks} in a row or {100.0 * self.max_stale_fraction:g}% of 1 s"
            self._faulted = message = (
                f"no status packet (PING, the watch) at {self.baud} baud after {self.retries + 1} tries, then one "
                f"per tick, too long ({limit}): {'; '.join(parts)}; check the cable, power and the baud rate"
            )
            link.error_count += 1
            raise BusError(message, ids=too_long)
        if link.alerts:
            self._raise_alerts()

    def _reset_stale(self) -> None:
        self._last_replies = None
        self._stale_run = {}
        self._stale_history = {}
        self._watch_run = {}
        self._watch_history = {}
        self._stale_reads = 0  #: servo reads that were stale since connect
        self._stale_ticks = 0  #: position reads with at least one stale servo
        self._worst_stale = 0  #: the longest run of stale reads of one servo

    def _note_stale(self, link: Link, ids: Sequence[int], replies: dict[int, StatusPacket]) -> dict[int, StatusPacket]:
        """Some servos of ``ids`` did not answer this read: their last replies stand in, counted as stale; a
        servo stale too long (``max_stale_ticks`` in a row, ``max_stale_fraction`` of the last second) faults
        the bus with a BusError naming it and the loss seen."""
        last = self._last_replies
        assert last is not None  # receive_group_read raised otherwise
        missing = [i for i in ids if i not in replies]
        run, history, tick = self._stale_run, self._stale_history, self._ticks
        for i in [i for i in run if i in replies]:
            del run[i]
        self._stale_ticks += 1
        self._stale_reads += len(missing)
        too_long: list[int] = []
        for i in missing:
            missed_too_long = self._count_miss(run, history, i)
            self._worst_stale = max(self._worst_stale, run[i])
            if missed_too_long:
                too_long.append(i)
        if too_long:
            self._faulted = message = self._stale_message(link, too_long)
            link.error_count += 1
            raise BusError(message, ids=too_long)
        log.debug("tick %d: servo %s stale", tick, ", ".join(map(str, missing)))
        merged = {i: replies[i] if i in replies else last[i] for i in ids}
        return merged

    def _count_miss(self, run: dict[int, int], history: dict[int, deque[int]], dxl_id: int) -> bool:
        """One more read that servo ``dxl_id`` missed (a position read's or the watch's): its run in a row in ``run``,
        this tick in its ``history`` of the last second (``stale_window`` ticks).  True once it was missed too long:
        more than ``max_stale_ticks`` in a row, or more than ``max_stale_fraction`` of the window."""
        n = run[dxl_id] = run.get(dxl_id, 0) + 1
        tick, window = self._ticks, self.stale_window
        seen = history.setdefault(dxl_id, deque())
        seen.append(tick)
        while seen[0] <= tick - window:
            seen.popleft()
        return n > self.max_stale_ticks or len(seen) > self.max_stale_fraction * window

    def _stale_message(self, link: Link, ids: Sequence[int]) -> str:
        """Why servos ``ids`` are stale too long: their runs, their share of the last second, the reply loss."""
        parts = []
        for i in ids:
            lost, asked = link.reply_loss(i)
            stale = len(self._stale_history[i])
            reads = min(self.stale_window, self._ticks + 1)
            parts.append(
                f"{i}: stale {self._stale_run[i]} reads in a row, {stale} of the last {reads} reads "
                f"({100.0 * stale / reads:.0f}%), {100.0 * lost / max(asked, 1):.0f}% of {asked} replies lost"
            )
        limit = f"more than {self.max_stale_ticks} in a row or {100.0 * self.max_stale_fraction:g}% of 1 s"
        return (
            f"no status packet (Present Position) at {self.baud} baud after {self.retries + 1} tries per read, "
            f"too long ({limit}): {'; '.join(parts)}; check the cable, power and the baud rate"
        )

    def _raise_alerts(self) -> None:
        link = self.link
        if not link.alerts:
            return
        ids = sorted(link.alerts)
        link.alerts.clear()
        found: dict[int, tuple[str, ...]] = {}
        for dxl_id in ids:
            s = self._servo(dxl_id)
            bits = link.read_register(dxl_id, s.model.register("Hardware Error Status"))
            found[dxl_id] = hardware_error_names(bits) or ("unknown alert",)
        self._hardware_errors.update(found)
        link.alerts.clear()  # reading Hardware Error Status set them again
        if len(found) == 1:  # BusError already starts with "servo N: "
            detail = ", ".join(next(iter(found.values())))
        else:
            detail = "; ".join(f"{i}: {', '.join(names)}" for i, names in found.items())
        if self.recover and all(self._recoveries.get(i, 0) < _MAX_RECOVERIES for i in ids):
            log.warning("hardware error (%s): rebooting and configuring again", detail)
            for dxl_id in ids:
                self._recoveries[dxl_id] = self._recoveries.get(dxl_id, 0) + 1
            for dxl_id in ids:
                self._reboot_and_configure(self._servo(dxl_id))
            link.alerts.clear()
            return
        self._faulted = f"hardware error: {detail}"
        link.error_count += 1
        if self.recover:
            advice = f"still failing after {_MAX_RECOVERIES} reboots: power it off and find the cause"
        else:
            advice = "a servo shuts its torque off on these: power-cycle it or reboot it (recover=True)"
        raise BusError(f"hardware error: {detail}; {advice}", ids=ids)

    def _servo(self, dxl_id: int) -> ServoPlan:
        return next(s for s in self.servos if s.id == dxl_id)

    def _check_servos(self) -> None:
        link = self.link
        missing: list[int] = []
        wrong: list[str] = []
        wrong_ids: list[int] = []
        for s in self.servos:
            reply = link.ping(s.id)
            if reply is None:
                missing.append(s.id)
                continue
            self._firmware[s.id] = reply.firmware
            if reply.model_number != s.model.number:
                wrong_ids.append(s.id)
                found = MODEL_BY_NUMBER.get(reply.model_number)
                found_name = f"{found.name} ({found.number})" if found else f"model {reply.model_number}"
                expected = f"{s.model.name} ({s.model.number})"
                wrong.append(f"servo {s.id} is {found_name}, the arm expects {expected}")
        problems: list[str] = []
        if missing:
            problems.append(
                f"no status packet from servo {', '.join(map(str, missing))} at {self.baud} baud on {self.port_name}: "
                "check the baud rate, the IDs, power and the cable"
            )
        if wrong:
            problems.append("; ".join(wrong) + f": is this the {self.arm.name} arm?")
        if problems:
            link.error_count += 1
            raise BusError("; ".join(problems), ids=sorted(missing + wrong_ids))
        addresses = {s.model.register("Present Position").address for s in self._joint_servos}
        capable = all(self._firmware[s.id] >= s.model.fast_read_min_firmware for s in self._joint_servos)
        self._use_fast = (capable and len(addresses) == 1) if self.fast_read is None else bool(self.fast_read)

    def _configure(self, s: ServoPlan) -> None:
        """Write what differs, EEPROM first with torque off (the EEPROM rule), then the RAM profile."""
        link = self.link
        # every reply on, first: a servo left at Status Return Level 0 or 1 answers only pings (or reads)
        link.write_maybe_unacknowledged(s.id, s.model.register("Status Return Level"), 2)
        eeprom, ram = self.settings.registers(s, self.arm)
        block = link.read(s.id, _EEPROM_START, _EEPROM_END - _EEPROM_START, what="the EEPROM settings").data
        changes = {}
        for name, value in eeprom.items():
            reg = s.model.register(name)
            current = reg.decode(block[reg.address - _EEPROM_START : reg.end - _EEPROM_START])
            if current != value:
                changes[name] = (current, value)
        if changes:
            torque = s.model.register("Torque Enable")
            holding = bool(link.read_register(s.id, torque))
            if holding:  # an arm left holding (shutdown HOLD): this servo goes limp only for its own EEPROM writes
                log.warning(
                    "servo %d: turning torque off to write its EEPROM settings (%s), then on again where it is",
                    s.id,
                    ", ".join(f"{name} {current} -> {value}" for name, (current, value) in changes.items()),
                )
                link.write_register(s.id, torque, 0)
            try:
                for name, (current, value) in changes.items():  # Operating Mode first: changing it resets the profile
                    log.info("servo %d: %s %d -> %d", s.id, name, current, value)
                    link.write_register(s.id, s.model.register(name), value)
            except BaseException:
                if holding:  # it was holding the arm: holding where it is beats dropping it
                    try:
                        self._hold_here(s)
                    except BusError as exc:
                        log.error("servo %d: torque back on after a failed EEPROM write: %s", s.id, exc)
                raise
            if holding:
                self._hold_here(s)
        for name, value in ram.items():
            link.write_register(s.id, s.model.register(name), value)

    def _reboot_and_configure(self, s: ServoPlan) -> None:
        link = self.link
        link.reboot(s.id)
        deadline = self.clock.now() + 2.0
        while link.ping_once(s.id) is None:
            if self.clock.now() > deadline:
                raise BusError("did not come back after REBOOT", ids=[s.id])
            self.clock.sleep_until(self.clock.now() + 0.05)
        self._configure(s)
        self._hold_here(s)  # the rebooted servo holds where it is
        if self._watchdog is not None:
            self._watchdog.rearm(link, s.id)  # REBOOT reset it with the RAM
        self._hardware_errors.pop(s.id, None)
        log.warning("servo %d rebooted and configured again", s.id)

    def _hold_here(self, s: ServoPlan) -> None:
        """Goal Position = the servo's present position (single-turn, clipped to its limits), then torque on."""
        link = self.link
        present = units.signed32(link.read_register(s.id, s.model.register("Present Position")))
        link.write_register(s.id, s.model.register("Goal Position"), hold_pulse(present, s.min_pulse, s.max_pulse))
        link.write_register(s.id, s.model.register("Torque Enable"), 1)

    def _torque_off_all(self) -> None:
        link = self.link
        failed: list[int] = []
        for s in self.servos:
            try:
                link.write_register(s.id, s.model.register("Torque Enable"), 0)
            except BusError as exc:
                log.error("torque off: %s", exc)
                failed.append(s.id)
        self._torque = False
        if failed:
            raise BusError("could not turn torque off", ids=failed)

    def _move_to_rest(self) -> None:
        """Slow profile, one goal at the rest pose, wait (on the bus clock) until reached or timed out.

        Policy after a hardware error (a faulted servo keeps the Alert bit in every status packet, so this
        path reads without raising on alerts and records every alerting servo instead):

        * a joint with ANY faulted servo is not commanded: its servos get no new goal and keep the one they
          had (a servo whose error is in its Shutdown mask has cut its own torque and cannot move; a healthy
          shadow beside it holds where it was, and is never asked to carry the joint alone through a move);
        * every other joint moves to rest at ``rest_speed``; a servo that faults during the move freezes its
          joint (its healthy servos get their own present position as goal) and the others carry on;
        * the wait ends when the commanded joints are at rest (or after ``rest_timeout``); close() then turns
          torque off on every servo, faulted joints included;
        * a joint servo that stays silent raises BusError here: without its reading the arm cannot be
          watched, so close() falls back to turning torque off at once.
        """
        link = self.link
        self._faulted = None  # a fault stops goals from the caller, not the shutdown sequence
        rest = np.clip(self.arm.rest, self.lower, self.upper)
        pulses = self._read_pulses_for_shutdown()
        held = self._faulted_joints()
        if held:
            log.warning(
                "%s: not moving %s to rest (faulted servo %s); the other joints go to rest, then torque off",
                self.arm.name,
                ", ".join(self.arm.joint_names[j] for j in sorted(held)),
                ", ".join(map(str, sorted(self._hardware_errors))),
            )
        moving = [j for j in range(self.arm.n_joints) if j not in held]
        if not moving:
            return
        servos = [s for s in self._joint_servos if s.joint not in held]
        present = self._primary_angles(pulses)
        if self.profile is Profile.TIME:
            # ramps of a quarter of the move each: the cruise speed is distance / (0.75 * duration), its
            # acceleration 16 distance / (3 duration^2), kept within every moving joint's max_acceleration
            distance = np.abs(rest - present)[moving]
            accel_limit = self.arm.max_acceleration[moving]
            duration = float(np.max(distance)) / (0.75 * self.rest_speed)
            duration = max(duration, float(np.max(np.sqrt(16.0 * distance / (3.0 * accel_limit)))))
            pv = min(int(units.seconds_to_ms(duration + 0.0005)), MAX_PROFILE_MS)  # rounded up to whole ms
            values = dict.fromkeys((s.id for s in servos), pv)
            accel = dict.fromkeys(values, pv // 4)
        else:  # the joint's own acceleration limit (the tick stream's Profile Acceleration is higher, see above)
            values = {
                s.id: int(units.rad_s_to_velocity_units(min(self.rest_speed, self.arm.joints[s.joint].max_velocity)))
                for s in servos
            }
            accel = {s.id: int(units.rad_s2_to_accel_units(self.arm.joints[s.joint].max_acceleration)) for s in servos}
        link.sync_write(_PROFILE_ACCELERATION.address, _PROFILE_ACCELERATION.size, _u32s(accel))
        link.sync_write(_PROFILE_VELOCITY.address, _PROFILE_VELOCITY.size, _u32s(values))
        goals = {}  # as _send_goals encodes them, for the commanded joints' servos only
        for s in servos:
            goals[s.id] = _clip_pulse(round(units.CENTER_PULSE + s.offset + rest[s.joint] / units.RAD_PER_PULSE), s)
        link.sync_write(_GOAL_POSITION.address, _GOAL_POSITION.size, _u32s(goals))
        start = self.clock.now()
        while True:
            pulses = self._read_pulses_for_shutdown()
            newly = self._faulted_joints() - held
            if newly:
                self._freeze_joints(newly, pulses)
                held |= newly
                moving = [j for j in moving if j not in newly]
                if not moving:
                    return
            err = float(np.max(np.abs(self._primary_angles(pulses) - rest)[moving]))
            if err <= self.rest_tolerance:
                log.info("%s reached its rest pose in %.2f s", self.arm.name, self.clock.now() - start)
                return
            if self.clock.now() - start > self.rest_timeout:
                log.warning(
                    "rest pose not reached after %.1f s (off by %.3f rad): torque off anyway", self.rest_timeout, err
                )
                return
            self.clock.sleep_until(self.clock.now() + 0.05)

    def _read_pulses_for_shutdown(self) -> np.ndarray:
        """Present Position of every joint servo ``(n_joint_servos,) int64`` pulses, in ``_joint_servos`` order,
        without raising on alerts: each newly alerting servo's Hardware Error Status is read and recorded in
        ``_hardware_errors`` (the shutdown sequence's view of which servos are faulted).  A silent servo raises."""
        link = self.link
        replies = link.group_read(self._position_requests, fast=self._use_fast, what="Present Position")
        new = sorted(i for i in link.alerts if i not in self._hardware_errors)
        link.alerts.clear()
        for dxl_id in new:
            s = self._servo(dxl_id)
            bits = link.read_register(dxl_id, s.model.register("Hardware Error Status"))
            if bits:  # an Alert bit with no error left is not a fault
                self._hardware_errors[dxl_id] = names = hardware_error_names(bits) or (f"error bits 0x{bits:02x}",)
                log.error("servo %d: hardware error during shutdown: %s", dxl_id, ", ".join(names))
        link.alerts.clear()
        return np.array(
            [int.from_bytes(replies[dxl_id].data, "little", signed=True) for dxl_id in self._position_requests],
            dtype=np.int64,
        )

    def _faulted_joints(self) -> set[int]:
        """Joints with at least one servo in hardware error."""
        return {s.joint for s in self._joint_servos if s.id in self._hardware_errors}

    def _freeze_joints(self, joints: set[int], pulses: np.ndarray) -> None:
        """Goal = own present position for the healthy servos of ``joints``: they stop where they are."""
        hold = {
            s.id: _clip_pulse(int(pulses[k]), s)
            for k, s in enumerate(self._joint_servos)
            if s.joint in joints and s.id not in self._hardware_errors
        }
        log.warning(
            "%s: a servo faulted during the rest move: %s stop%s where %s",
            self.arm.name,
            ", ".join(self.arm.joint_names[j] for j in sorted(joints)),
            "s" if len(joints) == 1 else "",
            "it is" if len(joints) == 1 else "they are",
        )
        if hold:
            self.link.sync_write(_GOAL_POSITION.address, _GOAL_POSITION.size, _u32s(hold))

    def _primary_angles(self, pulses: np.ndarray) -> np.ndarray:
        """Joint angles ``(n_joints,) float64`` rad from the primaries in ``pulses`` (``_joint_servos`` order)."""
        return units.pulses_to_rad(pulses[self._primary_index], offset=self._servo_offset[self._primary_index])


def hold_pulse(present: int, lo: int, hi: int) -> int:
    """The Goal Position that holds a position-mode servo where it is when its torque turns on.

    ``present``: Present Position read with torque off, signed pulses; it counts whole turns then, and torque on
    in position mode resets it into 0..4095, so it is taken modulo 4096 first (4196 -> 100, -100 -> 3996; the
    Homing Offset is 0 on this bus).  Then clipped to the servo's Min/Max Position Limit ``lo..hi``.

    >>> hold_pulse(4196, 0, 4095), hold_pulse(-100, 0, 4095), hold_pulse(4196, 1024, 3072)
    (100, 3996, 1024)
    """
    return min(max(int(present) % units.PULSES_PER_REV, lo), hi)


hold_tick = hold_pulse  #: the first release's name


def _clip_pulse(pulse: int, s: ServoPlan) -> int:
    return min(max(int(pulse), s.min_pulse), s.max_pulse)


def _u32s(values: Mapping[int, int]) -> dict[int, bytes]:
    """Servo ID -> value as the 4 little-endian bytes of a 4-byte register (signed: Goal Position may be < 0)."""
    return {dxl_id: int(v).to_bytes(4, "little", signed=True) for dxl_id, v in values.items()}


__all__: Sequence[str] = (
    "DynamixelBus",
    "Profile",
    "ServoPlan",
    "ServoState",
    "hold_pulse",
    "hold_tick",
    "plan_servos",
)
