"""Human -> arm mapping: invariances (units, rigid motion of the whole body), workspace clamp, IK weights, geometry."""

from __future__ import annotations

import logging

import numpy as np
import pytest

import retarget
from retarget.bvh import parse_bvh
from retarget.bvh.motion import ArmChain
from retarget.errors import BvhError, ConfigError
from retarget.mapping.config import Axis, MappingConfig
from retarget.mapping.geometry import (
    FROM_SHOULDERS,
    FROM_SPINE,
    HELD,
    ROLL_WEIGHT,
    WRIST_WEIGHT,
    Targets,
    Workspace,
    arm_geometry,
    body_frames,
    body_frames_masked,
    clip_body_frames,
    default_origin,
    hold_good_frames,
    ik_weights,
    retarget_targets,
    shoulder_offsets,
    spine_frames,
    torso_joint,
)
from tests.helpers import POS_XYZ, ROT_ZXY, J, arm_skeleton, joints_in_order
from tests.helpers import bvh_text as rig_text

# A small CMU-named skeleton, cm, facing +Z, Y up.  Root channels put Yrotation first, so adding to it turns
# the whole body about the vertical through the root.
JOINTS = [  # name, parent, offset (cm)
    ("Hips", None, (0.0, 0.0, 0.0)),
    ("Spine", "Hips", (0.0, 25.0, 0.0)),
    ("Neck", "Spine", (0.0, 30.0, 0.0)),
    ("LeftShoulder", "Spine", (3.0, 27.0, 0.0)),
    ("LeftArm", "LeftShoulder", (15.0, 0.0, 0.0)),
    ("LeftForeArm", "LeftArm", (29.0, 0.0, 0.0)),
    ("LeftHand", "LeftForeArm", (26.0, 0.0, 0.0)),
    ("RightShoulder", "Spine", (-3.0, 27.0, 0.0)),
    ("RightArm", "RightShoulder", (-15.0, 0.0, 0.0)),
    ("RightForeArm", "RightArm", (-29.0, 0.0, 0.0)),
    ("RightHand", "RightForeArm", (-26.0, 0.0, 0.0)),
]
ROOT_CHANNELS = "Xposition Yposition Zposition Yrotation Xrotation Zrotation"
CHANNELS = "Zrotation Xrotation Yrotation"


def bvh_text(frames: np.ndarray, *, scale: float = 1.0, frame_time: float = 1 / 60) -> str:
    """BVH text of the skeleton above; ``frames`` ``(n, 6 + 3 * 10)`` (root position cm, then degrees)."""
    lines = ["HIERARCHY"]
    depth = {}

    def emit(name: str, parent: str | None, offset: tuple[float, float, float]) -> None:
        d = 0 if parent is None else depth[parent] + 1
        depth[name] = d
        pad = "  " * d
        lines.append(f"{pad}{'ROOT' if parent is None else 'JOINT'} {name}")
        lines.append(pad + "{")
        lines.append(f"{pad}  OFFSET {' '.join(f'{v * scale:.9g}' for v in offset)}")
        channels = ROOT_CHANNELS if parent is None else CHANNELS
        lines.append(f"{pad}  CHANNELS {len(channels.split())} {channels}")
        children = [j for j in JOINTS if j[1] == name]
        for child in children:
            emit(*child)
        if not children:
            lines.extend([f"{pad}  End Site", f"{pad}  {{", f"{pad}    OFFSET 0 0 0", f"{pad}  }}"])
        lines.append(pad + "}")

    emit(*JOINTS[0])
    lines += ["MOTION", f"Frames: {len(frames)}", f"Frame Time: {frame_time:.9g}"]
    for row in frames:
        values = np.concatenate([row[:3] * scale, row[3:]])
        lines.append(" ".join(f"{v:.12g}" for v in values))
    return "\n".join(lines) + "\n"


def random_frames(seed: int, n: int = 90) -> np.ndarray:
    """Smooth random motion: the root walks and turns, every joint rotates a little, the arms a lot."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 1.5, n)[:, None]
    cols = 6 + 3 * (len(JOINTS) - 1)
    amp = np.full(cols, 15.0)
    amp[:3] = 20.0  # cm
    amp[3] = 90.0  # root yaw
    arm_cols = [6 + 3 * (i - 1) + k for i, (name, _, _) in enumerate(JOINTS) if "Arm" in name for k in range(3)]
    amp[arm_cols] = 60.0
    freq = rng.uniform(0.3, 1.5, cols)
    phase = rng.uniform(0, 2 * np.pi, cols)
    frames = amp * np.sin(2 * np.pi * freq * t + phase)
    frames[:, 1] += 95.0  # hips height
    return frames


def targets_of(frames: np.ndarray, arm, config: MappingConfig | None = None, *, scale: float = 1.0) -> Targets:
    return retarget_targets(parse_bvh(bvh_text(frames, scale=scale)), arm, config or MappingConfig())


@pytest.mark.parametrize("seed", [0, 1, 2], ids=lambda s: f"seed{s}")
@pytest.mark.parametrize("scale", [100.0, 0.01, 1 / 2.54], ids=["x100", "metres", "inches"])
def test_units_do_not_matter(arm, seed, scale):
    frames = random_frames(seed)
    base = targets_of(frames, arm)
    other = targets_of(frames, arm, scale=scale)
    np.testing.assert_allclose(other.raw, base.raw, atol=1e-9)
    np.testing.assert_array_equal(other.clamped, base.clamped)
    assert other.scale == pytest.approx(base.scale / scale)


@pytest.mark.parametrize("seed", [0, 3], ids=lambda s: f"seed{s}")
@pytest.mark.parametrize("yaw", [37.0, 180.0, -120.0], ids=lambda y: f"yaw{y:g}")
def test_turning_and_walking_the_whole_body_does_not_move_the_arm(arm, seed, yaw):
    frames = random_frames(seed)
    moved = frames.copy()
    moved[:, 3] += yaw  # the root's first rotation channel: a turn about the vertical
    moved[:, 0] += 250.0 * np.linspace(0, 1, len(frames))  # and a walk
    moved[:, 2] -= 80.0
    np.testing.assert_allclose(targets_of(moved, arm).raw, targets_of(frames, arm).raw, atol=1e-9)


def test_a_fixed_forward_axis_follows_the_world_instead(arm):
    frames = random_frames(4)
    moved = frames.copy()
    moved[:, 3] += 90.0
    fixed = MappingConfig(forward=Axis.PZ)
    assert not np.allclose(targets_of(moved, arm, fixed).raw, targets_of(frames, arm, fixed).raw, atol=1e-3)
    # translation alone still does not matter: only the wrist relative to the shoulder is used
    walked = frames.copy()
    walked[:, 0] += 100.0
    np.testing.assert_allclose(targets_of(walked, arm, fixed).raw, targets_of(frames, arm, fixed).raw, atol=1e-9)


def t_pose(n: int = 3) -> np.ndarray:
    frames = np.zeros((n, 6 + 3 * (len(JOINTS) - 1)))
    frames[:, 1] = 95.0
    return frames


@pytest.mark.parametrize(
    ("side", "forward", "sign"),
    [("right", "auto", -1.0), ("left", "auto", 1.0), ("right", "+z", -1.0), ("right", "-z", 1.0)],
    ids=["right-auto", "left-auto", "right-fixed+z", "right-fixed-z"],
)
def test_t_pose_arm_points_sideways_on_the_robot(arm, side, forward, sign):
    """In the T-pose the right arm points to the body's right: the robot's -y (its right), scaled to arm_scale."""
    config = MappingConfig.from_table({"side": side, "forward": forward, "arm_scale": 0.3})
    targets = targets_of(t_pose(), arm, config)
    g = arm_geometry(arm)
    origin = default_origin(config, g)
    expected = origin + np.array([0.0, sign * 0.3 * g.reach, 0.0])
    np.testing.assert_allclose(targets.raw, np.broadcast_to(expected, (3, 3)), atol=1e-9)


def test_arm_reaching_forward_maps_in_front(arm):
    frames = t_pose()
    right_arm = 6 + 3 * (next(i for i, j in enumerate(JOINTS) if j[0] == "RightArm") - 1)
    frames[:, right_arm + 2] = 90.0  # Yrotation +90 turns the arm from -X to +Z: forward
    targets = targets_of(frames, arm, MappingConfig(origin=(0.3, 0.0, 0.3), arm_scale=0.2))
    reach = arm_geometry(arm).reach
    np.testing.assert_allclose(targets.raw[0], [0.3 + 0.2 * reach, 0.0, 0.3], atol=1e-9)


def test_targets_outside_the_workspace_are_pulled_in_and_counted(arm):
    frames = random_frames(5)
    targets = targets_of(frames, arm, MappingConfig(arm_scale=0.8))
    ws = targets.workspace
    assert 0 < targets.n_clamped < targets.n_frames
    r = np.linalg.norm(targets.positions - ws.center, axis=1)
    assert np.all(r <= ws.r_max + 1e-9) and np.all(r >= ws.r_min - 1e-9)
    assert np.all(targets.positions[:, 2] >= ws.floor - 1e-12)
    untouched = ~targets.clamped
    np.testing.assert_array_equal(targets.positions[untouched], targets.raw[untouched])
    assert np.all(np.linalg.norm(targets.positions[targets.clamped] - targets.raw[targets.clamped], axis=1) > 0)


def test_hand_orientation_gives_rotation_targets(arm):
    frames = random_frames(6)
    targets = targets_of(frames, arm, MappingConfig(orientation_weight=0.5))
    R = targets.rotations
    assert R is not None and R.shape == (targets.n_frames, 3, 3)
    np.testing.assert_allclose(R @ np.swapaxes(R, -1, -2), np.broadcast_to(np.eye(3), R.shape), atol=1e-9)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-9)
    # T-pose: tool x along the right hand (robot -y), tool z up
    Rt = targets_of(t_pose(), arm, MappingConfig(orientation_weight=1.0)).rotations[0]
    np.testing.assert_allclose(Rt[:, 0], [0, -1, 0], atol=1e-9)
    np.testing.assert_allclose(Rt[:, 2], [0, 0, 1], atol=1e-9)
    assert targets_of(frames, arm).rotations is None


# --------------------------------------------------------------------------------------------- array level


def test_body_frames_are_right_handed_rotations():
    rng = np.random.default_rng(7)
    hips = rng.normal(size=(50, 3))
    left = hips + [0.2, 0.5, 0] + rng.normal(scale=0.05, size=(50, 3))
    right = hips + [-0.2, 0.5, 0] + rng.normal(scale=0.05, size=(50, 3))
    F = body_frames(hips, left, right)
    np.testing.assert_allclose(F @ np.swapaxes(F, -1, -2), np.broadcast_to(np.eye(3), F.shape), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(F), 1.0, atol=1e-12)
    assert np.all(F[:, 2, 0] > 0.5)  # facing +z when left is +x and up is +y
    with pytest.raises(ValueError, match="Expected a non-degenerate shoulder line"):
        body_frames(hips, left, left)


@pytest.fixture
def ws() -> Workspace:
    return Workspace(center=np.array([0.0, 0.0, 0.1]), r_min=0.1, r_max=0.5, floor=0.02)


@pytest.mark.parametrize(
    ("point", "expected"),
    [
        ((0.3, 0.0, 0.2), (0.3, 0.0, 0.2)),  # inside: untouched
        ((1.0, 0.0, 0.1), (0.5, 0.0, 0.1)),  # too far: along the ray
        ((0.0, 0.03, 0.1), (0.0, 0.1, 0.1)),  # too close: pushed out along the ray
        ((0.3, 0.0, -0.05), (0.3, 0.0, 0.02)),  # below the floor: lifted
        ((0.0, 0.0, 0.1), (0.1, 0.0, 0.1)),  # at the centre: pushed forward
    ],
    ids=["inside", "far", "near", "floor", "centre"],
)
def test_workspace_clamp(ws, point, expected):
    out, moved = ws.clamp(np.array([point]))
    np.testing.assert_allclose(out[0], expected, atol=1e-12)
    assert bool(moved[0]) == (point != expected)


def test_workspace_clamp_far_and_below_floor_lands_on_the_rim(ws):
    out, moved = ws.clamp(np.array([[2.0, 0.0, -1.0]]))
    assert moved[0]
    assert out[0, 2] == pytest.approx(0.02)
    assert np.linalg.norm(out[0] - ws.center) == pytest.approx(0.5)
    with pytest.raises(ValueError, match=r"Expected points of shape \(\.\.\., 3\), got \(4, 2\)"):
        ws.clamp(np.zeros((4, 2)))


def test_sampling_hits_frames_and_interpolates_between(arm):
    raw = np.array([[0.3, 0.0, 0.2], [0.3, 0.1, 0.2], [0.4, 0.1, 0.3]])
    targets = Targets.from_raw(raw, frame_time=0.5, workspace=Workspace.for_arm(arm))
    pos, rot, clamped = targets.sample(np.array([0.0, 0.25, 0.5, 1.0, 5.0]))
    expected = [[0.3, 0, 0.2], [0.3, 0.05, 0.2], [0.3, 0.1, 0.2], [0.4, 0.1, 0.3], [0.4, 0.1, 0.3]]
    np.testing.assert_allclose(pos, expected)
    assert rot is None and not clamped.any()
    with pytest.raises(ValueError, match=r"Expected raw targets of shape \(n_frames, 3\), got \(3,\)"):
        Targets.from_raw(raw[0], frame_time=0.5, workspace=targets.workspace)
    with pytest.raises(ValueError, match="Expected a frame time > 0 s, got 0"):
        Targets.from_raw(raw, frame_time=0, workspace=targets.workspace)


# ---------------------------------------------------------------------------------- fixed frames, IK weights, geometry


def test_fixed_forward_must_be_horizontal(arm):
    with pytest.raises(ConfigError, match=r"mapping\.forward: Expected a forward axis perpendicular to up \(\+y\)"):
        targets_of(t_pose(), arm, MappingConfig(forward=Axis.PY))


def test_default_ik_weights_hold_roll_joints_and_damp_the_wrist(arm):
    w = ik_weights(arm, MappingConfig())
    np.testing.assert_array_equal(w, [1.0, 1.0, 1.0, ROLL_WEIGHT, WRIST_WEIGHT, ROLL_WEIGHT])
    np.testing.assert_array_equal(ik_weights(arm, MappingConfig(orientation_weight=1.0)), np.ones(6))
    named = MappingConfig.from_table({"joint_weights": {"forearm_roll": 0.5}})
    assert ik_weights(arm, named)[3] == 0.5
    every = MappingConfig.from_table({"joint_weights": [1, 1, 1, 1, 1, 1]})
    np.testing.assert_array_equal(ik_weights(arm, every), np.ones(6))
    px100 = retarget.load_arm("px100")
    np.testing.assert_array_equal(ik_weights(px100, MappingConfig()), [1.0, 1.0, 1.0, WRIST_WEIGHT])


@pytest.mark.parametrize(
    ("table", "match"),
    [
        ({"joint_weights": {"wrist": 0.5}}, r"mapping\.joint_weights\.wrist: unknown joint; expected one of waist"),
        ({"joint_weights": [1, 1]}, r"mapping\.joint_weights: Expected 6 joint weights \(got \[1\.0, 1\.0\]\)"),
    ],
    ids=["unknown-joint", "count"],
)
def test_bad_joint_weights(arm, table, match):
    with pytest.raises(ConfigError, match=match):
        ik_weights(arm, MappingConfig.from_table(table))


def test_arm_geometry(arm):
    g = arm_geometry(arm)
    np.testing.assert_allclose(g.pivot, [0.0, 0.0, 0.072 + 0.03865])
    upper = np.hypot(0.04975, 0.25)
    assert g.reach == pytest.approx(upper + 0.175 + 0.075 + 0.065 + 0.093575)


def test_the_robot_forward_comes_from_the_home_pose():
    koch = retarget.load_arm("koch")  # the community URDF points the arm along -x
    g = arm_geometry(koch)
    np.testing.assert_array_equal(g.forward, [-1.0, 0.0, 0.0])
    np.testing.assert_array_equal(g.basis(), [[-1, 0, 0], [0, -1, 0], [0, 0, 1]])
    np.testing.assert_array_equal(g.basis(Axis.PY)[:, 0], [0, 1, 0])
    origin = default_origin(MappingConfig(), g)
    assert origin[0] < g.pivot[0]  # in front of the Koch is behind its base x axis
    # T-pose right arm: the robot's right, whichever way it faces
    targets = targets_of(t_pose(), koch, MappingConfig(arm_scale=0.3))
    np.testing.assert_allclose(targets.raw[0] - origin, [0.0, 0.3 * g.reach, 0.0], atol=1e-9)
    turned = targets_of(t_pose(), koch, MappingConfig(arm_scale=0.3, robot_forward=Axis.PX))
    assert turned.raw[0, 1] < origin[1]


@pytest.mark.parametrize("seed", [0, 1, 2], ids=lambda s: f"seed{s}")
def test_the_scalar_clamp_and_sample_agree_with_the_vectorized_ones(ws, seed):
    rng = np.random.default_rng(seed)
    points = rng.uniform(-0.8, 0.8, size=(300, 3))
    points[:10] = ws.center + rng.normal(scale=1e-3, size=(10, 3))  # near the centre
    out, moved = ws.clamp(points)
    for p, o, m in zip(points, out, moved, strict=True):
        x, y, z, mm = ws.clamp_point(*p.tolist())
        np.testing.assert_allclose((x, y, z), o, atol=1e-12)
        assert mm == m
    raw = rng.uniform(-0.6, 0.6, size=(40, 3))
    targets = Targets.from_raw(raw, frame_time=0.1, workspace=ws)
    times = rng.uniform(-0.5, 4.5, size=50)
    positions, _, clamped = targets.sample(times)
    for t, p, c in zip(times, positions, clamped, strict=True):
        one, moved = targets.at(float(t))
        np.testing.assert_allclose(one, p, atol=1e-12)
        assert moved == c


# ------------------------------------------------------------------------------------- body frame fallbacks
#: tests.helpers.arm_skeleton names: Hips > Chest > Neck, {Left,Right}Shoulder (clavicle) > Arm > ForeArm > Hand
NAMES = {"left": "Left", "right": "Right", "clavicle": "{side}Shoulder", "upper": "{side}Arm", "fore": "{side}ForeArm"}
NAMES["hand"] = "{side}Hand"


def rig(*, arms: tuple[str, ...] = ("left", "right"), positions: tuple[str, ...] = (), legs: bool = True) -> J:
    """``arm_skeleton`` with only the arms of ``arms``, position channels on the joints named in ``positions``
    (as some exporters write every joint), and with or without legs."""
    root = arm_skeleton(NAMES)
    chest = root.children[0]
    gone = {f"{NAMES[s]}Shoulder" for s in ("left", "right") if s not in arms}
    chest.children = [c for c in chest.children if c.name not in gone]
    if not legs:
        root.children = [chest]
    for j in joints_in_order(root):
        if j.name in positions:
            j.channels = (*POS_XYZ, *ROT_ZXY)
    return root


def pose(root: J, n: int, values: dict[tuple[str, str], object] | None = None) -> np.ndarray:
    """``(n, n_channels)`` frames of ``root``: position channels at the joint's OFFSET, rotations 0, except
    ``values[(joint, channel)]`` (a number or ``(n,)`` per frame)."""
    values = values or {}
    cols = []
    for j in joints_in_order(root):
        for ch in j.channels:
            default = j.offset["XYZ".index(ch[0])] if ch.endswith("position") else 0.0
            cols.append(np.broadcast_to(np.asarray(values.get((j.name, ch), default), dtype=np.float64), (n,)))
    return np.stack(cols, axis=-1)


def moving(n: int = 40) -> dict[tuple[str, str], object]:
    """The torso walks, turns and bends, the left and right arms swing; the clavicles stay still."""
    t = np.linspace(0.0, 1.0, n)
    return {
        ("Hips", "Xposition"): 80 * t,
        ("Hips", "Yrotation"): 120 * t,
        ("Hips", "Xrotation"): 10 * np.sin(5 * t),
        ("Chest", "Xrotation"): 25 * np.sin(3 * t),
        ("Chest", "Yrotation"): 30 * np.cos(4 * t),
        ("LeftArm", "Zrotation"): 70 * np.sin(6 * t),
        ("LeftForeArm", "Yrotation"): 60 * t,
        ("RightArm", "Xrotation"): 50 * np.cos(5 * t),
    }


def angles(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Degrees between rotations ``a`` and ``b`` ``(n, 3, 3)``."""
    m = np.einsum("nji,njk->nik", a, b)
    return np.degrees(np.arccos(np.clip((np.trace(m, axis1=1, axis2=2) - 1) / 2, -1.0, 1.0)))


def test_body_frames_masked_flags_the_degenerate_frames():
    hips = np.zeros((4, 3))
    left = np.array([[1.0, 5, 0], [0, 5, 0], [0, 10, 0], [np.nan, 5, 0]])
    right = np.array([[-1.0, 5, 0], [0, 5, 0], [0, 2, 0], [-1, 5, 0]])  # fine, coincide, along the spine, NaN
    frames, ok = body_frames_masked(hips, left, right)
    assert ok.tolist() == [True, False, False, False]
    np.testing.assert_array_equal(frames[0], body_frames(hips[:1], left[:1], right[:1])[0])
    assert np.isnan(frames[1:]).all()
    with pytest.raises(ValueError, match="Expected a non-degenerate torso"):
        body_frames(hips[2:3], left[2:3], right[2:3])


def test_the_torso_joint_carries_the_shoulders():
    motion = parse_bvh(rig_text(rig(), pose(rig(), 1)))
    both = [motion.joint_index("LeftArm"), motion.joint_index("RightArm")]
    assert motion.joint_names[torso_joint(motion.parents, both)] == "Chest"
    assert motion.joint_names[torso_joint(motion.parents, both[:1])] == "Chest"  # it branches to the neck too


@pytest.mark.parametrize("seed", [0, 1, 2], ids=lambda s: f"seed{s}")
def test_spine_frames_match_the_shoulder_frames(seed):
    """The torso joint carries the shoulders: exact while the clavicles are still, a few degrees when they move."""
    for clavicles, tolerance in ((0.0, 1e-4), (1 / 3, 7.0)):  # still, then +-5 degrees
        frames = random_frames(seed)
        for i, (name, _, _) in enumerate(JOINTS):
            if name.endswith("Shoulder"):
                frames[:, 6 + 3 * (i - 1) : 9 + 3 * (i - 1)] *= clavicles
        motion = parse_bvh(bvh_text(frames))
        positions = motion.positions()
        rotations, _ = motion.global_transforms()
        left, right = motion.arm_points("left").points[:, 0], motion.arm_points("right").points[:, 0]
        hips = positions[:, 0]
        truth = body_frames(hips, left, right)
        t = torso_joint(motion.parents, [motion.joint_index("LeftArm"), motion.joint_index("RightArm")])
        assert motion.joint_names[t] == "Spine"
        good = np.ones(len(hips), dtype=bool)
        rest = motion.rest_positions()
        for offsets in (
            shoulder_offsets(positions[:, t], rotations[:, t], left, side="left", other_shoulder=right, good=good),
            shoulder_offsets(positions[:, t], rotations[:, t], left, side="left", spine_axis=rest[t] - rest[0]),
            shoulder_offsets(positions[:, t], rotations[:, t], right, side="right", spine_axis=rest[t] - rest[0]),
        ):
            spine, ok = spine_frames(hips, positions[:, t], rotations[:, t], offsets)
            assert ok.all()
            assert angles(truth, spine).max() < tolerance


@pytest.mark.parametrize("side", ["left", "right"])
def test_a_one_armed_rig_takes_its_body_frame_from_the_spine(arm, caplog, side):
    values = moving()
    both = parse_bvh(rig_text(rig(), pose(rig(), 40, values)))
    one = rig(arms=(side,), legs=False)  # no legs: the structure has no other limb to mistake for an arm
    motion = parse_bvh(rig_text(one, pose(one, 40, values)), path="one_arm.bvh")
    with caplog.at_level(logging.INFO, logger="retarget.mapping.geometry"):
        body = clip_body_frames(motion, motion.arm_points(side))
    assert body.count(FROM_SPINE) == 40 and body.torso == "Chest"
    truth = body_frames(
        both.positions()[:, 0], both.arm_points("left").points[:, 0], both.arm_points("right").points[:, 0]
    )
    np.testing.assert_allclose(body.frames, truth, atol=1e-9)
    [record] = caplog.records
    assert record.levelno == logging.INFO
    assert record.getMessage().startswith(f"one_arm.bvh: body frame from the spine, Chest carrying the {side} shoulder")
    config = MappingConfig(side=retarget.mapping.Side(side))
    np.testing.assert_allclose(
        retarget_targets(motion, arm, config).raw, retarget_targets(both, arm, config).raw, atol=1e-9
    )


def test_a_fixed_forward_axis_needs_no_other_arm(arm, caplog):
    one = rig(arms=("left",))
    motion = parse_bvh(rig_text(one, pose(one, 5, moving(5))))
    with caplog.at_level(logging.INFO, logger="retarget.mapping.geometry"):
        targets = retarget_targets(motion, arm, MappingConfig(side=retarget.mapping.Side.LEFT, forward=Axis.PZ))
    assert np.isfinite(targets.raw).all() and not caplog.records


def coinciding(n: int, bad: list[int]) -> dict[tuple[str, str], object]:
    """``moving(n)``, with both shoulders moved onto the chest (position channels of clavicles and upper arms) in
    the frames ``bad``."""
    values = moving(n)
    for name in ("LeftShoulder", "RightShoulder", "LeftArm", "RightArm"):
        j = next(j for j in joints_in_order(rig()) if j.name == name)
        for k, axis in enumerate("XYZ"):
            per_frame = np.full(n, float(j.offset[k]))
            per_frame[bad] = 0.0
            values[(name, f"{axis}position")] = per_frame
    return values


def test_frames_whose_shoulders_coincide_come_from_the_spine(arm, caplog):
    kinect = rig(positions=("LeftShoulder", "RightShoulder", "LeftArm", "RightArm"))
    bad = [0, 7, 8, 9, 39]
    motion = parse_bvh(rig_text(kinect, pose(kinect, 40, coinciding(40, bad))), path="kinect.bvh")
    reference = parse_bvh(rig_text(rig(), pose(rig(), 40, moving())))
    with caplog.at_level(logging.INFO, logger="retarget.mapping.geometry"):
        body = clip_body_frames(motion, motion.arm_points("right"))
    assert np.flatnonzero(body.source == FROM_SPINE).tolist() == bad and body.count(FROM_SHOULDERS) == 35
    truth = clip_body_frames(reference, reference.arm_points("right")).frames
    np.testing.assert_allclose(body.frames, truth, atol=1e-9)  # the clavicles are still: the spine frames are exact
    [record] = caplog.records
    assert record.levelno == logging.WARNING
    assert "kinect.bvh: the shoulders RightArm and LeftArm coincide or line up with the spine in 5 of 40" in (
        record.getMessage()
    )
    assert np.isfinite(retarget_targets(motion, arm).raw).all()


def test_frames_with_no_body_frame_hold_the_previous_good_one(caplog):
    """Shoulders on the chest, and the chest moved so far down that the hips sit between them: no frame at all."""
    kinect = rig(positions=("Chest", "LeftShoulder", "RightShoulder", "LeftArm", "RightArm"))
    bad = [0, 1, 5, 6]
    values = coinciding(10, bad)
    chest_y = np.full(10, 30.0)
    chest_y[bad] = -17.0  # the shoulders' mean offset from the chest is (0, 17, 0): their midpoint lands on the hips
    values[("Chest", "Yposition")] = chest_y
    for channel in ("Xrotation", "Yrotation"):  # and the chest turns with the hips
        values[("Chest", channel)] = np.where(np.isin(np.arange(10), bad), 0.0, values[("Chest", channel)])
    motion = parse_bvh(rig_text(kinect, pose(kinect, 10, values)))
    with caplog.at_level(logging.INFO, logger="retarget.mapping.geometry"):
        body = clip_body_frames(motion, motion.arm_points("left"))
    assert body.source.tolist() == [HELD, HELD, 0, 0, 0, HELD, HELD, 0, 0, 0]
    for k, source in [(0, 2), (1, 2), (5, 4), (6, 4)]:  # the first good frame for the leading ones
        np.testing.assert_array_equal(body.frames[k], body.frames[source])
    assert "4 hold the previous good frame" in caplog.text


def test_hold_good_frames():
    values = np.arange(6.0)[:, None] * [1.0, 2.0]
    held = hold_good_frames(values, np.array([False, False, True, False, True, False]))
    np.testing.assert_array_equal(held[:, 0], [2, 2, 2, 2, 4, 4])
    with pytest.raises(ValueError, match="Expected at least one good frame, got none"):
        hold_good_frames(values, np.zeros(6, dtype=bool))


def test_no_body_frame_in_any_frame_is_a_bvh_error(arm):
    """Every joint placed by its position channels, the shoulders on the chest, and OFFSETs of zero (no rest pose)."""
    kinect = rig(positions=tuple(j.name for j in joints_in_order(rig())))
    for j in joints_in_order(kinect):
        j.offset = (0.0, 0.0, 0.0)
    values = {("Chest", "Yposition"): 30.0, ("LeftForeArm", "Xposition"): 28.0, ("RightForeArm", "Xposition"): -28.0}
    values |= {("LeftHand", "Xposition"): 25.0, ("RightHand", "Xposition"): -25.0}
    motion = parse_bvh(rig_text(kinect, pose(kinect, 3, values)), path="zeros.bvh")
    match = (
        r"^zeros\.bvh: Expected a torso for the body frame in at least one of the 3 frames, got none: the shoulders "
        r"LeftArm and RightArm and the spine \(Chest\) coincide"
    )
    with pytest.raises(BvhError, match=match):
        retarget_targets(motion, arm, MappingConfig(side=retarget.mapping.Side.LEFT))
    assert retarget_targets(motion, arm, MappingConfig(forward=Axis.PZ)).n_frames == 3  # no torso needed


def test_a_clip_without_frames_is_a_bvh_error(arm):
    motion = parse_bvh(rig_text(rig(), np.zeros((0, 0)), n_frames=0), path="template.bvh")
    assert motion.n_frames == 0
    with pytest.raises(BvhError, match=r"^template\.bvh: Expected at least one frame of motion, got Frames: 0") as info:
        retarget_targets(motion, arm)
    assert info.value.path == "template.bvh" and isinstance(info.value, ValueError)


def test_a_zero_length_arm_is_a_bvh_error(arm, monkeypatch):
    kinect = rig(positions=("LeftForeArm", "LeftHand"))
    values = {(name, f"{axis}position"): 0.0 for name in ("LeftForeArm", "LeftHand") for axis in "XYZ"}
    motion = parse_bvh(rig_text(kinect, pose(kinect, 4, values)), path="folded.bvh")
    # the skeleton detection may refuse the folded arm first, in its own words; either way one BvhError naming it
    with pytest.raises(BvhError, match=r"^folded\.bvh: Expected .*LeftArm > LeftForeArm"):
        retarget_targets(motion, arm, MappingConfig(side=retarget.mapping.Side.LEFT))
    assert retarget_targets(motion, arm).n_frames == 4  # the right arm is fine
    # the mapping's own check, whatever the detection lets through
    right = motion.arm_points("right")
    folded = ArmChain("right", right.names, right.indices, False, np.zeros((4, 3, 3)))
    monkeypatch.setattr(motion, "arm_points", lambda side, **_: folded if side == "right" else right)
    match = r"^folded\.bvh: Expected a right arm of positive length, got 0 .* for RightArm > RightForeArm > RightHand$"
    with pytest.raises(BvhError, match=match) as info:
        retarget_targets(motion, arm)
    assert info.value.path == "folded.bvh" and isinstance(info.value, ValueError)


def test_hand_orientation_with_a_zero_length_hand_bone(arm):
    """CMU hands: the finger joints sit on the wrist (zero OFFSET); the tool x follows the forearm instead."""
    root = rig()
    for j in joints_in_order(root):
        if j.name.endswith("Hand"):
            j.children = [J(j.name + "Finger", (0.0, 0.0, 0.0), end=(4.0, 0.0, 0.0))]
            j.end = None
    motion = parse_bvh(rig_text(root, pose(root, 3)))
    rotations = retarget_targets(motion, arm, MappingConfig(orientation_weight=1.0)).rotations
    assert rotations is not None and np.isfinite(rotations).all()
    np.testing.assert_allclose(rotations[0][:, 0], [0, -1, 0], atol=1e-9)  # T-pose: along the right arm
