"""Human -> arm mapping: invariances (units, rigid motion of the whole body), workspace clamp, IK weights, geometry."""

from __future__ import annotations

import numpy as np
import pytest

import retarget
from retarget.bvh import parse_bvh
from retarget.errors import ConfigError
from retarget.mapping.config import Axis, MappingConfig
from retarget.mapping.geometry import (
    ROLL_WEIGHT,
    WRIST_WEIGHT,
    Targets,
    Workspace,
    arm_geometry,
    body_frames,
    default_origin,
    ik_weights,
    retarget_targets,
)

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
