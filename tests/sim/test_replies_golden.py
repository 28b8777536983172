"""Golden replies: a scripted, seeded session on a simulated bus gives the same bytes, at the same times, forever.

The script drives six servos (four XM430-W350, two XL430-W250; one a Secondary-ID shadow) on a VirtualClock with
the wire model and seeded reply faults on: sync writes, sync reads, fast sync and bulk reads, reads of whole control
tables and of register blocks, writes of several registers and their errors, REG_WRITE/ACTION, every Operating
Mode, torque off/on mid-move, a hand turning a limp horn, a wall and its Overload, a scheduled hardware error and
REBOOT, a Bus Watchdog trip, Indirect Data, CLEAR and FACTORY_RESET.  Each phase's transcript (every reply's bytes,
sender and arrival time as an exact float, then each servo's whole control table) is hashed; the hashes were recorded
from the simulator before its per-transaction speed-up (sim.servo lazily computing its Present items), so any change
of a reply byte, of a reply's time or of a register value fails here.  On a mismatch the message shows the phase's
transcript; ``python -m tests.sim.test_replies_golden PHASE`` prints one phase's transcript, to diff against the
previous code's (without PHASE it prints every phase's digest).
"""

from __future__ import annotations

import hashlib
import sys
from functools import cache

from drivers.control_table import HardwareError, Instruction, common_register
from retarget.control.clock import VirtualClock
from sim import SimBus
from sim.faults import Faults, ReplyFaults
from sim.protocol import build_instruction
from sim.servo import SimServo

GOAL, PRESENT_BLOCK, TORQUE = (common_register(n).address for n in ("Goal Position", "Present PWM", "Torque Enable"))
PRESENT_BLOCK_LEN = 148 - PRESENT_BLOCK  #: Present PWM .. Backup Ready (Present Load on XL430)
REALTIME_TICK, PRESENT_POSITION = 120, 132
IDS = (1, 2, 3, 4, 5, 6)

#: sha256 (first 16 hex digits) of each phase's transcript, recorded from the simulator before its speed-up
GOLDEN = {
    "setup": "75a520cc05048397",
    "moves": "399d1e8552fd5329",
    "torque": "49f9f399801755c9",
    "modes": "40af8cb818a9371d",
    "fault": "943bc5f79836638d",
    "wall": "da7b780db88e0c3d",
    "watchdog": "184f29ee0f7420e7",
    "hand": "fa4b27c10aeeecc4",
    "reset": "668b936d29c1171e",
}


def _u16(v: int) -> bytes:
    return (v & 0xFFFF).to_bytes(2, "little")


def _i32(v: int) -> bytes:
    return (v & 0xFFFFFFFF).to_bytes(4, "little")


class Script:
    """A bus, its clock, and the transcript of what the servos answered."""

    def __init__(self) -> None:
        self.clock = VirtualClock()
        servos = [
            SimServo("XM430-W350", 1, clock=self.clock, position=1000.0),
            SimServo("XM430-W350", 2, clock=self.clock, position=2048.0),
            SimServo("XM430-W350", 3, clock=self.clock, position=3000.0),
            SimServo("XM430-W350", 4, clock=self.clock, position=2500.5),
            SimServo("XL430-W250", 5, clock=self.clock, position=1500.0, return_delay_time=10),
            SimServo("XL430-W250", 6, clock=self.clock, position=2100.0),
        ]
        faults = Faults(servos={6: ReplyFaults(drop=0.25, corrupt=0.25)}, wire=True, seed=7)
        self.bus = SimBus(servos, clock=self.clock, faults=faults)
        self.lines: list[str] = []
        self.step = 0

    def at(self, t: float) -> Script:
        self.clock.sleep_until(t)
        return self

    def send(self, dxl_id: int, inst: int, params: bytes = b"", *, corrupt: bool = False, wait: bool = True) -> None:
        packet = build_instruction(dxl_id, inst, params)
        if corrupt:
            packet = packet[:-1] + bytes((packet[-1] ^ 0xFF,))
        t = self.clock.now().hex()
        replies = self.bus.feed(packet)
        self.step += 1
        for r in replies:
            self.lines.append(f"{self.step} {t} {r.id} {r.due.hex()} {r.data.hex()}")
        if not replies:
            self.lines.append(f"{self.step} {t} -")
        if replies and wait:  # as a host does: the next instruction once the reply is in
            self.clock.sleep_until(max(r.due for r in replies))

    def read(self, dxl_id: int, address: int, length: int) -> None:
        self.send(dxl_id, Instruction.READ, _u16(address) + _u16(length))

    def write(self, dxl_id: int, address: int, data: bytes) -> None:
        self.send(dxl_id, Instruction.WRITE, _u16(address) + data)

    def sync_write(self, address: int, values: dict[int, bytes]) -> None:
        length = len(next(iter(values.values())))
        params = _u16(address) + _u16(length) + b"".join(bytes((i,)) + v for i, v in values.items())
        self.send(0xFE, Instruction.SYNC_WRITE, params)

    def sync_read(self, address: int, length: int, ids: tuple[int, ...] = IDS, *, fast: bool = False) -> None:
        inst = Instruction.FAST_SYNC_READ if fast else Instruction.SYNC_READ
        self.send(0xFE, inst, _u16(address) + _u16(length) + bytes(ids))

    def bulk_read(self, requests: list[tuple[int, int, int]], *, fast: bool = False) -> None:
        inst = Instruction.FAST_BULK_READ if fast else Instruction.BULK_READ
        self.send(0xFE, inst, b"".join(bytes((i,)) + _u16(a) + _u16(n) for i, a, n in requests))

    def snapshot(self) -> None:
        """Every servo's whole control table, now."""
        for s in self.bus.servos:
            self.lines.append(f"mem {s.id} {s.memory.hex()}")

    def cut(self) -> str:
        self.lines.append(f"collisions {len(self.bus.collisions)}")
        text = "\n".join(self.lines)
        self.lines = []
        return text


def _setup(s: Script) -> None:
    s.at(0.001).send(0xFE, Instruction.PING)
    s.at(0.010).read(1, 0, 4)
    s.read(1, 0, 700)  # beyond the table: Access error
    s.send(9, Instruction.READ, _u16(0) + _u16(4), wait=False)  # nobody
    s.send(1, 0x77, wait=False)  # unknown instruction, written before servo 9's timeout
    s.send(2, Instruction.PING, wait=False)  # written over the reply before: a collision
    s.read(2, PRESENT_POSITION, 4)
    s.send(2, Instruction.READ, _u16(132) + _u16(4), corrupt=True)  # CRC error
    s.write(1, 10, b"\x01")  # Drive Mode: reverse
    s.write(1, 20, _i32(100))  # Homing Offset
    s.write(2, 11, b"\x01")  # velocity mode
    s.write(3, 11, b"\x05")  # current-based position
    s.write(4, 11, b"\x00")  # current mode
    s.write(4, 11, b"\x07")  # no such mode: Data Range
    s.write(5, 10, b"\x04")  # time-based profile
    s.write(6, 12, b"\x05")  # Secondary ID 5: a shadow of 5
    s.write(6, 11, b"\x10")  # PWM mode
    s.write(1, 116, b"\x00\x08")  # part of Goal Position: Data Length
    s.write(1, 52, _i32(5000))  # Min Position Limit beyond 4095: Data Range
    s.write(1, GOAL, _i32(5000))  # beyond Max Position Limit: Data Limit
    s.write(1, 108, _i32(20) + _i32(150))  # Profile Acceleration + Profile Velocity
    s.write(3, 108, _i32(40) + _i32(0))
    s.write(5, 108, _i32(200) + _i32(800))  # time-based: ms
    s.write(3, 168, _u16(132) + _u16(133) + _u16(134) + _u16(135))  # Indirect Address 1-4 -> Present Position
    s.write(3, 102, _u16(300))  # Goal Current
    s.at(0.020).sync_write(TORQUE, {i: b"\x01" for i in IDS})
    s.write(1, 10, b"\x00")  # EEPROM with torque on: Access error
    s.read(3, 224, 4)  # Indirect Data 1-4: Present Position
    s.snapshot()


def _moves(s: Script) -> None:
    t = 0.030
    for k in range(60):
        t += 0.007
        s.at(t)
        if k % 10 == 0:
            goals = {1: 1000 + 40 * k, 3: 3000 - 30 * k, 5: 1500 + 25 * k}
            s.sync_write(GOAL, {i: _i32(g) for i, g in goals.items()})
        if k % 15 == 1:
            s.write(2, 104, _i32(60 - 8 * k))  # Goal Velocity
            s.write(4, 102, _u16((150 - 20 * k) & 0xFFFF))  # Goal Current
            s.write(6, 100, _u16(300 - 10 * k))  # Goal PWM
        if k % 4 == 0:
            s.sync_read(PRESENT_BLOCK, PRESENT_BLOCK_LEN)
        elif k % 4 == 1:
            s.sync_read(PRESENT_POSITION, 4, fast=True)
        elif k % 4 == 2:
            s.bulk_read([(1, REALTIME_TICK, 28), (3, 224, 4), (5, 128, 8), (6, 126, 2)])
        else:
            s.bulk_read([(2, 128, 8), (4, 126, 10), (1, 132, 4)], fast=True)
        if k % 12 == 5:
            s.read(k % 6 + 1, 0, 662)  # the whole table
        if k == 33:
            s.send(1, Instruction.REG_WRITE, _u16(GOAL) + _i32(1800))
            s.read(1, 69, 1)  # Registered Instruction
        if k == 40:
            s.send(1, Instruction.ACTION)
    s.snapshot()


def _torque(s: Script) -> None:
    s.at(0.480).sync_write(GOAL, {1: _i32(300), 3: _i32(1000), 5: _i32(3500)})
    s.at(0.500).sync_write(TORQUE, {1: b"\x00", 3: b"\x00", 5: b"\x00"})  # mid-move
    s.sync_read(PRESENT_BLOCK, PRESENT_BLOCK_LEN)
    s.at(0.530).sync_read(PRESENT_BLOCK, PRESENT_BLOCK_LEN, fast=True)
    s.at(0.540).sync_write(TORQUE, {1: b"\x01", 3: b"\x01", 5: b"\x01"})
    for k in range(6):
        s.at(0.550 + 0.02 * k).sync_read(PRESENT_BLOCK, PRESENT_BLOCK_LEN)
    s.snapshot()


def _modes(s: Script) -> None:
    s.at(0.700).sync_write(TORQUE, {2: b"\x00", 4: b"\x00"})
    s.write(2, 11, b"\x04")  # extended position
    s.write(4, 11, b"\x10")  # PWM
    s.sync_write(TORQUE, {2: b"\x01", 4: b"\x01"})
    s.write(2, GOAL, _i32(-5000))
    s.write(4, 100, _u16(500))
    for k in range(8):
        s.at(0.710 + 0.015 * k).sync_read(PRESENT_BLOCK, PRESENT_BLOCK_LEN, ids=(2, 4))
    s.at(0.850).send(2, Instruction.CLEAR, bytes((0x01, 0x44, 0x58, 0x4C, 0x22)))  # moving: Result Fail
    s.at(1.500).send(2, Instruction.CLEAR, bytes((0x01, 0x44, 0x58, 0x4C, 0x22)))
    s.read(2, PRESENT_POSITION, 4)
    s.snapshot()


def _fault(s: Script) -> None:
    s.bus.servo(4).schedule_hardware_error(HardwareError.OVERHEATING, 1.6)
    s.at(1.590).read(4, 70, 1)
    s.at(1.610).read(4, 70, 1)  # Alert bit, torque off
    s.write(4, TORQUE, b"\x01")  # ignored until REBOOT
    s.sync_read(PRESENT_BLOCK, PRESENT_BLOCK_LEN)
    s.send(4, Instruction.REBOOT)
    s.read(4, 64, 8)
    s.at(1.700).read(4, 64, 8)
    s.snapshot()


def _wall(s: Script) -> None:
    s.at(1.800).write(1, GOAL, _i32(2000))
    s.bus.servo(1).block_at(2400.0)
    for k in range(14):
        s.at(1.850 + 0.1 * k).sync_read(PRESENT_BLOCK, PRESENT_BLOCK_LEN, ids=(1,))
        s.read(1, 70, 1)
    s.at(3.280).read(1, 64, 8)  # pushed 1 s: Overload, torque off
    s.snapshot()


def _watchdog(s: Script) -> None:
    s.at(3.300).write(2, 98, b"\x05")  # 100 ms
    s.write(2, GOAL, _i32(4000))
    s.at(3.350).read(3, PRESENT_POSITION, 4)  # for another ID: no restart
    s.at(3.380).read(2, PRESENT_POSITION, 4)
    s.at(3.520).read(2, 98, 1)  # tripped at 3.48
    s.write(2, GOAL, _i32(1000))  # locked: Data Range
    s.write(2, 98, b"\x00")
    s.write(2, GOAL, _i32(1000))
    s.at(3.600).sync_read(PRESENT_BLOCK, PRESENT_BLOCK_LEN)
    s.snapshot()


def _hand(s: Script) -> None:
    s.at(3.700).write(5, TORQUE, b"\x00")
    s.bus.servo(5).turn_by_hand(2500.0, duration=0.5)
    for k in range(6):
        s.at(3.720 + 0.1 * k).sync_read(PRESENT_BLOCK, PRESENT_BLOCK_LEN, ids=(5, 6))
    s.bus.servo(5).move_by_hand(None)
    s.at(4.400).read(5, PRESENT_BLOCK, PRESENT_BLOCK_LEN)
    s.snapshot()


def _reset(s: Script) -> None:
    s.at(4.500).send(6, Instruction.FACTORY_RESET, b"\x02")
    s.send(5, Instruction.FACTORY_RESET, b"\x05")  # no such option
    s.send(0xFE, Instruction.PING)
    s.at(4.600).sync_read(PRESENT_BLOCK, PRESENT_BLOCK_LEN)
    s.snapshot()


PHASES = (_setup, _moves, _torque, _modes, _fault, _wall, _watchdog, _hand, _reset)


@cache
def transcripts() -> dict[str, str]:
    """{phase name: transcript} of each phase, in order, on one bus."""
    script = Script()
    out = {}
    for phase in PHASES:
        phase(script)
        out[phase.__name__.lstrip("_")] = script.cut()
    return out


def _digest(text: str) -> str:
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def test_every_phase_answers_what_the_simulator_always_answered() -> None:
    got = transcripts()
    assert list(got) == list(GOLDEN)
    for name, text in got.items():
        assert _digest(text) == GOLDEN[name], f"phase {name!r} answered differently:\n{text[:4000]}"


def test_the_script_exercises_errors_faults_and_every_read_kind() -> None:
    text = "\n".join(transcripts().values())
    replies = [line.split()[4] for line in text.splitlines() if line[0].isdigit() and line[-1] != "-"]
    errors = {bytes.fromhex(r)[8] for r in replies if bytes.fromhex(r)[4] != 0xFE}
    # Result Fail, Instruction, CRC, Data Range, Data Length, Data Limit, Access, and the Alert bit with none
    assert {0x01, 0x02, 0x03, 0x04, 0x05, 0x06, 0x07, 0x80} <= errors
    assert any(bytes.fromhex(r)[4] == 0xFE for r in replies)  # fast read replies
    assert len(replies) > 300


if __name__ == "__main__":  # print the digests, or one phase's transcript
    for name, text in transcripts().items():
        if len(sys.argv) > 1 and name == sys.argv[1]:
            print(text)
        elif len(sys.argv) == 1:
            print(f'    "{name}": "{_digest(text)}",')
