"""Where a rig's teleop messages arrive: :class:`RigInput` (fed by hand, or by the stdin and UDP readers).

Each raw message (one line, one datagram) goes through the rig's :class:`~retarget.rig.messages.RigGate`, whole or
not at all; every arm's part of an accepted one goes to that arm's own target
:class:`~retarget.teleop.sources.Source` (:attr:`RigInput.sources`), which that arm's
:class:`~retarget.teleop.follower.Follower` reads (:mod:`retarget.rig.teleop`).  :class:`RigStdinSource` and
:class:`RigUdpSource` are one arm's readers (:mod:`retarget.teleop.sources`: size limit, loopback by default,
threads) feeding a RigInput instead of one gate.

I/O only: no drivers, simulator or serial.
"""

from __future__ import annotations

import threading
from collections.abc import Mapping
from typing import IO

from retarget.rig.messages import RigGate
from retarget.teleop.gate import Target, TargetGate
from retarget.teleop.sources import DEFAULT_UDP_HOST, QUEUE_LENGTH, Source, StdinSource, UdpSource

__all__ = ["RigInput", "RigStdinSource", "RigUdpSource"]


class _ArmSource(Source):
    """One arm's targets, pushed by its :class:`RigInput` (a plain :class:`~retarget.teleop.sources.Source`)."""

    def push(self, target: Target) -> None:
        self._push(target)

    def finish(self) -> None:
        self._finish()


class RigInput:
    """Where a rig's messages go: ``gate`` takes each whole or not at all, and each arm's accepted target goes to
    that arm's source in :attr:`sources` (what its Follower reads).  Thread-safe: a reader thread feeds.

    >>> from retarget.control.clock import VirtualClock
    >>> from retarget.rig import load_rig
    >>> rig_input = RigInput(RigGate.for_rig(load_rig("wx250s-pair"), clock=VirtualClock()))
    >>> rig_input.feed("right 0.3 -0.35 0.2"); rig_input.feed("left nan 0 0")
    >>> [(name, s.queued) for name, s in rig_input.sources.items()], rig_input.gate.counts()["non_finite"]
    ([('left', 0), ('right', 1)], 1)
    """

    def __init__(self, gate: RigGate, *, queue_length: int = QUEUE_LENGTH):
        self.gate = gate
        self.sources: dict[str, _ArmSource] = {
            name: _ArmSource(arm_gate, queue_length=queue_length) for name, arm_gate in gate.gates.items()
        }
        for name, source in self.sources.items():
            source.name = name
        self._cond = threading.Condition()
        self._closed = False

    def feed(self, data: str | bytes, *, source: str = "") -> None:
        """Pass one raw message through the gate; each arm's part of an accepted one goes to its source."""
        targets = self.gate.accept(data, source=source)
        for name, target in (targets or {}).items():
            self.sources[name].push(target)
        with self._cond:
            self._cond.notify_all()

    def put(self, targets: Mapping[str, Target]) -> None:
        """Queue targets accepted already (a one-shot :meth:`~retarget.rig.messages.RigGate.one_shot`)."""
        for name, target in targets.items():
            self.sources[name].push(target)

    def close(self) -> None:
        """No more messages: every arm's source closes."""
        for source in self.sources.values():
            source.finish()
        with self._cond:
            self._closed = True
            self._cond.notify_all()

    @property
    def closed(self) -> bool:
        with self._cond:
            return self._closed

    def wait(self, timeout: float) -> bool:
        """Block up to ``timeout`` real seconds until an arm has a target queued or the input closes; True if so."""
        with self._cond:
            return self._cond.wait_for(lambda: self._closed or any(s.queued for s in self.sources.values()), timeout)


def _reader_gate(gate: RigGate) -> TargetGate:
    """The gate a one-arm reader thread sees: the rig's size limit and its message-level counter (the reader's
    ``feed`` is the rig's, so its bounds are never used)."""
    first = gate.gates[gate.names[0]]
    return TargetGate(first.bounds, clock=first.clock, max_bytes=gate.max_bytes, counter=gate.rejects)


class _IntoRig(Source):
    """A one-arm reader whose messages go to a :class:`RigInput` (``rig_input``) and whose end closes it."""

    rig_input: RigInput

    def feed(self, data: str | bytes) -> None:
        self.rig_input.feed(data, source=self.name)

    def _finish(self) -> None:
        super()._finish()
        self.rig_input.close()


class RigStdinSource(_IntoRig, StdinSource):
    """Two-arm messages from lines of a stream (default stdin's bytes) into ``rig_input``; end of input closes it.
    A line over the size limit is counted ``OVERSIZE`` for the message."""

    def __init__(self, rig_input: RigInput, stream: IO[bytes] | IO[str] | None = None):
        super().__init__(_reader_gate(rig_input.gate), stream)
        self.rig_input = rig_input


class RigUdpSource(_IntoRig, UdpSource):
    """Two-arm messages from UDP datagrams on ``host:port`` (default loopback) into ``rig_input``."""

    def __init__(self, rig_input: RigInput, host: str = DEFAULT_UDP_HOST, port: int = 0):
        super().__init__(_reader_gate(rig_input.gate), host, port)
        self.rig_input = rig_input
