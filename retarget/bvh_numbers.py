"""Fast, exact reading of the whitespace-separated decimal numbers of a BVH MOTION block.

``float()`` and ``np.loadtxt`` spend ~30 ms on the 174 000 numbers of a 1.8 MB
clip on a slow machine.  Here all tokens are decoded at once with SWAR
arithmetic on 64-bit words:

1. token boundaries and dot positions come from whole-block byte compares;
2. each token is anchored at its dot (or its end if it has none): the 8
   bytes before the dot hold the integer digits, the 8 after it the
   fraction digits; bytes outside the token are masked to zero;
3. both words are checked to be all digits and folded into integers, 8
   digits at a time (the fast_float/simdjson trick), giving
   ``m = int_part * 10**8 + fraction * 10**(8 - f)``;
4. ``value = m / 1e8``.

Exactness: with at most 7 integer and 8 fraction digits, ``m < 10**15 <
2**53`` is exact as a double and ``m / 1e8`` is one correctly rounded IEEE
division of the exact decimal value, so every result is bit-identical to
``float(token)``.  Anything else (exponents, longer numbers, ``nan``, stray
characters, a lone ``-``) is flagged in ``needs_slow`` for the caller.

Callers feed it ~100 KB windows (see ``retarget.bvh._read_frames``) so the
temporaries stay in cache and below the allocator's mmap threshold: on a
small VM, page-faulting fresh megabyte-sized temporaries costs more than the
arithmetic.
"""

from __future__ import annotations

import numpy as np

_U = np.uint64
_FULL = _U(0xFFFFFFFFFFFFFFFF)
_ZEROS = _U(0x3030303030303030)  # "00000000"
_SEVENTY_SIXES = _U(0x7676767676767676)
_HIGH = _U(0x8080808080808080)
_K1, _K2, _K3 = _U(2561), _U(6553601), _U(42949672960001)
_M2, _M3 = _U(0x00FF00FF00FF00FF), _U(0x0000FFFF0000FFFF)
_E8 = _U(100_000_000)
_0, _8, _16, _32 = (_U(v) for v in (0, 8, 16, 32))

# Per-token lookup tables.  ``_SIGNED``/``_DIVISOR`` by first byte; ``_KEEP_HIGH[k]`` keeps the top k bytes of a
# word (the k digits before a dot), ``_KEEP_LOW[k]`` the low k bytes (the k digits after it); ``_SLOW_CASE`` by
# ``int_len * 11 + frac_len + 1`` (int_len 0..8, frac_len -1..9): more than 7 + 8 digits, or none at all.
_SIGNED = np.zeros(256, dtype=np.intp)
_SIGNED[[43, 45]] = 1
_DIVISOR = np.full(256, 1e8)
_DIVISOR[45] = -1e8
_KEEP_HIGH = np.array([0] + [((1 << (8 * k)) - 1) << (8 * (8 - k)) for k in range(1, 9)], dtype=np.uint64)
_KEEP_LOW = np.array([(1 << (8 * k)) - 1 for k in range(10)], dtype=object).clip(max=(1 << 64) - 1).astype(np.uint64)
_SLOW_CASE = np.array([i == 8 or f == 9 or (i == 0 and f <= 0) for i in range(9) for f in range(-1, 10)])

CHUNK = 8192  #: tokens per vector step
PAD = 16  #: bytes of padding before the block (and after it) that :func:`parse_tokens` reads


def pad_block(block: bytes) -> np.ndarray:
    """The uint8 view :func:`parse_tokens` reads: ``PAD`` spaces, ``block``, ``PAD`` spaces."""
    return np.frombuffer(b" " * PAD + block + b" " * PAD, dtype=np.uint8)


def token_bounds(b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Start and end (exclusive) byte offsets of the tokens of ``b`` ``(n,)`` uint8.

    Any byte ``<= 0x20`` separates tokens (``bytes.split()`` plus the other
    control characters).
    """
    n = b.size
    if n == 0:
        empty = np.zeros(0, dtype=np.intp)
        return empty, empty
    ws = b <= 32
    edge = np.empty(n + 1, dtype=bool)
    edge[0] = not ws[0]
    np.not_equal(ws[1:], ws[:-1], out=edge[1:n])
    edge[n] = not ws[-1]
    bounds = np.flatnonzero(edge)
    return bounds[0::2], bounds[1::2]


def _digits(words: np.ndarray, keep: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The 8-digit integers in ``words`` (first digit in the low byte; bytes outside ``keep`` read as 0), and a
    non-zero flag word where a kept byte is not an ASCII digit."""
    v = words ^ _ZEROS  # '0'..'9' -> 0..9
    v &= keep
    bad = v + _SEVENTY_SIXES  # a byte 0..9 stays below 0x80, 10..0x7F reaches it; >= 0x80 is caught by v itself
    bad |= v
    bad &= _HIGH
    v *= _K1  # fold 8 digits: pairs, quads, then all eight (fast_float's parse_eight_digits)
    v >>= _8
    v &= _M2
    v *= _K2
    v >>= _16
    v &= _M3
    v *= _K3
    v >>= _32
    return v, bad


def _anchors(b: np.ndarray, starts: np.ndarray, ends: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
    """Per token, the offset of its dot (its end when it has none), and whether it has several dots (None: none
    has)."""
    dots = np.flatnonzero(b == 46)
    if dots.size == starts.size and bool(((dots >= starts) & (dots < ends)).all()):
        return dots, None
    owner = np.searchsorted(starts, dots, side="right") - 1  # a '.' is never whitespace: always inside a token
    anchors = ends.copy()
    anchors[owner] = dots
    return anchors, np.bincount(owner, minlength=starts.size) > 1


def parse_tokens(buf: np.ndarray, base: int, starts: np.ndarray, ends: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Values of the tokens ``buf[base + starts[i] : base + ends[i]]``.

    ``buf``: uint8 with at least 8 bytes before ``base`` and ``PAD`` bytes
    after the last token (any content: bytes outside a token are masked).
    Returns ``(values (n,) float64, needs_slow (n,) bool)``; ``values`` is
    garbage where ``needs_slow``.
    """
    n = starts.size
    values = np.empty(n)
    needs_slow = np.empty(n, dtype=bool)
    if n == 0:
        return values, needs_slow
    if base < 8 or buf.size < base + int(ends[-1]) + PAD:
        raise ValueError(f"Expected 8 bytes before and {PAD} after the tokens, got {base} and {buf.size - base}")
    b = buf[base : base + int(ends[-1])]
    anchors, several_dots = _anchors(b, starts, ends)
    first = b[starts]
    int_len = np.minimum(anchors - starts - _SIGNED.take(first), 8)  # digits before the dot (8: too many)
    frac_len = np.minimum(ends - anchors - 1, 9)  # digits after it (-1: no dot; 9: too many)
    case = int_len * 11 + frac_len + 1
    _SLOW_CASE.take(case, out=needs_slow)
    if several_dots is not None:
        needs_slow |= several_dots
    divisor = _DIVISOR.take(first)  # -1e8 after a minus sign: an exact sign flip of the rounded quotient
    keep_i = _KEEP_HIGH.take(int_len)
    keep_f = _KEEP_LOW.take(np.maximum(frac_len, 0))
    words = np.ndarray((buf.size - 7,), dtype="<u8", buffer=buf, strides=(1,))
    at_i = anchors + (base - 8)
    at_f = anchors + (base + 1)
    for s in range(0, n, CHUNK):
        part = slice(s, s + CHUNK)
        vi, bad = _digits(words[at_i[part]], keep_i[part])
        vf, bad_f = _digits(words[at_f[part]], keep_f[part])
        bad |= bad_f
        vi *= _E8
        vi += vf
        np.divide(vi, divisor[part], out=values[part])
        needs_slow[part] |= bad != _0
    return values, needs_slow
