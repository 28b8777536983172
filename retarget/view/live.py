"""A live view fed by the control loop, off the tick's critical path.

The loop's ``on_tick`` only enqueues the :class:`~retarget.control.loop.TickRecord` (``put_nowait`` on a
bounded queue; when full the record is dropped and counted).  A background thread drains the queue in
batches (at most every ``batch_s`` seconds) and logs each batch as columns
(:func:`~retarget.view.rerun_log.log_ticks`).  :meth:`LiveView.close` drains what is left, then flushes.

    with open_recording(scene, outputs) as rec, LiveView(rec, scene) as live:
        loop.on_tick = live
        loop.run(bus)
"""

from __future__ import annotations

import logging
import queue
import threading
import time
from types import TracebackType

import rerun as rr

from retarget.control.loop import TickRecord
from retarget.view.columns import TickColumns
from retarget.view.rerun_log import log_ticks
from retarget.view.scene import Scene

__all__ = ["LiveView"]

log = logging.getLogger(__name__)

_STOP = object()


class LiveView:
    """A bounded queue of tick records and the thread that logs them; callable as ``on_tick``."""

    def __init__(self, rec: rr.RecordingStream, scene: Scene, *, maxsize: int = 10_000, batch_s: float = 0.1):
        self.rec, self.scene, self.batch_s = rec, scene, batch_s
        self.queue: queue.Queue[object] = queue.Queue(maxsize=maxsize)
        self.dropped = 0  #: records not logged because the queue was full
        self.logged = 0  #: records logged
        self._thread = threading.Thread(target=self._drain, name="retarget-view", daemon=True)

    def __call__(self, record: TickRecord) -> None:
        try:
            self.queue.put_nowait(record)
        except queue.Full:
            self.dropped += 1

    def start(self) -> LiveView:
        self._thread.start()
        return self

    def close(self) -> None:
        """Log what is queued, stop the thread, flush the recording."""
        if self._thread.is_alive():
            self.queue.put(_STOP)
            self._thread.join()
        self.rec.flush()
        if self.dropped:
            log.warning("view: %d tick records dropped (the logger fell behind)", self.dropped)

    def __enter__(self) -> LiveView:
        return self.start()

    def __exit__(self, *exc: type[BaseException] | BaseException | TracebackType | None) -> None:
        self.close()

    def _drain(self) -> None:
        stop = False
        while not stop:
            batch: list[TickRecord] = []
            item = self.queue.get()
            deadline = time.monotonic() + self.batch_s
            while True:
                if item is _STOP:
                    stop = True
                    break
                if isinstance(item, TickRecord):
                    batch.append(item)
                try:
                    item = self.queue.get(timeout=max(0.0, deadline - time.monotonic()))
                except queue.Empty:
                    break
            if batch:
                try:
                    log_ticks(self.rec, self.scene, TickColumns.of(batch))
                    self.logged += len(batch)
                except Exception:  # never take the run down with the view
                    log.exception("view: logging %d ticks failed", len(batch))
