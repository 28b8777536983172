"""``retarget sim --rig``: every arm of a rig on its own simulated bus, each on a pty or a loopback TCP port.

Stdout gets one line per arm, ``NAME=WHERE`` (a pty path or a socket:// URL), in the rig's order: each line is
a ready ``--port`` value for the rig's replay and teleop.  The fault options apply to every bus alike (each
with its own seeded stream); hands, the control socket, mounts and ``--ids`` belong to one arm and are refused.
"""

from __future__ import annotations

import argparse
import contextlib
import signal
import sys
import threading
from collections.abc import Callable, Iterator

from retarget.arm.model import Arm
from retarget.errors import ConfigError
from retarget.rig import load_rig
from sim.bus import SimBus
from sim.server import PtyServer, SimServer, TcpServer

__all__ = ["serve_rig", "stop_on_signals"]

_ONE_ARM_OPTIONS = (("ids", "--ids"), ("arm", "--arm"), ("model", "--model"), ("base", "--base"), ("tip", "--tip"))
_ONE_ARM_LISTS = (("mount", "--mount"), ("reverse", "--reverse"), ("hand", "--hand"))


def refuse_one_arm_options(args: argparse.Namespace) -> None:
    for field, option in _ONE_ARM_OPTIONS:
        if getattr(args, field) is not None:
            raise ConfigError("Expected no such option with --rig (each arm's servos come from the rig file)",
                              key=option, value=getattr(args, field))  # fmt: skip
    for field, option in (*_ONE_ARM_LISTS, ("control", "--control")):
        value = getattr(args, field)
        if value:
            raise ConfigError("Expected no such option with --rig (it is one arm's)", key=option, value=value)


def _servers(
    args: argparse.Namespace, make_bus: Callable[[Arm], SimBus], tcp: tuple[str, int] | None
) -> list[tuple[str, SimServer, str]]:
    """One server per rig arm: ``(name, server, where)``; closes what it opened when one fails."""
    rig = load_rig(args.rig)
    host, port = tcp if tcp is not None else ("", 0)
    out: list[tuple[str, SimServer, str]] = []
    try:
        for i, rig_arm in enumerate(rig.arms):
            bus = make_bus(rig_arm.arm)
            if tcp is not None:
                on_tcp = TcpServer(bus, host, port + i if port else 0)
                out.append((rig_arm.name, on_tcp, on_tcp.url))
            else:
                on_pty = PtyServer(bus)
                out.append((rig_arm.name, on_pty, on_pty.path))
    except BaseException:
        for _, server, _ in out:
            server.close()
        raise
    return out


def serve_rig(args: argparse.Namespace, make_bus: Callable[[Arm], SimBus], tcp: tuple[str, int] | None) -> int:
    """Serve every arm of ``args.rig`` until SIGINT or SIGTERM (exit 0), each on a bus from ``make_bus`` and on a
    pty, or on TCP ``(host, first port)`` (port 0: any free ones); see the module docstring."""
    servers = _servers(args, make_bus, tcp)
    stop = threading.Event()
    threads = [
        threading.Thread(target=s.serve_forever, args=(stop,), name=f"sim-{n}", daemon=True) for n, s, _ in servers
    ]
    with stop_on_signals(stop):
        _serve(args, servers, threads, stop)
    print("retarget sim: stopped", file=sys.stderr)
    return 0


def _serve(
    args: argparse.Namespace, servers: list[tuple[str, SimServer, str]], threads: list[threading.Thread],
    stop: threading.Event,
) -> None:  # fmt: skip
    """Run the servers' threads until ``stop`` is set or one of them ends; then stop and close them all."""
    try:
        for name, _, where in servers:
            print(f"{name}={where}", flush=True)
        for thread in threads:
            thread.start()
        wire = "wire time at the baud rate" if servers[0][1].bus.faults.wire else "no wire time (--no-wire)"
        listing = "; ".join(f"{n} servos {', '.join(map(str, s.bus.ids))} on {w}" for n, s, w in servers)
        print(f"retarget sim: serving rig {args.rig}: {listing} ({wire}); Ctrl-C to stop", file=sys.stderr, flush=True)
        while not stop.wait(0.2):
            if not all(t.is_alive() for t in threads):  # a server ended on its own (an error): stop the others
                break
    finally:
        stop.set()
        for thread in threads:
            thread.join(timeout=2.0)
        for _, server, _ in servers:
            server.close()


@contextlib.contextmanager
def stop_on_signals(stop: threading.Event) -> Iterator[None]:
    """While inside, SIGINT and SIGTERM set ``stop`` (a server's clean end); the previous handlers come back on the
    way out.  Shared by ``retarget sim`` and ``retarget sim --rig``."""

    def on_signal(signum: int, frame: object) -> None:
        stop.set()

    previous = {sig: signal.signal(sig, on_signal) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
