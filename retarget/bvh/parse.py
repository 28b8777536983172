"""Read BVH motion capture files: ``load_bvh(path) -> Motion``.

Lenient where real exporters and other readers are.  Accepted as is:

- any order of rotation channels, differing per joint; position channels on
  any joint (they replace that joint's OFFSET); End Sites; several ROOTs;
- LF, CRLF or CR-only line ends; tabs and other spaces (Unicode ones too in
  the hierarchy); blank lines; a UTF-8 byte order mark; trailing whitespace
  and a missing final newline; keywords in any case; ``{`` on the joint's
  line; names with spaces or colons, kept whole; scientific notation;
- ``Frames: 0`` (a skeleton without motion, as in Perception Neuron's
  templates): a :class:`Motion` with 0 frames.

Accepted with a warning on the ``retarget.bvh.parse`` logger, naming the
file and line (``clip.bvh:2: ...``), logged once the whole file is read:

- a first joint written ``JOINT`` instead of ``ROOT`` (only the first);
- lines after the ``Frames:`` count of frame lines: the first ``Frames``
  lines are read and the rest ignored, whatever they hold, as most readers
  do; the warning says how many lines were ignored and what ``Frames:``
  promised.

Everything else is a :class:`~retarget.errors.BvhError` naming the file and
line and saying what was expected and what was found, e.g.
``clip.bvh:190: Expected 93 values on frame line, got 92``:

- an empty or binary file; a missing, misspelt or misplaced keyword, brace,
  OFFSET, CHANNELS (count in ASCII digits, known channel names), ``Frames:``
  (a whole number) or ``Frame Time:`` line; more than 500 nested joints;
- fewer frame lines than ``Frames:`` promises, or a frame line (among the
  first ``Frames``) without one value per channel;
- a value that is not a decimal number (``nan``, ``inf``, ``1,5``), one that
  overflows (``1e999``) or is larger in magnitude than ``MAX_VALUE`` (1e12:
  far past any capture; it keeps FK finite), and a frame time outside
  ``MIN_FRAME_TIME`` to ``MAX_FRAME_TIME`` (1e-4 to 10 seconds: 10 kHz to
  0.1 fps);
- a number token longer than ``MAX_TOKEN`` (100) characters, a count
  (``Frames:``, ``CHANNELS``) of more than 18 digits, a header line longer
  than ``MAX_HEADER_LINE`` (4096) bytes, a file larger than
  ``MAX_FILE_BYTES`` (1 GiB).  Messages quote at most 40 characters of a
  token, so a huge one never makes a huge error line.

Every regex is linear in its input (no nested or adjacent repeats of the
same characters), so no token, however long, takes quadratic time.

The first problem in file order is the one reported.  The parser never
loops on a short file and never returns partial data.

Speed: the MOTION block is read in ~100 KB windows of whole lines, each with
a handful of vectorised passes (token boundaries, per-line counts, the
numbers themselves: see :mod:`retarget.bvh.numbers`).  Only when something
is irregular (a wrong count, an exponent, a bad token) is the block read
again in one piece, to read the unusual numbers with ``float()`` and to report
the first problem in file order.  Lines after the promised frames do not
leave the windowed path: reading stops at the first of them.  A file with
any CR (CRLF, CR-only or mixed line ends) is made LF first, in one copy, so
every path sees the same lines.
"""

from __future__ import annotations

import logging
import math
import mmap
import os
import re
from os import PathLike
from pathlib import Path
from typing import BinaryIO

import numpy as np

import retarget.bvh.numbers as bvh_numbers
from retarget.bvh.motion import ChannelLayout, EndSite, Motion
from retarget.errors import BvhError

log = logging.getLogger(__name__)

#: The bundled demo clip (written by ``scripts/make_demo_clip.py``): a right arm reaching, waving and pointing.
DEMO_CLIP: Path = Path(__file__).resolve().parent / "data" / "demo.bvh"

#: Channel names a BVH file may use, in their canonical spelling.
CHANNEL_NAMES: tuple[str, ...] = ("Xposition", "Yposition", "Zposition", "Xrotation", "Yrotation", "Zrotation")
_CHANNEL_LOOKUP = {name.lower(): name for name in CHANNEL_NAMES}

_FRAMES_RE = re.compile(r"Frames\s*:\s*(\S*)\s*", re.IGNORECASE)
_FRAME_TIME_RE = re.compile(r"Frame\s+Time\s*:\s*(\S*)\s*", re.IGNORECASE)
_NUMBER = rb"[+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?"  # unambiguous: linear, even on a failing match
_NUMBER_RE = re.compile(_NUMBER)
_NUMBERS_RE = re.compile(rb"(?:%s\n)*%s" % (_NUMBER, _NUMBER))  # newline-separated
_NONFINITE_RE = re.compile(rb"[+-]?(?:nan|inf|infinity)(?:\(\w*\))?", re.IGNORECASE)

#: The largest magnitude of a number in the file (OFFSET, frame values).  No capture comes near it (1e12 cm is
#: 70 times the Sun's distance; 1e12 degrees, 3e9 turns), and below it every joint position, sum and square that
#: FK and the mapping compute stays finite, however deep the skeleton.
MAX_VALUE = 1e12
_TOO_BIG = f"Expected a number from {-MAX_VALUE:g} to {MAX_VALUE:g}"
#: The range of ``Frame Time`` (seconds): 10 kHz to 0.1 fps, past any capture system, so that the clip's duration
#: and the number of control ticks stay plausible (``1e300`` made export and replay run forever).
MIN_FRAME_TIME, MAX_FRAME_TIME = 1e-4, 10.0
#: The longest number token (characters): ``%.17g`` takes 24; longer ones are an error, not quadratic regex work.
MAX_TOKEN = 100
#: The most digits of a count (``Frames:``, ``CHANNELS``): ``int()`` refuses over 4300, and 18 already means
#: a file of exabytes.
_MAX_COUNT_DIGITS = 18
#: The longest line of the hierarchy and MOTION header (bytes); real ones are under 200.
MAX_HEADER_LINE = 4096
#: The largest file read (bytes): ~1 hour of a 60-joint skeleton at 120 fps; ``/dev/zero`` or an endless pipe
#: stops here.
MAX_FILE_BYTES = 1 << 30
_READ_CHUNK = 1 << 20


def load_bvh(path: str | PathLike[str]) -> Motion:
    """Read the BVH file at ``path`` into a :class:`~retarget.bvh.motion.Motion`.

    ``path``: a text BVH file, as real exporters write them (see the module notes).

    Returns the clip: ``joint_names`` (ROOT and JOINTs in file order), ``parents`` ``(n_joints,)``,
    ``offsets`` ``(n_joints, 3)`` float64 file units, ``channels`` ``(n_frames, n_channels)`` float64
    (the raw values in file order: degrees and file units), ``frame_time`` seconds, ``path``.  Joint
    positions come from its FK (:meth:`~retarget.bvh.motion.Motion.positions`,
    :meth:`~retarget.bvh.motion.Motion.arm_points`), computed on first use.

    Raises :class:`~retarget.errors.BvhError` ``"path:line: message"`` for a file that is not valid
    BVH (the message says what was expected and what was found; nothing partial is returned) and
    ``OSError`` for one that cannot be read.  Logs a warning ``"path:line: message"`` for what it
    lets go: a root written ``JOINT``, lines after the ``Frames:`` count (ignored).

    >>> motion = load_bvh(DEMO_CLIP)
    >>> motion
    <Motion 'demo.bvh': 21 joints, 630 frames at 60 fps>
    >>> motion.channels.shape, motion.frame_time  # (n_frames, n_channels), seconds per frame
    ((630, 66), 0.0166667)
    """
    p = Path(path)
    with open(p, "rb") as f:
        size = os.fstat(f.fileno()).st_size
        if size > MAX_FILE_BYTES:
            raise _too_large(p)
        try:  # map the file: its pages come from the page cache, not a fresh copy
            data: bytes | mmap.mmap = mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ)
        except (OSError, ValueError):  # empty, or not mappable (a pipe, /proc, /dev/zero): read it, bounded
            data = _read_bounded(f, p)
    return _parse(data, path=p)


def _too_large(path: Path) -> BvhError:
    return BvhError(f"Expected a BVH file of at most {MAX_FILE_BYTES >> 20} MiB, got more", path=path, line=1)


def _read_bounded(f: BinaryIO, path: Path) -> bytes:
    """At most ``MAX_FILE_BYTES`` of a stream; a first chunk with a NUL byte is returned alone (binary data: the
    parser then says so, without reading on)."""
    chunks: list[bytes] = []
    total = 0
    while True:
        chunk = f.read(_READ_CHUNK)
        if not chunk:
            return b"".join(chunks)
        chunks.append(chunk)
        total += len(chunk)
        if total > MAX_FILE_BYTES:
            raise _too_large(path)
        if b"\0" in chunk:  # not text: the parser reports the first NUL's line from what is read so far
            return b"".join(chunks)


def parse_bvh(text: str | bytes, *, path: str | PathLike[str] | None = None) -> Motion:
    """Read BVH from a string (or bytes): :func:`load_bvh` without the file.

    ``text``: the whole file (a ``str`` is encoded as UTF-8).  ``path``: only names the source, in
    errors and as ``Motion.path``; nothing is read from it.

    Returns the :class:`~retarget.bvh.motion.Motion`, as :func:`load_bvh` does.  Raises
    :class:`~retarget.errors.BvhError` ``"path:line: message"`` (``<bvh>`` without ``path``) for text
    that is not valid BVH, and logs the same warnings.

    >>> motion = parse_bvh('''HIERARCHY
    ... ROOT hips
    ... {
    ...   OFFSET 0 0 0
    ...   CHANNELS 3 Xposition Yposition Zposition
    ...   JOINT hand
    ...   {
    ...     OFFSET 0 10 0
    ...     CHANNELS 1 Zrotation
    ...     End Site
    ...     {
    ...       OFFSET 0 5 0
    ...     }
    ...   }
    ... }
    ... MOTION
    ... Frames: 2
    ... Frame Time: 0.5
    ... 0 0 0 0
    ... 1 2 3 90
    ... ''')
    >>> motion.joint_names, motion.n_frames, motion.frame_time
    (('hips', 'hand'), 2, 0.5)
    >>> motion.positions()[1].tolist()  # frame 1: (n_joints, 3) file units; the hips moved to (1, 2, 3)
    [[1.0, 2.0, 3.0], [1.0, 12.0, 3.0]]
    >>> motion.end_site_positions()[1].round(6).tolist()  # the hand turned 90 degrees about z
    [[-4.0, 12.0, 3.0]]
    >>> parse_bvh("MOTION", path="clip.bvh")
    Traceback (most recent call last):
    ...
    retarget.errors.BvhError: clip.bvh:1: Expected HIERARCHY, got 'MOTION'
    """
    data = text.encode("utf-8") if isinstance(text, str) else bytes(text)
    return _parse(data, path=None if path is None else Path(path))


# --------------------------------------------------------------------------------------------- whole file

_CONTROL_BYTES = bytes([*range(1, 9), *range(14, 32)])
_MAX_DEPTH = 500  # nested joints; real skeletons stay under 100
_HEAD = 1 << 16  # bytes tried first for the header


def _parse(data: bytes | mmap.mmap, *, path: Path | None) -> Motion:
    """Parse the file's bytes ``data`` (read through a read-only uint8 view)."""
    text = np.frombuffer(data, dtype=np.uint8)
    skip = 3 if data[:3] == b"\xef\xbb\xbf" else 0  # a UTF-8 byte order mark (line numbers are unchanged)
    text = text[skip:]
    size = text.size
    head = bytes(text[:_HEAD])
    if not head.strip() and not (text > 32).any():
        raise BvhError("Expected a BVH file starting with HIERARCHY, got an empty file", path=path, line=1)
    if data.find(b"\r", skip) >= 0:  # CR or CRLF line ends, even mixed with LF: made LF, then read (one memchr)
        return _parse_normalised(text, path)
    _reject_binary(text, head, path)
    header = _Header(head, path)
    try:
        header.parse()
        complete = header.pos <= len(head) or len(head) == size
    except BvhError:
        if len(head) == size:
            raise
        complete = False
    if not complete:  # a header longer than the first bytes tried
        header = _Header(bytes(text), path)
        header.parse()
    channels, extra = _read_frames(text, header.data_start, size - header.data_start, header, path)
    for line, message in [*header.warnings, *([extra] if extra else [])]:  # the file is read: say what was let go
        log.warning("%s:%d: %s", path or "<bvh>", line, message)
    return Motion(
        joint_names=tuple(j.name for j in header.joints),
        parents=np.array([j.parent for j in header.joints], dtype=np.intp),
        offsets=np.array([j.offset for j in header.joints], dtype=np.float64).reshape(-1, 3),
        layout=tuple(_layout(j) for j in header.joints),
        end_sites=tuple(EndSite(parent=e[0], offset=e[1]) for e in header.end_sites),
        channels=channels,
        frame_time=header.frame_time,
        path=path,
    )


def _parse_normalised(text: np.ndarray, path: Path | None) -> Motion:
    data = bytes(text).replace(b"\r\n", b"\n").replace(b"\r", b"\n")
    return parse_bvh(data, path=path)


def _reject_binary(text: np.ndarray, head: bytes, path: Path | None) -> None:
    """A NUL byte anywhere, or many control characters at the start, mean this is not a text file."""
    start = head[:4096]
    control = len(start) - len(start.translate(None, _CONTROL_BYTES))
    has_nul = text.size > 0 and int(text.min()) == 0  # a reduction: no 1-byte-per-byte temporary
    if has_nul or control > len(start) // 20:
        where = int(np.argmin(text)) if has_nul else 0
        line = int(np.count_nonzero(text[:where] == 10)) + 1
        raise BvhError("Expected a text BVH file, got binary data", path=path, line=line)


class _Joint:
    __slots__ = ("name", "parent", "offset", "channel_names", "first_column", "line")

    def __init__(self, name: str, parent: int, line: int):
        self.name = name
        self.parent = parent
        self.offset: tuple[float, float, float] | None = None
        self.channel_names: tuple[str, ...] | None = None
        self.first_column = 0
        self.line = line


def _layout(joint: _Joint) -> ChannelLayout:
    """The CHANNELS of a joint of a parsed header (``_Header._require_header`` saw them before its '}')."""
    if joint.channel_names is None:
        raise AssertionError(f"unreachable: joint {joint.name!r} of a parsed header without CHANNELS")
    return ChannelLayout(joint.channel_names, joint.first_column)


class _Header:
    """Recursive-descent reader of HIERARCHY and the two MOTION header lines, one logical line at a time."""

    def __init__(self, data: bytes, path: Path | None):
        self.data = data
        self.path = path
        self.pos = 0  # byte offset of the next unread line
        self.line = 0  # number of the last line read
        self.joints: list[_Joint] = []
        self.end_sites: list[tuple[int, tuple[float, float, float]]] = []
        self.n_channels = 0
        self.n_frames = 0
        self.frame_time = 0.0
        self.data_start = len(data)  # byte offset of the first frame line
        self.data_first_line = 1
        self.warnings: list[tuple[int, str]] = []  # (line, message): logged once the whole file is read

    # -- lines
    def _error(self, message: str, line: int | None = None) -> BvhError:
        return BvhError(message, path=self.path, line=self.line if line is None else line)

    def _next_line(self) -> str | None:
        """The next non-blank line, stripped; None at the end of the file."""
        data = self.data
        while self.pos < len(data):
            end = data.find(b"\n", self.pos, self.pos + MAX_HEADER_LINE + 1)  # bounded: never scans a huge line
            if end < 0:
                end = len(data)
                if end - self.pos > MAX_HEADER_LINE:
                    self.line += 1
                    raise self._error(f"Expected a header line of at most {MAX_HEADER_LINE} bytes, got more")
            raw = data[self.pos : end]
            self.pos = end + 1
            self.line += 1
            try:
                text = raw.decode("utf-8")
            except UnicodeDecodeError:
                text = raw.decode("latin-1")
            text = text.strip()  # also Unicode spaces (NBSP, U+3000, ...), which split() separates words on
            if text:
                return text
        return None

    def _expect_line(self, what: str) -> str:
        text = self._next_line()
        if text is None:
            self.line += 1
            raise self._error(f"Expected {what}, got end of file")
        return text

    # -- grammar
    def parse(self) -> None:
        first = self._next_line()
        if first is None:  # only spaces: Unicode ones too (ASCII-only files are caught before)
            raise self._error("Expected a BVH file starting with HIERARCHY, got an empty file", line=1)
        if first.split()[0].upper() != "HIERARCHY":
            raise self._error(f"Expected HIERARCHY, got {_show(first)}")
        if first.split()[1:]:
            raise self._error(f"Expected HIERARCHY alone on its line, got {_show(first)}")
        text = self._expect_line("ROOT")
        keyword = _keyword(text)
        if keyword == "JOINT":  # some exporters write the first joint as JOINT: it can only be the root
            self.warnings.append((self.line, f"Read {_show(text)} as the ROOT (the hierarchy's first joint)"))
        elif keyword != "ROOT":
            raise self._error(f"Expected ROOT after HIERARCHY, got {_show(text)}")
        while True:
            self._joint(text, parent=-1, keyword=keyword)
            keyword = "ROOT"
            text = self._expect_line("MOTION after the hierarchy")
            kw = _keyword(text)
            if kw == "MOTION":
                break
            if text.startswith("}"):
                raise self._error("Expected MOTION after the hierarchy, got an extra '}' (unbalanced braces)")
            if kw != "ROOT":
                raise self._error(f"Expected MOTION after the hierarchy, got {_show(text)}")
        if text.split()[1:]:
            raise self._error(f"Expected MOTION alone on its line, got {_show(text)}")
        self._motion_header()

    def _joint(self, text: str, *, parent: int, keyword: str, depth: int = 0) -> None:
        opened_line = self.line
        if depth >= _MAX_DEPTH:
            raise self._error(f"Expected at most {_MAX_DEPTH} nested joints, got more")
        name, brace = _name_and_brace(text, keyword)
        if not name:
            raise self._error(f"Expected a joint name after {keyword}, got nothing")
        joint = _Joint(name, parent, opened_line)
        index = len(self.joints)
        self.joints.append(joint)
        shown = _show(name, _EXCERPT)
        if not brace:
            self._open_brace(f"{keyword} {shown}")
        while True:
            text = self._expect_line(f"'}}' to close {keyword} {shown} (opened at line {opened_line})")
            kw = _keyword(text)
            if kw == "OFFSET":
                if joint.offset is not None:
                    raise self._error(f"Expected one OFFSET in {keyword} {shown}, got a second one")
                joint.offset = self._offset(text)
            elif kw == "CHANNELS":
                if joint.channel_names is not None:
                    raise self._error(f"Expected one CHANNELS line in {keyword} {shown}, got a second one")
                joint.channel_names = self._channels(text)
                joint.first_column = self.n_channels
                self.n_channels += len(joint.channel_names)
            elif kw == "JOINT":
                self._require_header(joint, keyword)
                self._joint(text, parent=index, keyword="JOINT", depth=depth + 1)
            elif kw == "END":
                self._require_header(joint, keyword)
                self._end_site(text, parent=index)
            elif text == "}":
                self._require_header(joint, keyword)
                return
            elif kw in ("MOTION", "ROOT"):
                raise self._error(
                    f"Expected '}}' to close {keyword} {shown} (opened at line {opened_line}), got {_show(text)}"
                )
            elif text.startswith("}"):
                raise self._error(f"Expected '}}' alone on its line, got {_show(text)}")
            else:
                raise self._error(
                    f"Expected OFFSET, CHANNELS, JOINT, End Site or '}}' in {keyword} {shown}, got {_show(text)}"
                )

    def _require_header(self, joint: _Joint, keyword: str) -> None:
        if joint.offset is None:
            raise self._error(
                f"Expected OFFSET in {keyword} {_show(joint.name, _EXCERPT)} (line {joint.line}) before its children"
            )
        if joint.channel_names is None:
            raise self._error(
                f"Expected CHANNELS in {keyword} {_show(joint.name, _EXCERPT)} (line {joint.line}) before its children"
            )

    def _open_brace(self, what: str) -> None:
        text = self._expect_line(f"'{{' after {what}")
        if text != "{":
            raise self._error(f"Expected '{{' after {what}, got {_show(text)}")

    def _end_site(self, text: str, *, parent: int) -> None:
        opened_line = self.line
        words = text.split()
        if len(words) < 2 or words[1].lower() != "site" or words[2:] not in ([], ["{"]):
            raise self._error(f"Expected 'End Site', got {_show(text)}")
        if words[2:] != ["{"]:
            self._open_brace("End Site")
        offset = None
        while True:
            text = self._expect_line(f"'}}' to close the End Site (opened at line {opened_line})")
            kw = _keyword(text)
            if kw == "OFFSET" and offset is None:
                offset = self._offset(text)
            elif text == "}":
                if offset is None:
                    raise self._error("Expected OFFSET in the End Site before '}'")
                self.end_sites.append((parent, offset))
                return
            else:
                raise self._error(f"Expected OFFSET or '}}' in the End Site, got {_show(text)}")

    def _offset(self, text: str) -> tuple[float, float, float]:
        words = text.split()[1:]
        if len(words) != 3:
            raise self._error(f"Expected 3 numbers after OFFSET, got {len(words)}")
        return self._number(words[0], "OFFSET"), self._number(words[1], "OFFSET"), self._number(words[2], "OFFSET")

    def _number(self, word: str, where: str) -> float:
        if len(word) > MAX_TOKEN:
            raise self._error(_too_long(word))
        if not _NUMBER_RE.fullmatch(word.encode("utf-8", "replace")):
            raise self._error(f"Expected a number in {where}, got {_show(word, _EXCERPT)}")
        value = float(word)
        if not math.isfinite(value):
            raise self._error(f"Expected a finite number in {where}, got {_show(word, _EXCERPT)}")
        if abs(value) > MAX_VALUE:
            raise self._error(f"{_TOO_BIG} in {where}, got {_show(word, _EXCERPT)}")
        return value

    def _count(self, word: str, what: str) -> int:
        """``word`` as a count: ASCII digits, at most ``_MAX_COUNT_DIGITS`` of them."""
        if not _is_count(word):
            raise self._error(f"Expected {what}, got {_show(word, _EXCERPT)}")
        if len(word) > _MAX_COUNT_DIGITS:
            raise self._error(
                f"Expected {what} of at most {_MAX_COUNT_DIGITS} digits, "
                f"got {_show(word, _EXCERPT)} ({len(word)} digits)"
            )
        return int(word)

    def _channels(self, text: str) -> tuple[str, ...]:
        words = text.split()[1:]
        count = self._count(words[0] if words else "", "a channel count after CHANNELS")
        names = words[1:]
        if len(names) != count:
            raise self._error(f"Expected {count} channel names after 'CHANNELS {count}', got {len(names)}")
        canonical = []
        for name in names:
            channel = _CHANNEL_LOOKUP.get(name.lower())
            if channel is None:
                raise self._error(f"Expected a channel name ({', '.join(CHANNEL_NAMES)}), got {_show(name, _EXCERPT)}")
            if channel.endswith("position") and channel in canonical:
                raise self._error(f"Expected each position channel once, got {channel} twice")
            canonical.append(channel)
        return tuple(canonical)

    def _motion_header(self) -> None:
        text = self._expect_line("'Frames: <count>' after MOTION")
        m = _FRAMES_RE.fullmatch(text)
        if not m:
            raise self._error(f"Expected 'Frames: <count>' after MOTION, got {_show(text)}")
        self.n_frames = self._count(m.group(1), "a whole number of frames")
        text = self._expect_line("'Frame Time: <seconds>' after Frames")
        m = _FRAME_TIME_RE.fullmatch(text)
        if not m:
            raise self._error(f"Expected 'Frame Time: <seconds>' after Frames, got {_show(text)}")
        word = m.group(1)
        if len(word) > MAX_TOKEN:
            raise self._error(_too_long(word))
        try:
            frame_time = float(word) if _NUMBER_RE.fullmatch(word.encode("utf-8", "replace")) else math.nan
        except ValueError:
            frame_time = math.nan
        if not (math.isfinite(frame_time) and frame_time > 0):
            raise self._error(f"Expected a positive frame time in seconds, got {_show(word, _EXCERPT)}")
        if not MIN_FRAME_TIME <= frame_time <= MAX_FRAME_TIME:
            raise self._error(
                f"Expected a frame time from {MIN_FRAME_TIME:g} to {MAX_FRAME_TIME:g} seconds, "
                f"got {_show(word, _EXCERPT)}"
            )
        self.frame_time = frame_time
        self.data_start = min(self.pos, len(self.data))
        self.data_first_line = self.line + 1
        if self.n_channels == 0:
            raise self._error("Expected at least one channel in the hierarchy, got none", line=2)


def _is_count(word: str) -> bool:
    """``word`` is a whole number >= 0 in ASCII digits (``str.isdigit`` also takes '²' and '١', which ``int`` may
    refuse)."""
    return word.isascii() and word.isdigit()


def _keyword(text: str) -> str:
    return text.split(None, 1)[0].upper()


def _name_and_brace(text: str, keyword: str) -> tuple[str, bool]:
    """The joint name after ROOT/JOINT (the rest of the line, kept whole) and whether a '{' ends the line."""
    rest = text[len(keyword) :].strip() if text[: len(keyword)].upper() == keyword else ""
    brace = False
    if rest.endswith("{") and (rest == "{" or rest[-2].isspace()):
        rest, brace = rest[:-1].rstrip(), True
    return rest, brace


def _show(text: str, limit: int = 60) -> str:
    return repr(text if len(text) <= limit else text[:limit] + "...")


_EXCERPT = 40  #: characters of a token quoted in an error


def _too_long(word: str, length: int | None = None) -> str:
    """The message for a token of ``length`` characters (default ``len(word)``) that starts with ``word``."""
    n = len(word) if length is None else length
    return f"Expected a number of at most {MAX_TOKEN} characters, got {_show(word, _EXCERPT)} ({n} characters)"


# ----------------------------------------------------------------------------------------------- MOTION


#: Bytes of MOTION block read per step: the temporaries of a step stay below glibc's mmap threshold, so they are
#: recycled instead of page-faulted in afresh (which costs more than the arithmetic on this kind of machine).
_WINDOW = 96 * 1024
_SEPARATORS = bytes(range(33))  # the bytes that separate numbers (see bvh_numbers.token_bounds)


def _read_frames(
    buf: np.ndarray, base: int, length: int, header: _Header, path: Path | None
) -> tuple[np.ndarray, tuple[int, str] | None]:
    """``(n_frames, n_channels)`` float64 from the frame lines in ``buf[base : base + length]``; every count and
    value checked.  The common case (all counts right, all numbers plain decimals) is read window by window;
    anything else is read again in one piece to find and report the first problem.

    Lines after the first ``n_frames`` are ignored, as other readers do; the second item is then the warning
    to log, ``(line, message)``, else None."""
    got = _read_frames_fast(buf, base, length, header.n_frames, header.n_channels)
    if got is None:
        got = _read_frames_checked(buf, base, length, header, path)
    channels, extra_from = got
    if extra_from is None:
        return channels, None
    block = buf[base : base + length]
    line = header.data_first_line + int(np.count_nonzero(block[:extra_from] == 10))
    rest = bytes(block[extra_from:]).split(b"\n")  # (line ends are LF by now)
    ignored = sum(1 for text in rest if text.translate(None, _SEPARATORS))
    n = header.n_frames
    message = f"Ignored {ignored} line{'s' * (ignored != 1)} after the {n} frame{'s' * (n != 1)} of 'Frames: {n}'"
    return channels, (line, message)


def _read_frames_fast(
    buf: np.ndarray, base: int, length: int, n_frames: int, n_channels: int
) -> tuple[np.ndarray, int | None] | None:
    """The frames and the block offset of the first line after them (None: there is none), if every line and
    number is regular, else None (nothing is reported from here)."""
    if n_frames * n_channels > (length + 1) // 2:  # each value takes 2 bytes at least: the file ends early
        return None
    values = np.empty(n_frames * n_channels)
    b = buf[base : base + length]
    filled = lines = 0
    extra_from = None
    lo = 0
    while lo < length:
        hi = min(lo + _WINDOW, length)
        window = b[lo:hi]
        breaks = np.flatnonzero(window == 10)
        if hi < length:
            if breaks.size == 0:
                return None  # a line longer than a window: let the checked path deal with it
            hi = lo + int(breaks[-1]) + 1
            window = b[lo:hi]
        starts, ends = bvh_numbers.token_bounds(window)
        first_token = np.searchsorted(starts, np.concatenate(([0], breaks[breaks < hi - lo] + 1)))
        counts = np.diff(np.append(first_token, starts.size))
        counts = counts[counts > 0]
        k = starts.size
        if lines + counts.size > n_frames:  # more lines than promised: read the first ones, ignore the rest
            counts = counts[: n_frames - lines]
            k = int(counts.sum())
            extra_from = lo + int(starts[k])
            starts, ends = starts[:k], ends[:k]
            hi = length
        if (counts != n_channels).any() or filled + k > values.size:
            return None
        if k:
            _, slow = _parse_tokens(buf, base + lo, starts, ends, out=values[filled : filled + k])
            if slow.any():
                return None
        filled += k
        lines += counts.size
        lo = hi
    if lines != n_frames or filled != values.size:  # (fast-path values are plain decimals: always finite)
        return None
    return values.reshape(n_frames, n_channels), extra_from


def _read_frames_checked(
    buf: np.ndarray, base: int, length: int, header: _Header, path: Path | None
) -> tuple[np.ndarray, int | None]:
    """Like :func:`_read_frames_fast`, in one piece, reporting the first problem in file order."""
    n_frames, n_channels, first_line = header.n_frames, header.n_channels, header.data_first_line
    b = buf[base : base + length]
    starts, ends = bvh_numbers.token_bounds(b)
    breaks = np.flatnonzero(b == 10)  # line i of the block ends at breaks[i]
    line_starts = np.concatenate(([0], breaks + 1))
    first_token = np.searchsorted(starts, line_starts)
    counts = np.diff(np.append(first_token, starts.size))
    filled = np.flatnonzero(counts)  # block line index of each non-blank line
    extra_from = None
    if filled.size > n_frames:  # the lines after the promised ones are ignored, whatever they hold
        cut = int(first_token[filled[n_frames]])
        extra_from = int(starts[cut])
        starts, ends = starts[:cut], ends[:cut]

    def line_of(token: int) -> int:
        return first_line + int(np.searchsorted(breaks, starts[token]))

    problem: tuple[int, str] | None = None  # (file line, message): the first in file order wins
    wrong = np.flatnonzero(counts[filled[:n_frames]] != n_channels)
    if wrong.size:
        k = filled[wrong[0]]
        problem = (first_line + int(k), f"Expected {n_channels} values on frame line, got {int(counts[k])}")
    if starts.size:
        values, slow = _parse_tokens(buf, base, starts, ends)
    else:
        values, slow = np.zeros(0), np.zeros(0, dtype=bool)
    bad_value = _read_slow_tokens(b, starts, ends, values, slow)
    if bad_value is not None:
        token, message = bad_value
        candidate = (line_of(token), message)
        if problem is None or candidate[0] < problem[0]:
            problem = candidate
    if problem is not None:
        raise BvhError(problem[1], path=path, line=problem[0])
    if filled.size < n_frames:
        n_lines = breaks.size + (1 if length and b[-1] != 10 else 0)
        raise BvhError(
            f"Expected {n_frames} frame lines (Frames: {n_frames}), got {filled.size}: the file ends early",
            path=path,
            line=first_line + n_lines,
        )
    return values.reshape(n_frames, n_channels), extra_from


def _parse_tokens(
    text: np.ndarray, base: int, starts: np.ndarray, ends: np.ndarray, *, out: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`bvh_numbers.parse_tokens` on ``text[base:]``, through a padded copy when the tokens run to the end."""
    stop = base + int(ends[-1])
    if base >= 8 and stop + bvh_numbers.PAD <= text.size:
        return bvh_numbers.parse_tokens(text, base, starts, ends, out=out)
    padded = np.full(stop - base + 8 + bvh_numbers.PAD, 32, dtype=np.uint8)
    padded[8 : 8 + stop - base] = text[base:stop]
    return bvh_numbers.parse_tokens(padded, 8, starts, ends, out=out)


def _read_slow_tokens(
    block: np.ndarray, starts: np.ndarray, ends: np.ndarray, values: np.ndarray, slow: np.ndarray
) -> tuple[int, str] | None:
    """Read the tokens the fast path flagged; return the first bad one as (token index, message).

    Valid ones (exponents, long numbers) are checked with one regex over all
    of them and converted in bulk; only a failure is looked at token by token.
    A number is bad when it is not finite or beyond ``MAX_VALUE`` (fast-path
    values have at most 7 integer digits: always within it).
    """
    index = np.flatnonzero(slow)
    if index.size == 0:
        return None
    long = np.flatnonzero(ends[index] - starts[index] > MAX_TOKEN)
    if long.size:  # read only the tokens before the first long one: an earlier bad token is reported first
        first_long = int(index[long[0]])
        found = _read_slow_tokens(block, starts, ends, values, slow & (np.arange(slow.size) < first_long))
        if found is not None:
            return found
        head = bytes(block[starts[first_long] : starts[first_long] + _EXCERPT + 1]).decode("utf-8", "replace")
        return first_long, _too_long(head, int(ends[first_long] - starts[first_long]))
    words = [bytes(block[s:e]) for s, e in zip(starts[index].tolist(), ends[index].tolist(), strict=True)]
    if _NUMBERS_RE.fullmatch(b"\n".join(words)):
        read = np.array(words).astype(np.float64)
        values[index] = read
        out_of_range = ~(np.abs(read) <= MAX_VALUE)  # also inf ('1e999' reads as inf)
        if not out_of_range.any():
            return None
        first = int(np.argmax(out_of_range))
        return int(index[first]), _bad_number(words[first], float(read[first]))
    for i, word in zip(index.tolist(), words, strict=True):
        if _NUMBER_RE.fullmatch(word):
            value = float(word)
            if abs(value) <= MAX_VALUE:
                continue
            return i, _bad_number(word, value)
        shown = _show(word.decode("utf-8", "replace"), _EXCERPT)
        if _NONFINITE_RE.fullmatch(word):
            return i, f"Expected a finite number, got {shown}"
        return i, f"Expected a number, got {shown}"
    raise AssertionError("unreachable: the joined tokens failed the regex but each one passed")


def _bad_number(word: bytes, value: float) -> str:
    """The message for a number token that reads as ``value``, infinite or beyond ``MAX_VALUE``."""
    return f"{'Expected a finite number' if math.isinf(value) else _TOO_BIG}, got {_show(word.decode(), _EXCERPT)}"
