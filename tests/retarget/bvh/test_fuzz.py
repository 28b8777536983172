"""Fuzz test of the BVH parser: thousands of seeded, mutated files, each a ``Motion`` or one ``BvhError``.

Every case starts from one of a few small valid files (a humanoid from ``arm_skeleton``, a chain with Y-X-Z
channels, their CRLF and tab variants, a one-joint file) or is built whole (empty, binary, unicode, deep
nesting), then takes one to three mutations: truncations, byte flips, duplicated, deleted or swapped lines,
huge numbers (``1e308``, ``1e999``), NaN/inf tokens, binary and unicode junk, missing or extra braces, a wrong
``Frames:`` count, extra frame lines, CRs, a root written as JOINT.

The contract checked for each: ``parse_bvh`` returns a :class:`Motion` whose channels, joint positions and End
Site positions are finite and computed without a numpy warning (RuntimeWarning is an error here), or raises a
:class:`BvhError` whose str is ``fuzz.bvh:LINE: message`` with LINE within the file; nothing else, and no hang
(an alarm fails a case that takes seconds).  Where the mutation says which line is bad (a NaN or an overflowing
number in an otherwise valid file), the error must name that line; and the same lines with other line ends (CRLF
for LF, LF for CRLF, CR-only or mixed) must give the same answer.

A failure prints the seed, the mutations and the text.  To replay one case::

    python -c "from tests.retarget.bvh.test_fuzz import case; print(case(1234))"
"""

from __future__ import annotations

import random
import re
import signal
import threading
import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np
import pytest

from retarget.arm import Arm, load_arm
from retarget.bvh import Motion, parse_bvh
from retarget.errors import BvhError, RetargetError
from retarget.mapping import MappingConfig, Side, retarget_targets
from tests.helpers import POS_XYZ, J, arm_skeleton, bvh_text, n_channels

N_CASES = 3000
PATH = "fuzz.bvh"
YXZ = ("Yrotation", "Xrotation", "Zrotation")
CMU = {"clavicle": "{side}Shoulder", "upper": "{side}Arm", "fore": "{side}ForeArm", "hand": "{side}Hand"}
CMU |= {"left": "Left", "right": "Right"}


def _frames(root: J, n: int, seed: int) -> np.ndarray:
    return np.random.default_rng(seed).uniform(-90, 90, size=(n, n_channels(root))).round(4)


def _bases() -> dict[str, bytes]:
    human = arm_skeleton(CMU)
    chain = J("root", (0, 1, 0), (*POS_XYZ, *YXZ), children=[J("a", (0, 2, 0), YXZ, children=[J("b", (1, 0, 0), YXZ)])])
    chain.children[0].children[0].end = (0, 0, 1.5)
    tiny = J("only", (0, 0, 0), POS_XYZ, end=(0, 1, 0))
    return {
        "human": bvh_text(human, _frames(human, 3, 0)).encode(),
        "human-crlf": bvh_text(human, _frames(human, 2, 1), newline="\r\n", fmt="{:.6f}").encode(),
        "yxz": bvh_text(chain, _frames(chain, 4, 2), fmt="{:.3e}").encode(),
        "yxz-crlf-tabs": bvh_text(chain, _frames(chain, 3, 3), newline="\r\n", indent="\t").encode(),
        "tiny": bvh_text(tiny, _frames(tiny, 2, 4)).encode(),
    }


BASES = _bases()


# ------------------------------------------------------------------------------------------- mutations


@dataclass
class Case:
    """One fuzz input: the bytes, what was done to them, and the line that must be reported, when known."""

    seed: int
    text: bytes
    steps: list[str] = field(default_factory=list)
    bad_line: int | None = None  # set by a single NaN/overflow mutation of a valid file

    def __str__(self) -> str:
        return f"seed {self.seed}: {' | '.join(self.steps)}\n{self.text!r}"


HUGE = [b"1e308", b"-1e308", b"1.7976931348623157e308", b"1e-999", b"9" * 400, b"1" + b"0" * 40, b"4e307"]
OVERFLOW = [b"1e999", b"-1e309", b"1e400", b"2e308"]
NONFINITE = [b"nan", b"NaN", b"-nan", b"inf", b"-inf", b"+Infinity", b"INF", b"nan(123)"]
UNICODE = ["\u00a0", "\u2028", "\u3000", "\u0085", "\u00b2", "\u0661\u0662", "\ufeff", "é", "🦴", "\u0301", "\x1c"]
INVALID_UTF8 = [b"\xff", b"\xc3", b"\xed\xa0\x80", b"\xe9t\xe9", b"\x80\x80"]
_NUMBER = re.compile(rb"(?<![^\s])[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?(?![^\s])")


def _lines(text: bytes) -> list[bytes]:
    return text.split(b"\n")


def _line_of(text: bytes, offset: int) -> int:
    """1-based line of byte ``offset``, counting LF, CRLF and lone CR as line ends."""
    head = text[:offset]
    return head.count(b"\n") + head.count(b"\r") - head.count(b"\r\n") + 1


def _number_token(case: Case, rng: random.Random, new: bytes, kind: str) -> None:
    tokens = list(_NUMBER.finditer(case.text))
    if not tokens:
        return
    m = tokens[rng.randrange(len(tokens))]
    if kind in ("nonfinite", "overflow") and not case.steps:
        case.bad_line = _line_of(case.text, m.start())
    case.steps.append(f"{kind} {m.group().decode()!r}->{new.decode()!r} at line {_line_of(case.text, m.start())}")
    case.text = case.text[: m.start()] + new + case.text[m.end() :]


def m_truncate(case: Case, rng: random.Random) -> None:
    cut = rng.randrange(len(case.text) + 1)
    case.steps.append(f"truncate at {cut}")
    case.text = case.text[:cut]


def m_flip(case: Case, rng: random.Random) -> None:
    if not case.text:
        return
    i = rng.randrange(len(case.text))
    new = rng.randrange(256) if rng.random() < 0.5 else case.text[i] ^ (1 << rng.randrange(8))
    case.steps.append(f"byte {i}: {case.text[i]:#04x}->{new:#04x}")
    case.text = case.text[:i] + bytes([new]) + case.text[i + 1 :]


def m_duplicate_line(case: Case, rng: random.Random) -> None:
    lines = _lines(case.text)
    k, at = rng.randrange(len(lines)), rng.randrange(len(lines) + 1)
    case.steps.append(f"line {k + 1} copied before line {at + 1}")
    lines.insert(at, lines[k])
    case.text = b"\n".join(lines)


def m_delete_line(case: Case, rng: random.Random) -> None:
    lines = _lines(case.text)
    k = rng.randrange(len(lines))
    case.steps.append(f"line {k + 1} deleted")
    del lines[k]
    case.text = b"\n".join(lines)


def m_swap_lines(case: Case, rng: random.Random) -> None:
    lines = _lines(case.text)
    a, b = rng.randrange(len(lines)), rng.randrange(len(lines))
    case.steps.append(f"lines {a + 1} and {b + 1} swapped")
    lines[a], lines[b] = lines[b], lines[a]
    case.text = b"\n".join(lines)


def m_huge(case: Case, rng: random.Random) -> None:
    _number_token(case, rng, rng.choice(HUGE), "huge")


def m_overflow(case: Case, rng: random.Random) -> None:
    _number_token(case, rng, rng.choice(OVERFLOW), "overflow")


def m_nonfinite(case: Case, rng: random.Random) -> None:
    _number_token(case, rng, rng.choice(NONFINITE), "nonfinite")


def m_binary(case: Case, rng: random.Random) -> None:
    i = rng.randrange(len(case.text) + 1)
    junk = bytes(rng.randrange(256) for _ in range(rng.randint(1, 24)))
    case.steps.append(f"binary {junk!r} at {i}")
    case.text = case.text[:i] + junk + case.text[i:]


def m_unicode(case: Case, rng: random.Random) -> None:
    junk = rng.choice(UNICODE).encode() if rng.random() < 0.7 else rng.choice(INVALID_UTF8)
    where = rng.randrange(3)
    if where == 0:  # anywhere
        i = rng.randrange(len(case.text) + 1)
    elif where == 1:  # a line of its own
        i = case.text.find(b"\n", rng.randrange(len(case.text) + 1)) + 1
        junk += b"\n"
    else:  # in place of a space (a separator to most readers)
        spaces = [m.start() for m in re.finditer(rb" ", case.text)]
        if not spaces:
            return
        i = rng.choice(spaces)
        case.text = case.text[:i] + case.text[i + 1 :]
    case.steps.append(f"unicode {junk!r} at {i}")
    case.text = case.text[:i] + junk + case.text[i:]


def m_brace(case: Case, rng: random.Random) -> None:
    braces = [m.start() for m in re.finditer(rb"[{}]", case.text)]
    if braces and rng.random() < 0.6:
        i = rng.choice(braces)
        case.steps.append(f"brace at {i} deleted")
        case.text = case.text[:i] + case.text[i + 1 :]
    else:
        lines = _lines(case.text)
        at = rng.randrange(len(lines) + 1)
        brace = rng.choice([b"{", b"}"])
        case.steps.append(f"{brace.decode()} inserted before line {at + 1}")
        lines.insert(at, brace)
        case.text = b"\n".join(lines)


def m_frames_count(case: Case, rng: random.Random) -> None:
    m = re.search(rb"Frames:\s*(\S*)", case.text)
    if not m:
        return
    old = int(m.group(1)) if m.group(1).isdigit() else 1
    new = rng.choice([b"0", b"%d" % max(old - 1, 0), b"%d" % (old + 1), b"%d" % (old + 5), b"10" * 12, b"-1", b""])
    new = rng.choice([new, b"x", b"2.5", "\u00b2".encode(), "\u0661".encode(), b"1e3"]) if rng.random() < 0.2 else new
    case.steps.append(f"Frames: {new!r}")
    case.text = case.text[: m.start(1)] + new + case.text[m.end(1) :]


def m_extra_frames(case: Case, rng: random.Random) -> None:
    body = case.text.rstrip(b"\r\n")
    last = _lines(body)[-1].rstrip(b"\r")
    nl = b"\r\n" if b"\r\n" in case.text else b"\n"
    extra = rng.choice([last, last[: len(last) // 2], b"0 0", b"junk", b"", b"nan " + last])
    n = rng.randint(1, 3)
    case.steps.append(f"{n} extra frame lines {extra[:20]!r}")
    case.text = body + (nl + extra) * n + nl


def m_frame_tokens(case: Case, rng: random.Random) -> None:
    tokens = list(_NUMBER.finditer(case.text))
    if not tokens:
        return
    m = tokens[rng.randrange(len(tokens))]
    if rng.random() < 0.5:
        case.steps.append(f"token {m.group()!r} deleted")
        case.text = case.text[: m.start()] + case.text[m.end() :]
    else:
        case.steps.append(f"token {m.group()!r} doubled")
        case.text = case.text[: m.end()] + b" " + m.group() + case.text[m.end() :]


def m_carriage_return(case: Case, rng: random.Random) -> None:
    i = rng.randrange(len(case.text) + 1)
    new = rng.choice([b"\r", b"\r\n", b"\n\r"])
    case.steps.append(f"{new!r} at {i}")
    case.text = case.text[:i] + new + case.text[i:]


def m_keyword(case: Case, rng: random.Random) -> None:
    old, new = rng.choice(
        [
            (b"ROOT", b"JOINT"),
            (b"ROOT", b"root"),
            (b"JOINT", b"ROOT"),
            (b"JOINT", b"Joint"),
            (b"End Site", b"End"),
            (b"End Site", b"EndSite"),
            (b"OFFSET", b"OFFSET 1"),
            (b"CHANNELS 3", b"CHANNELS 99999999999999999999"),
            (b"CHANNELS 3", b"CHANNELS -3"),
            (b"CHANNELS 3", b"CHANNELS 0"),
            (b"Frame Time:", b"Frame Time: 0 x"),
            (b"MOTION", b"MOTION extra"),
            (b"HIERARCHY", b"HIERARCHY\nHIERARCHY"),
            (b"Zrotation", b"Zposition"),
        ]
    )
    spots = [m.start() for m in re.finditer(re.escape(old), case.text)]
    if not spots:
        return
    i = rng.choice(spots)
    case.steps.append(f"{old!r}->{new!r} at line {_line_of(case.text, i)}")
    case.text = case.text[:i] + new + case.text[i + len(old) :]


def m_whitespace(case: Case, rng: random.Random) -> None:
    spaces = [m.start() for m in re.finditer(rb" ", case.text)]
    if not spaces:
        return
    i = rng.choice(spaces)
    new = rng.choice([b"\t", b"\x0b", b"\x0c", b"  ", b"\xc2\xa0", b"\x1f", b""])
    case.steps.append(f"space at {i} -> {new!r}")
    case.text = case.text[:i] + new + case.text[i + 1 :]


MUTATIONS: list[Callable[[Case, random.Random], None]] = [
    m_truncate,
    m_flip,
    m_flip,
    m_duplicate_line,
    m_delete_line,
    m_swap_lines,
    m_huge,
    m_huge,
    m_overflow,
    m_nonfinite,
    m_binary,
    m_unicode,
    m_unicode,
    m_brace,
    m_frames_count,
    m_extra_frames,
    m_frame_tokens,
    m_carriage_return,
    m_keyword,
    m_whitespace,
]


# -------------------------------------------------------------------------------------- whole files


def deep(depth: int, *, closed: bool = True) -> bytes:
    """A chain of ``depth`` nested joints with one frame (closed, or cut off before its braces)."""
    joint = "{} j{}\n{{\nOFFSET 0 1 0\nCHANNELS 1 Xrotation\n"
    head = "".join(joint.format("ROOT" if k == 0 else "JOINT", k) for k in range(depth))
    tail = "End Site\n{\nOFFSET 0 1 0\n}\n" + "}\n" * depth if closed else ""
    motion = f"MOTION\nFrames: 1\nFrame Time: 0.1\n{' '.join(['1.5'] * depth)}\n" if closed else ""
    return f"HIERARCHY\n{head}{tail}{motion}".encode()


def _whole(rng: random.Random) -> tuple[str, bytes]:
    kind = rng.randrange(6)
    if kind == 0:
        return "empty", rng.choice([b"", b" ", b"\n\n", b"\r\n", b"\t \x0b\x0c"])
    if kind == 1:
        return "binary", bytes(rng.randrange(256) for _ in range(rng.randint(1, 300)))
    if kind == 2:
        junk = "".join(rng.choice(UNICODE) for _ in range(rng.randint(1, 40)))
        return "unicode", junk.encode()
    if kind == 3:
        depth = rng.choice([rng.randint(1, 40), rng.randint(495, 505)])
        return f"deep {depth}", deep(depth)
    if kind == 4:
        depth = rng.randint(1, 600)
        return f"deep {depth} unclosed", deep(depth, closed=False)
    return "unicode+base", "\u00a0\u3000".encode() + BASES["tiny"]


def case(seed: int) -> Case:
    """The fuzz input of ``seed``: a mutated base file (most seeds) or a whole generated one."""
    rng = random.Random(seed)
    if seed % 25 == 24:
        name, text = _whole(rng)
        c = Case(seed, text, [name])
        if rng.random() < 0.5 and text:
            rng.choice(MUTATIONS)(c, rng)
        return c
    name = rng.choice(sorted(BASES))
    c = Case(seed, BASES[name])
    n = rng.choice([1, 1, 1, 2, 3])
    for _ in range(n):
        rng.choice(MUTATIONS)(c, rng)
    if n > 1:
        c.bad_line = None  # a later mutation may have moved the line, or broken an earlier one
    c.steps.insert(0, name)
    return c


# ------------------------------------------------------------------------------------------ checks


@contextmanager
def _no_hang(seconds: float, what: Case) -> Iterator[None]:
    """Fail (instead of hanging the run) when the body takes ``seconds``; a no-op where SIGALRM is missing."""
    if not hasattr(signal, "setitimer") or threading.current_thread() is not threading.main_thread():
        yield
        return

    def alarm(signum: int, frame: object) -> None:
        raise AssertionError(f"no answer after {seconds} s: {what}")

    old = signal.signal(signal.SIGALRM, alarm)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


def outcome(text: bytes) -> Motion | BvhError:
    """``parse_bvh(text)``'s Motion or BvhError, with every numpy RuntimeWarning raised as an error."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        try:
            return parse_bvh(text, path=PATH)
        except BvhError as exc:
            return exc


def check(c: Case) -> None:
    got = outcome(c.text)
    n_lines = len(c.text.replace(b"\r\n", b"\n").replace(b"\r", b"\n").split(b"\n"))
    if isinstance(got, BvhError):
        assert got.path == PATH and got.line is not None, f"no line: {got!r}"
        assert 1 <= got.line <= n_lines + 1, f"line {got.line} outside the file's {n_lines}: {got}"
        assert re.match(rf"{re.escape(PATH)}:{got.line}: \S", str(got)), str(got)
        assert "\n" not in str(got) and "\r" not in str(got), f"not one line: {str(got)!r}"
        if c.bad_line is not None:
            assert got.line == c.bad_line, f"expected an error on line {c.bad_line}: {got}"
    else:
        assert c.bad_line is None, f"a non-finite number was accepted: {got}"
        assert np.isfinite([got.frame_time, got.fps, got.duration]).all(), repr(got)
        n_channels = sum(len(lay.names) for lay in got.layout)
        assert got.channels.shape == (got.n_frames, n_channels) and n_channels > 0
        assert np.isfinite(got.channels).all() and np.isfinite(got.offsets).all()
        with warnings.catch_warnings():
            warnings.simplefilter("error", RuntimeWarning)
            positions = got.positions()
            ends = got.end_site_positions()
        assert positions.shape == (got.n_frames, got.n_joints, 3)
        assert ends.shape == (got.n_frames, len(got.end_sites), 3)
        assert np.isfinite(positions).all() and np.isfinite(ends).all()
    # the same lines with other line ends give the same answer: CRLF for an LF file, LF for one with CRs
    lf = c.text.replace(b"\r\n", b"\n").replace(b"\r", b"\n")
    other = outcome(c.text.replace(b"\n", b"\r\n") if lf == c.text else lf)
    if isinstance(got, BvhError) or isinstance(other, BvhError):
        assert str(other) == str(got), f"as given: {got}\nother line ends: {other}"
    else:
        np.testing.assert_array_equal(other.channels, got.channels)
        assert other.joint_names == got.joint_names


@pytest.mark.parametrize("seed", range(N_CASES), ids=lambda s: f"seed{s}")
def test_fuzz_parse_bvh(seed):
    c = case(seed)
    with _no_hang(5.0, c):
        try:
            check(c)
        except Exception as exc:  # any failure, of any type, names the seed and shows the text
            raise AssertionError(f"{type(exc).__name__}: {exc}\n{c}") from exc


#: every Nth fuzz case that loads also goes through the mapping: a clip that loads exports or fails in one line
MAP_EVERY = 5


@pytest.mark.parametrize("seed", range(0, N_CASES, MAP_EVERY), ids=lambda s: f"seed{s}")
def test_fuzz_a_clip_that_loads_maps_or_fails_in_one_line(wx250s, seed):
    c = case(seed)
    motion = outcome(c.text)
    if isinstance(motion, BvhError):
        return
    with _no_hang(5.0, c), warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        for side in ("left", "right"):
            try:
                targets = retarget_targets(motion, wx250s, MappingConfig(side=Side(side)))
            except RetargetError as exc:  # a BvhError about the clip, or a ConfigError: one line, no traceback
                assert "\n" not in str(exc), f"not one line: {str(exc)!r}\n{c}"
                continue
            except Exception as exc:
                raise AssertionError(f"{side}: {type(exc).__name__}: {exc}\n{c}") from exc
            assert targets.positions.shape == (motion.n_frames, 3), c
            assert np.isfinite(targets.positions).all(), f"{side}: non-finite targets\n{c}"


@pytest.fixture(scope="module")
def wx250s() -> Arm:
    return load_arm("wx250s")


def test_bases_are_valid():
    for name, text in BASES.items():
        motion = parse_bvh(text, path=name)
        assert motion.n_frames >= 2, name


def test_cases_are_reproducible():
    assert str(case(1234)) == str(case(1234))
    assert {case(s).text for s in range(50)} != {case(s).text for s in range(50, 100)}


# --------------------------------------------------------------------- regressions: what the fuzzer found
# Each was a crash or a wrong answer before the fix; the inputs are the fuzzer's, cut down by hand.


@pytest.mark.parametrize("space", ["\u00a0", "\u3000", "\u2028", "\u0085", "\x1c"], ids=repr)
def test_regression_a_line_of_unicode_spaces_is_blank(space):
    """IndexError from ``_keyword``: ``bytes.strip`` left the line, ``str.split`` found no word in it."""
    text = BASES["tiny"].decode().replace("{\n", f"{{\n{space}\n", 1)
    assert parse_bvh(text).joint_names == ("only",)


def test_regression_a_file_of_unicode_spaces_is_empty():
    """The same IndexError on the first line (``first.split()[0]``)."""
    for text in ["\u2028", "\u00a0 \u3000\n\n", b"\xa0\x85"]:  # the last is not UTF-8: read as Latin-1
        with pytest.raises(BvhError, match=r"^fuzz\.bvh:1: Expected a BVH file starting with HIERARCHY, got an empty"):
            parse_bvh(text, path=PATH)
    latin1 = BASES["tiny"].replace(b"{\n", b"{\n\x85\xa0\n", 1)
    assert parse_bvh(latin1).joint_names == ("only",)


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        ("CHANNELS 3", "CHANNELS \u00b3", "Expected a channel count after CHANNELS, got '\u00b3'"),
        ("CHANNELS 3", "CHANNELS \u0663", "Expected a channel count after CHANNELS, got '\u0663'"),
        ("Frames: 2", "Frames: \u00b2", "Expected a whole number of frames, got '\u00b2'"),
        ("Frames: 2", "Frames: \u00b94", "Expected a whole number of frames, got '\u00b94'"),
    ],
    ids=["channels-superscript", "channels-arabic", "frames-superscript", "frames-mixed"],
)
def test_regression_counts_in_non_ascii_digits(old, new, message):
    """ValueError from ``int()``: ``'²'.isdigit()`` is True, and ``int('٣')`` is 3 (now refused the same way)."""
    text = BASES["tiny"].decode().replace(old, new)
    with pytest.raises(BvhError, match=re.escape(f"{PATH}:") + r"\d+: " + re.escape(message)):
        parse_bvh(text, path=PATH)
    latin1 = BASES["tiny"].replace(b"CHANNELS 3", b"CHANNELS \xb3")  # not UTF-8: read as Latin-1 '³'
    with pytest.raises(BvhError, match="Expected a channel count after CHANNELS, got '\u00b3'"):
        parse_bvh(latin1)


def test_regression_huge_values_made_fk_overflow():
    """RuntimeWarning 'overflow encountered in add' in FK, and inf positions: an End Site OFFSET of 1e308 under
    a position channel of 1e308, each finite.  Numbers are now limited to 1e12 in magnitude."""
    tiny = BASES["tiny"].decode()
    lines = tiny.splitlines()
    text = tiny.replace("OFFSET 0 1 0", "OFFSET 0 1e308 0").replace(lines[-1], "0 1e308 0")
    with pytest.raises(
        BvhError, match=r"^fuzz\.bvh:8: Expected a number from -1e\+12 to 1e\+12 in OFFSET, got '1e308'"
    ):
        parse_bvh(text, path=PATH)
    text = tiny.replace(lines[-1], "0 1.7976931348623157e308 0")
    with pytest.raises(BvhError, match=r"^fuzz\.bvh:15: Expected a number from -1e\+12 to 1e\+12, got '1.79769"):
        parse_bvh(text, path=PATH)
    at_limit = parse_bvh(tiny.replace("OFFSET 0 1 0", "OFFSET 0 1e12 0").replace(lines[-1], "-1e12 1E12 1000000000000"))
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        assert np.isfinite(at_limit.end_site_positions()).all()


def test_regression_huge_frame_time_made_the_duration_infinite():
    """``Frame Time: 1e308`` gave ``duration == inf`` (and ``1e-310`` an infinite fps): now an error."""
    tiny = BASES["tiny"].decode()
    for word in ("1e308", "1e-310", "2e6", "1e-7", "10.001", "9.9e-5"):
        with pytest.raises(BvhError, match=r"^fuzz\.bvh:13: Expected a frame time from 0\.0001 to 10 seconds"):
            parse_bvh(tiny.replace("0.03333333333", word), path=PATH)
    assert parse_bvh(tiny.replace("0.03333333333", "10")).duration == 20
    assert parse_bvh(tiny.replace("0.03333333333", "1e-4")).frame_time == 1e-4


def test_regression_a_lone_cr_in_an_lf_file_is_a_line_end():
    """A CR between two values of a frame line in an LF file (a '-' flipped to 0x0d): the windowed reader took it
    for a space and read the line, with the sign lost; when anything else sent the file down the checked path,
    the CR ended the line, an error.  Found by the fuzzer's cases on a 4000-frame file (beyond the CI run's
    small files): any CR now makes the whole file LF first, so every path sees the same lines."""
    root = J("Hips", (0, 90, 0), POS_XYZ, end=(0, 1, 0))
    frames = np.random.default_rng(0).uniform(-100, 100, (4000, 3)).round(4)
    frames[3500, 1] = -abs(frames[3500, 1])
    text = bvh_text(root, frames, fmt="{:.4f}")
    assert text.index(f"{frames[3500, 0]:.4f}") > 1 << 16  # past the header's first bytes (which are searched for CRs)
    line = text.splitlines().index(" ".join(f"{v:.4f}" for v in frames[3500])) + 1
    bad = text.replace(f" {frames[3500, 1]:.4f} ", f" \r{-frames[3500, 1]:.4f} ", 1)
    for variant in (bad, bad.replace("\r", "\n")):
        with pytest.raises(BvhError, match=rf"^fuzz\.bvh:{line}: Expected 3 values on frame line, got 1"):
            parse_bvh(variant, path=PATH)


@pytest.mark.parametrize("newline", ["\n", "\r\n", "\r"], ids=["lf", "crlf", "cr"])
def test_regression_binary_data_is_reported_on_its_line_whatever_the_line_ends(newline):
    """The line of a NUL byte was counted in LFs alone: line 1 in a CR-only file.  Found by comparing each case
    with its LF twin (seed 2749 at the time: random bytes holding a CR)."""
    text = newline.join(["HIERARCHY", "ROOT Hips", "{", "  OFFSET 0 \x00 0"])
    with pytest.raises(BvhError, match=r"^fuzz\.bvh:4: Expected a text BVH file, got binary data$"):
        parse_bvh(text, path=PATH)
