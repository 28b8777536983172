"""Rotation matrices from Euler channels, vectorised over leading dimensions.

Conventions (the BVH ones): angles in radians, right-handed, active rotations
of column vectors.  An Euler order ``"ZXY"`` means the channels compose in the
listed order as *intrinsic* rotations::

    R = Rz(a0) @ Rx(a1) @ Ry(a2)

which is what Blender, pybvh and bvhio read from a BVH ``CHANNELS`` line with
``Zrotation Xrotation Yrotation``.  Any number of axes (including repeats)
is accepted; an empty order gives the identity.

Example::

    >>> R = euler_to_matrix(np.radians([[30.0, 10.0, -5.0]]), "ZXY")   # (1, 3, 3)
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TypeAlias

import numpy as np

AXIS_INDEX: dict[str, int] = {"X": 0, "Y": 1, "Z": 2}

#: One entry of a 3x3 product as :func:`compose_entries` gives it: ``None`` (zero), ``1.0`` or an array.
Entry: TypeAlias = np.ndarray | float | None


def _axis_index(axis: str | int) -> int:
    if isinstance(axis, str) and axis.upper() in AXIS_INDEX:
        return AXIS_INDEX[axis.upper()]
    if isinstance(axis, int | np.integer) and not isinstance(axis, bool) and 0 <= int(axis) <= 2:
        return int(axis)
    raise ValueError(f"Expected an axis 'X', 'Y', 'Z' or 0, 1, 2, got {axis!r}")


def axis_rotation(axis: str | int, angle: np.ndarray | float) -> np.ndarray:
    """Rotation about one coordinate axis.

    ``angle``: ``(...)`` radians.  Returns ``(..., 3, 3)`` float64.
    """
    a = _axis_index(axis)
    theta = np.asarray(angle, dtype=np.float64)
    c, s = np.cos(theta), np.sin(theta)
    i, k = (a + 1) % 3, (a + 2) % 3
    out = np.zeros(theta.shape + (3, 3))
    out[..., a, a] = 1.0
    out[..., i, i] = c
    out[..., k, k] = c
    out[..., i, k] = -s
    out[..., k, i] = s
    return out


def euler_to_matrix(angles: np.ndarray | Sequence[float], order: str) -> np.ndarray:
    """Compose intrinsic rotations in the listed ``order``.

    ``angles``: ``(..., len(order))`` radians, one column per letter of
    ``order`` (e.g. ``"ZXY"``).  Returns ``(..., 3, 3)`` float64 with
    ``R = R[order[0]] @ R[order[1]] @ ...``.
    """
    a = np.asarray(angles, dtype=np.float64)
    axes = [_axis_index(ch) for ch in order]
    if a.ndim == 0 or a.shape[-1] != len(axes):
        raise ValueError(f"Expected angles of shape (..., {len(axes)}) for order {order!r}, got {a.shape}")
    if not axes:
        return np.broadcast_to(np.eye(3), a.shape[:-1] + (3, 3)).copy()
    cos, sin = np.cos(a), np.sin(a)
    return compose_cos_sin(axes, [cos[..., m] for m in range(len(axes))], [sin[..., m] for m in range(len(axes))])


def compose_cos_sin(
    axes: Sequence[int], cos: Sequence[np.ndarray], sin: Sequence[np.ndarray], *, out: np.ndarray | None = None
) -> np.ndarray:
    """``R = R_axes[0] @ R_axes[1] @ ...`` from precomputed cosines and sines.

    ``cos[m]``, ``sin[m]``: ``(...)`` arrays of the m-th angle.  The product is
    built entry by entry with the zeros and ones of the elementary matrices
    folded away, so each entry costs a few elementwise operations instead of a
    batched 3x3 matmul.  Returns ``(..., 3, 3)``, written into ``out`` if given.
    """
    shape = tuple(np.shape(cos[0])) if len(cos) else ()
    if out is None:
        out = np.empty(shape + (3, 3))
    if not axes:
        out[...] = np.eye(3)
        return out
    mat = compose_entries(axes, cos, sin)
    for i in range(3):
        for k in range(3):
            entry = mat[i][k]
            out[..., i, k] = 0.0 if entry is None else entry
    return out


# fdlibm's __kernel_sin / __kernel_cos minimax coefficients (|x| <= pi/4, error < 1 ulp).
_S = (-1.66666666666666324348e-01, 8.33333333332248946124e-03, -1.98412698298579493134e-04,
      2.75573137070700676789e-06, -2.50507602534068634195e-08, 1.58969099521155010221e-10)  # fmt: skip
_C = (4.16666666666666019037e-02, -1.38888888888741095749e-03, 2.48015872894767294178e-05,
      -2.75573143513906633035e-07, 2.08757232129817482790e-09, -1.13596475577881948265e-11)  # fmt: skip

_QUARTER_COS = np.array([1.0, 0.0, -1.0, 0.0])  # cos(90 q degrees)
_QUARTER_SIN = np.array([0.0, -1.0, 0.0, 1.0])  # -sin(90 q degrees)


def cos_sin_degrees(degrees: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(cos, sin)`` of ``degrees`` ``(...)``, each ``(...)`` float64, in one pass.

    Equal to ``np.cos(np.radians(degrees))`` (and sin) to about 1 ulp, and
    about 3x faster where numpy's float64 ``cos``/``sin`` call libm per element:
    the angle is reduced exactly in degrees to ``q * 90 + r`` with ``|r| <=
    45`` (``x - 90 q`` is exact for ``|x| < 2**52``), both functions come from
    fdlibm's polynomials on ``r`` in radians, and the quadrant ``q`` swaps and
    negates them.  Non-finite angles give NaN, as ``np.cos`` does.
    """
    x = np.asarray(degrees, dtype=np.float64)
    r = x * (1.0 / 90.0)
    np.rint(r, out=r)  # q, the nearest quarter turn; a misrounded tie only leaves |x - 90 q| a hair above 45
    with np.errstate(invalid="ignore"):  # a NaN quadrant casts to anything: r is NaN there anyway
        quadrant = r.astype(np.intp)
    quadrant &= 3
    # cos x = (c, -s, -c, s)[quadrant] = c a + s b and sin x = (s, c, -s, -c)[quadrant] = s a - c b, with a, b
    # in {-1, 0, 1}: exact, and cheaper than masked selects.
    a = _QUARTER_COS.take(quadrant)
    b = _QUARTER_SIN.take(quadrant)
    r *= -90.0
    with np.errstate(invalid="ignore"):  # inf - inf: NaN, silently (np.cos warns)
        r += x
    r *= np.pi / 180.0  # r = x - 90 q, in radians: |r| <= pi/4
    z = r * r
    # sin r = r + r z (S1 + z (S2 + ... + z S6));  cos r = 1 - (z/2 - z^2 (C1 + z (C2 + ... + z C6)))
    sin = _horner(z, _S[1:])
    sin *= z
    sin += _S[0]
    sin *= z
    sin *= r
    sin += r
    cos = _horner(z, _C)
    cos *= z
    cos -= 0.5
    cos *= z
    cos += 1.0
    np.multiply(sin, b, out=z)  # s b
    sin *= a  # s a
    b *= cos  # c b
    a *= cos  # c a
    a += z  # cos x = c a + s b
    sin -= b  # sin x = s a - c b
    return a, sin


def _horner(z: np.ndarray, coefficients: Sequence[float]) -> np.ndarray:
    """``c0 + z (c1 + z (c2 + ...))`` elementwise, in one fresh array."""
    out = z * coefficients[-1]
    for c in coefficients[-2:0:-1]:
        out += c
        out *= z
    out += coefficients[0]
    return out


def compose_entries(
    axes: Sequence[int], cos: Sequence[np.ndarray] | np.ndarray, sin: Sequence[np.ndarray] | np.ndarray
) -> list[list[Entry]]:
    """The 3x3 product of :func:`compose_cos_sin` as nested lists of entries: ``None`` (zero), ``1.0`` or arrays.

    For callers that store matrices entry-major (``(3, 3, ...)``).  ``axes``
    must not be empty.  Signs are carried symbolically until the end, so a
    ZYX product costs 19 elementwise operations, as its closed form does.
    """
    mat = _elementary(axes[0], cos[0], sin[0])
    for m in range(1, len(axes)):
        mat = _symbolic_matmul(mat, _elementary(axes[m], cos[m], sin[m]))
    return [[_value(e) for e in row] for row in mat]


# Symbolic entries: None is 0, 1.0 is 1, (sign, array) is +/-array.
_Signed: TypeAlias = tuple[int, np.ndarray | float]
_Symbol: TypeAlias = _Signed | float | None


def _elementary(a: int, c: np.ndarray, s: np.ndarray) -> list[list[_Symbol]]:
    i, k = (a + 1) % 3, (a + 2) % 3
    m: list[list[_Symbol]] = [[None] * 3 for _ in range(3)]
    m[a][a] = 1.0
    m[i][i] = (1, c)
    m[k][k] = (1, c)
    m[i][k] = (-1, s)
    m[k][i] = (1, s)
    return m


def _mul(x: _Symbol, y: _Symbol) -> _Symbol:
    if x is None or y is None:
        return None
    if isinstance(x, float):
        return y
    if isinstance(y, float):
        return x
    return (x[0] * y[0], x[1] * y[1])


def _add(x: _Symbol, y: _Symbol) -> _Symbol:
    if x is None:
        return y
    if y is None:
        return x
    if isinstance(x, float) or isinstance(y, float):
        return (1, _dense(x) + _dense(y))
    if x[0] == y[0]:
        return (x[0], x[1] + y[1])
    return (x[0], x[1] - y[1])


def _value(e: _Symbol) -> Entry:
    if e is None or isinstance(e, float):
        return e
    return e[1] if e[0] > 0 else -e[1]


def _dense(e: _Signed | float) -> np.ndarray | float:
    """:func:`_value` of a non-zero entry."""
    if isinstance(e, float):
        return e
    return e[1] if e[0] > 0 else -e[1]


def _symbolic_matmul(p: list[list[_Symbol]], q: list[list[_Symbol]]) -> list[list[_Symbol]]:
    return [
        [_add(_add(_mul(p[i][0], q[0][k]), _mul(p[i][1], q[1][k])), _mul(p[i][2], q[2][k])) for k in range(3)]
        for i in range(3)
    ]


def matrix_to_rotvec(matrix: np.ndarray) -> np.ndarray:
    """Rotation vector (axis * angle, radians) of ``(..., 3, 3)`` rotation matrices; ``(..., 3)``.

    Handy to compare rotations by their angle; accurate away from 180 degrees.
    """
    m = np.asarray(matrix, dtype=np.float64)
    if m.shape[-2:] != (3, 3):
        raise ValueError(f"Expected matrices of shape (..., 3, 3), got {m.shape}")
    cos = np.clip((np.trace(m, axis1=-2, axis2=-1) - 1.0) / 2.0, -1.0, 1.0)
    angle = np.arccos(cos)
    v = np.stack([m[..., 2, 1] - m[..., 1, 2], m[..., 0, 2] - m[..., 2, 0], m[..., 1, 0] - m[..., 0, 1]], axis=-1)
    sin = np.sin(angle)
    with np.errstate(invalid="ignore", divide="ignore"):
        scale = np.where(sin > 1e-12, angle / (2.0 * sin), 0.5)
    return v * scale[..., None]
