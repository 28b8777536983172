"""The gripper from the clip's hand: a closure track 0 (open) .. 1 (closed) over the clip's time.

Rules (named in the replay summary), tried in this order on the fingers below the driving arm's wrist:

* ``pinch``: the distance from the thumb tip to the index tip, over the forearm length (the hand's size; a
  human forearm is ~0.26 m), mapped linearly from ``PINCH_OPEN`` (open) to ``PINCH_CLOSED`` (closed);
* ``curl``: without a thumb and an index finger, the mean distance from the wrist to each fingertip over the
  same distance in the rest pose (an extended finger is 1, a fist about 0.5), mapped from ``CURL_OPEN`` to
  ``CURL_CLOSED``.

A finger is the joints below the wrist whose name has ``thumb`` (the thumb) or ``index``/``fingerbase`` (the
index: Mixamo ``LeftHandIndex1..4``, CMU ``LeftFingerBase``); its tip is the deepest such joint's End Site, or
that joint.  The track is then smoothed forward and backward (zero phase) with a first-order filter of time
constant ``smoothing`` s, so a few frames of marker noise do not chatter the gripper.  A clip without fingers
gives None.  Fixed values and CSV tracks (``time_s,closure``) come from :meth:`GripperTrack.constant` and
:meth:`GripperTrack.from_csv`.

>>> track = GripperTrack.constant(0.25)
>>> track.at(3.0), track.rule
(0.25, 'fixed 0.25')
"""

from __future__ import annotations

import csv
import math
import os
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from retarget.bvh.motion import ArmChain, Motion
from retarget.errors import ConfigError

__all__ = ["GripperTrack", "hand_gripper_track"]

PINCH_OPEN = 0.35  #: thumb-index distance / forearm length of an open hand (~9 cm on a 26 cm forearm)
PINCH_CLOSED = 0.08  #: ... of a pinch (~2 cm: finger pads touching, tips a little apart)
CURL_OPEN = 0.95  #: wrist-fingertip distance / rest distance of an open hand
CURL_CLOSED = 0.55  #: ... of a fist


@dataclass(frozen=True)
class GripperTrack:
    """Closure 0 (open) .. 1 (closed) at ``times`` (``(n,)`` float64 s, increasing), held before and after."""

    times: npt.NDArray[np.float64] = field(repr=False)
    closure: npt.NDArray[np.float64] = field(repr=False)
    rule: str  #: how it was made: "pinch", "curl", "fixed 0.5", "csv FILE"

    def at(self, t: float) -> float:
        """Closure at clip time ``t`` (s), linearly interpolated."""
        return float(np.interp(t, self.times, self.closure))

    @classmethod
    def constant(cls, value: float) -> GripperTrack:
        """The same closure all along; ValueError outside 0..1."""
        if not 0.0 <= value <= 1.0:
            raise ValueError(f"Expected a gripper closure from 0 (open) to 1 (closed), got {value}")
        return cls(np.zeros(1), np.full(1, float(value)), f"fixed {value:g}")

    @classmethod
    def from_csv(cls, path: str | os.PathLike[str]) -> GripperTrack:
        """A CSV of ``time_s,closure`` rows (a header line allowed); ConfigError naming the file and line."""
        rows: list[tuple[float, float]] = []
        with open(path, newline="", encoding="utf-8") as f:
            for line, row in enumerate(csv.reader(f), start=1):
                if not row or (line == 1 and not _is_number(row[0])):
                    continue
                try:
                    t, c = float(row[0]), float(row[1])
                except (ValueError, IndexError):
                    raise ConfigError(f"line {line}: Expected time_s,closure", path=path, value=row) from None
                if not (math.isfinite(t) and 0.0 <= c <= 1.0) or (rows and t <= rows[-1][0]):
                    raise ConfigError(f"line {line}: Expected increasing times and closures 0..1", path=path, value=row)
                rows.append((t, c))
        if not rows:
            raise ConfigError("Expected at least one time_s,closure row", path=path)
        data = np.array(rows)
        return cls(data[:, 0], data[:, 1], f"csv {os.fspath(path)}")


def hand_gripper_track(motion: Motion, chain: ArmChain, *, smoothing: float = 0.08) -> GripperTrack | None:
    """The closure track of the hand at the end of ``chain`` (see the module docstring); None without fingers."""
    if chain.wrist_is_end_site or motion.n_frames == 0:
        return None
    wrist = chain.indices[2]
    below = _descendants(motion, wrist)
    thumb = _tip(motion, [j for j in below if "thumb" in motion.joint_names[j].lower()])
    index = _tip(motion, [j for j in below if _is_index(motion.joint_names[j])])
    fore = chain.bone_lengths[1]
    if thumb is not None and index is not None and fore > 0:
        d = np.linalg.norm(_track(motion, thumb) - _track(motion, index), axis=-1) / fore
        raw, rule = (PINCH_OPEN - d) / (PINCH_OPEN - PINCH_CLOSED), "pinch"
    else:
        leaves = [_tip(motion, [j]) for j in below if not motion.children(j)]
        tips = [t for t in leaves if t is not None]
        if not tips:
            return None
        wrist_path = motion.positions()[:, wrist]
        rest_wrist = motion.rest_positions()[wrist]
        ratios = [
            np.linalg.norm(_track(motion, t) - wrist_path, axis=-1) / max(_rest_distance(motion, t, rest_wrist), 1e-9)
            for t in tips
        ]
        raw, rule = (CURL_OPEN - np.mean(ratios, axis=0)) / (CURL_OPEN - CURL_CLOSED), "curl"
    closure = _smooth(np.clip(raw, 0.0, 1.0).astype(np.float64), motion.frame_time, smoothing)
    return GripperTrack(np.arange(motion.n_frames, dtype=np.float64) * motion.frame_time, closure, rule)


#: a fingertip: ("joint", index) or ("end", index into Motion.end_sites)
_Tip = tuple[str, int]


def _is_index(name: str) -> bool:
    low = name.lower()
    return "index" in low or "fingerbase" in low


def _descendants(motion: Motion, root: int) -> list[int]:
    out, todo = [], list(motion.children(root))
    while todo:
        j = todo.pop()
        out.append(j)
        todo += motion.children(j)
    return out


def _depth(motion: Motion, j: int) -> int:
    d = 0
    while motion.parents[j] >= 0:
        j, d = int(motion.parents[j]), d + 1
    return d


def _tip(motion: Motion, joints: list[int]) -> _Tip | None:
    """The deepest of ``joints``: its End Site if it has one, else the joint."""
    if not joints:
        return None
    deepest = max(joints, key=lambda j: _depth(motion, j))
    ends = [k for k, e in enumerate(motion.end_sites) if e.parent == deepest]
    return ("end", ends[0]) if ends else ("joint", deepest)


def _track(motion: Motion, tip: _Tip) -> npt.NDArray[np.float64]:
    """``(n_frames, 3)`` file units, BVH world."""
    kind, k = tip
    return motion.end_site_positions()[:, k] if kind == "end" else motion.positions()[:, k]


def _rest_distance(motion: Motion, tip: _Tip, rest_wrist: npt.NDArray[np.float64]) -> float:
    kind, k = tip
    p = motion.rest_end_site_positions()[k] if kind == "end" else motion.rest_positions()[k]
    return float(np.linalg.norm(p - rest_wrist))


def _smooth(x: npt.NDArray[np.float64], dt: float, tau: float) -> npt.NDArray[np.float64]:
    """First-order low-pass of time constant ``tau`` s, run forward then backward (zero phase)."""
    if tau <= 0 or x.size < 2:
        return x
    a = 1.0 - math.exp(-dt / tau)
    y = x.astype(np.float64).copy()
    for order in (range(1, y.size), range(y.size - 2, -1, -1)):
        step = 1 if order.step == 1 else -1
        for i in order:
            y[i] = y[i - step] + a * (y[i] - y[i - step])
    return y


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True
