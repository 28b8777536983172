"""Protocol 2.0 transactions on dynamixel-sdk with bounded retries and errors that name the servos.

:class:`Link` wraps one open port and the SDK's ``Protocol2PacketHandler`` (:class:`drivers.packets.PacketHandler`:
its CRC and byte stuffing faster, the same bytes).  Every transaction is the SDK's own packet code; what this module
adds is what the SDK leaves to its callers:

* a failed transaction is retried ``retries`` times, then raised as a :class:`~retarget.errors.BusError`
  naming the servo IDs that did not answer (never a value of 0 for a failed read);
* status error bytes are decoded into names ("access error"); the Alert bit is collected in
  :attr:`Link.alerts` for the caller to read Hardware Error Status;
* sync reads collect the status packets by ID, so a missing servo is named, not just "a timeout"; a corrupt
  packet is skipped and the replies after it are kept; a retry asks again only the servos still missing;
* late status packets (a reply that came after its transaction's timeout) are never taken for a later
  transaction's reply: the bytes waiting before an instruction are dropped (``UrlPortHandler.clearPort``), every
  packet is matched to its request by ID, expected set and length, and after a timeout the group reads ask a few
  extra bytes (a different length per try, :data:`PAD_CYCLE`) for :data:`PAD_HORIZON` s, so a late reply to an
  earlier try has the wrong length; :attr:`Link.late_packets` counts them all;
* a group read can be split in two (:meth:`Link.send_group_read`, then :meth:`Link.receive_group_read`), so
  the host can work while the status packets are on the wire.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import NamedTuple

from dynamixel_sdk import COMM_SUCCESS
from dynamixel_sdk.robotis_def import (
    COMM_NOT_AVAILABLE,
    COMM_PORT_BUSY,
    COMM_RX_CORRUPT,
    COMM_RX_FAIL,
    COMM_RX_TIMEOUT,
    COMM_TX_ERROR,
    COMM_TX_FAIL,
)

from drivers.control_table import ALERT_BIT, BROADCAST_ID, Instruction, Register, StatusError
from drivers.packets import PacketHandler
from drivers.port import PortHandler
from retarget.errors import BusError

log = logging.getLogger(__name__)

# Status packet layout (after byte-unstuffing): FF FF FD 00 ID LEN_L LEN_H 0x55 ERR PARAMS... CRC_L CRC_H
_PKT_ID = 4
_PKT_LEN_L = 5
_PKT_LEN_H = 6
_PKT_INSTRUCTION = 7
_PKT_ERROR = 8
_PKT_PARAMS = 9
_INST_STATUS = Instruction.STATUS.value
_NOT_ALERT = 0xFF & ~ALERT_BIT  #: the error-number bits of a status ERR byte

#: After a group-read try in which a servo was silent, its reply may still come, late: the next tries ask 1, 2, ...
#: PAD_CYCLE extra bytes per servo (a new length per silent try, dropped from the data), so a late reply to an
#: earlier try has the wrong length and is discarded, not taken for this one's.  Covers replies up to
#: PAD_CYCLE silent tries late (about PAD_CYCLE x the SDK's timeout).
PAD_CYCLE = 7
#: s without a silent try after which group reads ask the plain length again (a reply later than this is not told)
PAD_HORIZON = 1.0

COMM_RESULT_NAMES: Mapping[int, str] = {
    COMM_PORT_BUSY: "port busy",
    COMM_TX_FAIL: "failed to send the instruction packet",
    COMM_RX_FAIL: "failed to receive a status packet",
    COMM_TX_ERROR: "bad instruction packet",
    COMM_RX_TIMEOUT: "no status packet",
    COMM_RX_CORRUPT: "corrupt status packet",
    COMM_NOT_AVAILABLE: "not available",
}

STATUS_ERROR_NAMES: Mapping[int, str] = {
    StatusError.RESULT_FAIL: "result fail",
    StatusError.INSTRUCTION: "instruction error",
    StatusError.CRC: "CRC error",
    StatusError.DATA_RANGE: "data range error",
    StatusError.DATA_LENGTH: "data length error",
    StatusError.DATA_LIMIT: "data limit error",
    StatusError.ACCESS: "access error",
}


def comm_result_name(result: int) -> str:
    """The SDK's ``COMM_*`` result as a short phrase ("no status packet")."""
    return COMM_RESULT_NAMES.get(result, f"communication result {result}")


def status_error_name(error: int) -> str | None:
    """The error number of a status ERR byte as a name, ignoring the Alert bit; None when there is none."""
    number = error & ~ALERT_BIT
    if number == 0:
        return None
    return STATUS_ERROR_NAMES.get(number, f"status error {number}")


class StatusPacket(NamedTuple):
    """One servo's status packet, decoded: the servo's ID, its ERR byte and the data bytes it returned.

    Immutable; a NamedTuple rather than a frozen dataclass because every tick builds one per servo and this
    is half the cost.  (``sim.ScheduledReply`` is the simulator's side: the raw packet and when it arrives.)
    """

    id: int
    error: int
    data: bytes

    @property
    def alert(self) -> bool:
        return bool(self.error & ALERT_BIT)


Reply = StatusPacket  #: the first release's name


@dataclass(frozen=True)
class PingReply:
    id: int
    model_number: int
    firmware: int


class Link:
    """An open port plus the Protocol 2.0 packet handler, with retries and counters.

    ``retries``: how many times a failed transaction is repeated before it is raised (0 = no retry).
    """

    def __init__(self, port: PortHandler, *, retries: int = 3):
        if retries < 0:
            raise ValueError(f"Expected retries >= 0, got {retries}")
        self.port = port
        self.ph = PacketHandler()  #: the SDK's Protocol 2.0 handler, its CRC and stuffing faster (drivers.packets)
        self.retries = retries
        self.retry_count = 0  #: transactions repeated after a failure
        self.error_count = 0  #: failures raised after the retries ran out
        self.alerts: set[int] = set()  #: IDs whose status packets had the Alert bit, until the caller clears it
        self.fast_failures = 0  #: consecutive FAST_SYNC_READs that failed as a whole
        self.corrupt_count = 0  #: corrupt status packets skipped in group reads (the replies after them are kept)
        # reply loss per servo in group reads (each try counts); a try every servo answered only counts its IDs
        self.asked: dict[int, int] = {}  #: servo ID -> tries of a group read that was not clean at once
        self.answered: dict[int, int] = {}  #: servo ID -> replies it sent to those
        self.clean_tries: dict[tuple[int, ...], int] = {}  #: IDs of a group read -> first tries all answered
        self.late_count = 0  #: late status packets discarded by the matching (see :attr:`late_packets`)
        self._pad = 0  #: extra bytes the next group read asks per servo (0: none; see PAD_CYCLE)
        self._pad_at = 0.0  #: time.monotonic() of the last silent try
        self._sent_pad = 0  #: the extra bytes of the group read on the wire

    @property
    def late_packets(self) -> int:
        """Status packets that came after their transaction's timeout: dropped before an instruction (by a
        :class:`~drivers.port.UrlPortHandler`), or not matching the request they arrived in (an ID not asked,
        an ID that already answered, or the wrong length), and discarded."""
        return self.late_count + int(getattr(self.port, "stale_packets", 0))

    @property
    def baud(self) -> int:
        return int(self.port.getBaudRate())

    def release(self) -> None:
        """Forget a transaction cut short (Ctrl-C inside the SDK leaves the port marked busy) and drop stale bytes."""
        self.port.is_using = False
        try:
            self.port.clearPort()
        except Exception as exc:  # noqa: BLE001 - best effort before a shutdown sequence
            log.debug("clearPort failed: %s", exc)

    def reply_loss(self, dxl_id: int) -> tuple[int, int]:
        """``(lost, asked)``: group-read tries since the link opened that asked servo ``dxl_id``, and how many of
        them got no valid reply from it (silent, corrupt, or a status error)."""
        clean = sum(n for ids, n in self.clean_tries.items() if dxl_id in ids)
        asked = self.asked.get(dxl_id, 0)
        return asked - self.answered.get(dxl_id, 0), asked + clean

    def _note(self, reply: StatusPacket) -> StatusPacket:
        if reply.alert:
            self.alerts.add(reply.id)
        return reply

    def _retrying(self, what: str, ids: Iterable[int], reason: str) -> None:
        self.retry_count += 1
        log.debug("servo %s: %s: %s; retrying", ", ".join(map(str, ids)), what, reason)

    def _fail(self, message: str, ids: Iterable[int]) -> BusError:
        self.error_count += 1
        return BusError(message, ids=sorted(ids))

    # ------------------------------------------------------------------ single servo

    def _txrx(self, tx: list[int], n_params: int) -> tuple[list[int], int, int]:
        """The SDK's ``txRxPacket`` (the reply of the servo ``tx`` addresses), taking only a status packet with
        ``n_params`` data bytes: one of another length is a late reply to an earlier request, discarded and
        counted, and the wait for this one's goes on (within the same timeout)."""
        rx, result, error = self.ph.txRxPacket(self.port, tx)
        while result == COMM_SUCCESS and (rx[_PKT_LEN_L] | rx[_PKT_LEN_H] << 8) - 4 != n_params:
            self.late_count += 1
            log.debug("late status packet from servo %d (%d bytes) discarded", rx[_PKT_ID], len(rx))
            while True:
                rx, result = self.ph.rxPacket(self.port, False)
                if result != COMM_SUCCESS or rx[_PKT_ID] == tx[_PKT_ID]:
                    break
            error = rx[_PKT_ERROR] if result == COMM_SUCCESS else 0
        return rx, result, error

    def _write_once(self, dxl_id: int, address: int, data: Sequence[int]) -> tuple[int, int]:
        """One WRITE and its status packet: ``(result, error)`` as the SDK's ``writeTxRx``."""
        tx = [0] * (12 + len(data))
        tx[_PKT_ID] = dxl_id
        tx[_PKT_LEN_L] = (5 + len(data)) & 0xFF
        tx[_PKT_LEN_H] = (5 + len(data)) >> 8
        tx[_PKT_INSTRUCTION] = Instruction.WRITE.value
        tx[_PKT_PARAMS - 1] = address & 0xFF
        tx[_PKT_PARAMS] = address >> 8
        tx[_PKT_PARAMS + 1 : _PKT_PARAMS + 1 + len(data)] = data
        _, result, error = self._txrx(tx, 0)
        return result, error

    def ping_once(self, dxl_id: int) -> PingReply | None:
        """One PING; None when no status packet came back (the SDK's own ``ping``, plus the firmware byte)."""
        tx = [0] * 10
        tx[_PKT_ID] = dxl_id
        tx[_PKT_LEN_L] = 3
        tx[_PKT_INSTRUCTION] = Instruction.PING.value
        rx, result, error = self._txrx(tx, 3)
        if result != COMM_SUCCESS:
            return None
        self._note(StatusPacket(dxl_id, error, b""))
        return PingReply(dxl_id, rx[_PKT_PARAMS] | (rx[_PKT_PARAMS + 1] << 8), rx[_PKT_PARAMS + 2])

    def ping(self, dxl_id: int) -> PingReply | None:
        """PING with retries; None when the servo never answered."""
        for attempt in range(self.retries + 1):
            if attempt:
                self._retrying("PING", [dxl_id], "no status packet")
            reply = self.ping_once(dxl_id)
            if reply is not None:
                return reply
        return None

    def read(self, dxl_id: int, address: int, length: int, *, what: str = "") -> StatusPacket:
        """READ ``length`` bytes at ``address`` with retries; BusError naming the servo when it fails."""
        last = ""
        for attempt in range(self.retries + 1):
            if attempt:
                self._retrying(f"reading {what or address}", [dxl_id], last)
            tx = [0] * 14
            tx[_PKT_ID] = dxl_id
            tx[_PKT_LEN_L] = 7
            tx[_PKT_INSTRUCTION] = Instruction.READ.value
            tx[_PKT_PARAMS - 1 : _PKT_PARAMS + 3] = [address & 0xFF, address >> 8, length & 0xFF, length >> 8]
            rx, result, error = self._txrx(tx, length)
            data = rx[_PKT_PARAMS : _PKT_PARAMS + length] if result == COMM_SUCCESS else []
            if result == COMM_SUCCESS and len(data) == length:
                reply = self._note(StatusPacket(dxl_id, error, bytes(data)))
                name = status_error_name(error)
                if name is None:
                    return reply
                last = name
                continue
            last = comm_result_name(result) if result != COMM_SUCCESS else "short status packet"
        raise self._fail(f"{last} reading {what or f'address {address}'} at {self.baud} baud", [dxl_id])

    def read_register(self, dxl_id: int, reg: Register) -> int:
        return reg.decode(self.read(dxl_id, reg.address, reg.size, what=reg.name).data)

    def write(self, dxl_id: int, address: int, data: bytes, *, what: str = "") -> StatusPacket:
        """WRITE with retries; BusError naming the servo and the status error ("access error") when it fails."""
        last = ""
        for attempt in range(self.retries + 1):
            if attempt:
                self._retrying(f"writing {what or address}", [dxl_id], last)
            result, error = self._write_once(dxl_id, address, data)
            if result == COMM_SUCCESS:
                reply = self._note(StatusPacket(dxl_id, error, b""))
                name = status_error_name(error)
                if name is None:
                    return reply
                if error & ~ALERT_BIT in (StatusError.ACCESS, StatusError.DATA_RANGE, StatusError.DATA_LIMIT):
                    last = name  # the servo refused the value: repeating it cannot help
                    break
                last = name
                continue
            last = comm_result_name(result)
        raise self._fail(f"{last} writing {what or f'address {address}'}", [dxl_id])

    def write_register(self, dxl_id: int, reg: Register, value: int) -> None:
        self.write(dxl_id, reg.address, reg.encode(int(value)), what=f"{reg.name} = {int(value)}")

    def write_maybe_unacknowledged(self, dxl_id: int, reg: Register, value: int) -> None:
        """WRITE that may get no status packet (Status Return Level itself): silence is not an error.

        Retried like :meth:`write` on a corrupt or missing reply: once the servo took the value it answers the
        repeat (so a lost reply costs a retry, not the start).  Silence on every try is accepted: a servo at
        Status Return Level 0 or 1 that ignored it is named by the next transaction.  A status error raises.
        Each reply, when there is one, is waited for, so it cannot be mistaken for the next transaction's.
        """
        data = list(reg.encode(int(value)))
        what = f"{reg.name} = {int(value)}"
        result = COMM_SUCCESS
        silent = True
        for attempt in range(self.retries + 1):
            if attempt:
                self._retrying(f"writing {what}", [dxl_id], comm_result_name(result))
            result, error = self._write_once(dxl_id, reg.address, data)
            if result == COMM_SUCCESS:
                self._note(StatusPacket(dxl_id, error, b""))
                name = status_error_name(error)
                if name is not None:
                    raise self._fail(f"{name} writing {what}", [dxl_id])
                return
            silent = silent and result == COMM_RX_TIMEOUT
        if not silent:  # something answered, never cleanly
            raise self._fail(f"{comm_result_name(result)} writing {what}", [dxl_id])

    def reboot(self, dxl_id: int) -> None:
        """REBOOT with retries (the servo answers, then restarts: it is silent for a moment after)."""
        result = COMM_SUCCESS
        for attempt in range(self.retries + 1):
            if attempt:
                self._retrying("REBOOT", [dxl_id], comm_result_name(result))
            result, _ = self.ph.reboot(self.port, dxl_id)
            if result == COMM_SUCCESS:
                return
        raise self._fail(f"{comm_result_name(result)} to REBOOT", [dxl_id])

    # ------------------------------------------------------------------ groups

    def sync_write(self, address: int, size: int, values: Mapping[int, bytes]) -> None:
        """One SYNC_WRITE of ``size`` bytes per servo (no status packets come back)."""
        param: list[int] = []
        for dxl_id, data in values.items():
            param.append(dxl_id)
            param.extend(data)
        result = self.ph.syncWriteTxOnly(self.port, address, size, param, len(param))
        if result != COMM_SUCCESS:
            raise self._fail(f"{comm_result_name(result)} (sync write at address {address})", values)

    def sync_write_param(self, address: int, size: int, param: list[int]) -> None:
        """One SYNC_WRITE from the SDK's parameter list: per servo its ID then ``size`` data bytes, little-endian.

        The tick path's form of :meth:`sync_write` (no mapping or bytes objects to build).
        """
        result = self.ph.syncWriteTxOnly(self.port, address, size, param, len(param))
        if result != COMM_SUCCESS:
            raise self._fail(f"{comm_result_name(result)} (sync write at address {address})", param[:: size + 1])

    def _collect(self, lengths: Mapping[int, int], pad: int = 0) -> dict[int, StatusPacket]:
        """Status packets after a SYNC_READ or BULK_READ, matched by ID until all came or the timeout passed.

        ``pad``: the extra bytes each servo was asked (dropped from the data).  A packet from an ID not asked,
        from one that already answered, or of another length is late (a reply to an earlier request): counted
        in :attr:`late_count` and discarded.
        """
        replies: dict[int, StatusPacket] = {}
        while len(replies) < len(lengths):
            rx, result = self.ph.rxPacket(self.port, False)
            if result != COMM_SUCCESS:
                if result == COMM_RX_CORRUPT and _whole_packet(rx):
                    # a bad CRC on one whole packet: the SDK consumed exactly it, the next servo's reply follows
                    self.corrupt_count += 1
                    log.debug("corrupt status packet from servo %d: parsing on", rx[_PKT_ID])
                    continue
                break
            dxl_id = rx[_PKT_ID]
            length = lengths.get(dxl_id)
            n_params = (rx[_PKT_LEN_L] | (rx[_PKT_LEN_H] << 8)) - 4  # minus INST, ERR, CRC16
            if length is None or dxl_id in replies or n_params != length + pad or rx[_PKT_INSTRUCTION] != _INST_STATUS:
                self.late_count += 1
                log.debug("late status packet from servo %d (%d data bytes) discarded", dxl_id, n_params)
                continue
            replies[dxl_id] = self._note(
                StatusPacket(dxl_id, rx[_PKT_ERROR], bytes(rx[_PKT_PARAMS : _PKT_PARAMS + length]))
            )
        self.port.is_using = False
        return replies

    def _collect_fast(self, ids: Sequence[int], length: int, pad: int = 0) -> dict[int, StatusPacket] | None:
        """The one status packet after a FAST_SYNC_READ, split by servo; None when it failed as a whole.

        ``pad``: the extra bytes each servo was asked (dropped from the data).
        """
        slot = length + pad + 4
        raw, result, _ = self.ph.fastSyncReadRx(self.port, BROADCAST_ID, slot * len(ids))
        if result != COMM_SUCCESS or len(raw) < slot * len(ids) - 2:
            if result == COMM_SUCCESS:  # a plain status packet, late, where the fast one was expected
                self.late_count += 1
            return None
        replies: dict[int, StatusPacket] = {}
        alerts = self.alerts
        new = tuple.__new__  # StatusPacket(...) without the NamedTuple's Python-level __new__
        # slots of ERR ID DATA[length + pad] CRC16 (the last CRC is the packet's); inline, on the tick path
        for i in range(0, slot * len(ids), slot):
            dxl_id = raw[i + 1]
            if dxl_id not in ids:
                return None
            error = raw[i]
            if error & ALERT_BIT:
                alerts.add(dxl_id)
            replies[dxl_id] = new(StatusPacket, (dxl_id, error, bytes(raw[i + 2 : i + 2 + length])))
        return replies

    def _send_read(self, read: GroupRead, fast: bool) -> bool:
        """Send the instruction of one try of ``read``; False (and the port released) when it did not go out."""
        pad = self._pad
        if pad and time.monotonic() - self._pad_at > PAD_HORIZON:
            pad = self._pad = 0
        self._sent_pad = pad
        if read.same:
            length = read.length + pad
            result = self.ph.syncReadTx(self.port, read.address, length, list(read.ids), len(read.ids), fast)
        else:
            param = list(read.bulk_param)
            if pad:
                for k in range(3, len(param), 5):
                    n = param[k] | param[k + 1] << 8
                    param[k], param[k + 1] = (n + pad) & 0xFF, (n + pad) >> 8
            result = self.ph.bulkReadTx(self.port, param, len(param), False)
        if result == COMM_PORT_BUSY:  # another transaction holds the port: its lock is not ours to clear
            return False
        if result != COMM_SUCCESS:
            self.port.is_using = False
            return False
        return True

    def _receive_read(self, read: GroupRead, fast: bool, sent: bool) -> dict[int, StatusPacket] | None:
        """The replies of one try of ``read`` whose instruction was ``sent``: by ID (missing IDs absent), or None
        when a FAST_SYNC_READ failed as a whole."""
        if fast:
            got = self._collect_fast(read.ids, read.length, self._sent_pad) if sent else None
            if got is None and sent:
                self._silent_try()
            return got
        replies = self._collect(read.lengths, self._sent_pad) if sent else {}
        if sent and len(replies) < len(read.ids):
            self._silent_try()
        return replies

    def _silent_try(self) -> None:
        """A servo stayed silent: its reply may yet come, late.  The next tries ask another length (PAD_CYCLE)."""
        self._pad = self._pad % PAD_CYCLE + 1
        self._pad_at = time.monotonic()

    def send_group_read(self, read: GroupRead) -> GroupRead:
        """Send the instruction of ``read`` (from :meth:`GroupRead.plan`) and return without waiting: ``read``
        marked sent or not.

        The status packets come in while the caller works; :meth:`receive_group_read` takes them (with the
        retries of :meth:`group_read`).  Nothing else may use the link in between: the SDK keeps the port
        marked busy until the replies are read (a Ctrl-C there is undone by :meth:`release`).
        """
        return GroupRead._make((*read[:-1], self._send_read(read, read.fast)))  # read._replace(sent=...), faster

    def drain(self, read: GroupRead) -> None:
        """Wait for the status packets of ``read`` (sent, replies not taken) and drop them: no retries, no errors.

        So the next instruction does not go out while servos still answer on the half-duplex wire, and their
        packets are not taken for its reply.  At most the SDK's packet timeout when a servo stays silent.
        """
        try:
            if read.sent:
                self._receive_read(read, read.fast, True)
        except Exception as exc:  # noqa: BLE001 - only the wait matters: the replies are dropped either way
            log.debug("draining a group read: %s", exc)
        finally:
            self.port.is_using = False

    def receive_group_read(
        self, read: GroupRead, *, what: str = "", allow_missing: bool = False
    ) -> dict[int, StatusPacket]:
        """The replies of a group read sent by :meth:`send_group_read`, with the retries of :meth:`group_read`.

        Every try keeps what arrived; the next asks again only the servos still missing (or that answered with
        a status error).  ``allow_missing``: return the replies that came, without the servos still silent
        after the retries (the caller decides what a missing reply means); a status error still raises.
        """
        ids = read.ids
        use_fast = read.fast
        sent = read.sent
        asking = read
        replies: dict[int, StatusPacket] = {}
        errors: dict[int, str] = {}
        asked, answered, clean = self.asked, self.answered, self.clean_tries
        for attempt in range(self.retries + 1):
            if attempt:
                self._retrying(what or "a group read", asking.ids, "no reply or a status error")
                self.port.clearPort()  # the tail of a broken try must not be read as this one's
                sent = self._send_read(asking, use_fast)
            got = self._receive_read(asking, use_fast, sent)
            if use_fast:
                if got is None:  # one packet for all: repeat as a plain read, which names the silent servo
                    self.fast_failures += 1
                    self._retrying(what or "a group read", asking.ids, "FAST_SYNC_READ failed; as a plain SYNC_READ")
                    use_fast = False
                    got = self._receive_read(asking, False, self._send_read(asking, False))
                else:
                    self.fast_failures = 0
            assert got is not None  # only a fast read gives None
            if attempt == 0 and len(got) == len(ids) and not any(r.error & _NOT_ALERT for r in got.values()):
                clean[ids] = clean.get(ids, 0) + 1
                return got  # the tick path: every servo answered (only requested IDs are kept), none with an error
            for i in asking.ids:
                asked[i] = asked.get(i, 0) + 1
            for i, r in got.items():
                if r.error & _NOT_ALERT:
                    errors[i] = status_error_name(r.error) or f"status error {r.error}"
                else:
                    answered[i] = answered.get(i, 0) + 1
                    errors.pop(i, None)
                    replies[i] = r
            if len(replies) == len(ids):
                return {i: replies[i] for i in ids}  # in the read's order
            asking = read.subset([i for i in ids if i not in replies])
        what = what or "a group read"
        if errors:
            detail = ", ".join(f"{i}: {name}" for i, name in sorted(errors.items()))
            raise self._fail(f"status error ({what}): {detail}", errors)
        if allow_missing:
            return replies
        missing = set(ids) - set(replies)
        raise self._fail(f"no status packet ({what}) at {self.baud} baud after {self.retries + 1} tries", missing)

    def group_read(
        self,
        requests: Mapping[int, tuple[int, int]],
        *,
        fast: bool = False,
        what: str = "",
    ) -> dict[int, StatusPacket]:
        """Read every servo of ``{id: (address, length)}`` in one group transaction, with retries.

        Uses SYNC_READ when all servos share the address and length (FAST_SYNC_READ first when ``fast``; a
        failed fast read is repeated as a plain one, which tells which servo is silent), BULK_READ otherwise.
        Raises BusError naming the servos that never answered, or that answered with a status error.
        """
        return self.receive_group_read(self.send_group_read(GroupRead.plan(requests, fast=fast)), what=what)


class GroupRead(NamedTuple):
    """The plan of one group read (:meth:`Link.send_group_read`): which instruction, for which servos.

    A NamedTuple: the tick path builds one per tick.
    """

    ids: tuple[int, ...]
    lengths: Mapping[int, int]  #: bytes each servo returns, by ID
    same: bool  #: every servo reads the same address and length: SYNC_READ (else BULK_READ)
    address: int  #: of a SYNC_READ
    length: int  #: of a SYNC_READ
    fast: bool  #: FAST_SYNC_READ first
    bulk_param: tuple[int, ...]  #: the BULK_READ parameters (ID, address, length per servo)
    sent: bool = False  #: the first try's instruction went out (``send_group_read``)

    @classmethod
    def plan(cls, requests: Mapping[int, tuple[int, int]], *, fast: bool = False) -> GroupRead:
        """The read of ``{id: (address, length)}``: SYNC_READ when all share the address and length (FAST_SYNC_READ
        with ``fast``), else BULK_READ."""
        shapes = set(requests.values())
        same = len(shapes) == 1
        address, length = next(iter(shapes)) if same else (0, 0)
        param: list[int] = []
        if not same:
            for dxl_id, (a, n) in requests.items():
                param += [dxl_id, a & 0xFF, a >> 8, n & 0xFF, n >> 8]
        lengths = {dxl_id: n for dxl_id, (_, n) in requests.items()}
        return cls(tuple(requests), lengths, same, address, length, same and fast, tuple(param))

    def subset(self, ids: Sequence[int]) -> GroupRead:
        """The same read for ``ids`` only (a retry of the servos that did not answer), as a plain read."""
        if self.same:
            return GroupRead.plan(dict.fromkeys(ids, (self.address, self.length)))
        bulk = self.bulk_param
        shapes = {
            bulk[k]: (bulk[k + 1] | bulk[k + 2] << 8, bulk[k + 3] | bulk[k + 4] << 8) for k in range(0, len(bulk), 5)
        }
        return GroupRead.plan({i: shapes[i] for i in ids})


def _whole_packet(rx: Sequence[int]) -> bool:
    """``rx`` (what the SDK's rxPacket returned) holds one whole packet: it failed its CRC, not a timeout."""
    return len(rx) >= 11 and len(rx) == (rx[_PKT_LEN_L] | rx[_PKT_LEN_H] << 8) + _PKT_LEN_H + 1
