"""A simulated Dynamixel bus: servos on one half-duplex wire, answering Protocol 2.0 instructions byte for byte.

:meth:`SimBus.feed` takes the bytes a host wrote and returns the status packets the servos send back, each
with the clock time its last byte is on the wire (:class:`ScheduledReply`).  The transports (``sim.transport`` in
process, ``sim.server`` on a pty or TCP) deliver them at that time; :meth:`SimBus.handle` returns them at once
for tests of the protocol alone.

Instructions: PING (broadcast: every servo answers, in ID order), READ, WRITE, REG_WRITE, ACTION,
FACTORY_RESET, REBOOT, CLEAR, SYNC_READ, SYNC_WRITE, FAST_SYNC_READ, BULK_READ, BULK_WRITE, FAST_BULK_READ.
An unknown instruction answers Instruction Error (2); parameters of the wrong length answer Data Length
Error (5).

What the servos answer, as the e-Manual says:

* Status Return Level 0: PING only; 1: PING and reads; 2 (default): everything.
* Broadcast ID: no status for READ, WRITE, REG_WRITE, ACTION, REBOOT, FACTORY_RESET, CLEAR (and
  FACTORY_RESET 0xFF to broadcast is not executed, firmware >= 42).
* Each status starts Return Delay Time after the previous byte on the wire; sync and bulk read replies
  follow each other in the order of the instruction.  A servo that is missing, unplugged or whose reply is
  lost does not stop the later plain replies; in a fast read, it cuts the shared packet short (the later
  servos wait for it), which dynamixel-sdk sees as a corrupt packet.
* A servo listens only at its own Baud Rate item when the line rate is known (``line_baud``).
* Secondary (Shadow) ID (e-Manual, Secondary ID(12); :mod:`sim.rules`): a servo whose Secondary ID is N also
  carries out WRITE and REG_WRITE (RAM area only) and ACTION sent to ID N, and its slot N of a SYNC/BULK WRITE
  when there is none for its own ID, never answering; PING and reads for N are answered by servo N alone.
* Every instruction packet a servo takes as its own (its ID, its Secondary ID, broadcast; good CRC) restarts its
  Bus Watchdog interval, after the servo is brought up to the packet's time (:mod:`sim.watchdog`).
* Bad CRC: the servo addressed by a unicast instruction answers CRC Error (3), as the Protocol 2.0 error
  table defines (set ``crc_error_reply=False`` to make servos ignore such packets instead); broadcast
  packets with a bad CRC are ignored.  Bytes before a header, and broken headers, are skipped.

With the wire model on (``Faults(wire=True)``), a host that starts writing while a status packet is still on
the wire collides with it on a real half-duplex line: the simulator still delivers both, but records the
instruction in :attr:`SimBus.collisions` (and logs a warning), so a test can assert a driver never does it.
"""

from __future__ import annotations

import logging
import math
import operator
import threading
from collections import deque
from collections.abc import Iterable, Sequence
from typing import NamedTuple, Protocol

from drivers.control_table import (
    BROADCAST_ID,
    EEPROM_END,
    MAX_ID,
    RAD_PER_PULSE,
    FactoryReset,
    Instruction,
    StatusError,
)
from retarget.arm.load import load_arm
from retarget.arm.model import Arm
from retarget.control.clock import Clock, MonotonicClock
from retarget.errors import ConfigError
from sim.faults import Faults, ReplyFaults, wire_time
from sim.mount import ArmBody, Mounting
from sim.protocol import Packet, PacketParser, build_fast_read_status, build_status
from sim.servo import SimServo

log = logging.getLogger(__name__)
_by_id = operator.attrgetter("id")
_NO_FAULTS = ReplyFaults()  #: a fast read's reply faults when no slot has a delay (drop and corrupt are per slot)

_READ_INSTRUCTIONS = frozenset({Instruction.READ})
# the instructions a broadcast dispatches on, as constants (reading an Enum member costs ~0.1 us each time)
_PING, _SYNC_WRITE, _BULK_WRITE = Instruction.PING, Instruction.SYNC_WRITE, Instruction.BULK_WRITE
_SYNC_READS = frozenset({Instruction.SYNC_READ, Instruction.FAST_SYNC_READ})
_BULK_READS = frozenset({Instruction.BULK_READ, Instruction.FAST_BULK_READ})
_FAST_READS = frozenset({Instruction.FAST_SYNC_READ, Instruction.FAST_BULK_READ})
_ALWAYS_BROADCAST_SILENT = frozenset(
    {
        Instruction.READ,
        Instruction.WRITE,
        Instruction.REG_WRITE,
        Instruction.ACTION,
        Instruction.REBOOT,
        Instruction.FACTORY_RESET,
        Instruction.CLEAR,
    }
)


class ScheduledReply(NamedTuple):
    """A status packet on the wire: its bytes, the servo that sent it, the clock time its last byte arrives.

    The transports hand ``data`` to the host once the bus clock reaches ``due`` (seconds on the bus clock).
    ``drivers.comm.StatusPacket`` is the host's side: the same packet decoded.  Immutable (a NamedTuple: one per
    reply, on the tick path).
    """

    due: float
    data: bytes
    id: int


Reply = ScheduledReply  #: the first release's name (``sim.Reply``)


class _Sender(Protocol):
    """Who puts a status packet on the wire: a servo, or the first servo of a fast read (:class:`_FastSender`)."""

    @property
    def id(self) -> int: ...

    @property
    def return_delay(self) -> float: ...


class LogEntry(NamedTuple):
    """One instruction the bus received: clock time, target ID, instruction byte, unstuffed parameters.

    Immutable (a NamedTuple: one per instruction, on the tick path)."""

    t: float
    id: int
    instruction: int
    params: bytes
    crc_ok: bool = True


class SimBus:
    """Servos sharing one wire.  Build with :meth:`from_arm` or :meth:`from_ids`; see the module docstring.

    Arguments:
        servos: the servos on the wire (distinct IDs, one clock: ConfigError/ValueError otherwise).
        clock: the bus clock (seconds); default the servos' clock.  A ``VirtualClock`` makes time jump.
        baud: bps of the wire, for the wire-time model (each servo listens at its own Baud Rate item).
        faults: lost, corrupt and late replies, unplugged servos, hardware errors, the wire model.
        crc_error_reply: a unicast packet with a bad CRC answers CRC Error (3); False: it is ignored.

    Reach it as a serial port with :func:`sim.attach` (in process) or :mod:`sim.server` (pty, TCP); or feed
    it bytes directly.  A PING of servo 1, answered with its model number (1060 = XL430-W250) and firmware::

        >>> from retarget.control.clock import VirtualClock
        >>> from sim.protocol import build_instruction
        >>> bus = SimBus.from_ids([1, 2], "XL430-W250", clock=VirtualClock())
        >>> bus.handle(build_instruction(1, Instruction.PING)).hex(" ")
        'ff ff fd 00 01 07 00 55 00 24 04 2e fe df'
        >>> bus.servo(2).get("Present Position")
        2048
    """

    def __init__(
        self,
        servos: Iterable[SimServo],
        *,
        clock: Clock | None = None,
        baud: int = 1_000_000,
        faults: Faults | None = None,
        crc_error_reply: bool = True,
    ):
        self._servos: list[SimServo] = list(servos)
        self.clock: Clock = (
            clock if clock is not None else (self._servos[0].clock if self._servos else MonotonicClock())
        )
        for servo in self._servos:
            if servo.clock is not self.clock:
                raise ValueError(f"servo {servo.id} runs on another clock than the bus")
        ids = [s.id for s in self._servos]
        if len(set(ids)) != len(ids):
            raise ConfigError("Expected distinct servo IDs", key="ids", value=ids)
        self.baud = int(baud)  #: bps of the wire, for the wire-time model
        self.line_baud: int | None = None  #: the host port's rate when known; servos at another rate stay deaf
        self.faults = faults if faults is not None else Faults()
        self.crc_error_reply = crc_error_reply
        self.log: deque[LogEntry] = deque(maxlen=100_000)  #: the last instructions received
        self._parser = PacketParser()
        self._wire_free_at = -math.inf  #: clock time the last byte scheduled on the wire ends
        self._replies_end = -math.inf  #: clock time the last status packet's last byte is on the wire
        #: instructions the host started writing while a status packet was still on the wire (wire model on)
        self.collisions: list[LogEntry] = []
        #: the physical joints of an arm built by :meth:`from_arm` (read them, turn them by hand), else None
        self.body: ArmBody | None = None
        self._lock = threading.RLock()
        self.t_start = self.clock.now()
        self._apply_scheduled_faults()

    # ------------------------------------------------------------------ constructors

    @classmethod
    def from_ids(
        cls,
        ids: Iterable[int],
        model: str = "XL430-W250",
        *,
        clock: Clock | None = None,
        baud: int = 1_000_000,
        return_delay_time: int | None = None,
        position: float = 2048.0,
        boot_time: float = 0.0,
        faults: Faults | None = None,
        crc_error_reply: bool = True,
    ) -> SimBus:
        """Servos of one ``model`` with these IDs, set to ``baud`` (bps); every other item at its factory default.

        ``return_delay_time``: the Return Delay Time item (2 us units; default 250, the factory value);
        ``position``: Present Position of every servo (pulses); ``boot_time`` (s): how long a servo stays
        silent after REBOOT.  The other arguments as :class:`SimBus`.

        >>> SimBus.from_ids(range(1, 4), "XM430-W350", baud=57600)
        SimBus(ids=[1, 2, 3], baud=57600)
        """
        clock = clock if clock is not None else MonotonicClock()
        servos = [
            SimServo(
                model,
                i,
                clock=clock,
                baud=baud,
                return_delay_time=return_delay_time,
                position=position,
                boot_time=boot_time,
            )
            for i in ids
        ]
        return cls(servos, clock=clock, baud=baud, faults=faults, crc_error_reply=crc_error_reply)

    @classmethod
    def from_arm(
        cls,
        arm: Arm | str,
        *,
        clock: Clock | None = None,
        baud: int | None = None,
        pose: Sequence[float] | None = None,
        return_delay_time: int | None = None,
        boot_time: float = 0.0,
        faults: Faults | None = None,
        crc_error_reply: bool = True,
        mount: Mounting | None = None,
    ) -> SimBus:
        """Every servo of ``arm`` (an Arm, or the name or path it loads from): joints, shadows and gripper.

        The servos sit at ``pose`` (joint angles, rad; default the arm's rest pose), read through each servo's
        direction and offset as the driver will configure them; the gripper at its centre.  ``baud`` (bps)
        defaults to the arm's.  ``mount``: servos mounted off the arm file's zero or the other way round
        (:mod:`sim.mount`), as on a hand-built arm.  :attr:`body` then reads and turns the physical joints.
        The other arguments as :meth:`from_ids`.

        >>> SimBus.from_arm("wx250s")
        SimBus(ids=[1, 2, 3, 4, 5, 6, 7, 8, 9], baud=1000000)
        """
        if isinstance(arm, str):
            arm = load_arm(arm)
        clock = clock if clock is not None else MonotonicClock()
        baud = arm.baud if baud is None else baud
        q = list(arm.rest.tolist() if pose is None else pose)
        if len(q) != arm.n_joints:
            raise ConfigError(f"Expected {arm.n_joints} joint angles", key="pose", value=q)
        mount = mount if mount is not None else Mounting()
        unknown = mount.ids - {s.id for j in arm.joints for s in j.servos}
        if unknown:
            raise ConfigError(f"Expected joint servo IDs of {arm.name}", key="mount", value=sorted(unknown))
        servos = []
        for joint, angle in zip(arm.joints, q, strict=True):
            for s in joint.servos:
                sign, m = mount.sign(s.id), mount.offsets.get(s.id, 0)
                actual = 2048 + m + sign * s.direction * (s.offset + angle / RAD_PER_PULSE)
                servos.append(
                    SimServo(
                        s.model,
                        s.id,
                        clock=clock,
                        baud=baud,
                        return_delay_time=return_delay_time,
                        position=actual,
                        boot_time=boot_time,
                    )
                )
        if arm.gripper is not None:
            g = arm.gripper.servo
            servos.append(
                SimServo(
                    g.model, g.id, clock=clock, baud=baud, return_delay_time=return_delay_time, boot_time=boot_time
                )
            )
        bus = cls(servos, clock=clock, baud=baud, faults=faults, crc_error_reply=crc_error_reply)
        bus.body = ArmBody(arm, mount, {s.id: s for s in servos})
        return bus

    def _apply_scheduled_faults(self) -> None:
        for fault in self.faults.hardware:
            self.servo(fault.id).schedule_hardware_error(fault.bits, self.t_start + fault.at)
        for sid, at in self.faults.unplug.items():
            self.servo(sid).unplug(self.t_start + at)

    # ------------------------------------------------------------------ accessors

    @property
    def servos(self) -> tuple[SimServo, ...]:
        return tuple(self._servos)

    @property
    def ids(self) -> tuple[int, ...]:
        return tuple(sorted(s.id for s in self._servos))

    def servo(self, dxl_id: int) -> SimServo:
        """The servo whose ID item is ``dxl_id`` now; KeyError naming the IDs on the bus otherwise."""
        for s in self._servos:
            if s.id == dxl_id:
                return s
        raise KeyError(f"no servo with ID {dxl_id} on the bus (IDs: {list(self.ids)})")

    def __repr__(self) -> str:
        return f"SimBus(ids={list(self.ids)}, baud={self.baud})"

    # ------------------------------------------------------------------ the wire

    def reset(self) -> None:
        """Drop any partial instruction held by the receivers (a port reopened)."""
        with self._lock:
            self._parser.clear()

    def handle(self, request: bytes) -> bytes:
        """Every byte the servos answer to ``request``, in order, ignoring when it would arrive (tests)."""
        return b"".join(r.data for r in self.feed(request))

    def feed(self, data: bytes, now: float | None = None) -> list[ScheduledReply]:
        """Receive ``data`` written at ``now`` (default ``clock.now()``); the replies with their arrival times."""
        with self._lock:
            now = self.clock.now() if now is None else now
            collides = self.faults.wire and now < self._replies_end
            # half duplex: these bytes go out once the wire is free of earlier instructions and replies
            cursor = max(now, self._wire_free_at) if self.faults.wire else now
            cursor += wire_time(len(data), self.baud) if self.faults.wire else 0.0
            replies: list[ScheduledReply] = []
            for packet in self._parser.feed(data):
                entry = LogEntry(cursor, packet.id, packet.instruction, packet.params, packet.crc_ok)
                self.log.append(entry)
                if collides:
                    self.collisions.append(entry)
                    log.warning(
                        "collision: the host wrote %s at t=%.6f s while a status packet was on the wire until %.6f s",
                        _instruction_name(packet.instruction),
                        now,
                        self._replies_end,
                    )
                out = self._dispatch(packet, cursor)
                cursor = self._schedule(out, cursor, replies)
            self._wire_free_at = cursor
            if replies:
                self._replies_end = max(self._replies_end, max(r.due for r in replies))
            return replies

    def _schedule(self, out: list[tuple[_Sender, bytes]], cursor: float, replies: list[ScheduledReply]) -> float:
        """Put each servo's packet on the wire after its return delay; apply reply faults."""
        for servo, packet in out:
            f = servo.reply_faults if isinstance(servo, _FastSender) else self.faults.for_servo(servo.id)
            start = cursor + servo.return_delay
            end = start + (wire_time(len(packet), self.baud) if self.faults.wire else 0.0)
            cursor = end
            if self.faults.roll(f.drop):
                log.debug("dropped reply of servo %d", servo.id)
                continue
            if self.faults.roll(f.corrupt):
                packet = packet[:-1] + bytes((packet[-1] ^ 0x01,))
            replies.append(ScheduledReply(end + f.delay, packet, servo.id))
        return cursor

    def _listeners(self, t: float) -> list[SimServo]:
        line = self.line_baud
        return [s for s in self._servos if s.listening(t) and (line is None or s.baud == line)]

    def _dispatch(self, pkt: Packet, t: float) -> list[tuple[_Sender, bytes]]:
        listeners = self._listeners(t)
        for s in listeners:
            s.packet_at(t, pkt.id, pkt.crc_ok)  # first: a Bus Watchdog due before this packet trips on time
        if pkt.id == BROADCAST_ID:
            if not pkt.crc_ok:
                return []
            return self._broadcast(pkt, sorted(listeners, key=_by_id), t)
        if pkt.id > MAX_ID:
            return []
        target = next((s for s in listeners if s.id == pkt.id), None)
        shadows = [s for s in listeners if s is not target and s.secondary_id == pkt.id]
        if target is None:
            if pkt.crc_ok:
                _run_as_shadows(shadows, pkt)
            return []
        if not pkt.crc_ok:
            if self.crc_error_reply and target.status_return_level >= 2:
                return [(target, build_status(target.id, target.error_byte(StatusError.CRC)))]
            return []
        error, data, reboot = self._unicast(target, pkt)  # may change the ID (WRITE 7, FACTORY_RESET)
        _run_as_shadows(shadows, pkt)
        if error is None:
            return []
        inst = pkt.instruction
        srl = target.status_return_level
        reply: list[tuple[_Sender, bytes]] = []
        if inst == Instruction.PING or (inst in _READ_INSTRUCTIONS and srl >= 1) or srl >= 2:
            reply.append((target, build_status(pkt.id, target.error_byte(error), data)))  # from the ID addressed
        if reboot:
            target.reboot()
        return reply

    def _unicast(self, s: SimServo, pkt: Packet) -> tuple[int | None, bytes, bool]:
        """Execute one instruction on servo ``s``: (error or None for no reply, data, reboot after reply)."""
        inst, p = pkt.instruction, pkt.params
        if inst == Instruction.PING:
            return (StatusError.NONE, s.ping(), False) if not p else (StatusError.DATA_LENGTH, b"", False)
        if inst == Instruction.READ:
            if len(p) != 4:
                return StatusError.DATA_LENGTH, b"", False
            error, data = s.read(_u16(p, 0), _u16(p, 2))
            return error, data, False
        if inst in (Instruction.WRITE, Instruction.REG_WRITE):
            if len(p) < 3:
                return StatusError.DATA_LENGTH, b"", False
            do = s.write if inst == Instruction.WRITE else s.reg_write
            return do(_u16(p, 0), p[2:]), b"", False
        if inst == Instruction.ACTION:
            return s.action(), b"", False
        if inst == Instruction.REBOOT:
            return StatusError.NONE, b"", True
        if inst == Instruction.FACTORY_RESET:
            if len(p) != 1:
                return StatusError.DATA_LENGTH, b"", False
            return s.factory_reset(p[0]), b"", False
        if inst == Instruction.CLEAR:
            return s.clear(p), b"", False
        return StatusError.INSTRUCTION, b"", False

    def _broadcast(self, pkt: Packet, servos: list[SimServo], t: float) -> list[tuple[_Sender, bytes]]:
        inst, p = pkt.instruction, pkt.params
        if inst == _PING:
            return [(s, build_status(s.id, s.error_byte(StatusError.NONE), s.ping())) for s in servos]
        if inst in _ALWAYS_BROADCAST_SILENT:
            if inst == Instruction.FACTORY_RESET and p[:1] == bytes((FactoryReset.ALL,)):
                return []  # not executed for broadcast, firmware >= 42
            for s in servos:
                _, _, reboot = self._unicast(s, pkt)
                if reboot:
                    s.reboot()
            return []
        if inst == _SYNC_WRITE:
            return self._sync_write(p, servos)
        if inst == _BULK_WRITE:
            return self._bulk_write(p, servos)
        by_id = {s.id: s for s in servos}
        if inst in _SYNC_READS:
            if len(p) < 5:
                return []
            address, length = _u16(p, 0), _u16(p, 2)
            requests = [(i, address, length) for i in p[4:]]
        elif inst in _BULK_READS:
            if len(p) < 5 or len(p) % 5:
                return []
            requests = [(p[k], _u16(p, k + 1), _u16(p, k + 3)) for k in range(0, len(p), 5)]
        else:
            return []  # unknown broadcast instruction: nobody answers
        if inst in _FAST_READS:
            return self._fast_read(requests, by_id)
        out: list[tuple[_Sender, bytes]] = []
        for dxl_id, address, length in requests:
            servo = by_id.get(dxl_id)
            if servo is None or servo.status_return_level < 1:
                continue
            error, data = servo.read(address, length)
            out.append((servo, build_status(servo.id, servo.error_byte(error), data)))
        return out

    def _sync_write(self, p: bytes, servos: list[SimServo]) -> list[tuple[_Sender, bytes]]:
        if len(p) < 4:
            return []
        address, length = _u16(p, 0), _u16(p, 2)
        step = length + 1
        if length == 0 or (len(p) - 4) % step:
            return []
        _write_slots(servos, {p[k]: (address, p[k + 1 : k + step]) for k in range(4, len(p), step)})
        return []

    def _bulk_write(self, p: bytes, servos: list[SimServo]) -> list[tuple[_Sender, bytes]]:
        slots: dict[int, tuple[int, bytes]] = {}
        k = 0
        while k + 5 <= len(p):
            dxl_id, address, length = p[k], _u16(p, k + 1), _u16(p, k + 3)
            data = p[k + 5 : k + 5 + length]
            if len(data) != length:
                break
            slots.setdefault(dxl_id, (address, data))
            k += 5 + length
        _write_slots(servos, slots)
        return []

    def _fast_read(
        self, requests: list[tuple[int, int, int]], by_id: dict[int, SimServo]
    ) -> list[tuple[_Sender, bytes]]:
        """One shared packet; each servo's slot is ERR ID DATA CRC.  A silent servo cuts the packet there."""
        slots = []
        present: list[SimServo] = []
        for dxl_id, address, length in requests:
            s = by_id.get(dxl_id)
            if s is None or not s.model.fast_sync_read or s.status_return_level < 1:
                break
            error, data = s.read(address, length)
            slots.append((s.error_byte(error), dxl_id, data if not error else bytes(length)))
            present.append(s)
        if not present:
            return []
        full_slots = slots + [(0, dxl_id, bytes(length)) for dxl_id, _, length in requests[len(slots) :]]
        packet = build_fast_read_status(full_slots)
        cut = 8 + sum(len(d) + 4 for _, _, d in slots)
        faults = self.faults
        if faults.servos:
            f = [faults.for_servo(dxl_id) for _, dxl_id, _ in slots]
            faulty = not all(x.drop <= 0.0 and x.corrupt <= 0.0 for x in f)  # else no draws, nothing to cut or flip
            delay = max(x.delay for x in f)
        else:  # the bus's faults for every slot
            f = [faults.bus] * len(slots)
            faulty = not (faults.bus.drop <= 0.0 and faults.bus.corrupt <= 0.0)
            delay = faults.bus.delay
        # faults per slot: a dropped slot ends the packet there; a corrupt slot flips its CRC byte
        end = cut
        offset = 8
        for k, (_, _, data) in enumerate(slots if faulty else ()):
            slot_end = offset + len(data) + 4
            if self.faults.roll(f[k].drop):
                end = offset
                break
            if self.faults.roll(f[k].corrupt):
                packet = packet[: slot_end - 1] + bytes((packet[slot_end - 1] ^ 0x01,)) + packet[slot_end:]
            offset = slot_end
        if end <= 8:
            return []
        # the packet leaves as one stream; attribute it to the first servo (its return delay starts it)
        return [(_FastSender(present[0], ReplyFaults(delay=delay) if delay else _NO_FAULTS), packet[:end])]


class _FastSender:
    """The first servo of a fast read, with reply faults already applied per slot."""

    def __init__(self, servo: SimServo, reply_faults: ReplyFaults):
        self.id = BROADCAST_ID
        self.return_delay = servo.return_delay
        self.reply_faults = reply_faults


def _write_slots(servos: list[SimServo], slots: dict[int, tuple[int, bytes]]) -> None:
    """SYNC/BULK WRITE: each servo writes the slot for its ID, else (as a shadow, RAM only) its Secondary ID's."""
    for s in servos:
        slot = slots.get(s.id)
        if slot is not None:
            s.write(*slot)
        elif s.secondary_id in slots:
            address, data = slots[s.secondary_id]
            if address >= EEPROM_END:  # the EEPROM area cannot be changed through a Secondary ID (sim.rules)
                s.write(address, data)


def _run_as_shadows(shadows: list[SimServo], pkt: Packet) -> None:
    """Servos whose Secondary ID a unicast packet is for: WRITE/REG_WRITE (RAM only) and ACTION, silently."""
    inst, p = pkt.instruction, pkt.params
    for s in shadows:
        if inst in (Instruction.WRITE, Instruction.REG_WRITE) and len(p) >= 3 and _u16(p, 0) >= EEPROM_END:
            (s.write if inst == Instruction.WRITE else s.reg_write)(_u16(p, 0), p[2:])
        elif inst == Instruction.ACTION:
            s.action()


def _u16(p: bytes, k: int) -> int:
    return p[k] | p[k + 1] << 8


def _instruction_name(code: int) -> str:
    try:
        return Instruction(code).name
    except ValueError:
        return f"instruction 0x{code:02x}"
