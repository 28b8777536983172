"""Fast, exact parsing of the whitespace-separated decimal numbers of a BVH MOTION block.

``float()`` / ``np.loadtxt`` spend ~30 ms on the 174 000 numbers of a 1.8 MB
clip on a slow machine.  Here each token is read as two little-endian 64-bit
words (its last 16 bytes) and decoded with SWAR arithmetic on all tokens at
once: mask the bytes before the token to ``'0'``, find and blank the dot,
check every byte is a digit, fold 8 digits per word into an integer
(the fast_float/simdjson trick), then divide by a power of ten.

Exactness: a token with at most 15 significant digits gives an integer
mantissa ``m < 2**53`` and ``m / 10**f`` with ``f <= 15`` is one correctly
rounded IEEE division, so the result is bit-identical to ``float(token)``.
Tokens the fast path cannot prove (exponents, more digits, ``nan``, stray
characters, a lone ``-``) are flagged in ``needs_slow`` for the caller to
read with ``float()`` and report.

Work runs in chunks of a few thousand tokens so the temporaries stay in cache
and below the allocator's mmap threshold (page faults dominate otherwise).
"""

from __future__ import annotations

import numpy as np

_U = np.uint64
_FULL = _U(0xFFFFFFFFFFFFFFFF)
_ZEROS = _U(0x3030303030303030)  # "00000000"
_THREES = _U(0x3333333333333333)
_DOTS = _U(0x2E2E2E2E2E2E2E2E)
_LOW7 = _U(0x7F7F7F7F7F7F7F7F)
_HIGH = _U(0x8080808080808080)
_HIGHNIB = _U(0xF0F0F0F0F0F0F0F0)
_SIXES = _U(0x0606060606060606)
_ONES = _U(0x0101010101010101)
_WEIGHTS = _U(0x0102030405060708)  # byte k of a flag word -> k + 1 in the top byte
_K1, _K2, _K3 = _U(2561), _U(6553601), _U(42949672960001)
_M1, _M2, _M3 = _U(0x0F0F0F0F0F0F0F0F), _U(0x00FF00FF00FF00FF), _U(0x0000FFFF0000FFFF)
_E8 = _U(100_000_000)
_0, _1, _3, _4, _6, _7, _8, _15, _16, _56 = (_U(v) for v in (0, 1, 3, 4, 6, 7, 8, 15, 16, 56))
_POW10 = 10.0 ** np.arange(16)

CHUNK = 8192  #: tokens per vector step
PAD = 16  #: bytes of padding the caller puts before the block


def token_bounds(b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Start and end (exclusive) byte offsets of the tokens of ``b``.

    ``b``: ``(n,)`` uint8.  Any byte ``<= 0x20`` separates tokens (like
    ``bytes.split()`` plus the other control characters).
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


def _swar8(w: np.ndarray) -> np.ndarray:
    """Eight ASCII digits per word (first digit in the low byte) -> their integer value."""
    v = ((w & _M1) * _K1) >> _8
    v = ((v & _M2) * _K2) >> _U(16)
    return ((v & _M3) * _K3) >> _U(32)


def _keep_top(nbytes: np.ndarray) -> np.ndarray:
    """Masks keeping the top ``nbytes`` (0..8) bytes of a word (numpy shifts >= 64 give 0)."""
    return _FULL << ((_8 - nbytes) << _3)


def _digits_only(x: np.ndarray) -> np.ndarray:
    return ((x & _HIGHNIB) | (((x + _SIXES) & _HIGHNIB) >> _4)) == _THREES


def _decode(w0, w1, dlen, out_value, out_slow) -> None:
    """Decode right-aligned 16-byte windows ``w0`` (bytes 0-7) and ``w1`` (8-15) whose last ``dlen`` bytes are the
    unsigned token."""
    k1 = np.minimum(dlen, _8)
    k0 = np.minimum(dlen - k1, _8)
    m1, m0 = _keep_top(k1), _keep_top(k0)
    x1 = (w1 & m1) | (_ZEROS & ~m1)
    x0 = (w0 & m0) | (_ZEROS & ~m0)
    y1, y0 = x1 ^ _DOTS, x0 ^ _DOTS
    d1 = ~(((y1 & _LOW7) + _LOW7) | y1) & _HIGH  # 0x80 where the byte is '.'
    d0 = ~(((y0 & _LOW7) + _LOW7) | y0) & _HIGH
    x1 += d1 >> _6  # '.' + 2 == '0'
    x0 += d0 >> _6
    f1, f0 = d1 >> _7, d0 >> _7
    ndot = ((f1 * _ONES) >> _56) + ((f0 * _ONES) >> _56)
    p1, p0 = (f1 * _WEIGHTS) >> _56, (f0 * _WEIGHTS) >> _56  # 1-based column of the dot in its word, or 0
    has_dot = ndot == _1
    col = np.where(has_dot, p0 + (p1 + _8) * (p1 > _0) - _1, _15)  # window column of the dot
    np.minimum(col, _15, out=col)  # several dots: garbage, flagged below; keep the indexing in range
    right1 = np.minimum(_15 - col, _8)
    right0 = _15 - col - right1
    r1, r0 = _keep_top(right1), _keep_top(right0)
    full = _swar8(x0) * _E8 + _swar8(x1)  # all digits, the dot read as 0
    right = _swar8((x0 & r0) | (_ZEROS & ~r0)) * _E8 + _swar8((x1 & r1) | (_ZEROS & ~r1))
    # full = left * 10**(f + 1) + right; the mantissa is left * 10**f + right
    mantissa = (full - right).astype(np.float64)
    mantissa /= has_dot * 9.0 + 1.0
    mantissa += right
    np.divide(mantissa, _POW10[_15 - col], out=out_value)
    ndigits = dlen - ndot
    np.logical_not(_digits_only(x0) & _digits_only(x1), out=out_slow)
    out_slow |= (ndot > _1) | (ndigits > _15) | (ndigits == _0) | (dlen > _16)


def parse_tokens(padded: np.ndarray, starts: np.ndarray, ends: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Values of the tokens ``padded[PAD + starts[i] : PAD + ends[i]]``.

    ``padded``: uint8, the block with ``PAD`` bytes before it and 8 after.
    Returns ``(values (n,) float64, needs_slow (n,) bool)``; ``values`` is
    garbage where ``needs_slow``.
    """
    n = starts.size
    values = np.empty(n)
    needs_slow = np.empty(n, dtype=bool)
    if n == 0:
        return values, needs_slow
    words = np.ndarray((padded.size - 7,), dtype="<u8", buffer=padded, strides=(1,))
    first = padded[starts + PAD]
    negative = first == 45
    signed = negative | (first == 43)
    dlen = (ends - starts - signed).astype(np.uint64)
    tail = ends + (PAD - 8)
    for s in range(0, n, CHUNK):
        part = slice(s, s + CHUNK)
        t = tail[part]
        _decode(words[t - 8], words[t], dlen[part], values[part], needs_slow[part])
    np.negative(values, out=values, where=negative)
    return values, needs_slow


def pad_block(block: bytes) -> np.ndarray:
    """The ``PAD``-prefixed, 8-suffixed uint8 copy of ``block`` that :func:`parse_tokens` reads."""
    padded = np.full(len(block) + PAD + 8, 32, dtype=np.uint8)
    padded[PAD : PAD + len(block)] = np.frombuffer(block, dtype=np.uint8)
    return padded
