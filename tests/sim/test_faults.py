"""Fault options as URLs and the command line spell them."""

from __future__ import annotations

import pytest

from drivers.control_table import HardwareError
from retarget.errors import ConfigError
from sim.faults import Faults, HardwareFault, ReplyFaults, wire_time


def test_options_parse_bus_wide_and_per_servo():
    f = Faults.from_options(
        drop=["0.1", "3:0.5"],
        corrupt=["0.01"],
        delay_ms=["2,4:40"],
        unplug=["4@1.5", "5@3"],
        hwerror=["3:overload@2", "1:input_voltage@0"],
        wire="1",
        seed="7",
    )
    assert f.bus == ReplyFaults(drop=0.1, corrupt=0.01, delay=0.002)
    assert f.for_servo(3) == ReplyFaults(drop=0.5, corrupt=0.01, delay=0.002)
    assert f.for_servo(4) == ReplyFaults(drop=0.1, corrupt=0.01, delay=0.04)
    assert f.for_servo(9) == f.bus
    assert f.unplug == {4: 1.5, 5: 3.0}
    assert f.hardware == [
        HardwareFault(3, HardwareError.OVERLOAD, 2.0),
        HardwareFault(1, HardwareError.INPUT_VOLTAGE, 0.0),
    ]
    assert f.wire and f.seed == 7 and f.active


def test_defaults_are_inactive():
    f = Faults()
    assert not f.active and not f.wire
    assert f.roll(0.0) is False and f.roll(1.0) is True


def test_from_query_takes_the_last_flag():
    f = Faults.from_query({"wire": ["0", "1"], "seed": ["3"], "drop": ["0.2"]})
    assert f.wire and f.seed == 3 and f.bus.drop == 0.2


@pytest.mark.parametrize(
    ("options", "match"),
    [
        pytest.param({"drop": ["lots"]}, "drop: Expected a number", id="drop-text"),
        pytest.param({"drop": ["1.5"]}, r"drop: Expected a fraction in \[0, 1\]", id="drop-range"),
        pytest.param({"delay_ms": ["-3"]}, "delay_ms: Expected a finite value >= 0", id="delay-negative"),
        pytest.param({"corrupt": ["x:0.1"]}, "corrupt: Expected a servo ID", id="servo-id"),
        pytest.param({"unplug": ["4"]}, "unplug: Expected ID@SECONDS", id="unplug-form"),
        pytest.param({"unplug": ["300@1"]}, "unplug: Expected a servo ID 0..252", id="unplug-id"),
        pytest.param({"hwerror": ["3@2"]}, "hwerror: Expected ID:KIND@SECONDS", id="hwerror-form"),
        pytest.param({"hwerror": ["3:melting@2"]}, "hwerror: Expected a kind among", id="hwerror-kind"),
        pytest.param({"wire": "maybe"}, "wire: Expected 0 or 1", id="wire"),
        pytest.param({"seed": "x"}, "seed: Expected an integer", id="seed"),
    ],
)
def test_option_errors_name_the_option(options, match):
    with pytest.raises(ConfigError, match=match) as info:
        Faults.from_options(source="sim://?x", **options)
    assert info.value.path == "sim://?x"


def test_wire_time():
    assert wire_time(154, 1_000_000) == pytest.approx(1.54e-3)
    assert wire_time(1, 57600) == pytest.approx(173.6e-6, rel=1e-3)
