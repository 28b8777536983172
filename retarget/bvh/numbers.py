"""Fast, exact reading of the whitespace-separated decimal numbers of a BVH MOTION block.

``float()`` and ``np.loadtxt`` spend ~30 ms on the 174 000 numbers of a 1.8 MB
clip on a slow machine.  Here all tokens are decoded at once with SWAR
arithmetic on 64-bit words:

1. token boundaries and dot positions come from whole-block byte compares;
2. each token is anchored at its dot (or its end if it has none) and the 16
   bytes around it are fetched in one gather: the low word holds the 7 bytes
   before the dot (the integer digits) and the dot itself, the high word the
   8 bytes after it (the fraction digits); bytes outside the token, and the
   dot, are masked to zero;
3. both words are checked to be all digits and folded into integers, 8
   digits at a time (the fast_float/simdjson trick): the low word gives
   ``int_part * 10`` (the masked dot is a zero units digit), the high one
   ``fraction * 10**(8 - f)``, so ``m = low * 10**7 + high = int_part * 10**8
   + fraction * 10**(8 - f)``;
4. ``value = m / 1e8``.

Exactness: with at most 7 integer and 8 fraction digits, ``m < 10**15 <
2**53`` is exact as a double and ``m / 1e8`` is one correctly rounded IEEE
division of the exact decimal value, so every result is bit-identical to
``float(token)``.  Anything else (exponents, longer numbers, ``nan``, stray
characters, a lone ``-``, a token with two dots) is flagged in ``needs_slow``
for the caller.

Callers feed it ~100 KB windows (see ``retarget.bvh.parse._read_frames``) so the
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
_0, _8, _16, _32 = (_U(v) for v in (0, 8, 16, 32))

# Per-token lookup tables.  ``_SIGNED``/``_DIVISOR`` by first byte.  The others by the token's shape, ``case =
# (int_len + 1) * 12 + (tail + 1)``, with ``int_len`` the digits before the dot clipped to -1..8 and ``tail`` the
# bytes from the dot to the token's end clipped to -1..10 (0: no dot; 1 + the number of fraction digits).  -1 in
# either means the dot is not inside the token (a token with two dots and one with none): slow.
_SIGNED = np.zeros(256, dtype=np.intp)
_SIGNED[[43, 45]] = 1
_DIVISOR = np.full(256, 1e8)
_DIVISOR[45] = -1e8
_INT_LENS = np.arange(-1, 9)
_TAILS = np.arange(-1, 11)
_SLOW_CASE = np.array(
    [i < 0 or i > 7 or t < 0 or t > 9 or (i == 0 and t <= 1) for i in _INT_LENS for t in _TAILS], dtype=bool
)
# per case, the masks of the low word (the top ``int_len`` bytes below the dot, which is byte 7) and of the high
# word (the low ``tail - 1`` bytes)
_KEEP = np.array(
    [
        [((1 << (8 * i)) - 1) << (8 * (7 - i)) if 0 < i <= 7 else 0, (1 << (8 * (t - 1))) - 1 if 1 < t <= 9 else 0]
        for i in _INT_LENS
        for t in _TAILS
    ],
    dtype=np.uint64,
)
_E7 = _U(10_000_000)

CHUNK = 16384  #: tokens per vector step: a whole ~100 KB window in one
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


def _anchors(b: np.ndarray, starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """Per token, the offset of a dot (its end when it has none).

    The common case, as many dots as tokens, pairs them in order without
    checking: a dot paired with the wrong token lies outside it, which
    :func:`parse_tokens` flags as slow.  Otherwise a token with several dots
    is anchored at the byte before its start (flagged the same way).
    """
    dots = np.flatnonzero(b == 46)
    if dots.size == starts.size:
        return dots
    owner = np.searchsorted(starts, dots, side="right") - 1  # a '.' is never whitespace: always inside a token
    anchors = ends.copy()
    anchors[owner] = dots
    several = np.flatnonzero(np.bincount(owner, minlength=starts.size) > 1)
    anchors[several] = starts[several] - 1  # int_len < 0: slow (and still 8 bytes into the buffer's margin)
    return anchors


def parse_tokens(
    buf: np.ndarray, base: int, starts: np.ndarray, ends: np.ndarray, *, out: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Values of the tokens ``buf[base + starts[i] : base + ends[i]]``.

    ``buf``: uint8 with at least 8 bytes before ``base`` and ``PAD`` bytes
    after the last token (any content: bytes outside a token are masked).
    Returns ``(values (n,) float64, needs_slow (n,) bool)``, ``values``
    written into ``out`` if given; ``values`` is garbage where ``needs_slow``,
    finite elsewhere.
    """
    n = starts.size
    values = np.empty(n) if out is None else out
    if values.shape != (n,):
        raise ValueError(f"Expected out of shape ({n},), got {values.shape}")
    needs_slow = np.empty(n, dtype=bool)
    if n == 0:
        return values, needs_slow
    if base < 8 or buf.size < base + int(ends[-1]) + PAD:
        raise ValueError(f"Expected 8 bytes before and {PAD} after the tokens, got {base} and {buf.size - base}")
    b = buf[base : base + int(ends[-1])]
    anchors = _anchors(b, starts, ends)
    first = b[starts]
    int_len = anchors - starts
    int_len -= _SIGNED.take(first)
    np.clip(int_len, -1, 8, out=int_len)
    tail = ends - anchors
    np.clip(tail, -1, 10, out=tail)
    int_len += 1
    int_len *= _TAILS.size
    int_len += tail
    int_len += 1
    case = int_len
    _SLOW_CASE.take(case, out=needs_slow)
    divisor = _DIVISOR.take(first)  # -1e8 after a minus sign: an exact sign flip of the rounded quotient
    # the 16 bytes from 7 before each dot: two little-endian words per token
    pairs = np.ndarray((buf.size - 15,), dtype="V16", buffer=buf, strides=(1,))
    at = anchors + (base - 7)
    for s in range(0, n, CHUNK):
        part = slice(s, s + CHUNK)
        words = pairs[at[part]].view("<u8").reshape(-1, 2)  # indexing, not take(): take copies a strided source
        v, bad = _digits(words, _KEEP.take(case[part], axis=0))
        bad = bad[:, 0] | bad[:, 1]
        m = v[:, 0] * _E7
        m += v[:, 1]
        np.divide(m, divisor[part], out=values[part])
        needs_slow[part] |= bad != _0
    return values, needs_slow
