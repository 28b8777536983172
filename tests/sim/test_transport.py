"""The ``sim://`` pyserial port: URL grammar, registry, pyserial semantics, virtual-clock waiting, and TCP."""

from __future__ import annotations

import pytest
import serial
from serial.serialutil import PortNotOpenError, SerialException

import sim
from drivers import control_table
from retarget.control.clock import MonotonicClock, VirtualClock
from retarget.errors import ConfigError
from sim.faults import Faults
from sim.protocol import PacketParser, build_instruction
from sim.server import TcpServer
from sim.transport import bus_from_url, parse_ids

PING = build_instruction(1, 0x01)


@pytest.mark.parametrize(
    ("url", "ids", "model"),
    [
        pytest.param("sim://wx250s", tuple(range(1, 10)), "XM430-W350", id="arm"),
        pytest.param("sim://?ids=1-3,7&model=XM540-W270", (1, 2, 3, 7), "XM540-W270", id="ids"),
        pytest.param("sim://?ids=4", (4,), "XL430-W250", id="default-model"),
        pytest.param("SIM://?ids=2&model=xl330-m288", (2,), "XL330-M288", id="case"),
    ],
)
def test_url_builds_the_servos(url, ids, model):
    bus = bus_from_url(url)
    assert bus.ids == ids
    assert bus.servo(ids[0]).model.name == model


def test_url_options():
    bus = bus_from_url("sim://?ids=1-2&baud=57600&rdt=0&boot_ms=800&clock=virtual&drop=2:0.5&wire=1&seed=9")
    assert bus.servo(2).boot_time == 0.8
    assert isinstance(bus.clock, VirtualClock)
    assert bus.baud == 57600 and bus.servo(1).baud == 57600 and bus.servo(1).return_delay == 0
    assert bus.faults.wire and bus.faults.seed == 9 and bus.faults.for_servo(2).drop == 0.5
    assert isinstance(bus_from_url("sim://?ids=1").clock, MonotonicClock)
    assert bus_from_url("sim://?ids=1", port_baud=115200).servo(1).baud == 115200


@pytest.mark.parametrize(
    ("url", "error", "match"),
    [
        pytest.param("loop://", ConfigError, "sim://", id="scheme"),
        pytest.param("sim://", ConfigError, "ids=", id="nothing"),
        pytest.param("sim://?ids=1&colour=red", ConfigError, "unknown option.*colour", id="unknown-option"),
        pytest.param("sim://?ids=1-x", ConfigError, "IDs like", id="bad-ids"),
        pytest.param("sim://?ids=3,3", ConfigError, "distinct", id="duplicate-ids"),
        pytest.param("sim://?ids=1&clock=fast", ConfigError, "clock=real", id="clock"),
        pytest.param("sim://wx250s?delay_ms=inf", ConfigError, "delay_ms: Expected a finite value", id="delay-inf"),
        pytest.param("sim://wx250s?unplug=4@nan", ConfigError, "unplug: Expected a finite value", id="unplug-nan"),
        pytest.param("sim://wx250s?drop=nan", ConfigError, "drop: Expected a finite value", id="drop-nan"),
        pytest.param("sim://wx250s?boot_ms=-1", ConfigError, "boot_ms: Expected a number of millis", id="boot-neg"),
        pytest.param("sim://?ids=1&baud=fast", ConfigError, "baud: Expected an integer", id="baud"),
        pytest.param("sim://?ids=1&boot_ms=x", ConfigError, "boot_ms: Expected a number of milliseconds", id="boot"),
        pytest.param("sim://wx250s?ids=1", ConfigError, "not both", id="arm-and-ids"),
        pytest.param("sim://@nobody", KeyError, "no SimBus registered as 'nobody'", id="unregistered"),
        pytest.param("sim://?ids=1&drop=2", ConfigError, r"fraction in \[0, 1\]", id="drop-range"),
    ],
)
def test_url_errors(url, error, match):
    with pytest.raises(error, match=match):
        bus_from_url(url)


def test_parse_ids_is_the_control_tables():
    assert parse_ids is control_table.parse_ids  # one parser for sim://?ids= and ``retarget scan --ids``
    assert parse_ids("1-3, 8") == (1, 2, 3, 8)
    with pytest.raises(ConfigError, match="0..252"):
        parse_ids("250-253")


def test_registered_bus_by_url():
    bus = sim.SimBus.from_ids([1], clock=VirtualClock())
    url = sim.attach(bus)
    try:
        assert url.startswith("sim://@")
        port = serial.serial_for_url(url, timeout=0)
        assert port.bus is bus
        with pytest.raises(ConfigError, match="options cannot be given"):
            bus_from_url(url + "?drop=0.1")
        port.close()
        assert sim.registered(url) is sim.registered(url.removeprefix("sim://@")) is bus
    finally:
        sim.unregister(url)  # the URL attach returned
    with pytest.raises(KeyError, match="no SimBus registered"):
        sim.registered(url)
    sim.register("test-by-name", bus)
    sim.unregister("test-by-name")  # or the name
    with pytest.raises(KeyError, match="no SimBus registered as 'test-by-name'"):
        sim.registered("sim://@test-by-name")
    with pytest.raises(ValueError, match="without '/'"):
        sim.register("a/b", bus)


def test_open_failure_is_a_serial_exception():
    with pytest.raises(SerialException, match="could not open port 'sim://nosucharm'"):
        serial.serial_for_url("sim://nosucharm")


def test_pyserial_semantics_with_a_virtual_clock():
    port = serial.serial_for_url("sim://?ids=1&clock=virtual", baudrate=1_000_000, timeout=0)
    clock = port.bus.clock
    assert port.read(10) == b""
    assert port.write(PING) == len(PING)
    assert port.in_waiting == 0  # still 500 us away (factory Return Delay Time)
    reply = port.read(100)  # waiting on a virtual wire costs no real time: the clock jumps
    assert clock.now() == pytest.approx(0.0005)
    assert [p.id for p in PacketParser().feed(reply)] == [1]
    port.write(PING)
    clock.advance(0.001)
    assert port.in_waiting == 14
    port.reset_input_buffer()
    assert port.in_waiting == 0 and port.out_waiting == 0
    port.flush()
    port.reset_output_buffer()
    port.close()
    with pytest.raises(PortNotOpenError):
        port.read(1)
    with pytest.raises(PortNotOpenError):
        port.write(PING)


def test_reads_respect_the_wire_on_a_real_clock():
    port = serial.serial_for_url("sim://?ids=1&rdt=0", baudrate=1_000_000, timeout=0.5)
    port.write(PING)
    assert len(port.read(14)) == 14  # blocking read with a timeout returns once the reply is in
    port.timeout = 0
    port.write(build_instruction(7, 0x01))  # nobody: nothing ever arrives
    assert port.read(14) == b""
    port.close()


def test_a_port_at_another_baud_hears_nothing():
    port = serial.serial_for_url("sim://wx250s?clock=virtual", baudrate=57600, timeout=0)
    port.write(PING)
    assert port.read(14) == b""
    port.baudrate = 1_000_000
    port.write(PING)
    assert len(port.read(14)) == 14
    port.close()


def test_tcp_server_with_socket_url():
    bus = sim.SimBus.from_ids([1, 2], clock=VirtualClock(), faults=Faults())
    with TcpServer(bus) as server:
        assert server.url.startswith("socket://127.0.0.1:")
        port = serial.serial_for_url(server.url, timeout=2)
        port.write(build_instruction(2, 0x01))
        reply = port.read(14)
        assert [p.id for p in PacketParser().feed(reply)] == [2]
        port.close()
