"""Forward kinematics of an :class:`~retarget.arm.Arm`.

Frames follow URDF: joint ``i`` sits at ``origin_i = (xyz, rpy)`` in the frame of
joint ``i-1`` (the base frame for ``i = 0``) and rotates its child frame about
``axis_i`` (a unit vector in that child frame).  ``rpy`` is fixed-axis
roll-pitch-yaw, ``R = Rz(yaw) @ Ry(pitch) @ Rx(roll)``.  The tool point is a
constant transform in the last joint's child frame.

    T_tool = Π_i [origin_i @ Rot(axis_i, q_i)] @ tool

Everything is base-frame metres and radians.  :class:`Chain` precomputes the
constant transforms once per arm (``Arm.chain``); ``fk`` and ``fk_batch`` are
thin wrappers over it.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Protocol

import numpy as np

__all__ = ["Chain", "fk", "fk_batch", "rpy_matrix", "matrix_rpy", "axis_angle_matrix", "transform"]


def rpy_matrix(rpy: Sequence[float] | np.ndarray) -> np.ndarray:
    """``(3, 3)`` rotation of URDF roll-pitch-yaw ``rpy`` (radians): ``Rz(y) @ Ry(p) @ Rx(r)``."""
    r, p, y = (float(v) for v in rpy)
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


def matrix_rpy(R: np.ndarray) -> tuple[float, float, float]:
    """URDF roll-pitch-yaw (radians) of a ``(3, 3)`` rotation; the inverse of :func:`rpy_matrix`.

    At gimbal lock (pitch = +-pi/2) roll is set to 0.
    """
    R = np.asarray(R, dtype=np.float64)
    pitch = float(np.arcsin(np.clip(-R[2, 0], -1.0, 1.0)))
    if abs(R[2, 0]) < 1.0 - 1e-12:
        roll = float(np.arctan2(R[2, 1], R[2, 2]))
        yaw = float(np.arctan2(R[1, 0], R[0, 0]))
    else:
        roll = 0.0
        yaw = float(np.arctan2(-R[0, 1], R[1, 1]))
    clean = [0.0 if abs(v) < 1e-15 else v for v in (roll, pitch, yaw)]
    return clean[0], clean[1], clean[2]


def axis_angle_matrix(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rotations about unit ``axis`` ``(3,)`` by ``angle`` ``(...)`` radians -> ``(..., 3, 3)`` (Rodrigues)."""
    angle = np.asarray(angle, dtype=np.float64)
    x, y, z = (float(v) for v in axis)
    c, s = np.cos(angle), np.sin(angle)
    t = 1.0 - c
    out = np.empty(angle.shape + (3, 3))
    out[..., 0, 0] = t * x * x + c
    out[..., 0, 1] = t * x * y - s * z
    out[..., 0, 2] = t * x * z + s * y
    out[..., 1, 0] = t * x * y + s * z
    out[..., 1, 1] = t * y * y + c
    out[..., 1, 2] = t * y * z - s * x
    out[..., 2, 0] = t * x * z - s * y
    out[..., 2, 1] = t * y * z + s * x
    out[..., 2, 2] = t * z * z + c
    return out


def _axis_angle_entries(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """:func:`axis_angle_matrix` entry-major: rotations about unit ``axis`` ``(3,)`` by ``angle`` ``(n,)`` radians ->
    ``(3, 3, n)`` (entry ``[r, c]`` of every rotation, contiguous)."""
    x, y, z = (float(v) for v in axis)
    c, s = np.cos(angle), np.sin(angle)
    t = 1.0 - c
    return np.array([
        [t * x * x + c, t * x * y - s * z, t * x * z + s * y],
        [t * x * y + s * z, t * y * y + c, t * y * z - s * x],
        [t * x * z - s * y, t * y * z + s * x, t * z * z + c],
    ])  # fmt: skip


def transform(xyz: Sequence[float] | np.ndarray, rpy: Sequence[float] | np.ndarray) -> np.ndarray:
    """``(4, 4)`` homogeneous transform of a URDF origin (metres, radians)."""
    T = np.eye(4)
    T[:3, :3] = rpy_matrix(rpy)
    T[:3, 3] = np.asarray(xyz, dtype=np.float64)
    return T


class Chain:
    """The constant part of an arm's kinematics, computed once.

    Attributes (all base-frame-independent constants):

    - ``origins``: ``(n_joints, 4, 4)`` parent -> joint transforms;
    - ``axes``: ``(n_joints, 3)`` unit joint axes in each joint's child frame;
    - ``tool``: ``(4, 4)`` last child frame -> tool point;
    - ``lower``/``upper``: ``(n_joints,)`` limits, radians.
    """

    def __init__(
        self,
        *,
        origins: Sequence[tuple[Sequence[float], Sequence[float]]],
        axes: Sequence[Sequence[float]],
        tool: tuple[Sequence[float], Sequence[float]],
        lower: np.ndarray,
        upper: np.ndarray,
    ):
        """``origins``: each joint's URDF origin ``(xyz, rpy)`` (metres, radians); ``axes``: each joint's axis;
        ``tool``: the tool point's ``(xyz, rpy)`` in the last child frame; ``lower``/``upper``: limits, radians."""
        self.n = len(origins)
        self.origins = np.stack([transform(xyz, rpy) for xyz, rpy in origins])
        axes_array = np.array(axes, dtype=np.float64).reshape(self.n, 3)
        self.axes = axes_array / np.linalg.norm(axes_array, axis=1, keepdims=True)
        self.tool = transform(*tool)
        self.lower = lower
        self.upper = upper

    def _check(self, q: np.ndarray | Sequence[float], what: str = "q") -> np.ndarray:
        array = np.asarray(q, dtype=np.float64)
        if array.shape[-1:] != (self.n,):
            raise ValueError(f"Expected {what} of shape (..., {self.n}) for {self.n} joints, got {array.shape}")
        return array

    def fk(self, q: np.ndarray | Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
        """``(T_tool (4, 4), points (n_joints + 1, 3))`` for ``q`` ``(n_joints,)`` radians; base frame, metres."""
        q = self._check(q)
        if q.ndim != 1:
            raise ValueError(f"Expected q of shape ({self.n},), got {q.shape}; use fk_batch for many poses")
        T = np.eye(4)
        points = np.empty((self.n + 1, 3))
        rot = np.eye(4)
        for i in range(self.n):
            T = T @ self.origins[i]
            points[i] = T[:3, 3]
            rot[:3, :3] = axis_angle_matrix(self.axes[i], q[i])
            T = T @ rot
        T = T @ self.tool
        points[self.n] = T[:3, 3]
        return T, points

    def fk_batch(self, Q: np.ndarray) -> np.ndarray:
        """Tool poses ``(n, 4, 4)`` for joint angles ``Q`` ``(n, n_joints)`` radians; base frame, metres."""
        tool: np.ndarray = self.frames_batch(Q)[:, -1] @ self.tool
        return tool

    def tool_points(self, Q: np.ndarray) -> np.ndarray:
        """Tool points ``(n, 3)`` metres, base frame, of joint angles ``Q`` ``(n, n_joints)`` radians: the
        translations of :meth:`fk_batch`, a third of its cost (each product over the whole batch at once, rotations
        kept entry-major ``(3, 3, n)``, no 4x4 frames).

        >>> from retarget.arm.load import load_arm
        >>> arm = load_arm("wx250s")
        >>> Q = np.stack([arm.home, arm.rest])
        >>> bool(np.allclose(arm.chain.tool_points(Q), arm.chain.fk_batch(Q)[:, :3, 3], atol=1e-15))
        True
        """
        out: np.ndarray = self._walk(Q).T
        return out

    def tool_jacobians(self, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Tool points ``(n, 3)`` metres and their Jacobians ``(n, 3, n_joints)`` metres per radian, base frame, of
        joint angles ``Q`` ``(n, n_joints)`` radians: column ``i`` is joint ``i``'s axis (world) x (tool point -
        the joint's origin), the tool point's velocity per rad/s of that joint.  Entry-major as
        :meth:`tool_points`, the points equal to it.

        >>> from retarget.arm.load import load_arm
        >>> arm = load_arm("wx250s")
        >>> Q = np.stack([arm.home, arm.rest])
        >>> points, J = arm.chain.tool_jacobians(Q)
        >>> step = np.zeros(arm.n_joints); step[1] = 1e-6  # the shoulder, a micro-radian
        >>> moved = (arm.chain.tool_points(Q + step) - points) / 1e-6
        >>> J.shape, bool(np.allclose(moved, J[:, :, 1], atol=1e-5))
        ((2, 3, 6), True)
        """
        axes, origins = np.empty((self.n, 3, len(Q))), np.empty((self.n, 3, len(Q)))

        def joint(i: int, R: np.ndarray, p: np.ndarray) -> None:  # the joint's axis and origin, world
            axes[i], origins[i] = np.einsum("rkn,k->rn", R, self.axes[i]), p

        p = self._walk(Q, joint)
        jacobians = np.cross(axes, p[None] - origins, axis=1)  # (n_joints, 3, n)
        return np.ascontiguousarray(p.T), np.ascontiguousarray(jacobians.transpose(2, 1, 0))

    def _walk(self, Q: np.ndarray, joint: Callable[[int, np.ndarray, np.ndarray], None] | None = None) -> np.ndarray:
        """The tool points ``(3, n)`` of ``Q`` ``(n, n_joints)``, entry-major (rotations ``(3, 3, n)``, each product
        over the whole batch at once); ``joint(i, R, p)`` sees each joint's frame at its origin, before it turns."""
        Q = self._check(Q, "Q")
        if Q.ndim != 2:
            raise ValueError(f"Expected Q of shape (n, {self.n}), got {Q.shape}")
        R = np.zeros((3, 3, Q.shape[0]))
        R[0, 0] = R[1, 1] = R[2, 2] = 1.0
        p = np.zeros((3, Q.shape[0]))
        for i in range(self.n):
            origin = self.origins[i]
            p += np.einsum("rkn,k->rn", R, origin[:3, 3])
            R = np.einsum("rkn,kc->rcn", R, origin[:3, :3])
            if joint is not None:
                joint(i, R, p)
            R = np.einsum("rkn,kcn->rcn", R, _axis_angle_entries(self.axes[i], Q[:, i]))
        p += np.einsum("rkn,k->rn", R, self.tool[:3, 3])
        return p

    def frames_batch(self, Q: np.ndarray) -> np.ndarray:
        """Every link frame ``(n, n_joints + 1, 4, 4)`` for joint angles ``Q`` ``(n, n_joints)`` radians: the base
        frame (identity) first, then each joint's child frame; base frame, metres.

        >>> from retarget.arm.load import load_arm
        >>> arm = load_arm("omx")
        >>> frames = arm.chain.frames_batch(arm.home[None])
        >>> frames.shape, bool(np.allclose(frames[0, -1] @ arm.chain.tool, arm.fk(arm.home)[0]))
        ((1, 5, 4, 4), True)
        """
        Q = self._check(Q, "Q")
        if Q.ndim != 2:
            raise ValueError(f"Expected Q of shape (n, {self.n}), got {Q.shape}")
        frames = np.empty((Q.shape[0], self.n + 1, 4, 4))
        frames[:, 0] = np.eye(4)
        rot = np.broadcast_to(np.eye(4), (Q.shape[0], 4, 4)).copy()
        for i in range(self.n):
            rot[:, :3, :3] = axis_angle_matrix(self.axes[i], Q[:, i])
            frames[:, i + 1] = frames[:, i] @ self.origins[i] @ rot
        return frames


class HasChain(Protocol):
    """Anything with a precomputed :class:`Chain`: an :class:`~retarget.arm.model.Arm`."""

    @property
    def chain(self) -> Chain: ...


def fk(arm: HasChain, q: np.ndarray | Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
    """Forward kinematics: ``(T_tool (4, 4), points (n_joints + 1, 3))``, base frame, metres.

    ``q`` is ``(n_joints,)`` radians (limits are not enforced here).  ``points`` holds
    every joint origin, base to tip, then the tool point.
    """
    return arm.chain.fk(q)


def fk_batch(arm: HasChain, Q: np.ndarray) -> np.ndarray:
    """Tool poses ``(n, 4, 4)`` of joint angles ``Q`` ``(n, n_joints)`` radians, base frame, metres."""
    return arm.chain.fk_batch(Q)
