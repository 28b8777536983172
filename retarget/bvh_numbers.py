"""Fast, exact reading of the whitespace-separated decimal numbers of a BVH MOTION block.

``float()`` and ``np.loadtxt`` spend ~30 ms on the 174 000 numbers of a 1.8 MB
clip on a slow machine.  Here all tokens are decoded at once with SWAR
arithmetic on 64-bit words:

1. token boundaries and dot positions come from whole-block byte compares;
2. each token is anchored at its dot (or its end if it has none): the 8
   bytes before the dot hold the integer digits, the 8 after it the
   fraction digits; bytes outside the token are masked to ``'0'``;
3. both words are checked to be all digits and folded into integers, 8
   digits at a time (the fast_float/simdjson trick), giving
   ``m = int_part * 10**8 + fraction * 10**(8 - f)``;
4. ``value = m / 1e8``.

Exactness: with at most 7 integer and 8 fraction digits, ``m < 10**15 <
2**53`` is exact as a double and ``m / 1e8`` is one correctly rounded IEEE
division of the exact decimal value, so every result is bit-identical to
``float(token)``.  Anything else (exponents, longer numbers, ``nan``, stray
characters, a lone ``-``) is flagged in ``needs_slow`` for the caller.

Work runs in chunks so temporaries stay in cache and below the allocator's
mmap threshold (page faults dominate otherwise).
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


def _anchors(b: np.ndarray, starts: np.ndarray, ends: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per token, the offset of its dot (its end when it has none), and whether it has several dots."""
    dots = np.flatnonzero(b == 46)
    if dots.size == starts.size and bool(((dots >= starts) & (dots < ends)).all()):
        return dots, np.zeros(starts.size, dtype=bool)
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
    negative = first == 45
    divisor = 1e8 - 2e8 * negative  # -1e8 for a minus sign: an exact sign flip of the rounded quotient
    int_len = anchors - starts - (negative | (first == 43))
    frac_len = np.maximum(ends - anchors - 1, 0)
    # tokens the 7 + 8 digit fast path cannot take, decided for all at once
    np.greater(int_len, 7, out=needs_slow)
    needs_slow |= frac_len > 8
    needs_slow |= (int_len + frac_len) == 0
    needs_slow |= several_dots
    # shifts that keep the int_len bytes before the dot and the frac_len bytes after it
    shift_i = ((8 - np.minimum(int_len, 8)) * 8).astype(np.uint64)
    shift_f = ((8 - np.minimum(frac_len, 8)) * 8).astype(np.uint64)
    words = np.ndarray((buf.size - 7,), dtype="<u8", buffer=buf, strides=(1,))
    at_i = anchors + (base - 8)
    at_f = anchors + (base + 1)
    for s in range(0, n, CHUNK):
        part = slice(s, s + CHUNK)
        vi, bad = _digits(words[at_i[part]], _FULL << shift_i[part])
        vf, bad_f = _digits(words[at_f[part]], _FULL >> shift_f[part])
        bad |= bad_f
        vi *= _E8
        vi += vf
        np.divide(vi, divisor[part], out=values[part])
        needs_slow[part] |= bad != _0
    return values, needs_slow
