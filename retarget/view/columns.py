"""Tick records as columns: the per-tick arrays the views log, built once from a batch of
:class:`~retarget.control.loop.TickRecord` (pure numpy, no drawing library)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from retarget.control.loop import TickRecord

__all__ = ["TickColumns"]


@dataclass(frozen=True)
class TickColumns:
    """``n`` ticks side by side.  Angles radians, target metres (base frame), times seconds."""

    tick: np.ndarray  #: ``(n,)`` int64 slot index (negative in a lead-in)
    time: np.ndarray  #: ``(n,)`` run time, loop clock
    clip_time: np.ndarray  #: ``(n,)``
    target: np.ndarray  #: ``(n, 3)`` after the workspace clamp
    q_cmd: np.ndarray  #: ``(n, n_joints)``
    q_present: np.ndarray | None  #: ``(n, n_joints)``, NaN rows where nothing was read; None: no tick read any
    ik_error: np.ndarray  #: ``(n,)`` metres
    ik_sweeps: np.ndarray  #: ``(n,)`` int
    compute_time: np.ndarray  #: ``(n,)``
    bus_time: np.ndarray  #: ``(n,)``
    clamped: np.ndarray  #: ``(n,)`` bool
    velocity_limited: np.ndarray  #: ``(n,)`` bool
    overrun: np.ndarray  #: ``(n,)`` bool
    bus_retries: np.ndarray  #: ``(n,)`` int
    stale: np.ndarray  #: ``(n,)`` int

    @classmethod
    def of(cls, records: Sequence[TickRecord]) -> TickColumns:
        """The columns of ``records`` (at least one)."""
        if not records:
            raise ValueError("Expected at least one tick record, got none")
        n_joints = len(records[0].q_cmd)
        present = None
        if any(r.q_present is not None for r in records):
            blank = np.full(n_joints, np.nan)
            present = np.array([blank if r.q_present is None else r.q_present for r in records], dtype=np.float64)
        return cls(
            tick=np.array([r.tick for r in records], dtype=np.int64),
            time=np.array([r.time for r in records], dtype=np.float64),
            clip_time=np.array([r.clip_time for r in records], dtype=np.float64),
            target=np.array([r.target for r in records], dtype=np.float64).reshape(-1, 3),
            q_cmd=np.array([r.q_cmd for r in records], dtype=np.float64).reshape(-1, n_joints),
            q_present=present,
            ik_error=np.array([r.ik_error for r in records], dtype=np.float64),
            ik_sweeps=np.array([r.ik_sweeps for r in records], dtype=np.int64),
            compute_time=np.array([r.compute_time for r in records], dtype=np.float64),
            bus_time=np.array([r.bus_time for r in records], dtype=np.float64),
            clamped=np.array([r.clamped for r in records], dtype=bool),
            velocity_limited=np.array([r.velocity_limited for r in records], dtype=bool),
            overrun=np.array([r.overrun for r in records], dtype=bool),
            bus_retries=np.array([r.bus_retries for r in records], dtype=np.int64),
            stale=np.array([r.stale for r in records], dtype=np.int64),
        )

    def __len__(self) -> int:
        return int(self.tick.shape[0])
