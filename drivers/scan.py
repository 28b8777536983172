"""Find the Dynamixel servos on a port: ID, model, firmware and baud rate.

Per baud rate: one broadcast PING (every servo answers in turn; the SDK waits a fixed ~0.8 s at 1 Mbps).
When the broadcast answers are garbled (two servos with the same ID collide) or ``broadcast=False``, each
ID of the range is pinged on its own instead (about 35 ms per absent ID).

Servo ID lists such as ``"1-6"`` or ``"1,3,5"`` are parsed by :func:`drivers.control_table.parse_ids`.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterable, Sequence
from dataclasses import asdict, dataclass

from dynamixel_sdk import COMM_SUCCESS
from dynamixel_sdk.robotis_def import COMM_RX_TIMEOUT

from drivers.comm import Link, comm_result_name
from drivers.control_table import BAUD_RATES, MAX_ID, MODEL_BY_NUMBER
from drivers.latency import check_latency_timer
from drivers.port import SUPPORTED_BAUDS, open_port

log = logging.getLogger(__name__)

#: The bauds an X-series servo can be set to that dynamixel-sdk can open (4.5 Mbps cannot), most common first.
ALL_BAUDS: tuple[int, ...] = tuple(
    sorted((b for b in BAUD_RATES.values() if b in SUPPORTED_BAUDS), key=lambda b: (b != 1_000_000, b != 57_600, b))
)


@dataclass(frozen=True)
class FoundServo:
    """One servo that answered: its ID, model, firmware and the baud rate (bps) it answered at."""

    id: int
    model_number: int
    model: str  #: the model name, or "unknown" when it is not in drivers.control_table
    firmware: int
    baud: int

    def as_dict(self) -> dict[str, object]:
        return asdict(self)


def _found(dxl_id: int, number: int, firmware: int, baud: int) -> FoundServo:
    model = MODEL_BY_NUMBER.get(number)
    return FoundServo(dxl_id, number, model.name if model else "unknown", firmware, baud)


def scan_baud(link: Link, ids: Sequence[int], *, broadcast: bool = True) -> list[FoundServo]:
    """The servos answering on an open ``link`` among ``ids``."""
    baud = link.baud
    wanted = set(ids)
    if broadcast:
        answers, result = link.ph.broadcastPing(link.port)
        if result == COMM_SUCCESS:
            return [_found(i, number, fw, baud) for i, (number, fw) in sorted(answers.items()) if i in wanted]
        if result == COMM_RX_TIMEOUT:
            return []
        log.info("broadcast ping at %d baud: %s; pinging each ID", baud, comm_result_name(result))
    found = []
    for dxl_id in ids:
        reply = link.ping_once(dxl_id)
        if reply is not None:
            found.append(_found(dxl_id, reply.model_number, reply.firmware, baud))
    return found


def scan(
    port: str,
    bauds: Iterable[int] = (1_000_000,),
    ids: Sequence[int] = tuple(range(MAX_ID + 1)),
    *,
    broadcast: bool = True,
    progress: Callable[[str], None] | None = None,
) -> list[FoundServo]:
    """Every servo that answers on ``port`` at each of ``bauds``, by baud then ID.

    Arguments:
        port: a device path or pyserial URL (``/dev/ttyUSB0``, ``COM3``, ``socket://h:p``, ``sim://...``).
        bauds: the baud rates to try, bps, in order (:data:`ALL_BAUDS`: every one a servo can be set to).
        ids: the IDs to look for (0..252; :func:`drivers.control_table.parse_ids` reads ``"1-6"``).
        broadcast: one broadcast PING per baud rate (about 0.8 s however many answer); False pings each ID
            on its own (fast for a few IDs, about 35 ms per absent one).
        progress: called with a line of text before each baud rate.

    Returns a :class:`FoundServo` per answer.  BusError when the port cannot open at a baud rate.

    >>> found = scan("sim://?ids=1-2&model=XM430-W350&clock=virtual", ids=[1, 2, 3], broadcast=False)
    >>> [(s.id, s.model, s.firmware, s.baud) for s in found]
    [(1, 'XM430-W350', 46, 1000000), (2, 'XM430-W350', 46, 1000000)]
    """
    found: list[FoundServo] = []
    for k, baud in enumerate(bauds):
        if progress is not None:
            progress(f"scanning {port} at {baud} baud")
        handler = open_port(port, baud)
        if k == 0:
            check_latency_timer(port)  # a 16 ms FTDI timer makes every ping slow
        try:
            found.extend(scan_baud(Link(handler, retries=0), ids, broadcast=broadcast))
        finally:
            handler.closePort()
    return found
