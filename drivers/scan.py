"""Find the Dynamixel servos on a port: ID, model, firmware and baud rate.

Per baud rate: one broadcast PING (every servo answers in turn; the SDK waits a fixed ~0.8 s at 1 Mbps).
When the broadcast answers are garbled (two servos with the same ID collide) or ``broadcast=False``, each
ID of the range is pinged on its own instead (about 35 ms per absent ID).
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
from retarget.errors import ConfigError

log = logging.getLogger(__name__)

#: The bauds an X-series servo can be set to that dynamixel-sdk can open (4.5 Mbps cannot), most common first.
ALL_BAUDS: tuple[int, ...] = tuple(
    sorted((b for b in BAUD_RATES.values() if b in SUPPORTED_BAUDS), key=lambda b: (b != 1_000_000, b != 57_600, b))
)


@dataclass(frozen=True)
class FoundServo:
    id: int
    model_number: int
    model: str  #: the model name, or "unknown" when it is not in drivers.control_table
    firmware: int
    baud: int

    def as_dict(self) -> dict[str, object]:
        return asdict(self)


def parse_ids(text: str) -> tuple[int, ...]:
    """``"0-252"``, ``"1,2,5-9"`` -> sorted unique IDs; ConfigError naming the bad part."""
    ids: set[int] = set()
    for part in text.split(","):
        part = part.strip()
        try:
            if "-" in part:
                lo_text, hi_text = part.split("-", 1)
                lo, hi = int(lo_text), int(hi_text)
            else:
                lo = hi = int(part)
        except ValueError:
            raise ConfigError("expected IDs like 1-9 or 1,3,5", key="--ids", value=text) from None
        if not 0 <= lo <= hi <= MAX_ID:
            raise ConfigError(f"expected IDs within 0..{MAX_ID}, low before high", key="--ids", value=part)
        ids.update(range(lo, hi + 1))
    return tuple(sorted(ids))


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
    """Every servo found on ``port`` at each of ``bauds``, by baud then ID.  BusError when the port cannot open."""
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
