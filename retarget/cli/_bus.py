"""The bus options and their plumbing shared by the commands that drive an arm (``replay``, ``teleop``).

``--port`` (a serial port, a pyserial URL, ``sim://…``; none = an in-process simulated bus), ``--fast``
(a virtual clock shared by the loop and the simulator), ``--shutdown``, ``--telemetry``, ``--json`` and
``--progress``, ``--recover``; :func:`build_bus` turns them into a driver and the clock the loop must run on, and
:func:`signals_stop` makes the first Ctrl-C, SIGTERM or SIGHUP stop the loop at a tick boundary so the bus's
shutdown runs.  A run that a bus failure ends carries its summary on the ``BusError`` (``exc.summary``, set by
the control loop); ``--json`` then prints it with the failure in it (:func:`failure_summary`).
"""

from __future__ import annotations

import argparse
import math
import re
import signal
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

import numpy as np

import sim
from drivers import DynamixelBus
from retarget.arm import Arm
from retarget.control import LoopConfig
from retarget.control.bus import Bus
from retarget.control.clock import Clock, MonotonicClock, VirtualClock
from retarget.errors import BusError, ConfigError
from sim.transport import bus_from_url

SHUTDOWN_MODES = ("hold", "rest", "off")
WATCHDOG_MIN_MS, WATCHDOG_MAX_MS = 20.0, 2540.0  #: Bus Watchdog: 1..127 units of 20 ms (drivers.watchdog)


def add_bus_arguments(
    parser: argparse.ArgumentParser | Any, *, shutdown: str = "rest", rig_ports: bool = False
) -> None:
    """--port, --fast, --shutdown (default ``shutdown``), --telemetry, --json, --progress.  ``rig_ports``: ``--port``
    may be repeated (a list, or None): one port, or with ``--rig`` one ``NAME=PORT`` per arm (:func:`one_port`)."""
    helps = {
        "hold": "hold the last goal (default), move to rest then torque off, or torque off",
        "rest": "hold the last goal, move to rest then torque off (default), or torque off",
        "off": "hold the last goal, move to rest then torque off, or torque off (default)",
    }
    parser.add_argument(
        "--port",
        default=None,
        action="append" if rig_ports else "store",
        help="serial port or pyserial URL: /dev/ttyUSB0, COM3, socket://h:p, sim://ARM?... "
        "(default: an in-process simulated bus)"
        + ("; with --rig NAME=PORT, once per arm to override" if rig_ports else ""),
    )
    parser.add_argument("--fast", action="store_true", help="as fast as possible on a virtual clock (simulator only)")
    parser.add_argument(
        "--shutdown", default=shutdown, metavar="hold|rest|off", help=f"on exit/Ctrl-C: {helps[shutdown]}"
    )
    parser.add_argument("--telemetry", default=None, metavar="CSV", help="write one CSV row per tick ('-' = stdout)")
    parser.add_argument("--json", action="store_true", help="print the summary as JSON on stdout")
    parser.add_argument("--progress", action="store_true", help="progress lines on stderr even when not a TTY")
    parser.add_argument(
        "--recover",
        action="store_true",
        help="on a servo's hardware error (overload, overheating, voltage) reboot it and configure it again, up to "
        "3 times per servo, instead of stopping the run. Risk: the reboot drops that servo's torque for a moment "
        "(the joint can sag or fall) and the cause, such as a jam or a load, may still be there",
    )
    parser.add_argument(
        "--watchdog-ms",
        type=float,
        default=None,
        metavar="MS",
        help="arm the servos' Bus Watchdog: if this program dies or the cable is pulled, every servo stops where it "
        f"is within MS ms instead of finishing its last move ({WATCHDOG_MIN_MS:g}..{WATCHDOG_MAX_MS:g}, 20 ms steps, "
        "at least 3 ticks at --rate; default off)",
    )


def check_bus_options(args: argparse.Namespace) -> None:
    """ConfigError naming the option for a bad --shutdown, --fast with a real port, or two writers of stdout."""
    if args.shutdown not in SHUTDOWN_MODES:
        raise ConfigError("Expected hold, rest or off", key="--shutdown", value=args.shutdown)
    if args.fast and not is_sim_port(args.port):
        raise ConfigError("--fast needs the simulated bus (a sim:// port or none), not a real port", key="--port",
                          value=args.port)  # fmt: skip
    watchdog_ms = getattr(args, "watchdog_ms", None)
    in_range = watchdog_ms is None or (math.isfinite(watchdog_ms) and WATCHDOG_MIN_MS <= watchdog_ms <= WATCHDOG_MAX_MS)
    if not in_range:
        message = f"Expected a watchdog period from {WATCHDOG_MIN_MS:g} to {WATCHDOG_MAX_MS:g} ms"
        raise ConfigError(message, key="--watchdog-ms", value=watchdog_ms)
    if args.telemetry == "-" and args.json:
        raise ConfigError("--telemetry - and --json both write to stdout; give the telemetry a file", key="--telemetry",
                          value=args.telemetry)  # fmt: skip


def is_sim_port(port: str | None) -> bool:
    return port is None or port.startswith("sim://")


_NAMED_PORT = re.compile(r"^[A-Za-z][A-Za-z0-9_-]{0,31}=")  #: ``left=...``: a rig arm's name (no URL has one)


def is_named_port(item: str) -> bool:
    """Whether a ``--port`` item is ``NAME=PORT`` (a rig arm's port), not a port or URL (whose ``=`` come later).

    >>> is_named_port("right=/dev/ttyUSB1"), is_named_port("sim://wx250s?drop=0.1"), is_named_port("COM3")
    (True, False, False)
    """
    return bool(_NAMED_PORT.match(item))


def one_port(items: list[str] | str | None) -> str | None:
    """The one port of a repeatable ``--port`` without ``--rig``: None, or its single item; a ConfigError naming
    ``--port`` for a second one or a ``NAME=PORT`` item (an arm's, which needs ``--rig``)."""
    if items is None or isinstance(items, str):
        return items
    for item in items:
        if is_named_port(item):
            raise ConfigError("Expected a port; NAME=PORT gives a rig arm's port and needs --rig", key="--port",
                              value=item)  # fmt: skip
    if len(items) > 1:
        raise ConfigError("Expected one --port (one per arm needs --rig and NAME=PORT)", key="--port", value=items[1])
    return items[0] if items else None


#: the signals that stop a run as Ctrl-C does (those this platform has); the exit status is 128 + the number
STOP_SIGNALS: tuple[signal.Signals, ...] = tuple(
    getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name)
)


class SignalInterrupt(KeyboardInterrupt):
    """A second SIGTERM or SIGHUP: interrupts at once, as a second Ctrl-C does; ``signum`` gives the exit status."""

    def __init__(self, signum: int):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


@dataclass
class Stopped:
    """Which stop signal a run got first (None: none)."""

    signum: int | None = None

    @property
    def exit_status(self) -> int:
        """128 + the signal's number: 130 for Ctrl-C (also without a signal), 143 SIGTERM, 129 SIGHUP."""
        return 128 + (int(signal.SIGINT) if self.signum is None else self.signum)


def say(text: str) -> None:
    """A line on stderr that cannot fail: after a SIGHUP the terminal may be gone."""
    try:
        print(text, file=sys.stderr, flush=True)
    except (OSError, ValueError):
        pass


@contextmanager
def signals_stop(stop: Callable[[], None]) -> Iterator[Stopped]:
    """The first Ctrl-C, SIGTERM or SIGHUP calls ``stop`` (the loop ends at the next tick boundary, and the bus's
    shutdown runs); a second one interrupts at once (KeyboardInterrupt; :class:`SignalInterrupt` for SIGTERM and
    SIGHUP).  Yields the :class:`Stopped` that says which signal came first.  Outside the main thread nothing is
    installed; the previous handlers are put back on exit."""
    stopped = Stopped()

    def handler(signum: int, frame: Any) -> None:
        if stopped.signum is not None:
            if signum == signal.SIGINT:
                raise KeyboardInterrupt
            raise SignalInterrupt(signum)
        stopped.signum = signum
        stop()
        if signum == signal.SIGINT:
            say("retarget: stopping (Ctrl-C again to interrupt)")
        else:
            say(f"retarget: stopping on {signal.Signals(signum).name} (send it again to interrupt)")

    previous: dict[signal.Signals, Any] = {}
    try:
        for signum in STOP_SIGNALS:
            previous[signum] = signal.getsignal(signum)
            signal.signal(signum, handler)
    except ValueError:  # not the main thread
        for signum, old in previous.items():
            signal.signal(signum, old)
        yield stopped
        return
    try:
        yield stopped
    finally:
        for signum, old in previous.items():
            signal.signal(signum, old if old is not None else signal.SIG_DFL)


def failure_summary(summary: dict[str, Any], exc: BusError) -> dict[str, Any]:
    """``--json`` of a run that a bus failure ended: the summary so far and ``error``: kind, message, servo ids."""
    return {**summary, "error": {"kind": "bus", "message": str(exc), "ids": list(exc.ids)}}


@dataclass
class BusSetup:
    """The bus of a run, the clock the loop must run on, and what to undo afterwards."""

    bus: Bus
    clock: Clock
    registered: str | None = None  #: name of an in-process simulated bus this run registered

    def release(self) -> None:
        if self.registered is not None:
            sim.unregister(self.registered)


def servo_limits(arm: Arm, config: LoopConfig | None) -> dict[str, float | None]:
    """The driver's own speed limits for a run with ``config``, its second line of defence behind the loop's.

    ``dt = 1 / rate``: ``write_goals`` limits every joint's step per call to ``max_velocity * dt``.
    ``profile_velocity = velocity_scale x max_velocity`` rad/s: the servos' own profile then runs no faster
    than ``--velocity-scale`` allows, whatever goal reaches them.  The driver takes one value for every joint
    (capped by each joint's own max velocity), so an arm whose joints differ gets its fastest joint's cap;
    the loop still limits each joint to its own.  ``None`` (a velocity scale of 1): each joint's max velocity.
    Nothing without a config.
    """
    if config is None:
        return {}
    scale = config.velocity_scale
    profile_velocity = None if scale >= 1.0 else scale * float(np.max(arm.max_velocity))
    return {"dt": 1.0 / config.rate, "profile_velocity": profile_velocity}


def watchdog_option(args: argparse.Namespace, config: LoopConfig | None) -> dict[str, float]:
    """``--watchdog-ms`` as the driver's ``watchdog`` (s); ConfigError when it is shorter than 3 ticks at ``--rate``."""
    watchdog_ms = getattr(args, "watchdog_ms", None)
    if watchdog_ms is None:
        return {}
    if config is not None and watchdog_ms < 3000.0 / config.rate:
        message = f"Expected at least 3 control ticks ({3000.0 / config.rate:g} ms at --rate {config.rate:g})"
        raise ConfigError(message, key="--watchdog-ms", value=watchdog_ms)
    return {"watchdog": watchdog_ms / 1000.0}


def build_bus(args: argparse.Namespace, arm: Arm, config: LoopConfig | None = None) -> BusSetup:
    """The driver on ``--port``; for a simulated port, the in-process SimBus and the clock shared with it
    (:func:`port_bus`)."""
    return port_bus(args.port, arm, args, config)


def port_bus(
    port: str | None,
    arm: Arm,
    args: argparse.Namespace,
    config: LoopConfig | None = None,
    *,
    clock: VirtualClock | None = None,
) -> BusSetup:
    """The driver of ``arm`` on ``port``, with the other bus options of ``args``; for a simulated port, the SimBus
    and the clock shared with it.  ``clock``: with ``--fast``, the one virtual clock every simulated arm of a rig
    runs on (a registered ``sim://@NAME`` bus must already run on it); None: a clock of this bus's own.

    No ``--port``: every servo of the arm simulated in process, wire-time model on.  ``sim://…``: the
    simulator the URL describes, built here so the loop can share its clock (``--fast`` adds
    ``clock=virtual``).  A real port runs on the monotonic clock.  With the run's ``config`` the driver
    also limits speed itself (:func:`servo_limits`).  ``--recover``: the driver reboots a servo on a hardware
    error and configures it again (``DynamixelBus(recover=True)``).
    """

    limits: dict[str, Any] = {**servo_limits(arm, config), **watchdog_option(args, config)}
    recover = bool(getattr(args, "recover", False))
    if port is not None and not is_sim_port(port):
        wall: Clock = MonotonicClock()
        return BusSetup(DynamixelBus(arm, port, shutdown=args.shutdown, clock=wall, recover=recover, **limits), wall)

    name = None
    if port is None:
        simbus = sim.SimBus.from_arm(
            arm, clock=(clock or VirtualClock()) if args.fast else MonotonicClock(), faults=sim.Faults(wire=True)
        )
    elif port.startswith("sim://@"):
        try:
            simbus = bus_from_url(port)
        except KeyError as exc:  # no bus registered under that name in this process
            raise ConfigError(str(exc.args[0]), key="--port", value=port) from exc
    elif args.fast and clock is not None:
        simbus = bus_from_url(port, clock=clock)
    else:
        url = port + (("&" if "?" in port else "?") + "clock=virtual" if args.fast else "")
        simbus = bus_from_url(url)
    if args.fast and not isinstance(simbus.clock, VirtualClock):
        raise ConfigError("--fast needs a simulated bus on a virtual clock", key="--port", value=port)
    if args.fast and clock is not None and simbus.clock is not clock:
        raise ConfigError("--fast runs every simulated arm on one virtual clock; this registered bus has another",
                          key="--port", value=port)  # fmt: skip
    if port is None or not port.startswith("sim://@"):
        port = sim.attach(simbus)
        name = port  # the URL: sim.unregister takes it as it is
    bus = DynamixelBus(arm, port, shutdown=args.shutdown, clock=simbus.clock, recover=recover, **limits)
    return BusSetup(bus, simbus.clock, name)
