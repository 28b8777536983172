"""The FTDI USB latency timer on Linux.

USB-serial adapters on the FTDI driver (U2D2, USB2Dynamixel, most FT232 cables) buffer replies for
``latency_timer`` milliseconds, 16 by default, so every status packet waits up to 16 ms and a control loop
cannot run faster than about 60 Hz.  Setting it to 1 ms is what ROBOTIS and every ROS driver recommend.

:func:`check_latency_timer` reads ``/sys/bus/usb-serial/devices/ttyUSBn/latency_timer`` for a
``/dev/ttyUSBn`` port (following symlinks such as ``/dev/serial/by-id/...``), writes 1 when it is higher and
writable, and otherwise logs how to fix it.  ``sysfs_root`` lets tests point it at a fake tree.
"""

from __future__ import annotations

import logging
import os
import re
from dataclasses import dataclass
from pathlib import Path

log = logging.getLogger(__name__)

TARGET_MS = 1

_TTY_USB = re.compile(r"^ttyUSB\d+$")


@dataclass(frozen=True)
class LatencyCheck:
    """What :func:`check_latency_timer` found and did."""

    device: str  #: e.g. ``ttyUSB0``
    path: Path  #: the ``latency_timer`` file
    before_ms: int
    after_ms: int  #: equal to ``before_ms`` when it could not be changed

    @property
    def ok(self) -> bool:
        return self.after_ms <= TARGET_MS


def fix_hint(device: str) -> str:
    """The two usual fixes, as one line for a log message."""
    return (
        f"run 'echo 1 | sudo tee /sys/bus/usb-serial/devices/{device}/latency_timer', or make it permanent with a "
        'udev rule: ACTION=="add", SUBSYSTEM=="usb-serial", DRIVER=="ftdi_sio", ATTR{latency_timer}="1" '
        "in /etc/udev/rules.d/99-dynamixel-latency.rules"
    )


def tty_device(port: str) -> str | None:
    """The ``ttyUSBn`` kernel name behind a port path (symlinks resolved), or None for anything else.

    URLs (``socket://``, ``sim://``), ``COM3`` and ``ttyACMn`` (CDC-ACM adapters have no latency timer) give None.
    """
    if "://" in port or not port.startswith("/"):
        return None
    try:
        name = Path(os.path.realpath(port)).name
    except OSError:
        return None
    return name if _TTY_USB.match(name) else None


def check_latency_timer(
    port: str, *, sysfs_root: str | os.PathLike[str] = "/sys", fix: bool = True
) -> LatencyCheck | None:
    """Check (and with ``fix`` set, lower to 1 ms) the FTDI latency timer of ``port``.

    Returns None when the port is not a ``/dev/ttyUSBn`` device or has no ``latency_timer`` file (not FTDI).
    Never raises for a permission problem: it logs a warning with the fix instead.
    """
    device = tty_device(port)
    if device is None:
        return None
    path = Path(sysfs_root) / "bus" / "usb-serial" / "devices" / device / "latency_timer"
    try:
        before = int(path.read_text().strip())
    except FileNotFoundError:
        log.debug("%s has no latency_timer (not an FTDI adapter)", device)
        return None
    except (OSError, ValueError) as exc:
        log.warning("cannot read %s (%s); %s", path, exc, fix_hint(device))
        return None
    if before <= TARGET_MS:
        return LatencyCheck(device, path, before, before)
    if fix:
        try:
            path.write_text(f"{TARGET_MS}\n")
            after = int(path.read_text().strip())
        except (OSError, ValueError) as exc:
            log.warning(
                "%s: USB latency timer is %d ms (every read waits up to that long) and cannot be set (%s); %s",
                device,
                before,
                exc,
                fix_hint(device),
            )
            return LatencyCheck(device, path, before, before)
        log.info("%s: USB latency timer lowered from %d ms to %d ms", device, before, after)
        return LatencyCheck(device, path, before, after)
    log.warning(
        "%s: USB latency timer is %d ms (every read waits up to that long); %s", device, before, fix_hint(device)
    )
    return LatencyCheck(device, path, before, before)
