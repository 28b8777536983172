"""Teleop target sources: stdin/UDP/one-shot sources in order, their queue, staleness, addresses, loopback."""

from __future__ import annotations

import io
import logging
import random
import socket
import time

import numpy as np
import pytest

from retarget.control.clock import VirtualClock
from retarget.errors import ConfigError
from retarget.teleop.gate import TargetBounds, TargetGate, TargetRejected
from retarget.teleop.sources import OneShotSource, StdinSource, UdpSource, is_loopback, parse_address
from tests.helpers import garbage


@pytest.fixture
def gate(arm):
    return TargetGate(TargetBounds.for_arm(arm), clock=VirtualClock(5.0))


def test_stdin_source_in_order_with_garbage(gate):
    rng = random.Random(11)
    bad = garbage(rng, 1000)
    good = [f"{0.2 + 0.001 * i:.3f} 0 0.2".encode() for i in range(50)]
    lines = bad[:500] + good + bad[500:]
    with StdinSource(gate, io.BytesIO(b"\n".join(lines) + b"\n")) as src:
        src.join(10)
        assert src.closed
        got = src.drain()
    assert [t.seq for t in got] == list(range(50))
    np.testing.assert_allclose([t.position[0] for t in got], [0.2 + 0.001 * i for i in range(50)])
    assert gate.rejects.total == 1000 and src.lines == 1050
    assert src.latest() is got[-1] and src.drain() == []


def test_stdin_oversize_line_is_skipped_whole(gate):
    data = b"x" * 5000 + b" 1 2 3\n0.3 0 0.2\n" + b"9" * 2000  # a long line, a good one, a long last line (no EOL)
    src = StdinSource(gate, io.BytesIO(data)).start()
    src.join(5)
    assert [t.position.tolist() for t in src.drain()] == [[0.3, 0, 0.2]]
    assert src.rejects["oversize"] == 2


def test_stdin_text_stream(gate):
    src = StdinSource(gate, io.StringIO("0.3 0 0.2\r\n\n# hi\nnope\n")).start()
    src.join(5)
    assert len(src.drain()) == 1 and src.rejects["malformed"] == 1 and src.lines == 4


def test_queue_drops_oldest_when_full(gate):
    data = "".join(f"0.3 0 {0.1 + i * 1e-3:.4f}\n" for i in range(10)).encode()
    src = StdinSource(gate, io.BytesIO(data), queue_length=4).start()
    src.join(5)
    assert [t.seq for t in src.drain()] == [6, 7, 8, 9] and src.dropped == 6


def test_stale_detection_on_virtual_clock(gate):
    clock = gate.clock
    src = StdinSource(gate, io.BytesIO(b"0.3 0 0.2\n")).start()
    assert src.wait(5)
    src.join(5)
    assert src.is_stale(clock.now() + 10, 0.5)  # judged at a later time
    t = src.latest().received
    assert not src.is_stale(t + 0.5, 0.5)
    assert src.is_stale(t + 0.5001, 0.5)
    empty = StdinSource(gate, io.BytesIO(b"")).start()
    empty.join(5)
    assert empty.is_stale(clock.now(), 1.0) and empty.closed  # no target at all is stale


def test_one_shot_source(gate):
    src = OneShotSource(gate, "0.3,0,0.2", rpy="0,90,0")
    assert src.closed
    (t,) = src.drain()
    np.testing.assert_allclose(t.position, [0.3, 0, 0.2])
    np.testing.assert_allclose(t.rotation @ [0, 0, 1], [1, 0, 0], atol=1e-12)


@pytest.mark.parametrize(
    ("to", "rpy", "match"),
    [
        ("0.3,0", None, "position: Expected 'x y z'"),
        ("", None, "position: Expected X,Y,Z"),
        ("0.3,0,0.2,0,0,0", None, "position: Expected X,Y,Z metres only"),
        ("nan,0,0.2", None, "position: Expected finite"),
        ("5,0,0.2", None, "position: Expected a point inside the box"),
        ("0.3,0,0.2", "0,0", "rpy: Expected 'x y z'"),
        ("0.3,0,0.2", "#", "rpy: Expected R,P,Y"),
    ],
    ids=["short", "empty", "six", "nan", "box", "rpy-short", "rpy-empty"],
)
def test_one_shot_errors_name_the_option(gate, to, rpy, match):
    with pytest.raises(TargetRejected, match=match):
        OneShotSource(gate, to, rpy=rpy)


def _send(src: UdpSource, payloads: list[bytes], *, batch: int = 50) -> None:
    """Send ``payloads`` to ``src`` in batches, waiting for each batch to be read (UDP drops on a full buffer)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        for i in range(0, len(payloads), batch):
            want = src.datagrams + len(payloads[i : i + batch])
            for p in payloads[i : i + batch]:
                s.sendto(p, src.address)
            deadline = time.monotonic() + 5
            while src.datagrams < want and time.monotonic() < deadline:
                time.sleep(0.001)
            assert src.datagrams == want, "datagrams lost on loopback"


def test_udp_loopback_by_default_and_garbage(gate):
    rng = random.Random(5)
    with UdpSource(gate) as src:
        assert src.address[0] == "127.0.0.1" and src.address[1] > 0
        _send(src, garbage(rng, 1000))
        _send(src, [b"0.3 0 0.2"])
        assert src.wait(5)
        (t,) = src.drain()
        np.testing.assert_allclose(t.position, [0.3, 0, 0.2])
    assert src.closed
    assert src.datagrams == 1001 and gate.rejects.total == 1000 and gate.accepted == 1


def test_udp_oversize_datagram(gate):
    with UdpSource(gate) as src:
        _send(src, [b" " * 2000 + b"0.3 0 0.2", b"0.3 0 0.21"])
        assert src.wait(5)
        assert [t.position[2] for t in src.drain()] == [0.21]
    assert src.rejects["oversize"] == 1


def test_udp_non_loopback_warns(gate, caplog):
    # 192.0.2.1 (TEST-NET-1) is no address of this machine: the warning comes first, then the bind fails,
    # so the test never listens beyond loopback
    with caplog.at_level(logging.WARNING, logger="retarget.teleop.sources"), pytest.raises(ConfigError, match="bind"):
        UdpSource(gate, "192.0.2.1", 0)
    assert "192.0.2.1:0 is NOT loopback" in caplog.text
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="retarget.teleop.sources"):
        UdpSource(gate, "127.0.0.1", 0).close()
    assert caplog.text == ""


def test_udp_bind_error(gate):
    with UdpSource(gate) as src, pytest.raises(ConfigError, match="address: cannot bind UDP"):
        UdpSource(gate, "127.0.0.1", src.address[1])


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("9000", ("127.0.0.1", 9000)),
        ("0.0.0.0:9000", ("0.0.0.0", 9000)),
        ("[::1]:7", ("::1", 7)),
        (":5", ("127.0.0.1", 5)),
    ],
    ids=["port", "host", "v6", "empty-host"],
)
def test_parse_address(text, expected):
    assert parse_address(text) == expected


@pytest.mark.parametrize(
    ("text", "match"), [("x", "numeric"), ("1:2:3", "brackets"), ("70000", "0..65535")], ids=["word", "v6", "range"]
)
def test_parse_address_errors(text, match):
    with pytest.raises(ConfigError, match=match):
        parse_address(text)


@pytest.mark.parametrize(
    ("host", "loop"), [("127.0.0.1", True), ("::1", True), ("localhost", True), ("0.0.0.0", False), ("eth0", False)]
)
def test_is_loopback(host, loop):
    assert is_loopback(host) is loop
