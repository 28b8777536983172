"""Human arm motion -> tool-point targets of a robot arm, vectorized over frames.

The mapping is position based and built from five parts, each configurable in
the ``[mapping]`` table of an arm description and by CLI flags
(:class:`~retarget.mapping.config.MappingConfig`, in :mod:`retarget.mapping.config`):

1. the human **wrist relative to the shoulder** of the chosen side;
2. expressed in a **body frame** built from the torso (hips, the midpoint of
   both shoulders, the shoulder line), so walking or turning does not move the
   arm.  Its axes are forward, left and up; ``forward="+z"`` etc. replaces it
   by a fixed frame of the BVH world instead.  Where the shoulders give no
   frame (they coincide, or the rig has one arm) the body frame comes from the
   spine and hips instead (:func:`~retarget.mapping.torso.spine_frames`), and a
   frame neither gives holds the previous good one
   (:func:`~retarget.mapping.body.clip_body_frames`);
3. **scaled** by ``arm_scale`` x the robot's reach over the human arm length
   measured from the clip (median shoulder-elbow + elbow-wrist), so BVH units
   (cm, m, inches) do not matter;
4. **rotated** into the robot base frame (x forward, y left, z up; the body
   frame's forward/left/up map onto them, which also turns BVH Y-up into
   robot Z-up);
5. **offset** to ``origin``, a point of the workspace in the base frame where
   the human shoulder lands (default: in front of and above the robot's
   shoulder joint, so a hanging arm maps in front of the robot, not into the
   base).

The mapped points of a clip are then low-passed forward and backward at ``cutoff_hz`` (by default chosen from
the clip's own noise, :func:`~retarget.mapping.cutoff.auto_cutoff`: none for a clean capture;
:func:`~retarget.mapping.filter.zero_phase`: no lag, -6 dB at the cutoff), the hand's orientations too, and
only then clamped: targets outside the :class:`~retarget.mapping.workspace.Workspace` (a shell
``min_reach..max_reach`` around the robot's shoulder pivot, above ``floor``, out of blocked zones) are pulled
to the nearest reachable point and counted in ``Targets.clamped``, so every filtered target is reachable.
The unfiltered points stay in ``Targets.unfiltered``: :meth:`Targets.reference` is what the arm is measured
against (the tracking error of :mod:`retarget.control.tracking`).

Optionally (``orientation_weight > 0``) the hand's orientation becomes a tool
orientation: tool x along the hand bone, tool z the body's up in the rest pose.

This module holds the steps' last part and the result: :func:`map_points` (steps 1-5 on points),
:class:`Targets` (filtered, clamped, sampled at any time), :func:`retarget_targets` (a clip on an arm, with the
hand's orientation) and :func:`filter_targets` (unfiltered targets filtered afterwards).  The body frames are
in :mod:`retarget.mapping.body`, the arm's geometry and workspace in :mod:`retarget.mapping.workspace`.

Units: BVH file units in, metres and radians out.  This module is math only
(it imports neither drivers, sim nor serial).
"""

from __future__ import annotations

import dataclasses
import logging
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from retarget.arm.model import Arm
from retarget.bvh.motion import ArmChain, Motion
from retarget.errors import BvhError
from retarget.mapping.body import mapping_frames
from retarget.mapping.config import MappingConfig
from retarget.mapping.cutoff import auto_cutoff
from retarget.mapping.filter import AUTO, DEFAULT_CUTOFF, Cutoff, zero_phase
from retarget.mapping.workspace import Workspace, arm_geometry, default_origin

log = logging.getLogger(__name__)

if TYPE_CHECKING:
    from retarget.collision import CollisionModel

__all__ = ["Targets", "filter_targets", "map_points", "retarget_targets"]


def map_points(
    shoulder: np.ndarray,
    wrist: np.ndarray,
    frames: np.ndarray,
    *,
    scale: float,
    origin: np.ndarray,
    basis: np.ndarray | None = None,
) -> np.ndarray:
    """Wrist relative to shoulder, in body ``frames``, scaled, turned and offset: ``(n, 3)`` metres, base frame.

    ``shoulder``/``wrist`` ``(n, 3)`` file units, BVH world; ``frames`` ``(n, 3, 3)`` or ``(3, 3)``
    (columns forward, left, up); ``scale`` metres per file unit; ``origin`` ``(3,)`` metres;
    ``basis`` ``(3, 3)`` the robot's forward, left, up in its base frame (default identity: x, y, z).
    """
    rel = np.asarray(wrist, dtype=np.float64) - shoulder
    local = np.einsum("...ji,...j->...i", frames, rel)  # frames^T @ rel: (forward, left, up)
    if basis is not None:
        local = local @ np.asarray(basis).T
    targets: np.ndarray = local * scale + origin
    return targets


@dataclass(frozen=True)
class Targets:
    """Per-frame tool targets of one clip on one arm."""

    positions: np.ndarray  #: ``(n_frames, 3)`` metres, base frame, inside the workspace
    raw: np.ndarray  #: ``(n_frames, 3)`` metres, before the workspace clamp
    clamped: np.ndarray  #: ``(n_frames,)`` bool, the frame's target was pulled into the workspace
    rotations: np.ndarray | None  #: ``(n_frames, 3, 3)`` tool orientations in the base frame, or None
    frame_time: float  #: seconds between frames
    workspace: Workspace
    config: MappingConfig
    scale: float  #: metres per BVH file unit
    #: ``(n_frames,)`` bool, the frame's target was pushed out of a blocked zone (counted in ``clamped`` too);
    #: all False without a collision model (``workspace.blocked``)
    pushed: np.ndarray | None = None
    #: ``(n_frames, 3)`` metres, base frame: the mapped points before the zero-phase filter (``raw`` is them
    #: filtered); None: not filtered (``raw`` is the mapped points)
    unfiltered: np.ndarray | None = None
    cutoff_hz: float = 0.0  #: Hz, the zero-phase filter's cutoff applied to ``raw`` (and rotations); 0: none
    cutoff_auto: bool = False  #: ``cutoff_hz`` was chosen from the clip (``"auto"``), 0 included

    @classmethod
    def from_raw(
        cls,
        raw: np.ndarray,
        *,
        frame_time: float,
        workspace: Workspace,
        config: MappingConfig | None = None,
        rotations: np.ndarray | None = None,
        scale: float = 1.0,
        cutoff_hz: Cutoff = 0.0,
    ) -> Targets:
        """Targets from tool points ``raw`` ``(n_frames, 3)`` metres (base frame), clamped into ``workspace``.

        ``cutoff_hz > 0``: first low-pass ``raw`` and ``rotations`` ``(n_frames, 3, 3)`` forward and backward
        (:func:`~retarget.mapping.filter.zero_phase`; kept in ``unfiltered``), unless the cutoff is at or above
        the clip's Nyquist frequency ``0.5 / frame_time`` (then nothing is filtered: ``cutoff_hz`` 0).  ``"auto"``:
        the cutoff :func:`~retarget.mapping.cutoff.auto_cutoff` chooses from ``raw`` (0: none).
        """
        raw = np.asarray(raw, dtype=np.float64)
        if raw.ndim != 2 or raw.shape[1] != 3 or raw.shape[0] < 1:
            raise ValueError(f"Expected raw targets of shape (n_frames, 3), got {raw.shape}")
        if not (np.isfinite(frame_time) and frame_time > 0):
            raise ValueError(f"Expected a frame time > 0 s, got {frame_time}")
        unfiltered = None
        auto = cutoff_hz == AUTO
        if cutoff_hz == AUTO:
            cutoff_hz = auto_cutoff(raw, 1.0 / frame_time)
            log.info("target filter: auto, %s", f"{cutoff_hz:.1f} Hz" if cutoff_hz else "none (a clean clip)")
        if 0 < cutoff_hz < 0.5 / frame_time and len(raw) > 1:
            unfiltered, raw = raw, zero_phase(raw, 1.0 / frame_time, cutoff_hz)
            if rotations is not None:  # element-wise, then the nearest rotations again (they turn slowly)
                rotations = _orthonormalize(zero_phase(rotations, 1.0 / frame_time, cutoff_hz))
        else:
            cutoff_hz = 0.0
        positions, clamped, pushed = workspace.clamp_and_push(raw)
        return cls(
            positions=positions,
            raw=raw,
            clamped=clamped,
            rotations=rotations,
            frame_time=float(frame_time),
            workspace=workspace,
            config=config or MappingConfig(),
            scale=scale,
            pushed=pushed,
            unfiltered=unfiltered,
            cutoff_hz=float(cutoff_hz),
            cutoff_auto=auto,
        )

    @property
    def n_frames(self) -> int:
        return int(self.positions.shape[0])

    @property
    def n_clamped(self) -> int:
        return int(np.count_nonzero(self.clamped))

    @property
    def n_pushed(self) -> int:
        """Frames whose target was pushed out of a blocked zone."""
        return 0 if self.pushed is None else int(np.count_nonzero(self.pushed))

    def sample(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
        """Targets at clip ``times`` ``(n,)`` seconds by linear interpolation of the raw targets, then clamped.

        Returns ``(positions (n, 3) metres, rotations (n, 3, 3) or None, clamped (n,) bool)``.
        Times outside the clip hold the first/last frame.
        """
        i0, i1, w = self._interpolation(times)
        raw = self.raw[i0] * (1.0 - w)[:, None] + self.raw[i1] * w[:, None]
        positions, clamped = self.workspace.clamp(raw)
        rotations = None
        if self.rotations is not None:
            rotations = _orthonormalize(
                self.rotations[i0] * (1.0 - w)[:, None, None] + self.rotations[i1] * w[:, None, None]
            )
        return positions, rotations, clamped

    def _interpolation(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Frames ``i0``, ``i1`` ``(n,)`` and weights ``w`` ``(n,)`` of clip ``times`` (seconds, held at the ends)."""
        t = np.asarray(times, dtype=np.float64) / self.frame_time
        n = self.n_frames
        if n == 1:
            i0 = np.zeros(t.shape, dtype=np.intp)
            w = np.zeros(t.shape)
        else:
            t = np.clip(t, 0.0, n - 1)
            i0 = np.minimum(np.floor(t).astype(np.intp), n - 2)
            w = t - i0
        return i0, np.minimum(i0 + 1, n - 1), w

    def reference(self, times: np.ndarray) -> np.ndarray:
        """The *unfiltered* targets ``(n, 3)`` metres at clip ``times`` ``(n,)`` seconds, clamped (and pushed) into
        the workspace as :meth:`sample` clamps the filtered ones: what the arm's following is measured against.
        Without a filter, :meth:`sample`'s positions."""
        points = self.raw if self.unfiltered is None else self.unfiltered
        i0, i1, w = self._interpolation(times)
        positions, _ = self.workspace.clamp(points[i0] * (1.0 - w)[:, None] + points[i1] * w[:, None])
        return np.asarray(positions, dtype=np.float64)

    def at(self, time: float) -> tuple[np.ndarray, bool]:
        """The position target ``(3,)`` metres at one clip ``time`` and whether it was clamped (plain floats).

        Same values as :meth:`sample` (without rotations), for a single time.
        """
        n = self.n_frames
        f = min(max(time / self.frame_time, 0.0), n - 1.0)
        i0 = min(int(f), max(n - 2, 0))
        w = f - i0 if n > 1 else 0.0
        a, b = self.raw[i0].tolist(), self.raw[min(i0 + 1, n - 1)].tolist()
        u = 1.0 - w
        x, y, z, moved = self.workspace.clamp_point(a[0] * u + b[0] * w, a[1] * u + b[1] * w, a[2] * u + b[2] * w)
        return np.array((x, y, z)), moved


def _orthonormalize(m: np.ndarray) -> np.ndarray:
    """Nearest rotations ``(n, 3, 3)`` by Gram-Schmidt on the x and z columns."""
    x = m[..., :, 0] / np.linalg.norm(m[..., :, 0], axis=-1, keepdims=True)
    z = m[..., :, 2] - np.sum(m[..., :, 2] * x, axis=-1, keepdims=True) * x
    z /= np.linalg.norm(z, axis=-1, keepdims=True)
    return np.stack([x, np.cross(z, x), z], axis=-1)


def retarget_targets(
    motion: Motion, arm: Arm, config: MappingConfig | None = None, *, collision: CollisionModel | None = None
) -> Targets:
    """Tool-point targets for every frame of ``motion`` on ``arm``: the steps in the module docstring.

    ``motion``: the clip, in any length unit (the scale comes from its own arm length).  ``arm``: the
    robot.  ``config``: the mapping; default ``MappingConfig.from_table(arm.mapping, path=arm.source)``,
    the arm file's ``[mapping]`` table.

    Returns :class:`Targets`: ``positions`` ``(n_frames, 3)`` float64 metres in the arm's base frame,
    inside the :class:`~retarget.mapping.workspace.Workspace`; ``raw`` the same before the workspace clamp (after
    the zero-phase filter at ``config.cutoff_hz``; ``unfiltered`` before it); ``clamped`` ``(n_frames,)`` bool;
    ``rotations`` ``(n_frames, 3, 3)`` tool orientations in the base frame when ``config.orientation_weight > 0``
    (filtered too), else None; ``frame_time`` seconds; ``scale`` metres per file unit.
    ``collision``: a collision model whose blocked zones (below the table, keep-outs, the base) the targets are
    pushed out of as well (``pushed``, counted in ``clamped`` too).

    With ``config.forward`` AUTO the body frames come from :func:`~retarget.mapping.body.clip_body_frames`:
    from both shoulders, else (one arm, or shoulders that coincide) from the spine and hips, else the
    previous good frame, with one log line saying which fallback was used.

    Raises :class:`~retarget.errors.BvhError` (a ``ValueError``; naming the clip's path) for a clip
    that cannot drive the arm: no frames (``Frames: 0``), no arm chain for ``config.side``, an arm of
    zero length, or no frame giving a body frame; :class:`~retarget.errors.ConfigError` for a bad
    ``[mapping]`` table.

    >>> from retarget.arm.load import load_arm
    >>> from retarget.bvh.parse import DEMO_CLIP, load_bvh
    >>> targets = retarget_targets(load_bvh(DEMO_CLIP), load_arm("wx250s"))
    >>> targets.positions.shape, targets.n_clamped, targets.frame_time, targets.rotations is None
    ((630, 3), 0, 0.0166667, True)
    >>> bool(targets.workspace.clamp(targets.positions)[1].any())  # every target already inside the workspace
    False
    """
    if config is None:
        config = MappingConfig.from_table(arm.mapping, path=arm.source)
    if motion.n_frames == 0:
        raise BvhError(
            "Expected at least one frame of motion, got Frames: 0 (the clip has no frames)", path=motion.path
        )
    side = config.side.value
    chain = motion.arm_points(side)
    pts = np.asarray(chain.points, dtype=np.float64)  # (n, 3, 3) shoulder, elbow, wrist
    shoulder, wrist = pts[:, 0], pts[:, 2]
    human = _human_arm_length(motion, chain, pts, side)
    hand = _hand_alignment(motion, chain, config) if config.orientation_weight > 0 else None
    frames = mapping_frames(motion, chain, config.forward, config.up)

    geometry = arm_geometry(arm)
    scale = config.arm_scale * geometry.reach / human
    origin = np.asarray(config.origin, dtype=np.float64) if config.origin else default_origin(config, geometry)
    basis = geometry.basis(config.robot_forward)
    raw = map_points(shoulder, wrist, frames, scale=scale, origin=origin, basis=basis)
    rotations = None
    if hand is not None:  # tool orientations in the body frame, then in the base frame
        rotations = basis @ np.einsum("...ji,...jk,kl->...il", frames, hand[0], hand[1])
    return Targets.from_raw(
        raw,
        frame_time=float(motion.frame_time),
        workspace=Workspace.for_arm(arm, config).with_blocked(collision),
        config=config,
        rotations=rotations,
        scale=scale,
        cutoff_hz=config.cutoff_hz,
    )


def filter_targets(targets: Targets, cutoff_hz: Cutoff = DEFAULT_CUTOFF) -> Targets:
    """Unfiltered ``targets`` (``cutoff_hz`` 0) with their mapped points (``raw``) and rotations low-passed by
    :func:`zero_phase` at the clip's frame rate (``"auto"``: at the cutoff chosen from them), then clamped into the
    workspace again, as :func:`~retarget.mapping.retarget_targets` does with ``MappingConfig.cutoff_hz``;
    ``cutoff_hz <= 0``: ``targets`` itself.  ``ValueError`` for targets that were filtered already."""
    if cutoff_hz != AUTO and cutoff_hz <= 0:
        return targets
    if targets.unfiltered is not None:
        raise ValueError(f"Expected unfiltered targets, got targets filtered at {targets.cutoff_hz:g} Hz")
    return Targets.from_raw(
        targets.raw,
        frame_time=targets.frame_time,
        workspace=targets.workspace,
        config=dataclasses.replace(targets.config, cutoff_hz=cutoff_hz),
        rotations=targets.rotations,
        scale=targets.scale,
        cutoff_hz=cutoff_hz,
    )


def _human_arm_length(motion: Motion, chain: ArmChain, points: np.ndarray, side: str) -> float:
    """The human arm's length, file units: the median over frames of upper arm + forearm, of ``points`` ``(n, 3, 3)``.

    :class:`~retarget.errors.BvhError` (the clip's path) unless it is positive and finite.
    """
    shoulder, elbow, wrist = points[:, 0], points[:, 1], points[:, 2]
    human = float(np.median(np.linalg.norm(elbow - shoulder, axis=-1) + np.linalg.norm(wrist - elbow, axis=-1)))
    if not (math.isfinite(human) and human > 0):
        raise BvhError(
            f"Expected a {side} arm of positive length, got {human:g} (median upper arm + forearm) for "
            f"{' > '.join(chain.names)}",
            path=motion.path,
        )
    return human


def _hand_alignment(motion: Motion, chain: ArmChain, config: MappingConfig) -> tuple[np.ndarray, np.ndarray]:
    """The hand joint's global rotations ``(n, 3, 3)`` (hand local -> BVH world) and the tool's axes in it ``(3, 3)``.

    Tool x = the hand bone (the first child of the wrist joint away from it in the first frame, else the
    forearm direction), tool z = the BVH up axis seen from the hand in the rest pose (rest rotations are
    identity).  An End Site wrist has no rotation of its own: the forearm's is used.
    """
    rotations, positions = motion.global_transforms()
    w = chain.indices[1] if chain.wrist_is_end_site else chain.indices[2]
    R = rotations[:, w]  # (n, 3, 3) hand local -> world
    bones = [positions[0, c] - positions[0, w] for c in motion.children(w)]
    bones.append(np.asarray(chain.points[0, 2] - chain.points[0, 1], dtype=np.float64))  # the forearm
    bone = next((b for b in bones if np.linalg.norm(b) > 0), None)
    if bone is None:
        raise BvhError(
            f"Expected a hand bone or forearm of positive length in the first frame to follow the hand's "
            f"orientation, got none for {' > '.join(chain.names)}",
            path=motion.path,
        )
    x = R[0].T @ bone
    x /= np.linalg.norm(x)
    z = config.up.vector - (config.up.vector @ x) * x
    if np.linalg.norm(z) < 1e-6:
        z = np.cross(x, [1.0, 0.0, 0.0]) if abs(x[0]) < 0.9 else np.cross(x, [0.0, 0.0, 1.0])
    z /= np.linalg.norm(z)
    return R, np.stack([x, np.cross(z, x), z], axis=-1)  # tool -> hand local
