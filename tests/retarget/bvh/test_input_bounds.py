"""Issue 16, items 6-8: long tokens, huge integers, endless files and frame times give one short BvhError, fast."""

from __future__ import annotations

import time

import pytest

import retarget.bvh.parse as bvh_parse
from retarget.bvh import load_bvh, parse_bvh
from retarget.bvh.names import joint_roles, not_arm_kind
from retarget.errors import BvhError
from tests.helpers import SMALL_BVH

GOOD = SMALL_BVH
# line numbers of GOOD: 6 JOINT Arm, 8 its OFFSET, 9 its CHANNELS, 17 Frames, 18 Frame Time, 19-20 frames


def sub(old: str, new: str) -> str:
    assert old in GOOD
    return GOOD.replace(old, new, 1)


LONG = 100_000  # a 30,000-digit value took 14.5 s before; 100,000 ran past 2 minutes
SECONDS = 5.0  # generous bound per case: linear work on 100 KB takes milliseconds


def _error(text: str) -> BvhError:
    start = time.perf_counter()
    with pytest.raises(BvhError) as info:
        parse_bvh(text, path="big.bvh")
    assert time.perf_counter() - start < SECONDS
    message = str(info.value)
    assert len(message) < 300, message[:300]  # never the whole token
    assert "\n" not in message
    return info.value


DIGITS = "1" * LONG
CASES = {
    "frame-value": (sub("9 8 7 6 5", f"9 8 {DIGITS} 6 5"), 20, "Expected a number of at most 100 characters"),
    "frame-value-bad-end": (sub("9 8 7 6 5", f"9 8 {DIGITS}x 6 5"), 20, "Expected a number of at most 100 characters"),
    "frame-value-exponent": (sub("9 8 7 6 5", f"9 8 1e{DIGITS} 6 5"), 20, "Expected a number of at most 100"),
    "frame-value-fraction": (sub("1 2 3", f"1 2 0.{DIGITS}"), 19, "Expected a number of at most 100 characters"),
    # header lines are capped at 4096 bytes: a longer token there is a long line
    "offset-line": (sub("OFFSET 1 0 0", f"OFFSET 1 {DIGITS}x 0"), 8, "Expected a header line of at most 4096 bytes"),
    "frames-line": (sub("Frames: 2", f"Frames: {DIGITS}"), 17, "Expected a header line of at most 4096 bytes"),
    "channels-line": (sub("CHANNELS 3", f"CHANNELS {DIGITS}"), 9, "Expected a header line of at most 4096 bytes"),
    "joint-name-line": (sub("JOINT Arm", f"JOINT Arm{DIGITS}"), 6, "Expected a header line of at most 4096 bytes"),
    # and below that cap, tokens are still capped
    "offset": (sub("OFFSET 1 0 0", f"OFFSET 1 {DIGITS[:4000]}x 0"), 8, "Expected a number of at most 100 characters"),
    "frame-time": (sub("0.0333333", f"0.{DIGITS[:4000]}"), 18, "Expected a number of at most 100 characters"),
    "frames": (
        sub("Frames: 2", "Frames: " + "9" * 4000),
        17,
        "Expected a whole number of frames of at most 18 digits, got '9999",
    ),
    "channels": (
        sub("CHANNELS 3", "CHANNELS " + "3" * 4000),
        9,
        "Expected a channel count after CHANNELS of at most 18 digits",
    ),
}


@pytest.mark.parametrize(("text", "line", "message"), CASES.values(), ids=CASES.keys())
def test_a_huge_token_is_one_short_error_in_linear_time(text, line, message):
    error = _error(text)
    assert error.line == line
    assert message in str(error)


def test_the_excerpt_is_40_characters_and_the_length_is_given():
    error = _error(sub("9 8 7 6 5", f"9 8 {DIGITS} 6 5"))
    assert str(error) == (
        f"big.bvh:20: Expected a number of at most 100 characters, got '{'1' * 40}...' ({LONG} characters)"
    )


def test_an_earlier_bad_token_wins_over_a_later_long_one():
    text = sub("1 2 3 4 5", "1 x 3 4 5").replace("9 8 7 6 5", f"9 8 {DIGITS} 6 5")
    with pytest.raises(BvhError, match=r"^big\.bvh:19: Expected a number, got 'x'$"):
        parse_bvh(text, path="big.bvh")


def test_a_long_bad_token_is_quoted_short():
    with pytest.raises(BvhError, match=r"^big\.bvh:20: Expected a number, got 'a{40}\.\.\.'$"):
        parse_bvh(sub("9 8 7 6 5", "9 8 " + "a" * 90 + " 6 5"), path="big.bvh")


def test_a_long_joint_name_with_a_huge_number_loads_quickly():
    name = "RightForeArm" + "1" * 4000  # under the header line cap; int() of it would raise
    start = time.perf_counter()
    motion = parse_bvh(sub("JOINT Arm", f"JOINT {name}"))
    assert motion.joint_names[1] == name
    assert joint_roles([name, "hand" + "0" * 3999 + "1", "hand" + "2" * 4301])[1:] == [
        (None, "hand", 1),
        (None, None, 0),
    ]
    assert not_arm_kind("leg" + "9" * 5000) == "leg"
    assert time.perf_counter() - start < SECONDS


def test_dev_zero_is_binary_data_not_an_endless_read():
    start = time.perf_counter()
    with pytest.raises(BvhError, match=r"^/dev/zero:1: Expected a text BVH file, got binary data$"):
        load_bvh("/dev/zero")
    assert time.perf_counter() - start < SECONDS


def test_a_file_over_the_size_cap_is_refused(tmp_path, monkeypatch):
    path = tmp_path / "big.bvh"
    path.write_text(GOOD)
    monkeypatch.setattr(bvh_parse, "MAX_FILE_BYTES", len(GOOD) - 1)
    with pytest.raises(BvhError, match=r"big\.bvh:1: Expected a BVH file of at most 0 MiB, got more$"):
        load_bvh(path)
    monkeypatch.setattr(bvh_parse, "MAX_FILE_BYTES", len(GOOD))
    assert load_bvh(path).n_frames == 2


def test_an_endless_stream_is_cut_at_the_size_cap(tmp_path, monkeypatch):
    fifo_like = tmp_path / "stream.bvh"
    fifo_like.write_text(GOOD)
    monkeypatch.setattr(bvh_parse, "MAX_FILE_BYTES", 10)
    monkeypatch.setattr(bvh_parse, "_READ_CHUNK", 4)
    with open(fifo_like, "rb") as f, pytest.raises(BvhError, match=r"stream\.bvh:1: Expected a BVH file of at most"):
        bvh_parse._read_bounded(f, fifo_like)
    with open(fifo_like, "rb") as f:
        monkeypatch.setattr(bvh_parse, "MAX_FILE_BYTES", len(GOOD))
        assert bvh_parse._read_bounded(f, fifo_like) == GOOD.encode()


@pytest.mark.parametrize("word", ["1e-4", "0.0001", "10", "0.0333333"])
def test_frame_times_at_the_range_ends_load(word):
    assert parse_bvh(sub("0.0333333", word)).frame_time == float(word)


@pytest.mark.parametrize("word", ["9.99e-5", "10.0001", "1e300", "1e-300"])
def test_frame_times_outside_the_range_name_the_line(word):
    with pytest.raises(BvhError, match=r"^big\.bvh:18: Expected a frame time from 0\.0001 to 10 seconds, got '"):
        parse_bvh(sub("0.0333333", word), path="big.bvh")
