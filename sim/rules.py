"""Control-table rules of an X-series servo beyond plain ranges, from the ROBOTIS e-Manual (ROBOTIS-GIT/emanual).

* **Secondary(Shadow) ID (12)** (e-Manual X-series pages, section "Secondary(Shadow) ID(12)"): 0..252 turns it on,
  253..255 off (255 default).  A servo whose Secondary ID is N also carries out instructions sent to ID N,
  without a status packet; the EEPROM area cannot be changed through it, only RAM; ID (7) has priority (a servo
  whose ID is N acts as N's primary).  Which instructions: the e-Manual's example is a WRITE; the simulator also
  takes REG_WRITE, ACTION and the servo's slot of a SYNC WRITE / BULK WRITE addressed to N (how Interbotix arms
  drive their shoulder/elbow shadows), a slot for its own ID winning over one for its Secondary ID.  PING and
  reads addressed to N are not answered by shadows (they have no status to give).
* **Protocol Type (13)**: the simulator speaks Protocol 2.0 only, so any value but 2 answers Data Range (4).  That
  is the e-Manual's table on XL330 (values 2, 20, 21, 22; no 1.0); on X430/X540 a real servo would switch to
  Protocol 1.0 (not modelled).
* **Homing Offset (20)** (``control_table_homingoffset.md``): "In case of the Position Control Mode (Joint Mode)
  that rotates less than 360 degrees, any invalid Homing Offset values will be ignored (valid range: -1,024 ~
  1,024)": the value is stored and reads back, but Present Position is reported without it in mode 3.
* **Bus Watchdog (98)** (``control_table_buswatchdog.md``): see :mod:`sim.watchdog`; while it reads -1 the
  goal items (Goal PWM, Goal Current, Goal Velocity, Goal Position) are read-only and a write to them answers
  Data Range (4) until Bus Watchdog is written 0.
* **Indirect Data** (``control_table_indirect_data.md``): an Indirect Data item "inherits features and properties
  of the Data from the specific Address ... Size (Byte length), value range, and Access property": a write is
  checked as the same bytes written to the targets (read-only: Access 7, out of range: Data Range 4, part of a
  multi-byte item: Data Length 5), and refused as a whole when any target would refuse it.

>>> effective_homing_offset(2000, OperatingMode.POSITION), effective_homing_offset(2000, OperatingMode.VELOCITY)
(0, 2000)
>>> secondary_id(255), secondary_id(2)
(None, 2)
>>> indirect_runs({224: 116, 225: 117, 226: 118, 227: 119, 228: 65}, [(224, 0), (225, 4), (226, 0), (227, 0), (228, 1)])
[(116, b'\\x00\\x04\\x00\\x00'), (65, b'\\x01')]
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

from drivers.control_table import MAX_ID, Model, OperatingMode, Register

SECONDARY_ID_MAX = MAX_ID  #: 0..252 turn the Secondary ID on; 253..255 turn it off
PROTOCOL_TYPE_SUPPORTED = 2  #: Protocol 2.0, the only one the simulator speaks
HOMING_OFFSET_SINGLE_TURN = 1024  #: |Homing Offset| beyond this is ignored in Position Control Mode (3)
WATCHDOG_LOCKED = frozenset({"Goal PWM", "Goal Current", "Goal Velocity", "Goal Position"})


def secondary_id(value: int) -> int | None:
    """The ID a Secondary ID item ``value`` makes a servo listen to as a shadow, or None when it is off."""
    return value if 0 <= value <= SECONDARY_ID_MAX else None


def effective_homing_offset(offset: int, mode: int) -> int:
    """The Homing Offset the servo applies in Operating Mode ``mode``: 0 for an invalid one in position mode (3)."""
    if mode == OperatingMode.POSITION and abs(offset) > HOMING_OFFSET_SINGLE_TURN:
        return 0
    return offset


def indirect_targets(model: Model, mem: bytes | bytearray) -> dict[int, int]:
    """``{Indirect Data address: target address}`` of every Indirect Data item of ``model`` in memory ``mem``."""
    targets = {}
    for reg in model.registers.values():
        if reg.name.startswith("Indirect Address "):
            data = model.registers["Indirect Data " + reg.name.rsplit(" ", 1)[1]]
            targets[data.address] = reg.decode(mem[reg.address : reg.end])
    return targets


def indirect_runs(targets: Mapping[int, int], writes: Iterable[tuple[int, int]]) -> list[tuple[int, bytes]]:
    """``(target address, bytes)`` runs of consecutive targets for ``writes`` = ``(data address, byte)``.

    An Indirect Data item that points at an Indirect Data address (its default: itself) is plain storage and
    forwards nothing.
    """
    data_addresses = set(targets)
    runs: list[tuple[int, bytearray]] = []
    for data_addr, byte in writes:
        target = targets.get(data_addr)
        if target is None or target in data_addresses:
            continue
        if runs and runs[-1][0] + len(runs[-1][1]) == target:
            runs[-1][1].append(byte)
        else:
            runs.append((target, bytearray((byte,))))
    return [(target, bytes(run)) for target, run in runs]


def is_indirect_data(reg: Register) -> bool:
    return reg.name.startswith("Indirect Data")
