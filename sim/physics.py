"""No-load motor physics of a simulated servo: the load it reports, and how PWM and current modes move it.

The servo carries nothing (no arm, no gravity): the only torque its motor makes goes into accelerating the rotor
and gear train, plus a little friction that grows with speed.  So at rest Present Current / Present Load reads
about zero, as a real unloaded servo does, and it grows with acceleration and velocity.

Model, as data (one motor of ``Model``: ``no_load_rpm`` and ``stall_current`` come from the e-Manual
specifications, ``_data/dxl_x_info.yml`` of ROBOTIS-GIT/emanual; the shares below are this simulator's
assumptions, not published figures):

* the current share ``I / I_stall`` at acceleration ``a`` and velocity ``v`` is
  ``a / stall_accel + VISCOUS_SHARE * v / no_load`` (clipped to +-1), where ``stall_accel`` is
  ``no_load / STALL_ACCEL_TIME_S``: the stall current spins the unloaded horn up to no-load speed in 25 ms;
* PWM mode (16): Goal PWM is a duty cycle (unit 0.113 %, 885 = 100 %: e-Manual Goal PWM(100)); the unloaded
  motor runs at ``duty * no_load``, reached at ``stall_accel``;
* current mode (0): Goal Current drives the rotor at ``share * stall_accel`` until back EMF caps it at the no-load
  speed; below ``FRICTION_SHARE`` the horn does not turn (and a spinning horn coasts down at that share);
* current-based position mode (5): moves as position mode, its acceleration bounded by what Goal Current
  (capped by Current Limit; e-Manual Goal Current(102): "sets a limit to current in Current-based Position
  Control mode") can give, ``share * stall_accel``.

>>> from drivers.control_table import model
>>> motor = Motor.of(model("XM430-W350"))
>>> round(motor.load_share(0.0, 0.0), 3)  # at rest: nothing to carry
0.0
>>> round(motor.load_share(0.0, motor.stall_accel / 2), 3)  # half the stall acceleration: half the stall current
0.5
>>> round(motor.pwm_velocity(885 // 2) / motor.no_load, 2)  # half duty: half the no-load speed
0.5
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from drivers.control_table import PULSES_PER_REV, Model

STALL_ACCEL_TIME_S = 0.025  #: s the stall current takes to spin the unloaded horn up to no-load speed (assumption)
VISCOUS_SHARE = 0.10  #: current share of stall at no-load speed, unloaded: friction and back-EMF losses (assumption)
FRICTION_SHARE = 0.02  #: current share the unloaded horn needs to start turning (assumption)
PWM_FULL_SCALE = 885  #: Goal PWM units of 100 % duty: 885 x 0.113 % (e-Manual Goal PWM(100), PWM Limit(36))


@dataclass(frozen=True)
class Motor:
    """The motor of one servo model, unloaded: speeds in pulses/s, accelerations in pulses/s^2."""

    no_load: float  #: pulses/s at the nominal voltage (e-Manual "No Load Speed")
    stall_current: float  #: A at the nominal voltage (e-Manual "Stall Torque ... (at V, A)")
    current_unit_ma: float | None  #: Goal/Present Current unit (mA); None on XL430 (Present Load, 0.1 %)

    @classmethod
    def of(cls, model: Model) -> Motor:
        return cls(model.no_load_rpm / 60.0 * PULSES_PER_REV, model.stall_current, model.current_unit_ma)

    @property
    def stall_accel(self) -> float:
        """pulses/s^2 the stall current gives the unloaded rotor."""
        return self.no_load / STALL_ACCEL_TIME_S

    def load_share(self, v: float, a: float) -> float:
        """Signed share of the stall current (or torque) drawn at velocity ``v`` and acceleration ``a``."""
        share = a / self.stall_accel + VISCOUS_SHARE * v / self.no_load
        return max(-1.0, min(1.0, share))

    def current_share(self, units: int) -> float:
        """Goal/Present Current register units as a signed share of the stall current (0 without current sensing)."""
        if self.current_unit_ma is None:
            return 0.0
        return max(-1.0, min(1.0, units * self.current_unit_ma / 1000.0 / self.stall_current))

    def pwm_velocity(self, goal_pwm: int) -> float:
        """Steady no-load velocity (pulses/s, signed) at Goal PWM ``goal_pwm`` (already within PWM Limit)."""
        return max(-1.0, min(1.0, goal_pwm / PWM_FULL_SCALE)) * self.no_load

    def current_mode_target(self, goal_current: int) -> tuple[float, float]:
        """Current mode: ``(velocity it tends to, acceleration to get there)`` at Goal Current ``goal_current``."""
        share = self.current_share(goal_current)
        if abs(share) < FRICTION_SHARE:
            return 0.0, FRICTION_SHARE * self.stall_accel  # too weak to turn it: friction brings it to rest
        return math.copysign(self.no_load, share), abs(share) * self.stall_accel

    def accel_cap(self, goal_current: int, current_limit: int) -> float:
        """Current-based position: the acceleration (pulses/s^2) the current bound ``min(|goal|, limit)`` allows."""
        share = self.current_share(min(abs(goal_current), abs(current_limit)))
        return max(share - FRICTION_SHARE, 0.0) * self.stall_accel
