"""The servos of an arm during calibration: pinged, checked against the arm file, limp, read in raw pulses.

:class:`ServoLink` opens the port with the driver's :class:`~drivers.comm.Link` (retries, errors naming the
servos).  Readings are the shaft's *actual* position in pulses: Present Position with the servo's own Homing
Offset and Drive Mode undone (``actual = present - homing``, mirrored ``4096 - ...`` when Drive Mode bit 0 is
set), so a calibration does not depend on what an earlier program left in those registers.  Nothing is written
but Torque Enable.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

from drivers.comm import Link
from drivers.control_table import MODEL_BY_NUMBER, DriveMode, common_register
from drivers.port import open_port
from drivers.units import signed32
from retarget.arm.model import Arm
from retarget.errors import BusError

__all__ = ["ServoInfo", "ServoLink"]

log = logging.getLogger(__name__)

_PRESENT = common_register("Present Position")
_HOMING = common_register("Homing Offset")
_DRIVE = common_register("Drive Mode")
_TORQUE = common_register("Torque Enable")
_FIRMWARE = common_register("Firmware Version")
PULSES = 4096


@dataclass(frozen=True)
class ServoInfo:
    """What a servo said about itself: model (name and number), Firmware Version (6), Drive Mode, Homing Offset."""

    id: int
    model: str
    model_number: int
    firmware: int
    drive_mode: int
    homing: int


class ServoLink:
    """The joint servos of ``arm`` (and its gripper's, for torque) on ``port``; a context manager.

    >>> from retarget.arm.load import load_arm
    >>> with ServoLink(load_arm("koch"), "sim://koch?clock=virtual&mount=2:100") as link:
    ...     info = link.check()       # ping every servo, compare models with the arm file
    ...     link.torque_off()
    ...     link.read_actual()[2]     # servo 2's horn sits 100 pulses off
    2148
    """

    def __init__(self, arm: Arm, port: str, *, baud: int | None = None, retries: int = 2):
        self.arm = arm
        self.port_name = port
        self.baud = arm.baud if baud is None else baud
        self.retries = retries
        self.joint_ids = tuple(s.id for j in arm.joints for s in j.servos)
        self.all_ids = arm.servo_ids
        self.info: dict[int, ServoInfo] = {}
        self._link: Link | None = None

    def __enter__(self) -> ServoLink:
        self.open()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def open(self) -> None:
        if self._link is None:
            self._link = Link(open_port(self.port_name, self.baud), retries=self.retries)

    def close(self) -> None:
        if self._link is not None:
            self._link.release()
            self._link.port.closePort()
            self._link = None

    @property
    def link(self) -> Link:
        if self._link is None:
            raise BusError(f"{self.port_name} is not open")
        return self._link

    def check(self) -> dict[int, ServoInfo]:
        """Ping every servo of the arm and compare its model with the arm file's; BusError naming the missing
        servos, or the servos of another model."""
        expected = {s.id: s.model for j in self.arm.joints for s in j.servos}
        if self.arm.gripper is not None:
            expected[self.arm.gripper.servo.id] = self.arm.gripper.servo.model
        missing, wrong = [], []
        for dxl_id, model in expected.items():
            reply = self.link.ping(dxl_id)
            if reply is None:
                missing.append(dxl_id)
                continue
            found = MODEL_BY_NUMBER.get(reply.model_number)
            name = found.name if found is not None else f"model number {reply.model_number}"
            if name != model:
                wrong.append((dxl_id, model, name))
                continue
            self.info[dxl_id] = ServoInfo(
                dxl_id,
                name,
                reply.model_number,
                self.link.read_register(dxl_id, _FIRMWARE),  # the PING's firmware byte, read as the register (6)
                self.link.read_register(dxl_id, _DRIVE),
                signed32(self.link.read_register(dxl_id, _HOMING)),
            )
        if missing:
            ids = ", ".join(map(str, missing))
            raise BusError(
                f"servo(s) {ids} did not answer on {self.port_name} at {self.baud} baud: check power and cables, "
                f"then `retarget scan --port {self.port_name} --all-bauds`",
                ids=missing,
            )
        if wrong:
            text = "; ".join(f"servo {i} is a {got}, the arm file says {want}" for i, want, got in wrong)
            raise BusError(f"Expected the arm file's servo models: {text}", ids=[w[0] for w in wrong])
        return self.info

    def torque_off(self) -> None:
        """Torque off for every servo of the arm that answered :meth:`check` (the arm goes limp)."""
        for dxl_id in self.info:
            self.link.write_register(dxl_id, _TORQUE, 0)

    def read_actual(self, ids: tuple[int, ...] | None = None) -> dict[int, int]:
        """Each joint servo's actual shaft position, pulses (Homing Offset and Drive Mode undone; with torque off
        a servo may count past one turn)."""
        out = {}
        for dxl_id in self.joint_ids if ids is None else ids:
            info = self.info[dxl_id]
            p = signed32(self.link.read_register(dxl_id, _PRESENT)) - info.homing
            out[dxl_id] = PULSES - p if info.drive_mode & int(DriveMode.REVERSE) else p
        return out
