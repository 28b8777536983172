"""The control socket of ``retarget sim --control``: move limp joints by hand and read the servos while it serves.

A line-based text protocol on loopback TCP (``127.0.0.1:PORT``) or a unix socket (``unix:/path``), one command per
line, one JSON object per line back (``"ok": true`` and the result, or ``"ok": false`` and ``"error"``)::

    hand 2 sweep 1024 3072 2.0    -> {"ok": true, "id": 2, "hand": "sweep 1024..3072, 2 s per pass", "torque": false}
    hand 2 to 3000 1.0            -> {"ok": true, "id": 2, "hand": "to 3000 in 1 s", "torque": false}
    release 2                     -> {"ok": true, "id": 2, "hand": null, "torque": false}
    status [ID ...]               -> {"ok": true, "t": 12.5, "servos": [{"id": 1, "torque": false, "position": 2048,
                                      "velocity": 0, "moving": 0, "hand": null}, ...]}
    help                          -> {"ok": true, "commands": [...]}

Pulses (4096 per turn) and seconds, as ``--hand`` (:mod:`sim.hand_commands`); ``t`` is seconds since the simulator
started; ``position``, ``velocity`` and ``moving`` are the Present Position (pulses), Present Velocity (0.229 rpm
units) and Moving items, read without a packet on the bus.  A hand on a servo under torque waits: the motor holds
until torque goes off (``"torque": true`` says so).
Try it with ``nc 127.0.0.1 PORT`` or ``socat - UNIX-CONNECT:/path``.

The server runs in the serving loop of :mod:`sim.server` (a :class:`~sim.server.ServerHook`), so commands take
effect between packets, without locks.

>>> from retarget.control.clock import VirtualClock
>>> from sim.bus import SimBus
>>> from sim.hand_commands import HandSchedule
>>> bus = SimBus.from_ids([1, 2], clock=VirtualClock())
>>> control = ControlServer("127.0.0.1:0", HandSchedule(bus, []))
>>> control.execute("hand 2 to 3000 1.0")
'{"ok": true, "id": 2, "hand": "to 3000 in 1 s", "torque": false}'
>>> control.execute("hand 9 to 3000 1.0")
'{"ok": false, "error": "no servo with ID 9 on the bus (IDs: [1, 2])"}'
>>> control.close()
"""

from __future__ import annotations

import contextlib
import json
import logging
import math
import os
import socket
from collections.abc import Sequence
from typing import Any

from retarget.errors import ConfigError
from sim.hand_commands import SOCKET_FORMS, HandSchedule, parse_words

__all__ = ["ControlServer", "parse_address"]

log = logging.getLogger(__name__)

MAX_LINE = 1024  #: bytes of one command line; a longer one is an error and is dropped
MAX_CLIENTS = 8  #: connections at once; more are refused
COMMANDS = (SOCKET_FORMS.replace(" | ", "\n") + "\nstatus [ID ...]\nhelp").splitlines()


def parse_address(text: str) -> tuple[int, Any]:
    """``--control`` as (socket family, address): ``[HOST:]PORT`` (loopback by default) or ``unix:PATH``.

    >>> parse_address("4001"), parse_address("unix:/tmp/sim.sock")[1]
    ((<AddressFamily.AF_INET: 2>, ('127.0.0.1', 4001)), '/tmp/sim.sock')
    """
    if text.startswith("unix:"):
        path = text.removeprefix("unix:")
        if not path:
            raise ConfigError("Expected unix:PATH", key="--control", value=text)
        return socket.AF_UNIX, path
    host, sep, port = text.rpartition(":")
    try:
        number = int(port)
    except ValueError:
        raise ConfigError(
            "Expected [HOST:]PORT or unix:PATH, e.g. 127.0.0.1:4001", key="--control", value=text
        ) from None
    if not 0 <= number <= 65535:
        raise ConfigError("Expected a port 0..65535", key="--control", value=text)
    return socket.AF_INET, ((host if sep and host else "127.0.0.1"), number)


class ControlServer:
    """Listens on ``address`` (see :func:`parse_address`) and runs the commands of the module docstring on the bus
    of ``hands``.  :attr:`address` is what it listens on (the port chosen for port 0).  Close with :meth:`close`."""

    def __init__(self, address: str, hands: HandSchedule):
        self.hands = hands
        self.bus = hands.bus
        family, where = parse_address(address)
        self._unix_path: str | None = where if family == socket.AF_UNIX else None
        try:
            if family == socket.AF_UNIX:
                self._listener = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
                self._listener.bind(where)
                self._listener.listen()
            else:
                self._listener = socket.create_server(where)
        except OSError as exc:
            raise ConfigError(
                f"Expected an address to listen on ({exc.strerror})", key="--control", value=address
            ) from exc
        self._listener.setblocking(False)
        name = self._listener.getsockname()
        self.address = f"unix:{name}" if family == socket.AF_UNIX else f"{name[0]}:{name[1]}"
        self._clients: dict[int, tuple[socket.socket, bytearray]] = {}

    # ------------------------------------------------------------------ ServerHook

    def fds(self) -> Sequence[int]:
        return [self._listener.fileno(), *self._clients]

    def due(self) -> float:
        return math.inf

    def service(self, ready: Sequence[int], now: float) -> None:
        if self._listener.fileno() in ready:
            self._accept()
        for fd in [fd for fd in self._clients if fd in ready]:
            self._read(fd)

    # ------------------------------------------------------------------ connections

    def _accept(self) -> None:
        with contextlib.suppress(BlockingIOError):
            conn, _ = self._listener.accept()
            if len(self._clients) >= MAX_CLIENTS:
                with contextlib.suppress(OSError):
                    conn.sendall(b'{"ok": false, "error": "too many control connections"}\n')
                conn.close()
                return
            conn.setblocking(False)
            self._clients[conn.fileno()] = (conn, bytearray())

    def _read(self, fd: int) -> None:
        conn, buffer = self._clients[fd]
        try:
            data = conn.recv(4096)
        except BlockingIOError:
            return
        except OSError:
            data = b""
        if not data:
            self._drop(fd)
            return
        buffer += data
        while b"\n" in buffer:
            line, _, rest = bytes(buffer).partition(b"\n")
            buffer[:] = rest
            self._reply(fd, self.execute(line.decode("utf-8", "replace")))
        if len(buffer) > MAX_LINE:
            buffer.clear()
            self._reply(fd, _error(f"Expected a line of at most {MAX_LINE} bytes"))

    def _reply(self, fd: int, text: str) -> None:
        if not text or fd not in self._clients:
            return
        try:
            self._clients[fd][0].sendall(text.encode() + b"\n")
        except OSError:
            self._drop(fd)

    def _drop(self, fd: int) -> None:
        conn, _ = self._clients.pop(fd)
        conn.close()

    def close(self) -> None:
        """Close every connection and the listener (and remove a unix socket's file).  Safe to call twice."""
        for fd in list(self._clients):
            self._drop(fd)
        self._listener.close()
        if self._unix_path is not None:
            with contextlib.suppress(OSError):
                os.unlink(self._unix_path)
            self._unix_path = None

    # ------------------------------------------------------------------ commands

    def execute(self, line: str) -> str:
        """The JSON reply to one command line ('' for a blank line)."""
        words = line.split()
        if not words:
            return ""
        verb = words[0].lower()
        try:
            if verb in ("hand", "release"):
                command = parse_words(words)
                self.hands.apply(command, self.bus.clock.now())
                servo = self.bus.servo(command.id)
                result: dict[str, Any] = {
                    "id": command.id,
                    "hand": self.hands.gestures.get(command.id),
                    "torque": servo.torque,
                }
            elif verb == "status":
                result = self._status(_ids(words[1:], line) if len(words) > 1 else list(self.bus.ids))
            elif verb == "help":
                result = {"commands": list(COMMANDS)}
            else:
                raise ConfigError(
                    f"Expected a command: {', '.join(dict.fromkeys(c.split()[0] for c in COMMANDS))}", value=line
                )
        except ConfigError as exc:
            return _error(str(exc))
        except (KeyError, ValueError) as exc:
            return _error(str(exc.args[0]) if isinstance(exc, KeyError) else str(exc))
        return json.dumps({"ok": True, **result})

    def _status(self, ids: list[int]) -> dict[str, Any]:
        servos = []
        for dxl_id in ids:
            servo = self.bus.servo(dxl_id)
            servos.append(
                {
                    "id": dxl_id,
                    "torque": servo.torque,
                    "position": servo.get("Present Position"),
                    "velocity": servo.get("Present Velocity"),
                    "moving": servo.get("Moving"),
                    "hand": self.hands.gestures.get(dxl_id),
                }
            )
        return {"t": round(self.bus.clock.now() - self.bus.t_start, 6), "servos": servos}


def _ids(words: Sequence[str], line: str) -> list[int]:
    if not all(w.isdigit() for w in words):
        raise ConfigError("Expected status [ID ...] with servo IDs", value=line)
    return [int(w) for w in words]


def _error(message: str) -> str:
    return json.dumps({"ok": False, "error": message})
