"""One :class:`~retarget.control.bus.Bus` over the arms of a rig: the arms' wires carry each tick at the same time.

The rig's control loop is the single-arm loop run on a composite plant: a joint vector is the arms' joint vectors
concatenated in rig order (``Rig.names``), and :class:`RigBus` is the one bus it drives, over each arm's own bus.

Shapes and units: ``q`` ``(n_joints,) float64`` radians, ``n_joints`` the sum of the arms' joint counts, arm after
arm in the order of the mapping given; :attr:`RigBus.slices` says which part is whose, :meth:`RigBus.split` cuts
a vector into per-arm views.  Joint names are ``"<arm>/<joint>"``.

How the arms run at once (arms on separate ports; a tick costs about the slower arm's wire time, not the sum):

- the tick path (``write_goals``, ``read_positions``, ``request_positions``/``collect_positions``, ``exchange``) stays
  in the calling thread and splits every read: each arm's goals go out (a write waits for no reply), then each arm's
  read request, then each arm's replies are collected; while the first arm's replies are awaited, the others' are
  already on their wires.  The pipelined tick (:meth:`RigBus.exchange`, what the control loop calls) goes arm by arm:
  an arm's replies collected, its goals and its next read request sent at once, then the next arm's, so each arm's
  wire waits for no other arm's host work.  A bus that cannot split a read (its ``request_positions`` does nothing) is
  read in turn.  Threads were measured and lose here (``bench/bench_rig.py``): dynamixel-sdk busy-polls the port for a
  reply, holding the GIL, so two arms' threads take turns in 5 ms slices (the interpreter's switch interval) and a
  tick cost more than the two arms one after the other;
- ``connect``, ``close`` and ``set_torque`` (long sequences: pings, configuration, the move to the rest pose,
  which mostly sleeps) run in one persistent worker thread per arm, started on the first of them and ended by
  :meth:`RigBus.close`; each arm's bus is only ever used by one thread at a time.

Faults: a ``BusError`` of an arm is raised as a ``BusError`` whose message starts with the arm's name
(``"right: servo 4: no status packet ..."``) and that keeps the servo IDs; any other exception is raised as it
is, with a note naming the arm.  Either way only after every arm's call of that tick returned (a request that
failed on one arm still has the others' reads collected), so no arm is left mid-call by the error; when several
arms fail, the first in rig order is raised and the others are logged.  Ctrl-C (KeyboardInterrupt) on the tick
path stops at once, as on one arm's bus.  In the workers it reaches only the calling thread: the arms' calls still
finish, and the error is raised once they did (a Ctrl-C during :meth:`RigBus.close` does not cut the arms' rest
moves short; each is bounded by its own bus's timeout).

Status: :meth:`RigBus.status` merges the arms' counters (see it); :meth:`RigBus.statuses` has each arm's own.

Not supported yet: the grippers.  Each arm's driver still configures and watches its gripper servo, but RigBus
has no ``set_gripper``/``gripper_reading``; call them on an arm's own bus (``rig_bus.buses["left"]``) between
RigBus calls.

>>> import numpy as np
>>> from retarget.control.bus import BusStatus
>>> class Plant:                                   # a tiny in-memory Bus: goals become positions at once
...     def __init__(self, n): self.q, self.n, self.on = np.zeros(n), n, False
...     joint_names = property(lambda self: tuple(f"j{k}" for k in range(self.n)))
...     def connect(self): self.on = True
...     def close(self): self.on = False
...     def write_goals(self, q): self.q = np.array(q)
...     def read_positions(self): return self.q.copy()
...     def request_positions(self): pass
...     def collect_positions(self): return self.q.copy()
...     def exchange(self, q): p, self.q = self.q.copy(), np.array(q); return p
...     def set_torque(self, enabled): pass
...     def status(self): return BusStatus(connected=self.on)
>>> left, right = Plant(2), Plant(3)
>>> with RigBus({"left": left, "right": right}) as bus:
...     bus.write_goals(np.array([0.1, 0.2, 0.3, 0.4, 0.5]))   # (5,) rad: left's 2 joints, then right's 3
...     bus.read_positions().tolist(), right.q.tolist()
...     bus.exchange(np.zeros(5)).tolist(), right.q.tolist()  # the positions before, then the new goals sent
([0.1, 0.2, 0.3, 0.4, 0.5], [0.3, 0.4, 0.5])
([0.1, 0.2, 0.3, 0.4, 0.5], [0.0, 0.0, 0.0])
>>> bus.joint_names[1:3], bus.status().connected, left.on
(('left/j1', 'right/j0'), False, False)
"""

from __future__ import annotations

import logging
import queue
import threading
from collections.abc import Callable, Mapping, Sequence
from functools import partial
from types import MappingProxyType, TracebackType
from typing import Any

import numpy as np
import numpy.typing as npt

from retarget.control.bus import Bus, BusStatus, close_after_failure
from retarget.errors import BusError

__all__ = ["RigBus"]

log = logging.getLogger(__name__)

#: what a worker hands back for one job: the job's return value, or the exception it raised
_Outcome = tuple[Any, BaseException | None]


class _Worker:
    """One arm's thread: runs the jobs given to it one at a time, in order, and hands back each outcome.

    Plain ``queue.SimpleQueue`` hand-offs, a lock each way (about 40 us per call to two arms and back, as a
    ``ThreadPoolExecutor``: ``bench/bench_rig.py``), and each arm keeps its own thread.
    """

    def __init__(self, name: str):
        self._jobs: queue.SimpleQueue[Callable[[], Any] | None] = queue.SimpleQueue()
        self._outcomes: queue.SimpleQueue[_Outcome] = queue.SimpleQueue()
        self.thread = threading.Thread(target=self._serve, name=f"rig-bus-{name}", daemon=True)
        self.thread.start()

    def _serve(self) -> None:
        take, give = self._jobs.get, self._outcomes.put
        while (job := take()) is not None:
            try:
                give((job(), None))
            except BaseException as exc:  # noqa: BLE001 - handed to the calling thread, which raises it
                give((None, exc))

    def give(self, job: Callable[[], Any]) -> None:
        self._jobs.put(job)

    def take(self) -> _Outcome:
        """The next outcome, waiting for it (a Ctrl-C interrupts the wait, not the job)."""
        return self._outcomes.get()

    def stop(self) -> None:
        """End the thread after its last job."""
        self._jobs.put(None)
        self.thread.join()


class RigBus:
    """The buses of a rig's arms as one :class:`~retarget.control.bus.Bus`; see the module docstring.

    ``buses``: arm name -> that arm's bus (connected or not), in rig order; the joint vector follows that order.
    The arms' worker threads start with the first ``connect``, ``close`` or ``set_torque``; :meth:`close` ends
    them (a later one starts new ones).  No call may come while another runs (the control loop's calls never do).
    """

    def __init__(self, buses: Mapping[str, Bus]):
        if not buses:
            raise ValueError("Expected the bus of at least one arm, got none")
        self.names: tuple[str, ...] = tuple(buses)  #: the arms, in rig order
        self.buses: Mapping[str, Bus] = MappingProxyType(dict(buses))  #: arm name -> its own bus
        slices: dict[str, slice] = {}
        start = 0
        for name, bus in self.buses.items():
            slices[name] = slice(start, start + len(bus.joint_names))
            start = slices[name].stop
        #: arm name -> its part of a joint vector ``(n_joints,)``
        self.slices: Mapping[str, slice] = MappingProxyType(slices)
        self.n_joints = start  #: the rig's joint count, the length of every joint vector
        self._joint_names = tuple(f"{name}/{j}" for name, bus in self.buses.items() for j in bus.joint_names)
        self._slice_list = tuple(slices.values())
        # the tick path's bound methods, in rig order
        self._writes = tuple(bus.write_goals for bus in self.buses.values())
        self._requests = tuple(bus.request_positions for bus in self.buses.values())
        self._collects = tuple(bus.collect_positions for bus in self.buses.values())
        self._exchanges = tuple(bus.exchange for bus in self.buses.values())
        self._workers: tuple[_Worker, ...] | None = None

    # ------------------------------------------------------------------ Bus protocol

    @property
    def joint_names(self) -> tuple[str, ...]:
        """``"<arm>/<joint>"`` for every joint, in joint-vector order."""
        return self._joint_names

    def __enter__(self) -> RigBus:
        self.connect()
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        if exc is None:
            self.close()
        else:  # a failing shutdown must not mask the error that ended the block
            close_after_failure(self)

    def __repr__(self) -> str:
        return f"RigBus({', '.join(f'{n}={b!r}' for n, b in self.buses.items())})"

    def connect(self) -> None:
        """Connect every arm at once.  If one fails, close the arms that connected (their shutdown runs), then
        raise that failure (named by arm, as every fault).  A Ctrl-C waits for the connects, then closes every
        arm."""
        try:
            outcomes = self._run([bus.connect for bus in self.buses.values()])
        except KeyboardInterrupt:
            self._close_after_failure(self.names)
            raise
        up = [name for name, (_, exc) in zip(self.names, outcomes, strict=True) if exc is None]
        if len(up) < len(self.names):
            self._close_after_failure(up)
            self._raise_first(outcomes)

    def close(self) -> None:
        """Close every arm at once, each running its own shutdown sequence, even when some close raises; then end
        the worker threads and raise the first failure in rig order.  Safe to call twice."""
        try:
            outcomes = self._run([bus.close for bus in self.buses.values()])
        finally:
            self._stop()
        self._raise_first(outcomes)

    def write_goals(self, q: npt.ArrayLike) -> None:
        """Send goals ``q`` ``(n_joints,) float64`` radians: each arm gets its part (:attr:`slices`) in one write.

        A write waits for no reply: the arms' writes go out one after the other and are on their wires together.
        ValueError, before any arm's write, for another shape or a non-finite goal.
        """
        parts = self._goal_parts(q)
        self._raise_first(self._each([partial(w, p) for w, p in zip(self._writes, parts, strict=True)]))

    def read_positions(self) -> npt.NDArray[np.float64]:
        """Present joint angles ``(n_joints,) float64`` radians: every arm's read requested, then every arm's
        collected, so the arms' replies are on their wires at the same time."""
        sent = self._each(self._requests)
        got = self._each([c if exc is None else _nothing for c, (_, exc) in zip(self._collects, sent, strict=True)])
        self._raise_first([s if s[1] is not None else g for s, g in zip(sent, got, strict=True)])
        return np.concatenate([value for value, _ in got])

    def request_positions(self) -> None:
        """Start every arm's position read; :meth:`collect_positions` ends them.  Nothing else may use the bus in
        between."""
        self._raise_first(self._each(self._requests))

    def collect_positions(self) -> npt.NDArray[np.float64]:
        """Present joint angles ``(n_joints,) float64`` radians of the reads :meth:`request_positions` started."""
        got = self._each(self._collects)
        self._raise_first(got)
        return np.concatenate([value for value, _ in got])

    def exchange(self, q: npt.ArrayLike) -> npt.NDArray[np.float64]:
        """One pipelined tick, arm by arm: each arm's own ``exchange`` (collect its read in flight, send its part
        of the goals ``q`` ``(n_joints,) float64`` radians, request its next read), in rig order.  Returns the
        collected positions ``(n_joints,) float64`` radians.

        Arm by arm, an arm's next write follows its own replies at once, while the next arm's are taken: with
        every arm's collect first (:meth:`collect_positions`, then :meth:`write_goals`, :meth:`request_positions`)
        the first arm's write also waited for the others' collects and writes (``bench/bench_rig.py``: two arms
        at 0.84-0.93 of one arm's tick rate that way, 0.97-1.03 so).  Once an arm's call failed, the arms after it
        only collect (none of them gets this tick's goals; the arms before it did), then the failure is raised as
        any other.  ValueError, before any arm's call, for another shape or a non-finite goal.
        """
        calls = [partial(e, p) for e, p in zip(self._exchanges, self._goal_parts(q), strict=True)]
        outcomes = self._each(calls, once_failed=self._collects)
        self._raise_first(outcomes)
        return np.concatenate([value for value, _ in outcomes])

    def set_torque(self, enabled: bool) -> None:
        """Torque on or off on every arm at once."""
        self._raise_first(self._run([partial(bus.set_torque, enabled) for bus in self.buses.values()]))

    def status(self) -> BusStatus:
        """The arms' statuses merged: ``connected`` when every arm is; ``ticks`` the fewest any arm completed (the
        rig's complete cycles); ``worst_stale`` the worst arm's; the other counters summed over the arms (a rig
        tick that is stale on both arms counts 2 ``stale_ticks``).  ``hardware_errors``: servo ID -> alert names,
        each name prefixed with its arm (``{3: ("right: overload",)}``): IDs repeat across arms, so two arms'
        alerts of one ID share its entry.  Per arm, as each bus reports it: :meth:`statuses`.

        Read in the calling thread: call it between the other calls, as the control loop does.
        """
        statuses = self.statuses()
        alerts: dict[int, tuple[str, ...]] = {}
        for name, s in statuses.items():
            for dxl_id, kinds in s.hardware_errors.items():
                alerts[dxl_id] = alerts.get(dxl_id, ()) + tuple(f"{name}: {kind}" for kind in kinds)
        each = statuses.values()
        return BusStatus(
            connected=all(s.connected for s in each),
            ticks=min(s.ticks for s in each),
            retries=sum(s.retries for s in each),
            errors=sum(s.errors for s in each),
            hardware_errors=alerts,
            stale_reads=sum(s.stale_reads for s in each),
            stale_ticks=sum(s.stale_ticks for s in each),
            worst_stale=max(s.worst_stale for s in each),
            reboots=sum(s.reboots for s in each),
            late_packets=sum(s.late_packets for s in each),
        )

    def statuses(self) -> dict[str, BusStatus]:
        """Arm name -> that arm's own status, in rig order."""
        return {name: bus.status() for name, bus in self.buses.items()}

    # ------------------------------------------------------------------ joint vectors

    def split(self, q: npt.ArrayLike) -> dict[str, npt.NDArray[np.float64]]:
        """Arm name -> its part of ``q`` ``(n_joints,)`` (views, float64); ValueError for another shape."""
        q = np.asarray(q, dtype=np.float64)
        if q.shape != (self.n_joints,):
            arms = ", ".join(f"{n} {s.stop - s.start}" for n, s in self.slices.items())
            raise ValueError(f"Expected goals of shape ({self.n_joints},) in radians ({arms}), got shape {q.shape}")
        return {name: q[s] for name, s in zip(self.names, self._slice_list, strict=True)}

    def _goal_parts(self, q: npt.ArrayLike) -> list[npt.NDArray[np.float64]]:
        """Each arm's part of the goals ``q``, in rig order; ValueError for another shape or a non-finite goal."""
        q = np.asarray(q, dtype=np.float64)
        parts = list(self.split(q).values())
        if not np.isfinite(q).all():
            raise ValueError(f"Expected finite goals in radians, got {q}")
        return parts

    # ------------------------------------------------------------------ the workers

    def _close_after_failure(self, names: Sequence[str]) -> None:
        """Close the arms ``names`` while another failure is in flight: log their close failures; end the workers."""
        try:
            jobs = [self.buses[n].close if n in names else _nothing for n in self.names]
            for name, (_, exc) in zip(self.names, self._run(jobs), strict=True):
                if exc is not None:
                    log.error("%s: closing after a failed connect also failed: %s", name, exc)
        finally:
            self._stop()

    def _started(self) -> tuple[_Worker, ...]:
        if self._workers is None:
            self._workers = tuple(_Worker(name) for name in self.names)
        return self._workers

    def _stop(self) -> None:
        workers, self._workers = self._workers, None
        for worker in workers or ():
            worker.stop()

    def _run(self, jobs: Sequence[Callable[[], Any]]) -> list[_Outcome]:
        """Each arm's job in its worker, at once; the outcomes in rig order, once every job returned.  A Ctrl-C
        while waiting does not stop the wait (the jobs run on): it is raised after the last outcome."""
        workers = self._started()
        for worker, job in zip(workers, jobs, strict=True):
            worker.give(job)
        outcomes: list[_Outcome] = []
        interrupted: KeyboardInterrupt | None = None
        for worker in workers:
            while True:
                try:
                    outcomes.append(worker.take())
                    break
                except KeyboardInterrupt as exc:
                    interrupted = exc
                    log.warning("interrupted: waiting for every arm's call to end first")
        if interrupted is not None:
            raise interrupted
        return outcomes

    @staticmethod
    def _each(
        calls: Sequence[Callable[[], Any]], *, once_failed: Sequence[Callable[[], Any]] | None = None
    ) -> list[_Outcome]:
        """The tick path: each arm's call in turn, in the calling thread, every one even when an earlier one
        raised (a Ctrl-C stops at once); the outcomes in rig order.  With ``once_failed`` (one call per arm), the
        arms after one whose call raised run theirs instead."""
        outcomes: list[_Outcome] = []
        failed = False
        for k, call in enumerate(calls):
            try:
                outcomes.append(((once_failed[k] if failed and once_failed else call)(), None))
            except Exception as exc:  # noqa: BLE001 - raised by _raise_first once every arm had its turn
                outcomes.append((None, exc))
                failed = True
        return outcomes

    def _raise_first(self, outcomes: Sequence[_Outcome]) -> None:
        """Raise the first failure among ``outcomes`` (rig order) with its arm named; log the others."""
        failures = [(name, exc) for name, (_, exc) in zip(self.names, outcomes, strict=True) if exc is not None]
        if not failures:
            return
        for name, exc in failures[1:]:
            log.error("%s: %s", name, exc)
        name, exc = failures[0]
        if isinstance(exc, BusError):
            raise _named(name, exc) from exc
        exc.add_note(f"raised by the bus of rig arm {name!r}")
        raise exc


def _named(name: str, exc: BusError) -> BusError:
    """``exc`` as a BusError whose message starts with the arm's name, with the same servo IDs."""
    named = BusError(f"{name}: {exc.message}", ids=exc.ids)
    named.args = (f"{name}: {exc}",)  # "right: servo 4: ...", not "servo 4: right: ..."
    return named


def _nothing() -> None:
    return None
