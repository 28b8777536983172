"""drivers.latency against a fake sysfs tree."""

from __future__ import annotations

import logging
import os
from pathlib import Path

import pytest

from drivers.latency import check_latency_timer, tty_device


def _fake_sysfs(tmp_path, device="ttyUSB0", value="16"):
    d = tmp_path / "bus" / "usb-serial" / "devices" / device
    d.mkdir(parents=True)
    (d / "latency_timer").write_text(f"{value}\n")
    return d / "latency_timer"


@pytest.mark.parametrize(
    ("port", "device"),
    [
        ("/dev/ttyUSB0", "ttyUSB0"),
        ("/dev/ttyUSB12", "ttyUSB12"),
        ("/dev/ttyACM0", None),
        ("COM3", None),
        ("socket://localhost:4000", None),
        ("sim://wx250s", None),
    ],
    ids=["usb0", "usb12", "acm", "windows", "socket", "sim"],
)
def test_tty_device(port, device):
    assert tty_device(port) == device


def test_symlink_is_followed(tmp_path):
    link = tmp_path / "usb-FTDI_U2D2-if00-port0"
    os.symlink("/dev/ttyUSB3", link)
    assert tty_device(str(link)) == "ttyUSB3"


def test_high_timer_is_lowered_when_writable(tmp_path):
    path = _fake_sysfs(tmp_path)
    result = check_latency_timer("/dev/ttyUSB0", sysfs_root=tmp_path)
    assert (result.before_ms, result.after_ms, result.ok) == (16, 1, True)
    assert path.read_text().strip() == "1"


def test_read_only_timer_warns_with_the_fix(tmp_path, caplog, monkeypatch):
    _fake_sysfs(tmp_path)

    def refuse(self, *args, **kwargs):  # what a non-root user meets on the real sysfs file
        raise PermissionError(13, "Permission denied", str(self))

    monkeypatch.setattr(Path, "write_text", refuse)
    with caplog.at_level(logging.WARNING, logger="drivers.latency"):
        result = check_latency_timer("/dev/ttyUSB0", sysfs_root=tmp_path)
    assert result.after_ms == 16 and not result.ok
    assert "Permission denied" in caplog.text and "udev" in caplog.text and "echo 1 | sudo tee" in caplog.text


def test_no_fix_only_warns(tmp_path, caplog):
    path = _fake_sysfs(tmp_path)
    with caplog.at_level(logging.WARNING, logger="drivers.latency"):
        result = check_latency_timer("/dev/ttyUSB0", sysfs_root=tmp_path, fix=False)
    assert result.after_ms == 16 and path.read_text().strip() == "16"
    assert "echo 1 | sudo tee /sys/bus/usb-serial/devices/ttyUSB0/latency_timer" in caplog.text


def test_already_low_is_left_alone(tmp_path):
    path = _fake_sysfs(tmp_path, value="1")
    result = check_latency_timer("/dev/ttyUSB0", sysfs_root=tmp_path)
    assert result.ok and path.read_text().strip() == "1"


@pytest.mark.parametrize("port", ["/dev/ttyUSB5", "sim://wx250s", "COM3"], ids=["no-sysfs-entry", "sim", "windows"])
def test_not_ftdi_gives_none(tmp_path, port):
    assert check_latency_timer(port, sysfs_root=tmp_path) is None


def test_garbage_value_warns(tmp_path, caplog):
    _fake_sysfs(tmp_path, value="fast")
    with caplog.at_level(logging.WARNING, logger="drivers.latency"):
        assert check_latency_timer("/dev/ttyUSB0", sysfs_root=tmp_path) is None
    assert "cannot read" in caplog.text
