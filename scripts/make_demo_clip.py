"""Write the bundled demo clip ``retarget/bvh/data/demo.bvh``.

    python scripts/make_demo_clip.py            # rewrite retarget/bvh/data/demo.bvh
    python scripts/make_demo_clip.py -o x.bvh   # somewhere else

A ~10 s, 60 fps, centimetre clip on a small CMU-named skeleton (~170 cm,
Y up, facing +Z, T-pose rest): the right arm rests, reaches forward, reaches
up, waves, points forward-right and to the side, and comes back down, with
minimum-jerk moves between key poses, a little torso sway and a relaxed left
arm.  The output is deterministic (no randomness, no timestamps, fixed
number format), so re-running the script reproduces the committed file.

Arm poses are designed as world-frame bone directions and turned into BVH
rotations through the parent chain, so torso sway does not move the hand.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

FPS = 60
DURATION = 10.5  # seconds
OUT = Path(__file__).resolve().parent.parent / "retarget" / "bvh" / "data" / "demo.bvh"

# name, parent, offset (cm).  Rest pose: T-pose, Y up, facing +Z (the character's left is +X).
SKELETON: list[tuple[str, str | None, tuple[float, float, float]]] = [
    ("Hips", None, (0.0, 0.0, 0.0)),
    ("Spine", "Hips", (0.0, 10.0, 0.0)),
    ("Spine1", "Spine", (0.0, 18.0, 0.0)),
    ("Neck", "Spine1", (0.0, 22.0, -1.0)),
    ("Head", "Neck", (0.0, 9.0, 1.0)),
    ("LeftShoulder", "Spine1", (2.0, 15.0, 0.0)),
    ("LeftArm", "LeftShoulder", (16.0, 2.0, -1.0)),
    ("LeftForeArm", "LeftArm", (29.0, 0.0, 0.0)),
    ("LeftHand", "LeftForeArm", (25.0, 0.0, 0.0)),
    ("RightShoulder", "Spine1", (-2.0, 15.0, 0.0)),
    ("RightArm", "RightShoulder", (-16.0, 2.0, -1.0)),
    ("RightForeArm", "RightArm", (-29.0, 0.0, 0.0)),
    ("RightHand", "RightForeArm", (-25.0, 0.0, 0.0)),
    ("LeftUpLeg", "Hips", (9.0, -4.0, 0.0)),
    ("LeftLeg", "LeftUpLeg", (0.0, -43.0, 0.0)),
    ("LeftFoot", "LeftLeg", (0.0, -42.0, 0.0)),
    ("LeftToeBase", "LeftFoot", (0.0, -5.0, 13.0)),
    ("RightUpLeg", "Hips", (-9.0, -4.0, 0.0)),
    ("RightLeg", "RightUpLeg", (0.0, -43.0, 0.0)),
    ("RightFoot", "RightLeg", (0.0, -42.0, 0.0)),
    ("RightToeBase", "RightFoot", (0.0, -5.0, 13.0)),
]
END_SITES = {
    "Head": (0.0, 16.0, 0.0),
    "LeftHand": (17.0, 0.0, 0.0),
    "RightHand": (-17.0, 0.0, 0.0),
    "LeftToeBase": (0.0, 0.0, 5.0),
    "RightToeBase": (0.0, 0.0, 5.0),
}
HIP_HEIGHT = 94.0
ORDER = "ZYX"  # CHANNELS ... Zrotation Yrotation Xrotation, as CMU exports

# Right-arm key poses: (time s, upper-arm direction, forearm direction, hand flexion deg), world frame.
KEYS: list[tuple[float, tuple[float, float, float], tuple[float, float, float], float]] = [
    (0.0, (-0.10, -1.00, 0.05), (-0.05, -0.95, 0.30), 0.0),  # rest
    (1.0, (-0.10, -1.00, 0.05), (-0.05, -0.95, 0.30), 0.0),
    (2.2, (-0.12, -0.05, 1.00), (-0.05, 0.02, 1.00), -10.0),  # reach forward
    (2.8, (-0.12, 0.05, 1.00), (-0.05, 0.10, 1.00), -10.0),
    (3.9, (-0.20, 0.95, 0.25), (-0.10, 1.00, 0.15), 0.0),  # reach up
    (4.8, (-0.95, 0.15, 0.25), (-0.15, 1.00, 0.20), 0.0),  # to the wave pose
    (6.9, (-0.95, 0.15, 0.25), (-0.15, 1.00, 0.20), 0.0),  # (waving in between)
    (7.8, (-0.55, 0.20, 0.80), (-0.55, 0.22, 0.80), 5.0),  # point forward-right
    (8.4, (-0.55, 0.20, 0.80), (-0.55, 0.22, 0.80), 5.0),
    (9.2, (-1.00, 0.08, 0.15), (-1.00, 0.10, 0.15), 0.0),  # point to the side
    (10.5, (-0.10, -1.00, 0.05), (-0.05, -0.95, 0.30), 0.0),  # back to rest
]
WAVE = (4.9, 6.8, 3.0, 25.0)  # start s, end s, cycles, forearm swing amplitude deg


def minimum_jerk(u: np.ndarray) -> np.ndarray:
    """0 -> 1 with zero velocity and acceleration at both ends."""
    u = np.clip(u, 0.0, 1.0)
    return u**3 * (10.0 - 15.0 * u + 6.0 * u**2)


def unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def slerp(a: np.ndarray, b: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Unit vectors between ``a`` and ``b`` (3,) at fractions ``s`` (n,) -> (n, 3)."""
    a, b = unit(a), unit(b)
    omega = math.acos(float(np.clip(a @ b, -1.0, 1.0)))
    if omega < 1e-9:
        return np.tile(a, (len(s), 1))
    return (np.sin((1 - s) * omega)[:, None] * a + np.sin(s * omega)[:, None] * b) / math.sin(omega)


def axis_angle(axis, angle: np.ndarray) -> np.ndarray:
    """(n, 3, 3) rotations about a fixed axis by ``angle`` (n,) radians (Rodrigues)."""
    k = unit(axis)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    a = np.asarray(angle, dtype=np.float64)[:, None, None]
    return np.eye(3) + np.sin(a) * K + (1 - np.cos(a)) * (K @ K)


def rot_z(a):
    return axis_angle((0, 0, 1), a)


def rot_y(a):
    return axis_angle((0, 1, 0), a)


def rot_x(a):
    return axis_angle((1, 0, 0), a)


def align(rest_dir, target: np.ndarray) -> np.ndarray:
    """(n, 3, 3) shortest-arc rotations taking ``rest_dir`` (3,) onto ``target`` (n, 3)."""
    a = unit(rest_dir)
    b = unit(target)
    v = np.cross(a, b)
    c = b @ a
    K = np.zeros((len(b), 3, 3))
    K[:, 0, 1], K[:, 0, 2], K[:, 1, 0] = -v[:, 2], v[:, 1], v[:, 2]
    K[:, 1, 2], K[:, 2, 0], K[:, 2, 1] = -v[:, 0], -v[:, 1], v[:, 0]
    return np.eye(3) + K + (K @ K) / (1.0 + c)[:, None, None]


def to_euler_zyx(R: np.ndarray) -> np.ndarray:
    """(n, 3) degrees (z, y, x) with R = Rz @ Ry @ Rx."""
    y = np.arcsin(np.clip(-R[:, 2, 0], -1.0, 1.0))
    x = np.arctan2(R[:, 2, 1], R[:, 2, 2])
    z = np.arctan2(R[:, 1, 0], R[:, 0, 0])
    return np.degrees(np.stack([z, y, x], axis=1))


def key_track(t: np.ndarray, index: int) -> np.ndarray:
    """Minimum-jerk interpolation of key field ``index`` (a direction) over the times ``t``."""
    out = np.empty((len(t), 3))
    for (t0, *a), (t1, *b) in zip(KEYS[:-1], KEYS[1:], strict=True):
        sel = (t >= t0) & (t <= t1)
        out[sel] = slerp(np.array(a[index]), np.array(b[index]), minimum_jerk((t[sel] - t0) / (t1 - t0)))
    return out


def key_scalar(t: np.ndarray) -> np.ndarray:
    out = np.empty(len(t))
    for (t0, *_, a), (t1, *_, b) in zip(KEYS[:-1], KEYS[1:], strict=True):
        sel = (t >= t0) & (t <= t1)
        out[sel] = a + (b - a) * minimum_jerk((t[sel] - t0) / (t1 - t0))
    return out


def build_frames() -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Root positions (n, 3) and per-joint local rotations (n, 3, 3)."""
    n = int(round(DURATION * FPS))
    t = np.arange(n) / FPS
    ident = np.broadcast_to(np.eye(3), (n, 3, 3)).copy()
    local = {name: ident.copy() for name, _, _ in SKELETON}

    # torso: slow sway, a little breathing, turning slightly toward the working arm
    sway = np.radians(1.5) * np.sin(2 * np.pi * 0.23 * t)
    lean = np.radians(2.0) * np.sin(2 * np.pi * 0.11 * t + 0.4)
    turn = np.radians(-6.0) * minimum_jerk((t - 1.0) / 1.2) * (1 - minimum_jerk((t - 8.8) / 1.5))
    root = np.stack(
        [1.2 * np.sin(2 * np.pi * 0.23 * t + 0.3), HIP_HEIGHT + 0.4 * np.sin(2 * np.pi * 0.5 * t), 0.0 * t], axis=1
    )
    local["Hips"] = rot_y(turn * 0.4) @ rot_z(sway * 0.5)
    local["Spine"] = rot_x(lean) @ rot_z(sway)
    local["Spine1"] = rot_y(turn * 0.6) @ rot_x(np.radians(0.8) * np.sin(2 * np.pi * 0.25 * t))
    local["Neck"] = rot_y(-turn * 0.5)
    local["Head"] = rot_x(np.radians(3.0) * np.sin(2 * np.pi * 0.17 * t))

    def world(*chain: str) -> np.ndarray:
        g = ident.copy()
        for name in chain:
            g = g @ local[name]
        return g

    # right arm: designed in the world frame, expressed through the parent chain
    upper = key_track(t, 0)
    fore = key_track(t, 1)
    w0, w1, cycles, amp = WAVE
    env = minimum_jerk((t - w0) / 0.4) * (1 - minimum_jerk((t - (w1 - 0.4)) / 0.4))
    phase = 2 * np.pi * cycles * np.clip((t - w0) / (w1 - w0), 0.0, 1.0)
    fore = np.einsum("nij,nj->ni", rot_z(np.radians(amp) * env * np.sin(phase)), fore)
    lift = np.clip(upper[:, 1], 0.0, None)  # shrug the clavicle as the arm rises
    local["RightShoulder"] = rot_z(np.radians(-12.0) * lift)
    chest = world("Hips", "Spine", "Spine1", "RightShoulder")
    upper_world = align((-1.0, 0.0, 0.0), upper)
    local["RightArm"] = np.swapaxes(chest, 1, 2) @ upper_world
    fore_world = align((-1.0, 0.0, 0.0), fore)
    local["RightForeArm"] = np.swapaxes(upper_world, 1, 2) @ fore_world
    flex = np.radians(key_scalar(t)) + np.radians(12.0) * env * np.sin(phase - 0.8)
    local["RightHand"] = rot_z(flex)

    # left arm: relaxed, a slight swing
    swing = np.radians(4.0) * np.sin(2 * np.pi * 0.23 * t + 1.0)
    lchest = world("Hips", "Spine", "Spine1", "LeftShoulder")
    lupper_world = align((1.0, 0.0, 0.0), unit(np.stack([0.12 + 0 * t, -1.0 + 0 * t, 0.03 + swing], axis=1)))
    local["LeftArm"] = np.swapaxes(lchest, 1, 2) @ lupper_world
    lfore_world = align((1.0, 0.0, 0.0), unit(np.stack([0.06 + 0 * t, -0.95 + 0 * t, 0.25 + swing], axis=1)))
    local["LeftForeArm"] = np.swapaxes(lupper_world, 1, 2) @ lfore_world

    # legs: standing, knees soft, following the hip sway
    for side in ("Left", "Right"):
        local[f"{side}UpLeg"] = rot_z(-sway * 0.5) @ rot_x(np.radians(-4.0) + 0 * t)
        local[f"{side}Leg"] = rot_x(np.radians(7.0) + 0 * t)
        local[f"{side}Foot"] = rot_x(np.radians(-3.0) + 0 * t)
    return root, local


def fmt(v: float) -> str:
    text = f"{v:.3f}".rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


def write(path: Path) -> None:
    root, local = build_frames()
    n = len(root)
    children: dict[str | None, list[str]] = {}
    for name, parent, _ in SKELETON:
        children.setdefault(parent, []).append(name)
    offsets = {name: off for name, _, off in SKELETON}
    axis_names = " ".join(f"{a}rotation" for a in ORDER)
    lines = ["HIERARCHY"]

    def emit(name: str, depth: int) -> None:
        pad = "  " * depth
        kind = "ROOT" if depth == 0 else "JOINT"
        lines.append(f"{pad}{kind} {name}")
        lines.append(f"{pad}{{")
        lines.append(f"{pad}  OFFSET {' '.join(fmt(v) for v in offsets[name])}")
        if depth == 0:
            lines.append(f"{pad}  CHANNELS 6 Xposition Yposition Zposition {axis_names}")
        else:
            lines.append(f"{pad}  CHANNELS 3 {axis_names}")
        for child in children.get(name, []):
            emit(child, depth + 1)
        if name in END_SITES:
            lines.append(f"{pad}  End Site")
            lines.append(f"{pad}  {{")
            lines.append(f"{pad}    OFFSET {' '.join(fmt(v) for v in END_SITES[name])}")
            lines.append(f"{pad}  }}")
        lines.append(f"{pad}}}")

    emit("Hips", 0)
    lines += ["MOTION", f"Frames: {n}", f"Frame Time: {1.0 / FPS:.7f}"]
    euler = {name: to_euler_zyx(local[name]) for name, _, _ in SKELETON}
    order = [name for name, _, _ in _file_order(children)]
    for i in range(n):
        values = list(root[i])
        for name in order:
            values += list(euler[name][i])
        lines.append(" ".join(fmt(v) for v in values))
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(lines) + "\n", encoding="ascii", newline="\n")


def _file_order(children: dict[str | None, list[str]]) -> list[tuple[str, int, None]]:
    out: list[tuple[str, int, None]] = []

    def walk(name: str, depth: int) -> None:
        out.append((name, depth, None))
        for child in children.get(name, []):
            walk(child, depth + 1)

    walk("Hips", 0)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-o", "--output", type=Path, default=OUT, help=f"where to write (default {OUT})")
    args = parser.parse_args()
    write(args.output)
    print(f"wrote {args.output}")


if __name__ == "__main__":
    main()
