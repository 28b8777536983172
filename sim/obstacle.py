"""An object in a simulated servo's way: the horn stops at it, the motor pushes, and a servo that pushes too hard
for too long raises Overload, as a gripper closing on something does.

``block=ID:PULSES,...`` in a ``sim://`` URL puts a wall at Present Position ``PULSES``
of servo ``ID``, on the side away from where the servo is when the bus starts: the horn moves freely on its side
and stops dead at the wall.  While it is held there and its goal lies beyond, the motor pushes:

* current-based position mode (5): with the current bounded by Goal Current (capped by Current Limit), so
  Present Current reads that bound (e-Manual, Goal Current(102));
* position modes (3, 4): the position controller winds up to full output, the stall current (or 100 % load),
  bounded only by PWM Limit (e-Manual PWM Limit(36): it caps the output in every mode).

A push of at least ``OVERLOAD_SHARE`` of the stall current for ``OVERLOAD_AFTER_S`` raises the Overload hardware
error (bit 5, which the factory Shutdown mask includes: torque goes off), as real servos do when "a persistent load
exceeds the maximum output" (e-Manual, Hardware Error Status(70)).  Both numbers are this simulator's assumptions.

>>> parse_blocks(["9:2300,15:1500"], source="sim://vx300s?block=9:2300,15:1500")
{9: 2300, 15: 1500}
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from retarget.errors import ConfigError

BLOCK_KEYS = frozenset({"block"})  #: the ``sim://`` URL option of this module
OVERLOAD_SHARE = 0.5  #: share of the stall current a sustained push must reach to overload (assumption)
OVERLOAD_AFTER_S = 1.0  #: s of such a push before Overload (assumption)


@dataclass(frozen=True)
class Obstacle:
    """A wall at ``actual`` (physical pulses); the horn stays on the side of ``side`` (+1 above, -1 below)."""

    actual: float
    side: int

    def clamp(self, p: float, v: float, a: float) -> tuple[float, float, float, bool]:
        """``(p, v, a, touching)``: the state held back at the wall, and whether the horn is at it."""
        if (p - self.actual) * self.side > 0.0:
            return p, v, a, False
        return self.actual, 0.0, 0.0, True


def parse_blocks(values: Sequence[str], *, source: str) -> dict[int, int]:
    """``["ID:PULSES,..."]`` -> ``{id: pulses}``; ConfigError naming ``block`` and the bad item otherwise."""
    out: dict[int, int] = {}
    for text in values:
        for item in filter(None, (t.strip() for t in text.split(","))):
            sid, sep, pulses = item.partition(":")
            try:
                dxl_id, at = int(sid), int(pulses)
            except ValueError:
                dxl_id, at = -1, -1
            if not sep or not 0 <= dxl_id <= 252 or not 0 <= at <= 4095:
                raise ConfigError(
                    "Expected ID:PULSES (ID 0..252, pulses 0..4095)", path=source, key="block", value=item
                )
            out[dxl_id] = at
    return out


def blocks_from_query(query: Mapping[str, list[str]], *, source: str) -> dict[int, int]:
    """The ``block=`` option of a parsed ``sim://`` query (``urllib.parse.parse_qs``)."""
    return parse_blocks(query.get("block", []), source=source)
