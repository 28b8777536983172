"""Every kind of bad BVH input: a BvhError naming the file and line, saying what was expected and what was found."""

from __future__ import annotations

import re

import pytest

from retarget.bvh import load_bvh, parse_bvh
from retarget.errors import BvhError
from tests.helpers import SMALL_BVH

GOOD = SMALL_BVH
# line numbers of GOOD: 1 HIERARCHY, 2 ROOT, 5 root CHANNELS, 9 Arm CHANNELS, 16 MOTION, 17 Frames, 19-20 frames


def sub(old: str, new: str, count: int = 1) -> str:
    assert old in GOOD
    return GOOD.replace(old, new, count)


CASES = {
    # missing or malformed HIERARCHY
    "no-hierarchy": (sub("HIERARCHY\n", ""), 1, "Expected HIERARCHY, got 'ROOT Hips'"),
    "hierarchy-misspelt": (sub("HIERARCHY", "HIERARCHIE"), 1, "Expected HIERARCHY, got 'HIERARCHIE'"),
    "no-root": (sub("ROOT Hips", "BONE Hips"), 2, "Expected ROOT after HIERARCHY, got 'BONE Hips'"),
    "second-root-as-joint": (  # only the first joint may be written JOINT (with a warning: see test_parse)
        sub("}\nMOTION", "}\nJOINT Prop\n{\n  OFFSET 0 0 0\n  CHANNELS 1 Xposition\n}\nMOTION"),
        16,
        "Expected MOTION after the hierarchy, got 'JOINT Prop'",
    ),
    "root-without-name": (sub("ROOT Hips", "ROOT"), 2, "Expected a joint name after ROOT, got nothing"),
    "no-open-brace": (sub("ROOT Hips\n{", "ROOT Hips\nOFFSET 0 0 0"), 3, "Expected '{' after ROOT 'Hips', got"),
    "unknown-keyword": (sub("  OFFSET 1 0 0", "  OFSET 1 0 0"), 8, "Expected OFFSET, CHANNELS, JOINT, End Site"),
    "offset-two-numbers": (sub("OFFSET 1 0 0", "OFFSET 1 0"), 8, "Expected 3 numbers after OFFSET, got 2"),
    "offset-not-number": (sub("OFFSET 1 0 0", "OFFSET 1 x 0"), 8, "Expected a number in OFFSET, got 'x'"),
    "offset-nan": (sub("OFFSET 1 0 0", "OFFSET 1 nan 0"), 8, "Expected a number in OFFSET, got 'nan'"),
    "offset-overflow": (
        sub("OFFSET 1 0 0", "OFFSET 1 0 -1e999"),
        8,
        "Expected a finite number in OFFSET, got '-1e999'",
    ),
    "offset-too-big": (
        sub("OFFSET 1 0 0", "OFFSET 1 0 1.5e12"),
        8,
        "Expected a number from -1e+12 to 1e+12 in OFFSET, got '1.5e12'",
    ),
    "offset-missing": (
        sub("    OFFSET 1 0 0\n", ""),
        9,
        "Expected OFFSET in JOINT 'Arm' (line 6) before its children",
    ),
    "end-site-without-offset": (sub("      OFFSET 0 1 0\n", ""), 12, "Expected OFFSET in the End Site before '}'"),
    "end-not-site": (sub("End Site", "End Sight"), 10, "Expected 'End Site', got 'End Sight'"),
    # unbalanced braces
    "missing-close-brace": (
        sub("    }\n  }\n}\n", "    }\n  }\n"),
        15,
        "Expected '}' to close ROOT 'Hips' (opened at line 2), got 'MOTION'",
    ),
    "extra-close-brace": (
        sub("}\nMOTION", "}\n}\nMOTION"),
        16,
        "Expected MOTION after the hierarchy, got an extra '}' (unbalanced braces)",
    ),
    "unclosed-at-eof": ("HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0 0\n", 5, "Expected '}' to close ROOT 'Hips'"),
    # channels
    "channel-count-more": (
        sub("CHANNELS 3 Zrotation", "CHANNELS 4 Zrotation"),
        9,
        "Expected 4 channel names after 'CHANNELS 4', got 3",
    ),
    "channel-count-fewer": (
        sub("CHANNELS 6 Xposition", "CHANNELS 5 Xposition"),
        5,
        "Expected 5 channel names after 'CHANNELS 5', got 6",
    ),
    "channel-count-missing": (sub("CHANNELS 3 Zrotation", "CHANNELS Zrotation"), 9, "Expected a channel count"),
    "channel-count-superscript": (  # fuzz: '²'.isdigit() is True but int('²') raised ValueError
        sub("CHANNELS 3 Zrotation", "CHANNELS \u00b3 Zrotation"),
        9,
        "Expected a channel count after CHANNELS, got '\u00b3'",
    ),
    "channel-count-arabic-digits": (
        sub("CHANNELS 3 Zrotation", "CHANNELS \u0663 Zrotation"),
        9,
        "Expected a channel count after CHANNELS, got '\u0663'",
    ),
    "unknown-channel": (
        sub("Zrotation Xrotation Yrotation\n    End", "Zrotation Wrotation Yrotation\n    End"),
        9,
        "Expected a channel name (Xposition, Yposition, Zposition, Xrotation, Yrotation, Zrotation), got 'Wrotation'",
    ),
    "duplicate-position": (
        sub("Xposition Yposition Zposition", "Xposition Xposition Zposition"),
        5,
        "Expected each position channel once, got Xposition twice",
    ),
    # MOTION header
    "no-motion": (GOOD.split("MOTION")[0], 16, "Expected MOTION after the hierarchy, got end of file"),
    "motion-misspelt": (sub("MOTION", "MOTON"), 16, "Expected MOTION after the hierarchy, got 'MOTON'"),
    "no-frames-line": (sub("Frames: 2\n", ""), 17, "Expected 'Frames: <count>' after MOTION, got 'Frame Time:"),
    "frames-not-integer": (sub("Frames: 2", "Frames: 2.5"), 17, "Expected a whole number of frames, got '2.5'"),
    "frames-negative": (sub("Frames: 2", "Frames: -1"), 17, "Expected a whole number of frames, got '-1'"),
    "frames-superscript": (sub("Frames: 2", "Frames: \u00b2"), 17, "Expected a whole number of frames, got '\u00b2'"),
    "frames-arabic-digits": (
        sub("Frames: 2", "Frames: \u0662"),
        17,
        "Expected a whole number of frames, got '\u0662'",
    ),
    "no-frame-time": (sub("Frame Time: 0.0333333\n", ""), 18, "Expected 'Frame Time: <seconds>' after Frames"),
    "frame-time-zero": (sub("0.0333333", "0"), 18, "Expected a positive frame time in seconds, got '0'"),
    "frame-time-word": (sub("0.0333333", "fast"), 18, "Expected a positive frame time in seconds, got 'fast'"),
    "frame-time-huge": (  # fuzz: the duration was inf
        sub("0.0333333", "1e308"),
        18,
        "Expected a frame time from 0.0001 to 10 seconds, got '1e308'",
    ),
    "frame-time-tiny": (sub("0.0333333", "1e-310"), 18, "Expected a frame time from 0.0001 to 10 seconds"),
    "frame-time-1e300": (sub("0.0333333", "1e300"), 18, "Expected a frame time from 0.0001 to 10 seconds"),
    "frame-time-11s": (sub("0.0333333", "11"), 18, "Expected a frame time from 0.0001 to 10 seconds, got '11'"),
    "frame-time-below-1e-4": (sub("0.0333333", "9e-5"), 18, "Expected a frame time from 0.0001 to 10 seconds"),
    # values
    "non-numeric": (sub("9 8 7 6 5", "9 8 seven 6 5"), 20, "Expected a number, got 'seven'"),
    "comma-decimal": (sub("1 2 3 4 5", "1 2,5 3 4 5"), 19, "Expected a number, got '2,5'"),
    "nan-value": (sub("9 8 7 6 5", "9 8 nan 6 5"), 20, "Expected a finite number, got 'nan'"),
    "inf-value": (sub("1 2 3 4 5", "1 2 -inf 4 5"), 19, "Expected a finite number, got '-inf'"),
    "overflow-value": (sub("1 2 3 4 5", "1 2 1e999 4 5"), 19, "Expected a finite number, got '1e999'"),
    "overflow-long-integer": (
        sub("9 8 7 6 5", "9 8 " + "9" * 400 + " 6 5"),
        20,
        "Expected a number of at most 100 characters, got '" + "9" * 40 + "...' (400 characters)",
    ),
    "overflow-integer-at-token-cap": (
        sub("9 8 7 6 5", "9 8 " + "9" * 100 + " 6 5"),
        20,
        "Expected a number from -1e+12",
    ),
    "value-too-big": (  # fuzz: two such values summed to inf in FK
        sub("9 8 7 6 5", "9 8 -1e308 6 5"),
        20,
        "Expected a number from -1e+12 to 1e+12, got '-1e308'",
    ),
    "value-too-big-plain": (sub("1 2 3 4 5", "1 2 3 4000000000000.5 5"), 19, "got '4000000000000.5'"),
    # frame lines
    "too-few-values": (sub("1 2 3 4 5 6 7 8 9", "1 2 3 4 5 6 7 8"), 19, "Expected 9 values on frame line, got 8"),
    "too-many-values": (sub("9 8 7 6 5 4 3 2 1", "9 8 7 6 5 4 3 2 1 0"), 20, "Expected 9 values on frame line, got 10"),
    "fewer-lines": (
        sub("Frames: 2", "Frames: 3"),
        21,
        "Expected 3 frame lines (Frames: 3), got 2: the file ends early",
    ),
    "fewer-lines-no-newline": (
        sub("Frames: 2", "Frames: 3").rstrip("\n"),
        21,
        "Expected 3 frame lines (Frames: 3), got 2",
    ),
    "last-line-short": (sub("Frames: 2", "Frames: 3") + "1 2\n", 21, "Expected 9 values on frame line, got 2"),
    # empty and binary
    "empty": ("", 1, "Expected a BVH file starting with HIERARCHY, got an empty file"),
    "whitespace-only": ("  \n\t\n", 1, "got an empty file"),
    "binary-nul": ("HIERARCHY\nROOT \x00\x01", 2, "Expected a text BVH file, got binary data"),
    "binary-control": ("\x01\x02\x03\x04\x05\x06\x07\x08" * 20, 1, "Expected a text BVH file, got binary data"),
}


@pytest.mark.parametrize(("text", "line", "message"), CASES.values(), ids=CASES.keys())
def test_bad_input(text, line, message):
    with pytest.raises(BvhError, match=re.escape(message)) as info:
        parse_bvh(text, path="bad.bvh")
    assert info.value.line == line
    assert info.value.path == "bad.bvh"
    assert str(info.value).startswith(f"bad.bvh:{line}: ")
    assert isinstance(info.value, ValueError)


def test_first_problem_in_file_order_wins():
    text = sub("1 2 3 4 5 6 7 8 9", "1 2 3 4 5 6 7 8").replace("9 8 7 6 5", "9 8 x 6 5")
    with pytest.raises(BvhError, match="Expected 9 values on frame line, got 8") as info:
        parse_bvh(text)
    assert info.value.line == 19
    text = sub("1 2 3 4 5", "1 2 x 4 5").replace("9 8 7 6 5 4 3 2 1", "9 8 7")
    with pytest.raises(BvhError, match="Expected a number, got 'x'") as info:
        parse_bvh(text)
    assert info.value.line == 19
    # a number out of range before a word that is not a number (each checked on its own when one is bad)
    text = sub("1 2 3 4 5", "1 2 1e999 4 5").replace("9 8 7 6 5", "9 8 x 6 5")
    with pytest.raises(BvhError, match="Expected a finite number, got '1e999'") as info:
        parse_bvh(text)
    assert info.value.line == 19
    text = sub("1 2 3 4 5", "1 2 3 4e15 5").replace("9 8 7 6 5", "9 8 x 6 5")
    with pytest.raises(BvhError, match="Expected a number from -1e.12 to 1e.12, got '4e15'") as info:
        parse_bvh(text)
    assert info.value.line == 19


@pytest.mark.parametrize("newline", ["\r\n", "\r"], ids=["crlf", "cr"])
@pytest.mark.parametrize("where", ["everywhere", "frames-only"])
def test_line_numbers_with_other_line_ends(newline, where):
    text = sub("9 8 7 6 5", "9 8 x 6 5")
    if where == "everywhere":
        text = text.replace("\n", newline)
    else:
        head, frames = text.split("0.0333333\n")
        text = head + "0.0333333\n" + frames.replace("\n", newline)
    with pytest.raises(BvhError, match="Expected a number, got 'x'") as info:
        parse_bvh(text)
    assert info.value.line == 20


def test_error_from_a_file_names_the_file(tmp_path):
    path = tmp_path / "short.bvh"
    path.write_text(sub("Frames: 2", "Frames: 5"))
    with pytest.raises(BvhError, match=r"short\.bvh:21: Expected 5 frame lines \(Frames: 5\), got 2"):
        load_bvh(path)


@pytest.mark.parametrize("frames", [3, 1000000, 10**15], ids=["3", "1e6", "1e15"])
def test_a_short_file_does_not_hang_nor_allocate_what_frames_says(frames):
    # one popular parser loops forever when Frames: says more than there is
    text = sub("Frames: 2", f"Frames: {frames}")
    with pytest.raises(BvhError, match=f"Expected {frames} frame lines .* got 2: the file ends early"):
        parse_bvh(text)


def test_every_truncation_is_an_error_never_partial_data():
    for cut in range(len(GOOD) - 2):  # GOOD[:-1] only lacks the final newline, which is fine
        with pytest.raises(BvhError):
            parse_bvh(GOOD[:cut])
