"""Reading valid BVH: every accepted variant, the bulk number reader, the real clips and the demo clip."""

from __future__ import annotations

import numpy as np
import pytest

from retarget.bvh import DEMO_CLIP, load_bvh, parse_bvh
from retarget.bvh import numbers as bvh_numbers
from retarget.errors import BvhError
from tests.helpers import POS_XYZ, REPO, ROT_ZXY, J, arm_skeleton, bvh_text, n_channels


def small() -> J:
    root = J("Hips", (0, 90, 0), (*POS_XYZ, *ROT_ZXY))
    arm = J("Arm", (10, 40, 0), ("Yrotation", "Xrotation", "Zrotation"), end=(0, -20, 0))
    root.children = [J("Spine", (0, 10, 0), ("Xrotation", "Zrotation", "Yrotation"), children=[arm])]
    return root


FRAMES = np.array([[1.5, 90.25, -3.0, 10, 20, 30, 1, 2, 3, -4, -5, -6], [0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0.125]])


def test_reads_skeleton_and_frames():
    m = parse_bvh(bvh_text(small(), FRAMES, frame_time=1 / 60), path="x.bvh")
    assert m.joint_names == ("Hips", "Spine", "Arm")
    assert m.parents.tolist() == [-1, 0, 1]
    np.testing.assert_array_equal(m.offsets, [[0, 90, 0], [0, 10, 0], [10, 40, 0]])
    assert m.rotation_orders == ("ZXY", "XZY", "YXZ")  # orders differ per joint
    assert [lay.first_column for lay in m.layout] == [0, 6, 9]
    assert m.end_sites[0].parent == 2 and m.end_sites[0].offset == (0, -20, 0)
    np.testing.assert_array_equal(m.channels, FRAMES)
    assert m.n_frames == 2 and m.frame_time == pytest.approx(1 / 60)
    assert str(m.path) == "x.bvh"


def _after_motion(text: str, change) -> str:
    head, rest = text.split("Frame Time", 1)
    line, rest = rest.split("\n", 1)
    return head + "Frame Time" + line + "\n" + change(rest)


VARIANTS = {
    "crlf": lambda t: t.replace("\n", "\r\n"),
    "cr-only": lambda t: t.replace("\n", "\r"),
    "crlf-frames-only": lambda t: _after_motion(t, lambda rest: rest.replace("\n", "\r\n")),
    "cr-frames-only": lambda t: _after_motion(t, lambda rest: rest.replace("\n", "\r")),
    "tabs": lambda t: t.replace("  ", "\t").replace(" ", "\t"),
    "trailing-space": lambda t: t.replace("\n", "  \t\n"),
    "no-final-newline": lambda t: t.rstrip("\n"),
    "blank-lines": lambda t: t.replace("MOTION\n", "\nMOTION\n\n").replace("\n0 0", "\n\n0 0"),
    "utf8-bom": lambda t: "\ufeff" + t,
    "frames-tab": lambda t: t.replace("Frames: 2", "Frames:\t2"),
    "brace-on-joint-line": lambda t: t.replace("ROOT Hips\n{", "ROOT Hips {"),
    "lowercase-channels": lambda t: t.replace("Xrotation Zrotation", "XROTATION zrotation"),
}


@pytest.mark.parametrize("change", VARIANTS.values(), ids=VARIANTS.keys())
def test_accepted_variants_read_the_same(change):
    base = parse_bvh(bvh_text(small(), FRAMES))
    m = parse_bvh(change(bvh_text(small(), FRAMES)))
    assert m.joint_names == base.joint_names
    np.testing.assert_array_equal(m.channels, base.channels)
    np.testing.assert_array_equal(m.positions(), base.positions())


def test_scientific_notation_and_signs():
    text = bvh_text(small(), FRAMES, fmt="{:.6e}").replace("0.000000e+00", "+0E0", 1)
    m = parse_bvh(text)
    np.testing.assert_array_equal(m.channels, FRAMES)


def test_frames_zero():
    m = parse_bvh(bvh_text(small(), np.zeros((0, 12))))
    assert m.n_frames == 0 and m.channels.shape == (0, 12)


@pytest.mark.parametrize("name", ["mixamorig:LeftArm", "Right Arm", "ns:Left  Fore Arm", "upper_arm.L", "Ünïcødé"])
def test_names_with_spaces_and_colons_are_kept_whole(name):
    root = small()
    root.children[0].name = name
    m = parse_bvh(bvh_text(root, FRAMES))
    assert m.joint_names[1] == name


def test_several_roots():
    text = bvh_text(small(), FRAMES)
    second = "ROOT Prop\n{\n  OFFSET 1 2 3\n  CHANNELS 3 Xposition Yposition Zposition\n}\nMOTION"
    text = text.replace("MOTION", second, 1).replace("Frames: 2\nFrame Time: 0.03333333333\n", "Frames: 1\n")
    lines = text.splitlines()
    motion_at = lines.index("MOTION")
    lines[motion_at + 1 :] = ["Frames: 1", "Frame Time: 0.1", " ".join(["0"] * 12 + ["7", "8", "9"])]
    m = parse_bvh("\n".join(lines))
    assert m.joint_names[-1] == "Prop" and m.parents[-1] == -1
    np.testing.assert_array_equal(m.positions()[0, -1], [7, 8, 9])


@pytest.mark.parametrize("fmt", ["{:.6f}", "{:.4f}", "{:.9f}", "{:.3e}", "{!r}"], ids=["f6", "f4", "f9", "exp", "repr"])
def test_many_frames_across_read_windows(fmt):
    rng = np.random.default_rng(len(fmt))
    frames = rng.uniform(-500, 500, size=(3000, 12)) * rng.choice([1e-3, 1, 10], size=(3000, 12))
    text = bvh_text(small(), frames, fmt=fmt)
    assert len(text) > 3 * 96 * 1024  # several windows of the windowed reader
    m = parse_bvh(text)
    want = np.array([float(fmt.format(float(v))) for v in frames.ravel()]).reshape(frames.shape)
    np.testing.assert_array_equal(m.channels, want)


def test_frame_line_longer_than_a_read_window():
    root = J("Hips", (0, 0, 0), POS_XYZ, children=[J(f"j{k}", (0, 1, 0), ROT_ZXY) for k in range(4500)])
    rng = np.random.default_rng(4)
    frames = np.round(rng.uniform(-90, 90, size=(2, 3 + 3 * 4500)), 4)  # a frame line is > 100 KB
    m = parse_bvh(bvh_text(root, frames, fmt="{:.4f}"))
    np.testing.assert_array_equal(m.channels, frames)


def test_absurdly_deep_hierarchy_is_an_error_not_a_crash():
    text = "HIERARCHY\n" + "".join(
        f"{'ROOT' if k == 0 else 'JOINT'} j{k}\n{{\nOFFSET 0 1 0\nCHANNELS 1 Xrotation\n" for k in range(3000)
    )
    with pytest.raises(BvhError, match="Expected at most 500 nested joints, got more") as info:
        parse_bvh(text)
    assert info.value.line == 2 + 4 * 500


def test_load_bvh_reads_a_file(tmp_path):
    path = tmp_path / "clip.bvh"
    path.write_text(bvh_text(small(), FRAMES))
    m = load_bvh(path)
    assert m.path == path and m.n_frames == 2
    np.testing.assert_array_equal(m.channels, FRAMES)
    with pytest.raises(FileNotFoundError):
        load_bvh(tmp_path / "missing.bvh")
    with pytest.raises(IsADirectoryError):
        load_bvh(tmp_path)


def test_load_bvh_edge_files(tmp_path):
    empty = tmp_path / "empty.bvh"  # cannot be memory-mapped: read instead
    empty.write_bytes(b"")
    with pytest.raises(BvhError, match=r"empty\.bvh:1: Expected a BVH file starting with HIERARCHY"):
        load_bvh(empty)
    bom = tmp_path / "bom.bvh"
    bom.write_bytes(b"\xef\xbb\xbf" + bvh_text(small(), FRAMES).encode().rstrip(b"\n"))  # and no final newline
    np.testing.assert_array_equal(load_bvh(bom).channels, FRAMES)


# ------------------------------------------------------------------------------- bulk number reader


def _tokens(rng: np.random.Generator, n: int) -> list[str]:
    kinds = [
        lambda: f"{rng.uniform(-400, 400):.6f}",
        lambda: f"{rng.uniform(-1, 1):.{rng.integers(0, 15)}f}",
        lambda: str(int(rng.integers(-100000, 100000))),
        lambda: f"{rng.uniform(-1e6, 1e6):.{rng.integers(1, 9)}f}",
        lambda: f"{rng.uniform(-1, 1):.3e}",
        lambda: repr(float(rng.normal())),
        lambda: ("+" if rng.random() < 0.5 else "-") + f"{rng.uniform(0, 10):.4f}",
        lambda: "." + str(int(rng.integers(0, 10**6))),
        lambda: str(int(rng.integers(0, 10**6))) + ".",
        lambda: "0" * int(rng.integers(1, 20)) + "1.5",
        lambda: str(int(rng.integers(10**14, 10**17))),
    ]
    return [kinds[int(rng.integers(len(kinds)))]() for _ in range(n)]


@pytest.mark.parametrize("seed", range(5))
def test_bulk_reader_is_bit_identical_to_float(seed):
    rng = np.random.default_rng(seed)
    tokens = _tokens(rng, 3000)
    seps = [" ", "\t", "  ", "\n", " \r\n"]
    block = "".join(t + seps[int(rng.integers(len(seps)))] for t in tokens).encode()
    padded = bvh_numbers.pad_block(block)
    starts, ends = bvh_numbers.token_bounds(padded[bvh_numbers.PAD : bvh_numbers.PAD + len(block)])
    assert starts.size == len(tokens)
    values, slow = bvh_numbers.parse_tokens(padded, bvh_numbers.PAD, starts, ends)
    want = np.array([float(t) for t in tokens])
    fast = ~slow
    assert fast.mean() > 0.6  # the fast path does the bulk of the work
    np.testing.assert_array_equal(values[fast], want[fast])
    # what it leaves to float(): exponents, more than 7 integer or 8 fraction digits
    for t in np.array(tokens)[slow]:
        whole, _, fraction = t.lstrip("+-").partition(".")
        assert "e" in t or len(whole) > 7 or len(fraction) > 8, t


@pytest.mark.parametrize(
    "token", ["-", ".", "-.", "1.2.3", "12-3", "1+2", "nan", "inf", "1e5", "0x1A", "1_000", "١٢", "--1", "+-1"]
)
def test_bulk_reader_flags_what_it_cannot_prove(token):
    block = f"1.5 {token} 2.5\n".encode()
    padded = bvh_numbers.pad_block(block)
    starts, ends = bvh_numbers.token_bounds(padded[bvh_numbers.PAD : bvh_numbers.PAD + len(block)])
    values, slow = bvh_numbers.parse_tokens(padded, bvh_numbers.PAD, starts, ends)
    assert slow.tolist() == [False, True, False]
    assert values[0] == 1.5 and values[2] == 2.5


def test_numpy_shifts_past_the_word_give_zero():
    # bvh_numbers relies on this numpy behaviour for its byte masks
    word = np.array([0xFFFFFFFFFFFFFFFF] * 2, dtype=np.uint64)
    assert (word << np.array([64, 72], dtype=np.uint64)).tolist() == [0, 0]


# ------------------------------------------------------------------------------------------ real clips

FRAME_COUNTS = {
    "motion_walk.bvh": 1752,
    "motion_dance.bvh": 1871,
    "motion_basket.bvh": 1146,
    "push.bvh": 200,
    "unity_walk_random.bvh": 3846,
}


@pytest.mark.shared
@pytest.mark.parametrize("name", sorted(FRAME_COUNTS), ids=sorted(FRAME_COUNTS))
def test_real_clip_frame_counts(shared_bvh, name):
    path = shared_bvh / name
    if not path.exists():
        pytest.skip(f"{name} not in {shared_bvh}")
    m = load_bvh(path)
    assert m.n_frames == FRAME_COUNTS[name]
    assert m.positions().shape == (FRAME_COUNTS[name], m.n_joints, 3)
    assert np.isfinite(m.positions()).all()


@pytest.mark.shared
@pytest.mark.parametrize("name", sorted(FRAME_COUNTS), ids=sorted(FRAME_COUNTS))
def test_real_clip_values_equal_float_of_each_token(shared_bvh, name):
    path = shared_bvh / name
    if not path.exists():
        pytest.skip(f"{name} not in {shared_bvh}")
    m = load_bvh(path)
    text = path.read_text()
    tokens = text[text.index("Frame Time") :].split("\n", 1)[1].split()
    np.testing.assert_array_equal(m.channels.ravel(), np.array(tokens, dtype=np.float64))


def test_demo_clip():
    m = load_bvh(DEMO_CLIP)
    assert 8.0 <= m.duration <= 12.0
    assert m.fps == pytest.approx(60.0, rel=1e-5)
    assert m.joint_names[:5] == ("Hips", "Spine", "Spine1", "Neck", "Head")
    assert m.guess_units().unit == "cm"
    assert 160 <= m.guess_units().height <= 180
    right = m.arm_points("right")
    assert right.names == ("RightArm", "RightForeArm", "RightHand")
    reach = right.points[:, 2] - right.points[:, 0]  # wrist from shoulder, cm, Y up, facing +Z
    assert reach[:, 2].max() > 45  # reaches forward
    assert reach[:, 1].max() > 45  # reaches up
    assert reach[:, 0].min() < -45  # reaches out to its right (-X)
    steps = np.linalg.norm(np.diff(right.points[:, 2], axis=0), axis=1) * m.fps
    assert steps.max() < 300  # smooth: wrist speed stays under 3 m/s
    assert n_channels(J("x")) == 3


def test_demo_clip_is_reproducible(tmp_path):
    import runpy
    import sys

    out = tmp_path / "demo.bvh"
    argv = sys.argv
    try:
        sys.argv = ["make_demo_clip.py", "-o", str(out)]
        runpy.run_path(str(REPO / "scripts" / "make_demo_clip.py"), run_name="__main__")
    finally:
        sys.argv = argv
    assert out.read_bytes() == DEMO_CLIP.read_bytes()


def test_regular_files_take_the_windowed_path(monkeypatch):
    import retarget.bvh.parse as bvh_module

    def fail(*args, **kwargs):
        raise AssertionError("the one-piece checked path ran for a regular file")

    monkeypatch.setattr(bvh_module, "_read_frames_checked", fail)
    frames = np.random.default_rng(0).uniform(-100, 100, size=(2000, 12))
    m = parse_bvh(bvh_text(small(), frames, fmt="{:.5f}").replace("\n", "  \n"))
    assert m.n_frames == 2000
    assert load_bvh(DEMO_CLIP).n_frames == 630


# ------------------------------------------------------------------------------- lenient, with a warning

LOGGER = "retarget.bvh.parse"
N_LINES = bvh_text(small(), FRAMES).count("\n")  # lines of the small file with its 2 frames


def _warnings(caplog) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.name == LOGGER and r.levelname == "WARNING"]


EXTRA = {
    "one-line": "0 0 0 0 0 0 0 0 0 0 0 0\n",
    "short-and-garbage": "0 0\njunk nan ,\n\n1 2 3\n",
    "no-final-newline": "1 2 3 4 5 6 7 8 9 10 11 12",
    "blank-lines-between": "\n\n0 0 0 0 0 0 0 0 0 0 0 0\n\n",
}


@pytest.mark.parametrize("extra", EXTRA.values(), ids=EXTRA.keys())
def test_lines_after_the_frames_count_are_ignored_with_a_warning(caplog, extra):
    text = bvh_text(small(), FRAMES)
    n_ignored = sum(1 for line in extra.splitlines() if line.strip())
    first = text.count("\n") + 1 + (len(extra) - len(extra.lstrip("\n")))  # the first ignored line
    m = parse_bvh(text + extra, path="x.bvh")
    np.testing.assert_array_equal(m.channels, FRAMES)
    plural = "s" if n_ignored > 1 else ""
    assert _warnings(caplog) == [f"x.bvh:{first}: Ignored {n_ignored} line{plural} after the 2 frames of 'Frames: 2'"]


@pytest.mark.parametrize("newline", ["\r\n", "\r"], ids=["crlf", "cr"])
def test_extra_lines_with_other_line_ends(caplog, newline):
    text = bvh_text(small(), FRAMES, newline=newline) + newline.join(["1 2", "3 4", ""])
    m = parse_bvh(text, path="x.bvh")
    np.testing.assert_array_equal(m.channels, FRAMES)
    assert _warnings(caplog) == [f"x.bvh:{N_LINES + 1}: Ignored 2 lines after the 2 frames of 'Frames: 2'"]


def test_extra_lines_after_frames_with_exponents(caplog):
    # exponents take the one-piece checked path: it ignores the extra lines the same way
    m = parse_bvh(bvh_text(small(), FRAMES, fmt="{:.6e}") + "nan\n", path="x.bvh")
    np.testing.assert_array_equal(m.channels, FRAMES)
    assert _warnings(caplog) == [f"x.bvh:{N_LINES + 1}: Ignored 1 line after the 2 frames of 'Frames: 2'"]


def test_extra_lines_in_a_long_file_take_the_windowed_path(caplog, monkeypatch):
    import retarget.bvh.parse as bvh_module

    def fail(*args, **kwargs):
        raise AssertionError("the one-piece checked path ran for a regular file with extra lines")

    monkeypatch.setattr(bvh_module, "_read_frames_checked", fail)
    frames = np.random.default_rng(1).uniform(-100, 100, size=(3000, 12)).round(5)
    text = bvh_text(small(), frames, fmt="{:.5f}")
    for n in (2999, 1500, 3, 0):  # the ignored lines start in the last window, a middle one, the first
        m = parse_bvh(text.replace("Frames: 3000", f"Frames: {n}"), path="x.bvh")
        np.testing.assert_array_equal(m.channels, frames[:n])
        lines = f"{3000 - n} line{'s' * (n != 2999)}"
        assert (
            _warnings(caplog)[-1] == f"x.bvh:{N_LINES - 1 + n}: Ignored {lines} after the {n} frames of 'Frames: {n}'"
        )


def test_trailing_blank_lines_are_not_extra_lines(caplog):
    m = parse_bvh(bvh_text(small(), FRAMES) + "\n \t\n\r\n", path="x.bvh")
    assert m.n_frames == 2 and _warnings(caplog) == []


def test_fewer_lines_than_promised_is_still_an_error(caplog):
    with pytest.raises(
        BvhError, match=rf"x\.bvh:{N_LINES + 1}: Expected 3 frame lines \(Frames: 3\), got 2: the file ends early"
    ):
        parse_bvh(bvh_text(small(), FRAMES, n_frames=3), path="x.bvh")
    assert _warnings(caplog) == []


def test_root_written_as_joint_is_read_with_a_warning(caplog):
    text = bvh_text(small(), FRAMES).replace("ROOT Hips", "JOINT Hips")
    m = parse_bvh(text, path="x.bvh")
    base = parse_bvh(bvh_text(small(), FRAMES))
    assert m.joint_names == base.joint_names and m.parents.tolist() == [-1, 0, 1]
    np.testing.assert_array_equal(m.positions(), base.positions())
    assert _warnings(caplog) == ["x.bvh:2: Read 'JOINT Hips' as the ROOT (the hierarchy's first joint)"]
    lower = text.replace("JOINT Hips\n{", "joint Hips {")  # any case, brace on the line: as ROOT takes it
    assert parse_bvh(lower).joint_names == base.joint_names


def test_root_written_as_joint_errors_name_the_joint():
    text = bvh_text(small(), FRAMES).replace("ROOT Hips", "JOINT Hips").replace("OFFSET 0 90 0", "OFFSET 0 90")
    with pytest.raises(BvhError, match=r"<bvh>:4: Expected 3 numbers after OFFSET, got 2"):
        parse_bvh(text)
    with pytest.raises(BvhError, match=r"<bvh>:2: Expected a joint name after JOINT, got nothing"):
        parse_bvh(bvh_text(small(), FRAMES).replace("ROOT Hips", "JOINT"))


def test_warnings_are_logged_once_when_the_file_is_read_again(caplog):
    # CRs met only in the frames make the parser read the whole file again, normalised
    text = _after_motion(bvh_text(small(), FRAMES).replace("ROOT", "JOINT"), lambda rest: rest.replace("\n", "\r"))
    m = parse_bvh(text + "1 2\r", path="x.bvh")
    np.testing.assert_array_equal(m.channels, FRAMES)
    assert _warnings(caplog) == [
        "x.bvh:2: Read 'JOINT Hips' as the ROOT (the hierarchy's first joint)",
        f"x.bvh:{N_LINES + 1}: Ignored 1 line after the 2 frames of 'Frames: 2'",
    ]
    # a header longer than the first bytes tried is read twice too
    root = J("Hips", (0, 0, 0), POS_XYZ, children=[J(f"joint_{k:05d}", (0, 1, 0), ROT_ZXY) for k in range(1200)])
    frames = np.zeros((2, n_channels(root)))
    caplog.clear()
    m = parse_bvh(bvh_text(root, frames).replace("ROOT Hips", "JOINT Hips"), path="y.bvh")
    assert m.n_joints == 1201
    assert _warnings(caplog) == ["y.bvh:2: Read 'JOINT Hips' as the ROOT (the hierarchy's first joint)"]


def test_no_warning_for_a_regular_file(caplog):
    parse_bvh(bvh_text(small(), FRAMES))
    load_bvh(DEMO_CLIP)
    assert _warnings(caplog) == []


# -------------------------------------------------------------------------------------- Frames: 0


@pytest.mark.filterwarnings("error::RuntimeWarning")
@pytest.mark.parametrize("extra", ["", "1 2 3\n"], ids=["template", "with-data"])
def test_frames_zero_gives_an_empty_motion_that_works(caplog, tmp_path, extra):
    """Perception Neuron's template files: a skeleton, ``Frames: 0``, and sometimes frame lines all the same."""
    names = {"clavicle": "{side}Shoulder", "upper": "{side}Arm", "fore": "{side}ForeArm", "hand": "{side}Hand"}
    root = arm_skeleton(names | {"left": "Left", "right": "Right"})
    path = tmp_path / "template.bvh"
    path.write_text(bvh_text(root, np.zeros((0, n_channels(root)))) + extra)
    m = load_bvh(path)
    n = m.n_joints
    assert (m.n_frames, m.duration, m.channels.shape) == (0, 0.0, (0, n_channels(root)))
    assert m.positions().shape == (0, n, 3)
    assert m.end_site_positions().shape == (0, len(m.end_sites), 3)
    rotations, positions = m.global_transforms()
    assert rotations.shape == (0, n, 3, 3) and positions.shape == (0, n, 3)
    arm = m.arm_points("right")
    assert arm.names == ("RightArm", "RightForeArm", "RightHand") and arm.points.shape == (0, 3, 3)
    assert np.isfinite(arm.bone_lengths).all()  # (what they are without frames is motion.py's business)
    assert m.scaled(0.01).positions().shape == (0, n, 3)
    assert m.guess_units().unit == "cm" and m.rest_positions().shape == (n, 3)
    assert repr(m) == f"<Motion 'template.bvh': {n} joints, 0 frames at 30 fps>"
    first = path.read_text().count("\n")  # the last line
    expected = [f"{path}:{first}: Ignored 1 line after the 0 frames of 'Frames: 0'"]
    assert _warnings(caplog) == (expected if extra else [])
