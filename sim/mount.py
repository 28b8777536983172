"""How the servos of a simulated arm sit in it: per-servo mounting offsets and reversed servos, and the arm's
physical joints turned by hand.

A factory arm's servo of joint angle ``q`` (rad) sits at the physical (actual) position
``2048 + direction * (offset + q / RAD_PER_PULSE)`` pulses, with the arm file's ``direction`` and ``offset``:
what :meth:`sim.bus.SimBus.from_arm` builds.  A hand-built or repaired arm differs per servo: its horn is
mounted ``mount`` pulses away, or the servo is turned round (``reverse``: the shaft turns the other way for the
same joint motion).  Its physical position is then

    actual = 2048 + mount + sign * direction * (offset + q / RAD_PER_PULSE),   sign = -1 when reversed, else +1

so the arm file is wrong for it, and ``retarget calibrate`` must find, per servo, the direction
``sign * direction`` and the offset ``offset + sign * direction * mount`` (:meth:`Mounting.truth`).

Spelled ``mount=ID:PULSES,...`` and ``reverse=ID,...`` in ``sim://ARM`` URLs and ``--mount ID:PULSES`` /
``--reverse ID`` on ``retarget sim``.

>>> m = Mounting.from_options(mount=["1:+300,2:-150"], reverse=["3"])
>>> m.offsets, sorted(m.reversed)
({1: 300, 2: -150}, [3])
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from drivers.control_table import RAD_PER_PULSE
from retarget.arm.model import Arm
from retarget.errors import ConfigError
from sim.hand import HandPath, smoothstep_path
from sim.servo import SimServo

__all__ = ["MOUNT_KEYS", "ArmBody", "Mounting"]

MOUNT_KEYS = frozenset({"mount", "reverse"})  #: the ``sim://`` URL options of this module
MAX_MOUNT = 2047  #: pulses: a mounting offset is within one half turn


@dataclass(frozen=True)
class Mounting:
    """Per-servo mounting offsets (pulses) and the IDs of servos mounted the other way round."""

    offsets: Mapping[int, int] = field(default_factory=dict)
    reversed: frozenset[int] = frozenset()

    @property
    def ids(self) -> set[int]:
        return set(self.offsets) | set(self.reversed)

    def sign(self, dxl_id: int) -> int:
        return -1 if dxl_id in self.reversed else 1

    def truth(self, dxl_id: int, direction: int, offset: int) -> tuple[int, int]:
        """The (direction, offset) a calibration must find for a servo the arm file gives ``direction``/``offset``."""
        d = self.sign(dxl_id) * direction
        return d, offset + d * self.offsets.get(dxl_id, 0)

    @classmethod
    def from_options(
        cls, *, mount: Iterable[str] = (), reverse: Iterable[str] = (), source: str | None = None
    ) -> Mounting:
        """``mount``: ``ID:PULSES`` items (comma-separated allowed), ``reverse``: IDs; ConfigError naming the key."""
        offsets: dict[int, int] = {}
        for item in _split(mount):
            sid, sep, pulses = item.partition(":")
            try:
                dxl_id, value = int(sid), int(pulses.strip())
            except ValueError:
                dxl_id, value = -1, 0
            if not sep or not 0 <= dxl_id <= 252 or not -MAX_MOUNT <= value <= MAX_MOUNT:
                message = f"Expected ID:PULSES, an ID 0..252 and pulses within +-{MAX_MOUNT}"
                raise ConfigError(message, path=source, key="mount", value=item)
            offsets[dxl_id] = value
        ids = set()
        for item in _split(reverse):
            try:
                ids.add(int(item))
            except ValueError:
                raise ConfigError("Expected a servo ID", path=source, key="reverse", value=item) from None
        return cls(offsets, frozenset(ids))

    @classmethod
    def from_query(cls, query: Mapping[str, Sequence[str]], *, source: str | None = None) -> Mounting:
        return cls.from_options(mount=query.get("mount", ()), reverse=query.get("reverse", ()), source=source)


def _held(servo: SimServo, path: HandPath) -> HandPath:
    """``path`` of physical pulses as the reporting-frame path ``move_by_hand`` takes (read at each instant)."""

    def present(t: float) -> float:
        return servo._present_from_actual(path(t))  # the sim's own frames

    return present


def _split(values: Iterable[str]) -> list[str]:
    return [v.strip() for value in values for v in value.split(",") if v.strip()]


class ArmBody:
    """The physical joints of a simulated arm: read them, and turn them by hand while torque is off.

    ``servos``: the SimServo of every joint servo of ``arm`` (by ID).  Angles are radians of the physical joint,
    whatever the servos' Drive Mode and Homing Offset say.
    """

    def __init__(self, arm: Arm, mounting: Mounting, servos: Mapping[int, SimServo]):
        self.arm = arm
        self.mounting = mounting
        self._servos = dict(servos)
        self._plan = [
            (j, s.id, mounting.sign(s.id) * s.direction, s.offset, mounting.offsets.get(s.id, 0))
            for j, joint in enumerate(arm.joints)
            for s in joint.servos
        ]

    def actual(self, q: Sequence[float]) -> dict[int, float]:
        """The actual (physical) pulses of every joint servo at joint angles ``q`` ``(n_joints,)`` rad."""
        return {sid: 2048.0 + m + d * (off + q[j] / RAD_PER_PULSE) for j, sid, d, off, m in self._plan}

    def angles(self) -> np.ndarray:
        """``(n_joints,) float64`` rad: the physical joint angles, from each joint's primary servo."""
        q = np.zeros(self.arm.n_joints)
        seen: set[int] = set()
        for j, sid, d, off, m in self._plan:
            if j not in seen:
                seen.add(j)
                servo = self._servos[sid]
                actual = servo._actual_from_present(servo.get("Present Position"))  # the sim's own frames
                q[j] = ((actual - 2048.0 - m) * d - off) * RAD_PER_PULSE
        return q

    def turn(self, q: Sequence[float], *, duration: float, joints: Iterable[int] | None = None) -> float:
        """A hand turns the joints (all, or ``joints``) from where they are to ``q`` rad over ``duration`` s, each
        servo of a joint with it; the hand keeps holding there.  Returns the clock time the turn ends."""
        which = set(range(self.arm.n_joints)) if joints is None else set(joints)
        target = self.actual(q)
        end = 0.0
        for j, sid, *_ in self._plan:
            if j in which:
                servo = self._servos[sid]
                t0 = servo.clock.now()
                start = servo._actual_from_present(servo.get("Present Position"))
                path = smoothstep_path(t0=t0, start=start, end=target[sid], duration=duration)
                # the hand holds the horn at a physical position, whatever frame the servo reports in meanwhile
                servo.move_by_hand(_held(servo, path))
                end = max(end, t0 + duration)
        return end

    def release(self) -> None:
        """Let go of every joint: each stays where it was left."""
        for servo in self._servos.values():
            servo.move_by_hand(None)
