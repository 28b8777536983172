"""What each servo of an arm is configured to: its role, position limits and the register values the bus writes.

:func:`plan_servos` turns an arm description into one :class:`ServoPlan` per servo (joints in order, primary
then shadows, then the gripper), with the Min/Max Position Limit in pulses.  :class:`ServoSettings` holds
the bus options that become register values, and :meth:`ServoSettings.registers` lists them per servo,
EEPROM first (written with torque off) then RAM.

Pulses are in the servo's register space, where Drive Mode bit 0 already reverses the shaft: every servo of
a joint holds ``2048 + offset + q / RAD_PER_PULSE``, so the limits use the offset and never the direction.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

import numpy as np

from drivers import units
from drivers.control_table import RETURN_DELAY_UNIT_US, DriveMode, Model, OperatingMode
from drivers.control_table import model as lookup_model
from drivers.gripper import gripper_registers
from retarget.arm.model import Arm, Joint
from retarget.errors import ConfigError

MAX_PROFILE_MS = 32737  #: the largest Profile Velocity of a time-based profile


class Profile(enum.Enum):
    """How the servo shapes each move toward a new goal (Drive Mode bit 2)."""

    VELOCITY = "velocity"  #: Profile Velocity/Acceleration are a rate cap (0.229 rpm, 214.577 rev/min^2)
    TIME = "time"  #: Profile Velocity/Acceleration are the move's duration and ramp time (ms)


@dataclass(frozen=True)
class ServoPlan:
    """One servo of the arm as the bus drives it: where it sits and what it is configured to."""

    id: int
    model: Model
    role: str  #: "primary", "shadow" or "gripper"
    joint: int  #: index into the arm's joints; -1 for the gripper
    offset: int  #: pulses: the joint's 0 rad is at 2048 + offset
    direction: int  #: +1 or -1, written to Drive Mode bit 0
    min_pulse: int  #: Min Position Limit
    max_pulse: int  #: Max Position Limit

    @property
    def min_tick(self) -> int:
        """The first release's name of :attr:`min_pulse`."""
        return self.min_pulse

    @property
    def max_tick(self) -> int:
        """The first release's name of :attr:`max_pulse`."""
        return self.max_pulse


def pulse_limits(lower: float, upper: float, offset: int = 0, *, where: str = "limits") -> tuple[int, int]:
    """Min/Max Position Limit (pulses) inside ``[lower, upper]`` rad and the single-turn range 0..4095.

    >>> pulse_limits(-math.pi / 2, math.pi / 2, offset=10)
    (1034, 3082)
    """
    lo = math.ceil(units.CENTER_PULSE + offset + lower / units.RAD_PER_PULSE - 1e-6)
    hi = math.floor(units.CENTER_PULSE + offset + upper / units.RAD_PER_PULSE + 1e-6)
    lo, hi = max(lo, units.MIN_PULSE), min(hi, units.MAX_PULSE)
    if lo >= hi:
        raise ConfigError(
            "joint limits do not fit the servo's single-turn range 0..4095 pulses", key=where, value=(lower, upper)
        )
    return lo, hi


tick_limits = pulse_limits  #: the first release's name


def plan_servos(arm: Arm) -> tuple[ServoPlan, ...]:
    """Every servo of ``arm`` (joints in order, primary then shadows, then the gripper) with its position limits."""
    plans: list[ServoPlan] = []
    for j, joint in enumerate(arm.joints):
        for k, servo in enumerate(joint.servos):
            where = f"joints[{j}].servos[{k}]"
            try:
                model = lookup_model(servo.model)
            except KeyError as exc:
                raise ConfigError(str(exc.args[0]), path=arm.source, key=f"{where}.model", value=servo.model) from exc
            lo, hi = pulse_limits(joint.lower, joint.upper, servo.offset, where=f"joints[{j}].limits")
            role = "primary" if k == 0 else "shadow"
            plans.append(ServoPlan(servo.id, model, role, j, servo.offset, servo.direction, lo, hi))
    if arm.gripper is not None:
        g = arm.gripper
        try:
            model = lookup_model(g.servo.model)
        except KeyError as exc:
            key = "gripper.servo.model"
            raise ConfigError(str(exc.args[0]), path=arm.source, key=key, value=g.servo.model) from exc
        lo, hi = pulse_limits(g.lower, g.upper, g.servo.offset, where="gripper.limits")
        plans.append(ServoPlan(g.servo.id, model, "gripper", -1, g.servo.offset, g.servo.direction, lo, hi))
    seen: set[int] = set()
    for p in plans:
        if p.id in seen:
            raise ConfigError("servo ID used twice", path=arm.source, key="servos", value=p.id)
        seen.add(p.id)
    return tuple(plans)


DEFAULT_DT = 0.01  #: s, the tick period :func:`servo_acceleration` assumes when the bus has none (100 Hz)


def servo_acceleration(joint: Joint, dt: float | None = None) -> float:
    """The servo's own Profile Acceleration (rad/s^2) for ``joint`` when the loop streams a goal every ``dt`` s
    (None: :data:`DEFAULT_DT`): the larger of the joint's ``max_acceleration`` and ``max_velocity / (2 dt)``.

    The velocity-based profile plans each new goal to a stop on it, from the present velocity (the e-Manual's
    "velocity override"), so a servo streamed goals along a trajectory moving at ``v`` trails it by about
    ``v^2 / (2 a)``, where it has to start braking: at our own limit that is up to 0.11 rad at 180 deg/s (measured
    on the simulator: tool 39 mm behind the last goal, p95 on motion_dance).  ``max_velocity / (2 dt)`` keeps
    that trail within one tick's travel at full speed (a quarter of it at half speed), and is still a cap on a
    goal that jumps (full speed in two ticks, where Profile Acceleration 0 would take the motor's stall current).
    Profile Velocity 0 turns the whole profile off (the e-Manual: no profile, step), so this then does nothing.

    >>> from retarget.arm.model import Joint
    >>> j = Joint("j", (0, 0, 0), (0, 0, 0), (0, 0, 1), -1.0, 1.0, math.pi, (), max_acceleration=40.0)
    >>> round(servo_acceleration(j), 1), round(servo_acceleration(j, dt=0.002), 1)
    (157.1, 785.4)
    """
    period = DEFAULT_DT if dt is None else dt
    return max(joint.max_acceleration, joint.max_velocity / (2.0 * period))


@dataclass(frozen=True)
class ServoSettings:
    """The bus options that become register values (see ``DynamixelBus`` for their meaning)."""

    profile: Profile = Profile.VELOCITY
    profile_velocity: float | None = None  #: rad/s (VELOCITY); None: the joint's max velocity; 0: no cap
    #: rad/s^2 (VELOCITY); None: :func:`servo_acceleration` of the joint (the arm's gripper: unlimited); 0: unlimited
    profile_acceleration: float | None = None
    profile_time: float | None = None  #: s per move (TIME); None: ``dt`` or 0.1 s
    dt: float | None = None  #: the control tick period, s
    return_delay_us: int = 0

    def registers(self, s: ServoPlan, arm: Arm) -> tuple[dict[str, int], dict[str, int]]:
        """``(eeprom, ram)``: register name -> value for servo ``s``; EEPROM in the order to write it."""
        reg_max = s.model.register("Velocity Limit").maximum or 1023
        if s.role == "gripper":
            max_velocity = float(np.max(arm.max_velocity))
        else:
            max_velocity = float(arm.joints[s.joint].max_velocity)
        velocity_limit = min(int(units.rad_s_to_velocity_units(max_velocity)), reg_max)
        drive = DriveMode.REVERSE if s.direction < 0 else DriveMode(0)
        if self.profile is Profile.TIME:
            drive |= DriveMode.TIME_BASED_PROFILE
            duration = self.profile_time if self.profile_time is not None else (self.dt or 0.1)
            pv = min(int(units.seconds_to_ms(duration)), MAX_PROFILE_MS)
            pa = pv // 4  # the ramp may not exceed half the move
        else:
            speed = max_velocity if self.profile_velocity is None else min(self.profile_velocity, max_velocity)
            pv = min(int(units.rad_s_to_velocity_units(speed)), velocity_limit)
            accel = self.profile_acceleration
            if accel is None:
                accel = 0.0 if s.role == "gripper" else servo_acceleration(arm.joints[s.joint], self.dt)
            pa = int(units.rad_s2_to_accel_units(accel))
        eeprom = {  # Operating Mode first: changing it resets the profile registers
            "Operating Mode": int(OperatingMode.POSITION),
            "Drive Mode": int(drive),
            "Homing Offset": 0,  # the arm description's offset is the one calibration
            "Max Position Limit": s.max_pulse,
            "Min Position Limit": s.min_pulse,
            "Velocity Limit": velocity_limit,
            "Return Delay Time": self.return_delay_us // RETURN_DELAY_UNIT_US,
        }
        ram = {"Profile Acceleration": pa, "Profile Velocity": pv}
        if s.role == "gripper" and arm.gripper is not None:  # mode 5 and its current limit (drivers.gripper)
            g_eeprom, g_ram = gripper_registers(arm.gripper, s.model)
            eeprom.update(g_eeprom)
            ram.update(g_ram)
        return eeprom, ram
