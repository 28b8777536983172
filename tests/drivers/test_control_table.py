"""The register tables: consistent, matching the e-Manual's key facts, and the encode/decode helpers."""

from __future__ import annotations

import math

import pytest

from drivers import control_table as ct
from drivers import units
from retarget.arm import SERVO_MODELS
from retarget.errors import ConfigError


def test_models_are_the_arm_models():
    assert set(ct.MODELS) == set(SERVO_MODELS)
    assert {m.number for m in ct.MODELS.values()} == {1060, 1020, 1200, 1120}
    assert all(ct.MODEL_BY_NUMBER[m.number] is m for m in ct.MODELS.values())


@pytest.mark.parametrize("model", list(ct.MODELS.values()), ids=lambda m: m.name)
def test_registers_do_not_overlap_and_defaults_fit(model):
    regs = sorted(model.registers.values(), key=lambda r: r.address)
    for a, b in zip(regs, regs[1:], strict=False):
        assert a.end <= b.address, (a.name, b.name)
    assert regs[-1].end <= model.table_size
    memory = model.defaults()
    assert len(memory) == model.table_size
    for reg in regs:
        if reg.default is not None:
            assert reg.in_range(reg.default), reg.name
            assert reg.decode(memory[reg.address : reg.end]) == reg.default
    assert model.register("Model Number").default == model.number
    assert all(r.eeprom == (r.address < 64) for r in regs)


# (model, register, address, size, default) as printed in the e-Manual control tables
MANUAL_FACTS = [
    ("XL430-W250", "Velocity Limit", 44, 4, 265),
    ("XL430-W250", "Present Load", 126, 2, 0),
    ("XM430-W350", "Current Limit", 38, 2, 1193),
    ("XM430-W350", "Velocity Limit", 44, 4, 200),
    ("XL330-M288", "Current Limit", 38, 2, 1750),
    ("XL330-M288", "Shutdown", 63, 1, 53),
    ("XM540-W270", "Current Limit", 38, 2, 2047),
    ("XM540-W270", "Velocity Limit", 44, 4, 128),
    ("XM540-W270", "Goal Position", 116, 4, None),
    ("XM540-W270", "Return Delay Time", 9, 1, 250),
]


@pytest.mark.parametrize(("name", "register", "address", "size", "default"), MANUAL_FACTS)
def test_manual_facts(name, register, address, size, default):
    reg = ct.MODELS[name].register(register)
    assert (reg.address, reg.size, reg.default) == (address, size, default)


def test_model_specific_items():
    xl430 = ct.model("XL430-W250")
    assert xl430.load_register == "Present Load" and xl430.current_unit_ma is None
    assert "Goal Current" not in xl430.registers
    assert ct.OperatingMode.CURRENT not in xl430.operating_modes
    assert ct.model(1020).load_register == "Present Current"
    assert "External Port Data 1" in ct.model("XM540-W270").registers
    assert ct.model("xl330-m288").max_baud_code == 6
    assert all(m.fast_sync_read for m in ct.MODELS.values())


def test_lookup_errors():
    with pytest.raises(KeyError, match="Expected one of XL430-W250"):
        ct.model("XM999")
    with pytest.raises(KeyError, match="XL430-W250 has no register 'Goal Current'"):
        ct.model("XL430-W250").register("Goal Current")


def test_encode_decode_round_trip_and_errors():
    reg = ct.model("XM430-W350").register("Homing Offset")
    for value in (-1_044_479, -1, 0, 1, 1_044_479):
        assert reg.decode(reg.encode(value)) == value
    assert reg.encode(-1) == b"\xff\xff\xff\xff"
    with pytest.raises(ValueError, match="LED: expected 0..255, got 256"):
        ct.model("XM430-W350").register("LED").encode(256)
    with pytest.raises(ValueError, match="expected 4 bytes, got 2"):
        reg.decode(b"\x00\x00")
    assert not reg.in_range(1_044_480)


def test_covering_and_at():
    model = ct.model("XM430-W350")
    assert [r.name for r in model.covering(108, 12)] == ["Profile Acceleration", "Profile Velocity", "Goal Position"]
    assert model.at(116).name == "Goal Position" and model.at(117) is None


def test_units_and_names():
    assert ct.RAD_PER_PULSE * ct.PULSES_PER_REV == pytest.approx(2 * math.pi)
    assert units.RAD_PER_PULSE is ct.RAD_PER_PULSE and units.PULSES_PER_REV == 4096
    # drivers.units encodes joints with the table's units, not copies of them
    assert units.velocity_units_to_rad_s(1) == pytest.approx(0.229 * 2 * math.pi / 60)
    assert units.rad_s2_to_accel_units(214.577 * 2 * math.pi / 3600) == 1
    assert ct.RETURN_DELAY_UNIT_S == 2e-6 and ct.VOLT_PER_UNIT == 0.1
    assert ct.hardware_error_names(0x25) == ("input_voltage", "overheating", "overload")
    assert ct.BAUD_CODES[1_000_000] == 3 and ct.BAUD_RATES[1] == 57600


def test_common_register_is_the_same_on_every_model():
    goal = ct.common_register("Goal Position")
    assert (goal.address, goal.size) == (116, 4)
    assert all(m.register("Goal Position") == goal for m in ct.MODELS.values())
    assert ct.common_register("Present Current").address == ct.XL430_W250.register("Present Load").address == 126
    with pytest.raises(KeyError, match="no model has a register 'Goal Torque'"):
        ct.common_register("Goal Torque")
    with pytest.raises(ValueError, match="'Indirect Data 1' differs between models"):
        ct.common_register("Indirect Data 1")  # 224 on X430/X540, 208 on XL330


@pytest.mark.parametrize(
    ("text", "ids"),
    [
        ("1-3", (1, 2, 3)),
        ("5", (5,)),
        ("1,3,5-6", (1, 3, 5, 6)),
        (" 8 , 1 - 2", (1, 2, 8)),
        ("0-252", tuple(range(253))),
    ],
    ids=["range", "one", "mixed", "spaces-and-order", "all"],
)
def test_parse_ids(text, ids):
    assert ct.parse_ids(text) == ids


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("a-b", "IDs like 1-6 or 1,3,5 .got 'a-b'"),
        ("5-1", "within 0..252, low before high .got '5-1'"),
        ("253", "within 0..252"),
        ("-", "IDs like"),
        ("1,,2", "IDs like"),
        ("1-5,4", "distinct IDs; repeated: 4"),
    ],
    ids=["letters", "reversed", "too-high", "dash", "empty-part", "overlap"],
)
def test_parse_ids_rejects(text, match):
    with pytest.raises(ConfigError, match=r"^ids: .*" + match) as info:
        ct.parse_ids(text)
    assert info.value.key == "ids"  # the library names its field; the CLI maps it to --ids
