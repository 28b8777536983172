"""The simulated servo's fast paths against plain restatements of what they shortcut, on seeded random servos.

* A read of Present Position alone computes that item only (``SimServo.read``): its bytes are those of the whole
  Present block computed at the same moment, and the other Present items, read later, are what they would have been.
* A write is checked against rules worked out once per item (``sim.servo_writes``): the error of every write here
  is the one the e-Manual's rules give, restated plainly below (:func:`expected_error`).

(``tests/sim/test_replies_golden.py`` holds whole sessions' replies, times and control tables to their values before
any of these fast paths.)
"""

from __future__ import annotations

import random

import pytest

from drivers.control_table import DriveMode, Model, OperatingMode, Register, StatusError, model
from retarget.control.clock import VirtualClock
from sim import rules
from sim.servo import SimServo
from sim.watchdog import WATCHDOG_ERROR
from tests.helpers import GOAL, PRESENT, TORQUE, address

PRESENT_BLOCK = address("Realtime Tick")  #: 120: Realtime Tick .. Present Temperature, 27 bytes
PRESENT_BLOCK_LEN = 27
MODELS = ("XM430-W350", "XL430-W250")
POSITION_WINDOWS = [(PRESENT, 4), (PRESENT, 2), (PRESENT + 1, 3), (PRESENT + 3, 1)]


def _random_servo(rng: random.Random, clock: VirtualClock) -> SimServo:
    """A servo in a random mode, direction, homing offset and profile, moving toward a random goal."""
    servo = SimServo(rng.choice(MODELS), 1, clock=clock, position=rng.uniform(500, 3500))
    mode = rng.choice((OperatingMode.POSITION, OperatingMode.EXTENDED_POSITION, OperatingMode.VELOCITY))
    servo.set("Operating Mode", mode)
    servo.set("Drive Mode", rng.choice((0, DriveMode.REVERSE, DriveMode.TIME_BASED_PROFILE)))
    servo.set("Homing Offset", rng.choice((0, rng.randint(-1024, 1024), rng.randint(-5000, 5000))))
    servo.set("Profile Velocity", rng.choice((0, rng.randint(50, 300))))
    servo.set("Profile Acceleration", rng.choice((0, rng.randint(20, 400))))
    assert servo.write(TORQUE, b"\x01") == StatusError.NONE
    if mode == OperatingMode.VELOCITY:
        servo.write(address("Goal Velocity"), rng.randint(-200, 200).to_bytes(4, "little", signed=True))
    else:
        servo.write(GOAL, rng.randint(100, 4000).to_bytes(4, "little", signed=True))
    return servo


@pytest.mark.parametrize("seed", range(3))
def test_a_position_read_is_the_present_block_computed_at_that_moment(seed):
    rng = random.Random(seed)
    for _ in range(40):
        clocks = VirtualClock(), VirtualClock()
        twin = rng.random()
        fast, whole = (_random_servo(random.Random(twin), c) for c in clocks)  # the same servo, twice
        window = rng.choice(POSITION_WINDOWS)
        for _ in range(rng.randint(1, 4)):
            step = rng.choice((0.0, 1e-4, rng.uniform(0.0, 0.3)))
            for clock in clocks:
                clock.advance(step)
            fast.update(clocks[0].now())
            whole.update(clocks[1].now())
            error, block = whole.read(PRESENT_BLOCK, PRESENT_BLOCK_LEN)  # every Present item, computed now
            assert error == StatusError.NONE
            offset = window[0] - PRESENT_BLOCK
            assert fast.read(*window) == (StatusError.NONE, block[offset : offset + window[1]])
        assert fast.memory == whole.memory  # the items the position read left due are what they would have been


def _value(servo: SimServo, new: dict[str, int], name: str) -> int:
    return new[name] if name in new else servo.get(name)


def expected_error(servo: SimServo, items: list[tuple[Register, int]]) -> int:
    """The error a write of ``items`` (whole items, back to back) answers, by the e-Manual's rules, plainly."""
    if any(not reg.writable for reg, _ in items):
        return StatusError.ACCESS
    if any(reg.eeprom for reg, _ in items) and servo.get("Torque Enable"):
        return StatusError.ACCESS
    new = {reg.name: value for reg, value in items}
    for reg, v in items:
        if not reg.in_range(v):
            return StatusError.DATA_RANGE
        if reg.name == "Operating Mode" and v not in servo.model.operating_modes:
            return StatusError.DATA_RANGE
        if reg.name == "Protocol Type" and v != rules.PROTOCOL_TYPE_SUPPORTED:
            return StatusError.DATA_RANGE
        if reg.name in rules.WATCHDOG_LOCKED and servo.memory[address("Bus Watchdog")] == WATCHDOG_ERROR:
            return StatusError.DATA_RANGE
        if reg.limit is None:
            continue
        if reg.name == "Goal Position" and _value(servo, new, "Operating Mode") != OperatingMode.POSITION:
            continue
        low_name, high_name = reg.limit
        low = -_value(servo, new, low_name[1:]) if low_name.startswith("-") else _value(servo, new, low_name)
        if not low <= v <= _value(servo, new, high_name):
            return StatusError.DATA_LIMIT
    return StatusError.NONE


def _runs(m: Model) -> list[list[Register]]:
    """Items to write: each alone, and runs of up to four items back to back (no gap between them)."""
    regs = sorted(m.registers.values(), key=lambda r: r.address)
    runs = [[r] for r in regs]
    for k, first in enumerate(regs):
        run = [first]
        for reg in regs[k + 1 : k + 4]:
            if reg.address != run[-1].end:
                break
            run.append(reg)
            runs.append(list(run))
    return runs


def _random_value(rng: random.Random, servo: SimServo, reg: Register) -> int:
    """Near the item's bounds (static and run-time), inside or out, or anywhere its size allows."""
    near = [reg.type_min, reg.type_max, 0]
    near += [b for b in (reg.minimum, reg.maximum) if b is not None]
    for name in reg.limit or ():
        if name.removeprefix("-") in servo.model.registers:
            bound = servo.get(name.removeprefix("-"))
            near.append(-bound if name.startswith("-") else bound)
    if reg.name == "Operating Mode":
        near += [m.value for m in OperatingMode]
    value = (
        rng.choice(near) + rng.choice((-1, 0, 0, 1)) if rng.random() < 0.8 else rng.randint(reg.type_min, reg.type_max)
    )
    return max(reg.type_min, min(reg.type_max, value))


@pytest.mark.parametrize("name", MODELS)
def test_every_write_answers_the_error_the_rules_give(name):
    rng = random.Random(name)
    runs = _runs(model(name))
    seen = set()
    for _ in range(60):
        servo = SimServo(name, 1, clock=VirtualClock())
        servo.set("Operating Mode", rng.choice([m.value for m in servo.model.operating_modes]))
        servo.set("Min Position Limit", rng.randint(0, 2000))
        servo.set("Max Position Limit", rng.randint(2000, 4095))
        servo.set("Torque Enable", rng.random() < 0.5)
        if rng.random() < 0.2:
            servo.set("Bus Watchdog", WATCHDOG_ERROR)  # tripped: goals read-only
        for run in rng.sample(runs, 40):
            items = [(reg, _random_value(rng, servo, reg)) for reg in run]
            data = b"".join(v.to_bytes(reg.size, "little", signed=reg.signed) for reg, v in items)
            want = expected_error(servo, items)
            assert servo.check_write(run[0].address, data) == want, [(r.name, v) for r, v in items]
            seen.add(want)
    assert seen == {StatusError.NONE, StatusError.ACCESS, StatusError.DATA_RANGE, StatusError.DATA_LIMIT}
