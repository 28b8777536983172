"""Issue 16, item 9: every number of an arm file has a physical range, so an arm that loads also runs."""

from __future__ import annotations

import math
import random
import re
import time
from pathlib import Path

import numpy as np
import pytest

from drivers.control_table import BAUD_RATES, MODELS
from drivers.port import SUPPORTED_BAUDS as SDK_BAUDS
from drivers.scan import ALL_BAUDS
from drivers.servo_plan import ServoSettings, plan_servos
from retarget import ConfigError, load_arm
from retarget.arm.config import arm_dirs, list_arms
from retarget.arm.model import SERVO_BAUDS, SUPPORTED_BAUDS
from retarget.control.replay import LeadIn
from retarget.ik.ccd import CCDSolver
from tests.helpers import urdf_text


def bundled(name: str) -> str:
    for folder in arm_dirs():
        path = folder / f"{name}.toml"
        if path.is_file():
            return path.read_text()
    raise AssertionError(f"no bundled {name}.toml")


WX = bundled("wx250s")


def edited(old: str, new: str, text: str = WX) -> str:
    assert old in text, old
    return text.replace(old, new, 1)


def write(tmp_path: Path, text: str, name: str = "arm.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


# ------------------------------------------------------------------------------------------------ baud tables


def test_the_servo_baud_set_equals_the_drivers_register_table():
    assert SERVO_BAUDS == tuple(BAUD_RATES[code] for code in sorted(BAUD_RATES))


def test_an_arm_file_may_use_the_bauds_every_model_and_the_sdk_support():
    assert set(SUPPORTED_BAUDS) == set(ALL_BAUDS) == {b for b in SERVO_BAUDS if b in SDK_BAUDS}
    for model in MODELS.values():  # every supported baud is settable on every model
        assert all(BAUD_RATES[code] in SUPPORTED_BAUDS for code in range(model.max_baud_code + 1) if code < 7)
        assert max(SUPPORTED_BAUDS) <= BAUD_RATES[model.max_baud_code]


# ------------------------------------------------------------------------------------------------ TOML ranges

FIRST_LIMITS = "limits = [-179.9994, 179.9994]"
BAD = [
    ("baud-12345", ("baud = 1_000_000", "baud = 12345"), "baud", "expected a baud rate the servos and dynamixel-sdk"),
    ("baud-4.5M", ("baud = 1_000_000", "baud = 4_500_000"), "baud", "expected a baud rate"),
    ("baud-float", ("baud = 1_000_000", "baud = 1e6"), "baud", "expected an integer"),
    ("limits-1e308", (FIRST_LIMITS, "limits = [-1e308, 1e308]"), "joints[0].limits", "from -360 to 360 deg"),
    ("limits-huge-int", (FIRST_LIMITS, "limits = [-1, 9" + "9" * 400 + "]"), "joints[0].limits", "expected a list"),
    ("limits-361", (FIRST_LIMITS, "limits = [-10, 361]"), "joints[0].limits", "from -360 to 360 deg"),
    ("velocity-1e300", ("max_velocity = 180", "max_velocity = 1e300"), "joints[0].max_velocity", "0.1 to 1000 deg/s"),
    ("velocity-tiny", ("max_velocity = 180", "max_velocity = 0.01"), "joints[0].max_velocity", "0.1 to 1000 deg/s"),
    ("velocity-zero", ("max_velocity = 180", "max_velocity = 0"), "joints[0].max_velocity", "> 0"),
    ("xyz-1e300", ("xyz = [0.0, 0.0, 0.072]", "xyz = [0.0, 0.0, 1e300]"), "joints[0].xyz", "from -10 to 10 m"),
    ("tool-xyz", ("xyz = [0.093575, 0.0, 0.0]", "xyz = [11, 0.0, 0.0]"), "tool.xyz", "from -10 to 10 m"),
    ("tool-rpy", ("rpy = [0.0, 0.0, 0.0]", "rpy = [1e308, 0.0, 0.0]"), "tool.rpy", "from -360 to 360 deg"),
    ("axis-tiny", ("axis = [0, 0, 1]", "axis = [0, 0, 1e-300]"), "joints[0].axis", "zero length"),
    ("gripper-limits", ("limits = [-21.7, 72.7]", "limits = [-21.7, 1e9]"), "gripper.limits", "-360 to 360 deg"),
    ("pose-huge", ("home = [0.0,", "home = [1e308,"), "poses.home[0]", "outside the limits"),
]


@pytest.mark.parametrize(("change", "key", "message"), [b[1:] for b in BAD], ids=[b[0] for b in BAD])
def test_a_number_out_of_its_range_names_the_key(tmp_path, change, key, message):
    path = write(tmp_path, edited(*change))
    with pytest.raises(ConfigError, match=re.escape(message)) as info:
        load_arm(path)
    assert info.value.key == key and info.value.path == str(path)


def runs(arm) -> None:
    """What replay does with an arm before and around its first ticks, without a bus: the servo plan and register
    values, FK, IK and a lead-in plan; every number finite."""
    settings = ServoSettings(dt=0.01)
    for servo in plan_servos(arm):
        eeprom, ram = settings.registers(servo, arm)
        for name, value in [*eeprom.items(), *ram.items()]:
            servo.model.register(name).encode(value)  # raises when a value does not fit its register
    T, points = arm.fk(arm.home)
    assert np.isfinite(T).all() and np.isfinite(points).all()
    result = CCDSolver(arm, max_iterations=5).solve(T[:3, 3], arm.rest)
    assert np.isfinite(result.q).all()
    lead = LeadIn.plan(arm.rest, arm.home, speed=0.5 * arm.max_velocity, rate=100.0, target=T[:3, 3])
    assert lead.n_slots < 10**7


@pytest.mark.parametrize(
    "change",
    [
        ("baud = 1_000_000", "baud = 9600"),
        ("baud = 1_000_000", "baud = 4_000_000"),
        (FIRST_LIMITS, "limits = [-360, 360]"),
        ("max_velocity = 180", "max_velocity = 1000"),
        ("max_velocity = 180", "max_velocity = 0.1"),
        ("xyz = [0.0, 0.0, 0.072]", "xyz = [10, -10, 10]"),
        ("rpy = [0.0, 0.0, 0.0]", "rpy = [360, -360, 0]"),
        ("axis = [0, 0, 1]", "axis = [0, 0, 1e300]"),
    ],
    ids=["9600", "4M", "limits-360", "velocity-1000", "velocity-0.1", "xyz-10", "rpy-360", "axis-huge"],
)
def test_an_arm_at_the_ends_of_the_ranges_loads_and_runs(tmp_path, change):
    arm = load_arm(write(tmp_path, edited(*change)))
    runs(arm)


def test_a_huge_axis_is_normalised_not_zeroed(tmp_path):
    arm = load_arm(write(tmp_path, edited("axis = [0, 0, 1]", "axis = [0, 0, 1e300]")))
    assert arm.joints[0].axis == (0.0, 0.0, 1.0)


# ------------------------------------------------------------------------------------------------ URDF ranges

SERVOS = "[joints.j]\nservos = [{ id = 1, model = 'XL430-W250' }]\n"


def urdf_arm(tmp_path: Path, *, xyz="0 0 0.1", limit=("-1", "1"), velocity=None, servos=SERVOS) -> Path:
    text = urdf_text([("j", "revolute", "base", "tip", xyz, "0 0 1", limit)])
    if velocity is not None:
        text = text.replace('velocity="3.14159"', f'velocity="{velocity}"')
    path = tmp_path / "robot.urdf"
    path.write_text(text)
    (tmp_path / "robot.servos.toml").write_text(servos)
    return path


@pytest.mark.parametrize(
    ("kwargs", "key", "message"),
    [
        ({"velocity": "1e300"}, "joint[j].limit.velocity", "or set max_velocity (deg/s) in robot.servos.toml"),
        ({"velocity": "1e-9"}, "joint[j].limit.velocity", "expected a velocity from 0.001745 to 17.45 rad/s"),
        ({"limit": ("-1e308", "1e308")}, "joint[j].limit", "expected limits within +-6.28319 rad"),
        ({"xyz": "0 0 1e300"}, "joint[j].origin.xyz", "expected an origin within +-10 m"),
        ({"servos": "baud = 12345\n" + SERVOS}, "baud", "expected a baud rate"),
        ({"servos": SERVOS + "max_velocity = 1e300\n"}, "joints.j.max_velocity", "0.1 to 1000 deg/s"),
        ({"servos": SERVOS + "limits = [-1e308, 1e308]\n"}, "joints.j.limits", "from -360 to 360 deg"),
    ],
    ids=["velocity-huge", "velocity-tiny", "limits", "origin", "baud", "servo-velocity", "servo-limits"],
)
def test_urdf_numbers_out_of_range_name_the_key(tmp_path, kwargs, key, message):
    with pytest.raises(ConfigError, match=re.escape(message)) as info:
        load_arm(urdf_arm(tmp_path, **kwargs))
    assert info.value.key == key


def test_a_urdf_velocity_out_of_range_can_be_overridden_in_the_servo_file(tmp_path):
    arm = load_arm(urdf_arm(tmp_path, velocity="1e300", servos=SERVOS + "max_velocity = 90\n"))
    assert arm.max_velocity.tolist() == [math.pi / 2]
    runs(arm)


# ------------------------------------------------------------------------------------------------ fuzz

_NUMBER = re.compile(r"(?<![\w.\"-])-?\d[\d_]*(?:\.\d+)?(?:[eE][+-]?\d+)?")
EXTREMES = [
    "0", "-0.0", "1e308", "-1e308", "1e-300", "nan", "inf", "-inf", "9" * 30, "-" + "9" * 400, "0.5", "-1", "1",
    "4_500_000", "12345", "360", "-360", "360.001", "1000", "1000.5", "0.1", "0.09", "10", "10.5", "254", "253",
    "true", '"x"', "[]", "[1, 2]", "{}",
]  # fmt: skip


def mutate(text: str, rng: random.Random) -> str:
    """One to three seeded edits: a number swapped for an extreme or a scaled one, a line dropped or doubled."""
    for _ in range(rng.randint(1, 3)):
        kind = rng.random()
        numbers = list(_NUMBER.finditer(text))
        if kind < 0.7 and numbers:
            m = rng.choice(numbers)
            if rng.random() < 0.6:
                new = rng.choice(EXTREMES)
            else:
                new = repr(float(m.group().replace("_", "")) * rng.choice([-1, 10, 1e3, 1e-3, 1e6]))
            text = text[: m.start()] + new + text[m.end() :]
        else:
            lines = text.split("\n")
            i = rng.randrange(len(lines))
            if kind < 0.85:
                del lines[i]
            else:
                lines.insert(i, lines[i])
            text = "\n".join(lines)
    return text


CASE_SECONDS = 1.0


def test_fuzz_the_arm_reader_every_mutant_loads_and_runs_or_names_a_key(tmp_path):
    """Seeded mutations of every bundled arm file: each gives an Arm that runs, or a ConfigError naming a key
    (or the TOML line); never another exception, and each case is quick."""
    rng = random.Random(16)
    sources = {name: bundled(name) for name in list_arms()}
    loaded = rejected = 0
    for case in range(400):
        name = rng.choice(sorted(sources))
        text = mutate(sources[name], rng)
        path = write(tmp_path, text, f"fuzz{case % 7}.toml")
        start = time.perf_counter()
        try:
            arm = load_arm(path)
        except ConfigError as exc:
            assert exc.key, f"case {case} ({name}): no key in {exc}"
            rejected += 1
        else:
            runs(arm)
            loaded += 1
        assert time.perf_counter() - start < CASE_SECONDS, f"case {case} ({name}) took too long"
    assert loaded > 40 and rejected > 100, (loaded, rejected)


@pytest.mark.parametrize(
    ("arm_name", "line", "message"),
    [
        ("wx250s", "current_limit = 500", r"gripper\.current_limit: XL430-W250 has no current sensing: use pwm_limit"),
        ("vx300s", "current_limit = 5380", r"gripper\.current_limit: expected at most 3209 mA for XM430-W350"),
    ],
    ids=["no-current-sensing", "above-the-register"],
)
def test_a_gripper_current_limit_the_servo_cannot_take_is_refused_at_load(tmp_path, arm_name, line, message):
    text = re.sub(r"(?m)^current_limit = .*$\n?", "", bundled(arm_name))
    text = text.replace('[gripper]\nname = "gripper"\n', f'[gripper]\nname = "gripper"\n{line}\n')
    with pytest.raises(ConfigError, match=message):
        load_arm(write(tmp_path, text))
