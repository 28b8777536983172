"""The whole ``retarget calibrate`` flow: connect, reference pose, directions, ranges, verify; a Calibration.

:func:`calibrate` runs the steps of :mod:`retarget.calibrate.steps` in order and returns the result; it saves
nothing (the caller does, atomically, with :func:`retarget.arm.calibration.save_calibration`), so an interrupted
or failed calibration leaves no file.  Torque is off from step 1 to 4 (sent again on any interruption) and the
verification's bus turns it off when it ends, Ctrl-C included.
"""

from __future__ import annotations

import datetime
import logging
from dataclasses import dataclass, field

from retarget.arm.calibration import Calibration, JointCalibration, apply_calibration
from retarget.arm.model import Arm
from retarget.calibrate import steps
from retarget.calibrate.hands import Hands
from retarget.calibrate.prompts import Prompter
from retarget.calibrate.servos import ServoLink
from retarget.control.clock import Clock, MonotonicClock
from retarget.errors import BusError

__all__ = ["CalibrationResult", "calibrate"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class CalibrationResult:
    """The calibration measured, whether the user confirmed every verification pose, and the warnings given."""

    calibration: Calibration
    verified: bool | None  #: None: not verified (``verify=False``)
    warnings: tuple[str, ...] = field(default=())


def calibrate(
    arm: Arm,
    port: str,
    io: Prompter,
    *,
    name: str | None = None,
    hands: Hands | None = None,
    clock: Clock | None = None,
    directions: bool | None = None,
    verify: bool = True,
    auto: bool = False,
    baud: int | None = None,
) -> CalibrationResult:
    """Calibrate ``arm`` (its file's servos, limits and calibration pose) on ``port``; see the module docstring.

    ``name``: the instance's name (default the arm's); ``hands``: what moves the limp joints when nobody does
    (:class:`~retarget.calibrate.hands.SimHands` on a simulated bus); ``directions``: find each servo's direction
    too (default the arm file's ``calibrate_directions``); ``auto``: ``--yes`` (no nudges or sweeps without
    ``hands``: the arm file's directions stay, no range is measured, no verification move is made).

    A Koch whose servo 1 horn sits 300 pulses off and whose servo 3 is turned round, calibrated unattended::

        >>> import io, sim
        >>> from retarget.arm.load import load_arm
        >>> from retarget.calibrate import AutoPrompter, SimHands
        >>> bus = sim.transport.bus_from_url("sim://koch?clock=virtual&mount=1:+300&reverse=3")
        >>> url = sim.attach(bus)
        >>> result = calibrate(load_arm("koch"), url, AutoPrompter(out=io.StringIO()),
        ...                    hands=SimHands(bus.body, bus.clock), clock=bus.clock, auto=True)
        >>> [(s.id, s.offset, s.direction) for s in result.calibration.servos][:3], result.verified
        ([(1, 300, 1), (2, 0, 1), (3, 0, -1)], True)
        >>> sim.unregister(url)
    """
    clock = clock if clock is not None else MonotonicClock()
    find_directions = arm.calibrate_directions if directions is None else directions
    warnings: list[str] = []
    link = ServoLink(arm, port, baud=baud)
    with link:
        info = steps.connect_step(io, link)
        try:
            ref = steps.reference_step(io, link, hands)
            file_dirs = {s.id: s.direction for j in arm.joints for s in j.servos}
            if find_directions and (hands is not None or not auto):
                dirs = steps.direction_step(io, link, ref, hands, tries=1 if auto else 5)
            else:
                if find_directions:
                    warnings.append("--yes on a real arm: the arm file's servo directions kept")
                    io.say(f"  warning: {warnings[-1]}")
                dirs = file_dirs
            servos = steps.servo_calibrations(arm, ref, dirs, info)
            for s in servos:
                io.say(f"  servo {s.id:>3} {s.joint:<14} offset {s.offset:+5d} pulses  direction {s.direction:+d}")
            for note in steps.single_turn_notes(arm, servos):
                warnings.append(note)
                io.say(f"  warning: {note}")
            measured = steps.range_step(io, link, steps.Angles(arm, ref, dirs), hands, auto=auto)
            narrowed = steps.check_ranges(io, arm, measured)
            measured = {k: v for k, v in measured.items() if v[1] - v[0] >= steps.MIN_RANGE}  # the joints turned
        except BaseException:
            _torque_off(link)
            raise
    joints = tuple(
        JointCalibration(j.name, measured.get(j.name), narrowed.get(j.name))
        for j in arm.joints
        if j.name in measured or j.name in narrowed
    )
    date = datetime.datetime.now(datetime.UTC).replace(microsecond=0).isoformat()
    cal = Calibration(arm.name, name or arm.name, date, servos, joints)
    verified: bool | None = None
    if verify and hands is not None:
        hands.release()
    if verify and (hands is not None or not auto):
        verified = steps.verify_step(io, apply_calibration(arm, cal), port, clock, baud=baud)
    elif verify:
        io.say("Step 5/5: verify: skipped with --yes on a real arm (run `retarget teleop --to ...` slowly)")
    return CalibrationResult(cal, verified, tuple(warnings))


def _torque_off(link: ServoLink) -> None:
    """Torque off again after an interruption (best effort: the bus may be what failed)."""
    try:
        link.link.release()  # a Ctrl-C inside the SDK leaves the port marked busy
        link.torque_off()
    except (BusError, OSError, KeyboardInterrupt) as exc:
        log.warning("could not send torque off after the interruption: %s", exc)
