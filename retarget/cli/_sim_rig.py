"""``retarget sim --rig``: every arm of a rig on its own simulated bus, each on a pty or a loopback TCP port.

Stdout gets one line per arm, ``NAME=WHERE`` (a pty path or a socket:// URL), in the rig's order: each line is
a ready ``--port`` value for the rig's replay and teleop.  The fault options apply to every bus alike (each
with its own seeded stream); hands, the control socket, mounts and ``--ids`` belong to one arm and are refused.

Each arm's bus is served by its own process (forked once its pty or port is open; named ``sim-NAME`` in ``ps``), as
each arm of a real rig has its own wire: in one process the arms' simulated servos would share one interpreter
lock, and at 1 Mbps with the wire model on two arms' servos take more Python time per tick than the wire does
(measured: 1.7 ms of CPU per rig tick of ``bench/bench_rig.py``, whose wire time is 1.48 ms), so their replies
would come late.  When one arm's process ends on its own (an error, a kill), the others are stopped and the command
exits 1 with one line naming the arm; an arm's process whose parent is gone (killed) stops by itself.
"""

from __future__ import annotations

import argparse
import contextlib
import multiprocessing
import os
import signal
import sys
import threading
from collections.abc import Callable, Iterator
from multiprocessing.connection import Connection
from multiprocessing.process import BaseProcess
from pathlib import Path

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
    """Serve every arm of ``args.rig``, each on a bus from ``make_bus``, on a pty or on TCP ``(host, first port)``
    (port 0: any free ones), each in its own process, until SIGINT or SIGTERM (exit 0) or until one arm's process
    ends on its own (exit 1, one line naming the arm); see the module docstring."""
    servers = _servers(args, make_bus, tcp)
    stop = threading.Event()
    with stop_on_signals(stop):
        failure = _serve(args, servers, stop)
    if failure is not None:
        print(f"retarget sim: {failure}; stopped the other arms", file=sys.stderr)
        return 1
    print("retarget sim: stopped", file=sys.stderr)
    return 0


class _Arm:
    """One arm's serving process and the pipe it reports a failure on."""

    def __init__(self, name: str, server: SimServer):
        self.name = name
        self.report, child_end = multiprocessing.Pipe(duplex=False)
        self.process: BaseProcess = multiprocessing.get_context("fork").Process(
            target=_serve_arm, args=(name, server, child_end), name=f"sim-{name}", daemon=True
        )
        self.process.start()
        child_end.close()  # the child's copy only: the pipe ends when the child does

    def failure(self) -> str:
        """Why the process ended on its own: its message, or its exit status."""
        with contextlib.suppress(EOFError, OSError):  # EOF: it ended without a word (killed)
            if self.report.poll():
                return f"arm {self.name}: {self.report.recv()}"
        self.process.join(timeout=1.0)
        code = self.process.exitcode
        how = f"killed by signal {-code}" if code is not None and code < 0 else f"exit status {code}"
        return f"arm {self.name}: its server process ended ({how})"

    def stop(self) -> None:
        """SIGTERM (a clean end), then SIGKILL if it is still there after 2 s."""
        if self.process.is_alive():
            self.process.terminate()
            self.process.join(timeout=2.0)
        if self.process.is_alive():
            self.process.kill()
        self.process.join(timeout=2.0)


def _serve(args: argparse.Namespace, servers: list[tuple[str, SimServer, str]], stop: threading.Event) -> str | None:
    """Run each server in its own process until ``stop`` is set (None) or one of them ends (its failure, one
    line); then stop them all and close the servers."""
    arms: list[_Arm] = []
    try:
        for name, _, where in servers:
            print(f"{name}={where}", flush=True)
        wire = "wire time at the baud rate" if servers[0][1].bus.faults.wire else "no wire time (--no-wire)"
        listing = "; ".join(f"{n} servos {', '.join(map(str, s.bus.ids))} on {w}" for n, s, w in servers)
        print(f"retarget sim: serving rig {args.rig}: {listing} ({wire}); Ctrl-C to stop", file=sys.stderr, flush=True)
        for name, server, _ in servers:  # forked with nothing buffered and no thread running
            arms.append(_Arm(name, server))
        while not stop.wait(0.2):
            for arm in arms:
                if not arm.process.is_alive():  # a server ended on its own: stop the others
                    return arm.failure()
        return None
    finally:
        for arm in arms:
            arm.stop()
            arm.report.close()
        for _, server, _ in servers:  # the parent's copies; the children, which used them, have ended
            server.close()


def _serve_arm(name: str, server: SimServer, report: Connection) -> None:
    """In the arm's process: serve until SIGINT or SIGTERM, or until the parent is gone (killed: no server is left
    behind); a failure goes to ``report`` and exits 1."""
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda signum, frame: stop.set())
    threading.Thread(target=_stop_when_orphaned, args=(os.getppid(), stop), daemon=True).start()
    with contextlib.suppress(OSError):  # the name ps and top show (Linux)
        Path("/proc/self/comm").write_text(f"sim-{name}"[:15])
    try:
        server.serve_forever(stop)
    except Exception as exc:  # noqa: BLE001 - reported as one line by the parent
        report.send(f"its server failed: {type(exc).__name__}: {exc}")
        raise SystemExit(1) from None
    if server.pacing.replies and server.bus.faults.wire:
        print(f"retarget sim: {name}: {server.pacing.summary()}", file=sys.stderr, flush=True)


def _stop_when_orphaned(parent: int, stop: threading.Event) -> None:
    """Set ``stop`` once this process's parent is no longer ``parent`` (it died); checks twice a second."""
    while not stop.wait(0.5):
        if os.getppid() != parent:
            stop.set()


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
