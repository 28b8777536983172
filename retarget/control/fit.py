"""The least-squares fits of :func:`~retarget.control.plan.plan_path`: a joint path near its goals within the speed
and acceleration limits, by ADMM (Boyd et al., "Distributed optimization and statistical learning via the
alternating direction method of multipliers", 2011, sec. 5: a quadratic cost with box constraints on linear maps
of ``q``).

* :func:`fit_joints`: the cost ``1/2 |q - g|^2`` per joint, each joint alone.  The path is padded (``q_start``
  before, the last goal after) and mirrored, so its differences are circular and each sweep's linear solve is
  diagonal in the Fourier basis: one real FFT pair over all the joints together.
* :func:`fit_task`: the cost of the *task*, linearised at the goals (:class:`Task`: the tool point's Jacobian and
  residual per tick), over the joints together: where one joint falls behind its goal, the others make up for it
  where their own limits allow.  A ``k x k`` solve per tick (inverted once) joins the sweep; the path's own solve
  is in the cosine basis, unmirrored (:func:`_cosine_solve`).

Both return paths not yet exactly within the limits (ADMM's few sweeps leave the constraints nearly but not exactly
met): the planner's last pass, the limiter's own profile, makes them so.  Units are slots: rad, rad per slot, rad
per slot^2.  Pure numpy.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

__all__ = [
    "ACCEL_SHARE",
    "Costs",
    "Halfspaces",
    "Task",
    "check_task",
    "fit_joints",
    "fit_task",
    "joint_task",
    "task_of",
]

Array = npt.NDArray[np.float64]


@dataclass(frozen=True)
class Costs:
    """The fits' soft costs (:func:`~retarget.control.plan.plan_path`'s): on speeds above ``easy_speed`` of the
    limit (``speed``, per (share of the limit)^2), and on the change of acceleration per slot (``jerk``, per (share
    of the acceleration limit)^2: a full reversal of the acceleration from one slot to the next costs ``2 jerk``)."""

    speed: float
    easy_speed: float
    jerk: float


#: ADMM's penalty weights of the speed and the acceleration constraints, each per (share of its limit)^2: the
#: quickest to settle on the shared clips at 100 Hz (a step's end within 0.5 % of the goal after 20 sweeps).  Being
#: relative to the limits per slot, the costs and weights keep their meaning at any rate.
_RHO_SPEED, _RHO_ACCEL = 0.1, 0.02
#: the share of the acceleration limit the least-squares path may use: the last pass needs room to catch up where
#: ADMM's few sweeps left the path slightly over the limit (planned to the full limit, a joint that fell behind there
#: stays behind for as long as the goal keeps it at the limit: a quarter period on a long too-sharp oscillation)
ACCEL_SHARE = 0.97
_PAD = 50  #: slots of padding at each end (at q_start before, at the last goal after)


def fit_joints(goal: Array, q0: Array, vmax: Array, amax: Array, iterations: int, costs: Costs) -> Array:
    """The paths ``(k, n)`` rad nearest ``goal`` ``(k, n)`` rad by the module docstring's cost, approximately
    (``iterations`` ADMM sweeps, scaled form), each joint from ``q0`` ``(k,)`` rad with its own ``vmax`` and
    ``amax`` ``(k,)`` per slot.  Not yet exactly within the limits: the profile's last pass makes it so."""
    k, n = goal.shape
    size = _fft_size(2 * (n + 2 * _PAD))
    half = size // 2
    x = _padded(goal, q0, half)
    x = np.concatenate([x, x[:, ::-1]], axis=1)  # mirrored: a circular path whose differences are circular too
    lam = 2.0 - 2.0 * np.cos(2.0 * np.pi * np.arange(half + 1) / size)  # |1 - e^-iw|^2, the difference's gain
    rho1, rho2 = (_RHO_SPEED / vmax**2)[:, None], (_RHO_ACCEL / amax**2)[:, None]  # per rad^2 (per slot)
    jerk = (costs.jerk / amax**2)[:, None]  # the jerk cost, a term of the update itself (D'D'D'DDD: lam^3)
    inverse = 1.0 / (1.0 + rho1 * lam + (rho2 + jerk * lam) * lam * lam)  # (I + rho1 D'D + rho2 D'D'DD + ..)^-1
    fixed = np.fft.rfft(x) * inverse
    easy, vcap, acap = (costs.easy_speed * vmax)[:, None], vmax[:, None], (ACCEL_SHARE * amax)[:, None]
    keep = _RHO_SPEED / (_RHO_SPEED + costs.speed)  # the share of a speed above ``easy`` that the soft cost keeps
    q, d1 = x, _diff(x)
    z1, z2 = np.clip(d1, -vcap, vcap), np.clip(_diff(d1), -acap, acap)
    u1, u2 = np.zeros_like(x), np.zeros_like(x)
    rfft, irfft, clip = np.fft.rfft, np.fft.irfft, np.clip
    for _ in range(iterations):
        r = _diff_t(_diff_t(rho2 * (z2 - u2)) + rho1 * (z1 - u1))
        q = irfft(fixed + inverse * rfft(r), n=size)
        d1 = _diff(q)
        d2 = _diff(d1)
        u1 += d1
        z1 = _speed_prox(u1, easy, keep, vcap)
        u1 -= z1
        u2 += d2
        z2 = clip(u2, -acap, acap)
        u2 -= z2
    return q[:, _PAD : _PAD + n]


@dataclass(frozen=True)
class Task:
    """The linearised task of :func:`fit_task`, over the planned ``joints`` (k of them): per tick the
    cost ``1/2 e' e / lever^2 + REG/2 |q - g|^2`` of the task error ``e = J (q - g) + r``, as ``A`` ``(k, k, n)``
    (``J'J / lever^2 + REG I``) and ``b`` ``(k, n)`` (``J' r / lever^2``), entry-major."""

    joints: list[int]
    A: Array
    b: Array


@dataclass(frozen=True)
class Halfspaces:
    """Linear constraints on single ticks of a path: ``normals[i] . q[ticks[i]] >= offsets[i]``, ``ticks``
    ``(c,)`` (distinct), ``normals`` ``(c, k)`` over the path's ``k`` joints, ``offsets`` ``(c,)`` (a clearance
    linearised at a planned pose: :mod:`~retarget.control.keepclear`)."""

    ticks: npt.NDArray[np.intp]
    normals: Array
    offsets: Array

    def over(self, joints: list[int], goals: Array) -> Halfspaces:
        """The same constraints over ``joints`` alone, the other joints held at ``goals`` ``(n, n_joints)`` (their
        part moved into the offsets)."""
        others = np.ones(self.normals.shape[1], dtype=bool)
        others[joints] = False
        held = (self.normals[:, others] * goals[self.ticks][:, others]).sum(axis=1)
        return Halfspaces(self.ticks, self.normals[:, joints], self.offsets - held)


#: the task fit's joint-space term, per rad^2 against the task error per (lever x rad)^2: a joint the task does not
#: need (a direction the Jacobian does not see) still stays near its goal
_TASK_REG = 0.01
#: the task fit's ADMM weights, as :data:`_RHO_SPEED` and :data:`_RHO_ACCEL` (each a share of the joint's own task
#: weight), and of the consensus with the task's own term; and its over-relaxation
_TASK_RHO = (0.01, 0.001, 1.0)
_TASK_RELAX = 1.8


def check_task(
    jacobians: npt.ArrayLike | None, residuals: npt.ArrayLike | None, n: int, m: int
) -> tuple[Array, Array] | None:
    """:func:`~retarget.control.plan.plan_path`'s ``jacobians`` ``(n, d, m)`` and ``residuals`` ``(n, d)`` (default
    zeros), checked; None without ``jacobians``."""
    if jacobians is None:
        if residuals is not None:
            raise ValueError("Expected jacobians with residuals, got residuals alone")
        return None
    J = np.asarray(jacobians, dtype=np.float64)
    if J.ndim != 3 or J.shape[0] != n or J.shape[2] != m:
        raise ValueError(f"Expected jacobians of shape ({n}, d, {m}), got {J.shape}")
    r = np.zeros(J.shape[:2]) if residuals is None else np.asarray(residuals, dtype=np.float64)
    if r.shape != J.shape[:2]:
        raise ValueError(f"Expected residuals of shape {J.shape[:2]}, got {r.shape}")
    return J, r


def task_of(goals: Array, jacobians: Array, r: Array, hard: list[int]) -> Task | None:
    """The :class:`Task` of ``goals`` ``(n, n_joints)`` (``jacobians`` and residuals ``r`` as
    :func:`~retarget.control.plan.plan_path`'s) over the joints in ``hard`` and every other joint that moves (its
    goal path is not constant) and moves the task point; None when none of them moves it."""
    m = goals.shape[1]
    reach = np.sqrt(np.mean(jacobians**2, axis=(0, 1)))  # (m,) rms metres per rad
    moving = np.ptp(goals, axis=0) > 0
    joints = [j for j in range(m) if j in hard or (moving[j] and reach[j] > 0)]
    J = jacobians[:, :, joints]
    lever2 = float(np.mean(np.sum(J**2, axis=1)))
    if lever2 == 0.0:
        return None
    A = np.einsum("tdi,tdj->ijt", J, J) / lever2
    A[np.arange(len(joints)), np.arange(len(joints))] += _TASK_REG
    return Task(joints, A, np.einsum("tdi,td->it", J, r) / lever2)


def joint_task(joints: list[int], n: int) -> Task:
    """The joints' own cost ``1/2 |q - g|^2`` over ``n`` ticks as a :class:`Task` (``A = I``, ``b = 0``): for
    :func:`fit_task` to meet :class:`Halfspaces` where no task point moves with the joints."""
    k = len(joints)
    return Task(joints, np.repeat(np.eye(k)[:, :, None], n, axis=2), np.zeros((k, n)))


def fit_task(
    goal: Array,
    q0: Array,
    vmax: Array,
    amax: Array,
    iterations: int,
    costs: Costs,
    task: Task,
    halfspaces: Halfspaces | None = None,
) -> Array:
    """:func:`fit_joints` with the task's cost (:class:`Task`) in place of ``1/2 |q - g|^2``: ADMM with three
    blocks, the task term (a ``k x k`` solve per tick, inverted once: :func:`_task_prox`), the speeds and the changes
    of speed, over-relaxed (:data:`_TASK_RELAX`, Boyd et al. sec. 3.4.3); the jerk cost is a term of the joints' own
    update.  Each joint's weights scale with its own task weight (the mean of its diagonal entry of ``A``): a
    diagonal preconditioner, so that a long lever and a short one settle alike.

    The path is kept unmirrored (``h`` slots: padding, goals, padding), its steps ``D q`` ``(k, h - 1)`` and changes
    of step ``-L q`` ``(k, h)`` (``L = D'D``, the path's Laplacian): the mirrored circle's values, each once, so every
    sweep's work is half of :func:`fit_joints`'s, and the joints' own update solves in the cosine basis (where
    ``L`` is diagonal, :func:`_cosine_solve`).

    ``halfspaces`` (over the task's joints) join the task term's prox: a tick's prox that breaks its constraint is
    moved onto it along ``(A + rho0)^-1 normal`` (the nearest point of the halfspace in the prox's own metric: the
    exact prox of the task term with the constraint), a few products on those ticks alone."""
    k, n = goal.shape
    h = _fft_size(n + 2 * _PAD)
    x = _padded(goal, q0, h)
    weight = task.A[np.arange(k), np.arange(k)].mean(axis=1)[:, None]  # (k, 1)
    r_speed, r_accel, r_task = _TASK_RHO
    rho0 = r_task * weight
    rho1, rho2 = weight * r_speed / vmax[:, None] ** 2, weight * r_accel / amax[:, None] ** 2
    twiddle, eigen = _cosine_basis(h)
    rho3 = (costs.jerk * weight / amax[:, None] ** 2)[:, :, None]  # the jerk cost: a term of the update itself
    inverse = _inverse(rho0, rho1, rho2, rho3, eigen)
    solve, shift = _task_prox(task, rho0, h - _PAD - n)
    onto = None if halfspaces is None or not len(halfspaces.ticks) else _onto(halfspaces, solve, rho0)
    aims = x[:, _PAD:]  # (k, h - PAD): the goals, then the last one
    easy, vcap, acap = costs.easy_speed * vmax[:, None], vmax[:, None], ACCEL_SHARE * amax[:, None]
    keep = r_speed / (r_speed + costs.speed)
    pad_keep = rho0 / (weight + rho0)  # the padding before the first goal: 1/2 |q - q0|^2 at the joint's weight
    real = slice(_PAD, h)
    d1 = _steps(x)
    z0, z1, z2 = x.copy(), np.clip(d1, -vcap, vcap), np.clip(-_steps_t(d1), -acap, acap)
    u0, u1, u2 = np.zeros_like(z0), np.zeros_like(z1), np.zeros_like(z2)
    al, clip = _TASK_RELAX, np.clip
    q = x
    for _ in range(iterations):
        w = rho2 * (z2 - u2)
        r = rho0 * (z0 - u0) + _steps_t(rho1 * (z1 - u1) - _steps(w))  # D'(rho1 (z1 - u1)) - L (rho2 (z2 - u2))
        q = _cosine_solve(r, inverse, twiddle)
        d1 = _steps(q)
        d2 = -_steps_t(d1)
        v = z0 + al * (q - z0) + u0
        z0 = x + pad_keep * (v - x)
        z0[:, real] = aims + shift + (solve * (v[:, real] - aims)[None]).sum(axis=1)
        if onto is not None:
            cols, normals, offsets, step = onto
            short = offsets - (normals * z0[:, cols]).sum(axis=0)
            z0[:, cols] += step * np.maximum(short, 0.0)
        u0 = v - z0
        u1 += z1 + al * (d1 - z1)
        z1 = _speed_prox(u1, easy, keep, vcap)
        u1 -= z1
        u2 += z2 + al * (d2 - z2)
        z2 = clip(u2, -acap, acap)
        u2 -= z2
    return q[:, _PAD : _PAD + n]


def _speed_prox(u: Array, easy: Array, keep: float, cap: Array) -> Array:
    """The prox of the soft speed cost and the hard limit on steps ``u`` ``(k, h)``: within ``easy`` ``(k, 1)`` a
    step is kept, beyond it ``keep`` of the excess is, and the result is clipped to ``cap`` ``(k, 1)``."""
    within = np.clip(u, -easy, easy)
    return np.clip(within + keep * (u - within), -cap, cap)


def _task_prox(task: Task, rho0: Array, after: int) -> tuple[Array, Array]:
    """The task term's prox at each tick: ``z = g + shift + solve (v - g)``, with ``solve = (A + rho0)^-1 rho0``
    ``(k, k, n + after)`` and ``shift = -(A + rho0)^-1 b`` ``(k, n + after)``; the ``after`` slots of padding past
    the last goal keep the last tick's task (its residual too)."""
    inv = np.moveaxis(np.linalg.inv(np.moveaxis(task.A, -1, 0) + np.diag(rho0[:, 0])), 0, -1)  # (k, k, n)
    inv = np.concatenate([inv, np.repeat(inv[:, :, -1:], after, axis=2)], axis=2)
    b = np.concatenate([task.b, np.repeat(task.b[:, -1:], after, axis=1)], axis=1)
    return inv * rho0[None, :, :], -(inv * b[None]).sum(axis=1)


def _onto(halfspaces: Halfspaces, solve: Array, rho0: Array) -> tuple[npt.NDArray[np.intp], Array, Array, Array]:
    """What the task prox needs to meet ``halfspaces``: their columns of the padded path, normals ``(k, c)`` and
    offsets ``(c,)``, and the step ``(k, c)`` per unit of shortfall, ``(A + rho0)^-1 n / (n' (A + rho0)^-1 n)``
    (``(A + rho0)^-1`` being ``solve`` over ``rho0``, :func:`_task_prox`)."""
    ticks = halfspaces.ticks
    normals = halfspaces.normals.T  # (k, c)
    toward = np.einsum("ijc,jc->ic", solve[:, :, ticks] / rho0[None, :, :], normals)  # (A + rho0)^-1 n
    return _PAD + ticks, normals, halfspaces.offsets, toward / (normals * toward).sum(axis=0)


def _inverse(rho0: Array, rho1: Array, rho2: Array, rho3: Array, eigen: Array) -> Array:
    """``1 / (rho0 + rho1 L + rho2 L^2 + rho3 L^3)`` ``(k, 2, m)`` at the path Laplacian's eigenvalues ``eigen``
    ``(2, m)``, each weight ``(k, 1)`` (``rho3`` ``(k, 1, 1)``): the joints' own update in the cosine basis."""
    return 1.0 / (rho0[:, :, None] + eigen * (rho1[:, :, None] + eigen * (rho2[:, :, None] + rho3 * eigen)))


def _cosine_basis(h: int) -> tuple[npt.NDArray[np.complex128], Array]:
    """For :func:`_cosine_solve` on paths of ``h`` slots: the twiddles ``(m,)`` (``m = h // 2 + 1``) and the path
    Laplacian's eigenvalues ``(2, m)`` at cosine frequency ``j`` (row 0) and ``h - j`` (row 1), ``j < m``."""
    j = np.arange(h // 2 + 1)
    return np.exp(-0.5j * np.pi * j / h), 2.0 - 2.0 * np.cos(np.pi * np.stack([j, h - j]) / h)


def _cosine_solve(r: Array, inverse: Array, twiddle: npt.NDArray[np.complex128]) -> Array:
    """``q`` ``(k, h)`` solving ``f(L) q = r`` row by row, ``L`` the path Laplacian (:func:`_steps_t` of
    :func:`_steps`, diagonal in the cosine basis), given ``1 / f`` at each row's eigenvalues ``inverse``
    ``(k, 2, m)`` (:func:`_cosine_basis`): the cosine transform (DCT-II) by one real FFT of ``h`` points (Makhoul,
    "A fast cosine transform in one and two dimensions", 1980), the division, and back.  The same as mirroring the
    path to ``2 h`` slots and solving in the Fourier basis, at half the FFT's length."""
    h = r.shape[1]
    odd = (h + 1) // 2
    v = np.empty_like(r)
    v[:, :odd], v[:, odd:] = r[:, ::2], r[:, 1::2][:, ::-1]
    y = twiddle * np.fft.rfft(v)
    y = y.real * inverse[:, 0] + 1j * (y.imag * inverse[:, 1])
    v = np.fft.irfft(np.conj(twiddle) * y, n=h)
    q = np.empty_like(r)
    q[:, ::2], q[:, 1::2] = v[:, :odd], v[:, odd:][:, ::-1]
    return q


def _steps(y: Array) -> Array:
    """``D y``: the steps ``y[i + 1] - y[i]`` ``(k, h - 1)`` of a path ``y`` ``(k, h)``."""
    return y[:, 1:] - y[:, :-1]


def _steps_t(a: Array) -> Array:
    """``D' a``: the transpose of :func:`_steps`, ``(k, h - 1)`` -> ``(k, h)``: ``a[i - 1] - a[i]`` (0 beyond the
    ends)."""
    out = np.empty((a.shape[0], a.shape[1] + 1))
    out[:, 0] = -a[:, 0]
    out[:, -1] = a[:, -1]
    np.subtract(a[:, :-1], a[:, 1:], out=out[:, 1:-1])
    return out


def _padded(goal: Array, q0: Array, h: int) -> Array:
    """``goal`` ``(k, n)`` rad padded to ``h`` slots: :data:`_PAD` slots at ``q0`` before, the last goal after."""
    x = np.empty((goal.shape[0], h))
    x[:, :_PAD] = q0[:, None]
    x[:, _PAD : _PAD + goal.shape[1]] = goal
    x[:, _PAD + goal.shape[1] :] = goal[:, -1:]
    return x


def _diff(y: Array) -> Array:
    """The circular backward difference along the last axis: ``y[i] - y[i - 1]``."""
    out = np.empty_like(y)
    np.subtract(y[:, 1:], y[:, :-1], out=out[:, 1:])
    np.subtract(y[:, 0], y[:, -1], out=out[:, 0])
    return out


def _diff_t(y: Array) -> Array:
    """The transpose of :func:`_diff`: ``y[i] - y[i + 1]``, circular."""
    out = np.empty_like(y)
    np.subtract(y[:, :-1], y[:, 1:], out=out[:, :-1])
    np.subtract(y[:, -1], y[:, 0], out=out[:, -1])
    return out


def _fft_size(n: int) -> int:
    """The smallest even length >= ``n`` with no prime factor above 5 (a fast FFT length)."""
    best = 1 << max(1, (n - 1).bit_length())
    for odd in (3, 5, 9, 15, 25, 27, 45, 75, 81, 125, 135, 225):
        size = 2 * odd
        while size < n:
            size *= 2
        best = min(best, size)
    return best
