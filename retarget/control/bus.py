"""The small interface the control loop needs from a servo bus.

The control loop (``retarget.control.loop``) only ever talks to an object that
follows :class:`Bus`.  ``drivers.DynamixelBus`` implements it on dynamixel-sdk;
anything else that moves joints (another servo family, a physics simulator)
can implement it too.  Angles are joint angles of the arm description, in
radians, ordered as ``Arm.joint_names`` (the gripper is not part of them).
"""

from __future__ import annotations

import contextlib
import enum
import logging
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np

log = logging.getLogger(__name__)


class ShutdownMode(enum.Enum):
    """What the bus does with the arm on close, Ctrl-C or an unrecoverable fault.

    In every mode new goals stop first.
    """

    HOLD = "hold"  #: keep torque on at the last goal
    REST = "rest"  #: move to the arm's rest pose at a safe speed, then torque off
    OFF = "off"  #: torque off at once (the arm falls under gravity)


@dataclass(frozen=True)
class BusStatus:
    """Counters and health of a bus since it connected."""

    connected: bool
    ticks: int = 0  #: write+read cycles completed
    retries: int = 0  #: communication attempts repeated after a failure
    errors: int = 0  #: failures that were raised after the retries ran out
    hardware_errors: Mapping[int, tuple[str, ...]] = field(default_factory=dict)  #: servo ID -> alert names
    #: servo reads that came back stale: a servo still silent after the retries, its last position standing in
    stale_reads: int = 0
    stale_ticks: int = 0  #: position reads with at least one stale servo
    worst_stale: int = 0  #: the longest run of consecutive stale reads of one servo
    reboots: int = 0  #: servos rebooted and configured again after a hardware error (recover=True)
    late_packets: int = 0  #: status packets that came after their transaction's timeout (dropped or discarded)


@runtime_checkable
class Bus(Protocol):
    """A connected set of servos that drive the joints of one arm."""

    @property
    def joint_names(self) -> tuple[str, ...]: ...

    def connect(self) -> None:
        """Open the port, check the servos against the arm, configure them and enable torque."""

    def close(self) -> None:
        """Run the shutdown sequence and release the port.  Safe to call twice."""

    def read_positions(self) -> np.ndarray:
        """Present joint angles, ``(n_joints,) float64``, radians.

        Raises ``BusError``; never returns 0 for a failed read.  A bus may return a servo's last position for a
        read it missed, counted in ``status().stale_reads``, and raise once it was stale too long.
        """

    def request_positions(self) -> None:
        """The first half of :meth:`read_positions`: start the read and return without waiting for it.

        The control loop computes its next tick while the replies are on the wire, then calls
        :meth:`collect_positions`; no other call comes in between.  A bus that cannot split a read may
        do nothing here and the whole read in ``collect_positions``.
        """

    def collect_positions(self) -> np.ndarray:
        """The second half of :meth:`read_positions`: the positions of the read ``request_positions`` started."""

    def write_goals(self, q: np.ndarray) -> None:
        """Send goal angles ``(n_joints,) float64`` radians to every servo in one write."""

    def exchange(self, q: np.ndarray) -> np.ndarray:
        """One pipelined tick: the positions of the read in flight, then goals ``q`` sent and the next read started.

        The same as :meth:`collect_positions`, :meth:`write_goals` ``(q)`` and :meth:`request_positions` in turn
        (what a bus of one arm does); a bus over several arms (``retarget.rig.RigBus``) goes arm by arm, so each
        arm's next write follows its own replies without waiting for the others'.  Returns ``(n_joints,) float64``
        radians; raises as those calls do.
        """

    def set_torque(self, enabled: bool) -> None:
        """Enable or disable torque on every servo of the arm."""

    def status(self) -> BusStatus:
        """Counters and health since connect."""


@contextlib.contextmanager
def connected(bus: Bus) -> Iterator[Bus]:
    """Connect ``bus`` for a ``with`` block and always close it, so its shutdown sequence runs.

    When the block fails (a bus error, Ctrl-C), a failure of the shutdown itself
    is logged, not raised: the error that stopped the run is the one the user
    must see, not a consequence of it such as a torque-off that also got no reply.
    """
    bus.connect()
    try:
        yield bus
    except BaseException:
        close_after_failure(bus)
        raise
    bus.close()


def close_after_failure(bus: Bus) -> None:
    """Close ``bus`` while another exception is in flight: log a failing shutdown instead of masking that exception."""
    try:
        bus.close()
    except Exception as exc:  # noqa: BLE001 - the original failure is re-raised by the caller
        log.error("shutdown after the failure also failed: %s", exc)
