"""Damped least squares (DLS, Levenberg-Marquardt) steps on a :class:`~retarget.ik.ccd.CCDSolver`'s chain.

CCD takes each joint's *exact* minimiser, which is ill-conditioned where a joint's lever to the target is
short: near the base's vertical axis a millimetre of target motion asks the waist for a half turn, and near a
folded elbow the shoulder swings by tenths of a radian per millimetre.  A warm-started control loop wants the
opposite: the smallest joint motion that follows the target.  One DLS step from ``q`` solves, with the
position Jacobian ``J`` (``(3, n)``, column ``j`` = ``a_j x (e - p_j)``, metres per radian) and the per-joint
weights ``W`` (0 locks a joint)::

    dq = W J^T (J W J^T + lambda^2 I)^-1 (t - e)

the weighted minimum-norm step toward the target.  Along a direction where the arm is singular (singular value
``s`` of ``J``) the step is ``s / (s^2 + lambda^2)`` times the error, at most ``1 / (2 lambda)`` radians per
metre of error, so a target near the base axis or a folded elbow never asks for a flip: the arm keeps its branch
and accepts a position error there (the loop's next ticks close it as far as the geometry allows).  Steps that
would cross a joint limit are clamped, and the joint is left out of the next step's Jacobian; a step that does
not lower the distance is taken back and the damping raised (x4), Levenberg-Marquardt style.

Everything is plain Python floats on the solver's forward-pass buffers (``_fk`` fills the world pivots and
axes), like the CCD sweeps: a 3x3 system per step, solved by Cramer's rule.
"""

from __future__ import annotations

import math
from typing import Protocol

import numpy as np

__all__ = ["Chain", "dls_pose_steps", "dls_steps"]


class Chain(Protocol):
    """What the DLS steps use of :class:`~retarget.ik.ccd.CCDSolver`: its forward pass, whose world pivots and
    axes land in the ``_px`` .. ``_az`` buffers, and the current solve's bounds and weights (a protocol, so this
    module does not import the solver's, which imports this one)."""

    n: int
    reach: float
    orientation_weight: float
    _w: tuple[float, ...]
    _lo: tuple[float, ...]
    _hi: tuple[float, ...]
    _px: list[float]
    _py: list[float]
    _pz: list[float]
    _ax: list[float]
    _ay: list[float]
    _az: list[float]
    _fk_memo: tuple[list[float], tuple[float, ...], tuple[list[float], ...]] | None

    def _fk(self, q: list[float]) -> tuple[float, ...]: ...


def dls_steps(
    s: Chain, q: list[float], tx: float, ty: float, tz: float, tol2: float, steps: int, damping: float
) -> tuple[float, int]:
    """Up to ``steps`` DLS steps on ``q`` (in place, radians) toward the target ``(tx, ty, tz)`` (metres, base frame).

    ``damping`` is ``lambda`` in metres.  Stops once the squared distance is within ``tol2`` (m^2).  Returns the
    squared distance and the steps taken (a step taken back counts).  The solver's per-solve bounds and weights
    (``_lo``, ``_hi``, ``_w``) apply: :meth:`~retarget.ik.ccd.CCDSolver.solve` sets them.

    >>> from retarget.arm.load import load_arm
    >>> from retarget.ik.ccd import CCDSolver
    >>> arm = load_arm("wx250s")
    >>> solver = CCDSolver(arm)
    >>> q = [0.2, -0.3, 0.4, 0.0, 0.5, 0.0]
    >>> x, y, z = solver.tool_point(q)
    >>> err2, steps = dls_steps(solver, q, x + 0.004, y - 0.003, z, 1e-8, 8, 0.01)  # 5 mm away, to 0.1 mm
    >>> err2 <= 1e-8, steps
    (True, 1)
    >>> err2, steps = dls_steps(solver, q, x + 0.004, y - 0.003, z, 1e-14, 8, 0.01)  # q moved: on to 0.1 um
    >>> err2 <= 1e-14, steps
    (True, 1)
    """
    n = s.n
    w, lower, upper = s._w, s._lo, s._hi
    px, py, pz, ax, ay, az = s._px, s._py, s._pz, s._ax, s._ay, s._az
    lam2 = base2 = damping * damping
    memo = s._fk_memo  # the last call's end: when at q, its forward pass is copied back, not run again
    if memo is not None and memo[0] == q:
        f = memo[1]
        px[:], py[:], pz[:], ax[:], ay[:], az[:] = memo[2]
    else:
        f = s._fk(q)
    ex, ey, ez = f[0], f[1], f[2]
    dx, dy, dz = tx - ex, ty - ey, tz - ez
    err2 = dx * dx + dy * dy + dz * dz
    cols = [(0.0, 0.0, 0.0)] * n
    taken = 0
    while taken < steps and err2 > tol2:
        taken += 1
        # A = J W J^T + lambda^2 I (symmetric 3x3); joints locked (w = 0) or pinned on a limit drop out
        a00 = a11 = a22 = lam2
        a01 = a02 = a12 = 0.0
        for j in range(n):
            wj = w[j]
            if wj == 0.0:
                continue
            kx, ky, kz = ax[j], ay[j], az[j]
            ux, uy, uz = ex - px[j], ey - py[j], ez - pz[j]
            cx, cy, cz = ky * uz - kz * uy, kz * ux - kx * uz, kx * uy - ky * ux
            g = cx * dx + cy * dy + cz * dz  # the joint's pull toward the target
            qj = q[j]
            if (qj <= lower[j] and g < 0.0) or (qj >= upper[j] and g > 0.0):
                cols[j] = (0.0, 0.0, 0.0)
                continue
            cols[j] = (cx, cy, cz)
            a00 += wj * cx * cx
            a01 += wj * cx * cy
            a02 += wj * cx * cz
            a11 += wj * cy * cy
            a12 += wj * cy * cz
            a22 += wj * cz * cz
        # y = A^-1 d by Cramer's rule (A is positive definite: lambda^2 > 0)
        m00 = a11 * a22 - a12 * a12
        m01 = a02 * a12 - a01 * a22
        m02 = a01 * a12 - a02 * a11
        det = a00 * m00 + a01 * m01 + a02 * m02
        m11 = a00 * a22 - a02 * a02
        m12 = a01 * a02 - a00 * a12
        m22 = a00 * a11 - a01 * a01
        yx = (m00 * dx + m01 * dy + m02 * dz) / det
        yy = (m01 * dx + m11 * dy + m12 * dz) / det
        yz = (m02 * dx + m12 * dy + m22 * dz) / det
        old = q[:]
        for j in range(n):
            cx, cy, cz = cols[j]
            if cx == cy == cz == 0.0:
                continue
            v = q[j] + w[j] * (cx * yx + cy * yy + cz * yz)
            q[j] = lower[j] if v < lower[j] else upper[j] if v > upper[j] else v
        f = s._fk(q)
        nx, ny, nz = tx - f[0], ty - f[1], tz - f[2]
        new2 = nx * nx + ny * ny + nz * nz
        if new2 >= err2:  # no progress: take the step back, damp harder
            q[:] = old
            f = s._fk(q)
            lam2 *= 4.0
            continue
        lam2 = max(base2, lam2 * 0.25)
        ex, ey, ez = f[0], f[1], f[2]
        dx, dy, dz = nx, ny, nz
        err2 = new2
    s._fk_memo = (q[:], f, (px[:], py[:], pz[:], ax[:], ay[:], az[:]))  # f is q's pass, as the buffers are
    return err2, taken


def dls_pose_steps(
    s: Chain,
    q: list[float],
    target: tuple[float, float, float],
    rot: tuple[tuple[float, ...], ...],
    tol: float,
    rtol: float,
    steps: int,
    damping: float,
) -> tuple[bool, int]:
    """Up to ``steps`` DLS steps on ``q`` (in place) toward a tool pose: point ``target`` (metres) and rotation
    ``rot`` (rows of a ``(3, 3)`` matrix, base frame).

    The residual stacks the position error over the solver's reach and ``sqrt(orientation_weight)`` times the
    rotation vector from the tool frame to the target frame (world axes), the square root of the CCD pose cost
    ``(d / reach)^2 + orientation_weight * (3 - tr(R^T R_target))`` near a solution; the Jacobian's column ``j`` is
    ``(a_j x (e - p_j) / reach, sqrt(w_o) a_j)``.  ``damping`` is ``lambda`` in metres (divided by the reach here).
    A step that raises the cost is taken back and the damping raised.  Returns (converged to ``tol`` m and
    ``rtol`` rad, steps taken).
    """
    w, lower, upper = s._w, s._lo, s._hi
    inv = 1.0 / s.reach
    so = math.sqrt(s.orientation_weight) if s.orientation_weight > 0 else 0.0
    lam2 = base2 = (damping * inv) ** 2
    goal = np.array(rot, dtype=np.float64)
    t = np.array(target, dtype=np.float64)
    weights = np.array(w, dtype=np.float64)

    def residual(qq: list[float]) -> tuple[np.ndarray, float, float]:
        f = s._fk(qq)
        e = np.array(f[:3])
        R = np.array(f[3:]).reshape(3, 3)
        omega, angle = _rotation_vector(goal @ R.T)
        r = np.concatenate([(t - e) * inv, so * omega])
        return r, float(np.linalg.norm(t - e)), angle

    r, perr, oerr = residual(q)
    cost = float(r @ r)
    taken = 0
    while taken < steps and not (perr <= tol and oerr <= rtol):
        taken += 1
        f = s._fk(q)
        e = np.array(f[:3])
        p = np.array([s._px, s._py, s._pz]).T  # (n, 3) pivots
        a = np.array([s._ax, s._ay, s._az]).T  # (n, 3) unit axes
        J = np.concatenate([np.cross(a, e - p).T * inv, so * a.T])  # (6, n)
        qa = np.array(q)
        pinned = ((qa <= np.array(lower)) & (J.T @ r < 0)) | ((qa >= np.array(upper)) & (J.T @ r > 0))
        wj = np.where(pinned, 0.0, weights)
        JW = J * wj
        dq = JW.T @ np.linalg.solve(JW @ J.T + lam2 * np.eye(6), r)
        trial = np.clip(qa + dq, lower, upper).tolist()
        r_new, p_new, o_new = residual(trial)
        c_new = float(r_new @ r_new)
        if c_new >= cost:
            lam2 *= 4.0
            continue
        q[:] = trial
        r, perr, oerr, cost = r_new, p_new, o_new, c_new
        lam2 = max(base2, lam2 * 0.25)
    return perr <= tol and oerr <= rtol, taken


def _rotation_vector(R: np.ndarray) -> tuple[np.ndarray, float]:
    """The rotation vector ``(3,)`` (axis times angle, radians) of the rotation ``R`` ``(3, 3)``, and its angle."""
    c = max(-1.0, min(1.0, (float(np.trace(R)) - 1.0) * 0.5))
    angle = math.acos(c)
    v = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    s = math.sin(angle)
    if s > 1e-6:
        return v * (angle / (2.0 * s)), angle
    if c > 0.0:  # a small angle: sin(angle) ~ angle
        return v * 0.5, angle
    # near a half turn: the axis is the column of R + I with the largest norm
    B = R + np.eye(3)
    k = int(np.argmax(np.linalg.norm(B, axis=0)))
    axis = B[:, k] / np.linalg.norm(B[:, k])
    return axis * angle, angle
