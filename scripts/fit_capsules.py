"""Fit the ``[collision]`` shapes of a bundled arm file to its vendor's meshes (prints TOML to paste).

Usage (the meshes are read from the vendor's repository, never committed here)::

    git clone https://github.com/ROBOTIS-GIT/open_manipulator            # @ 3fd6fa9
    python scripts/fit_capsules.py omx --repo open_manipulator
    python scripts/fit_capsules.py koch --repo koch-v1-1                  # s1lent4gnt/koch-v1-1 @ cc1a4eb
    python scripts/fit_capsules.py wx250s --repo interbotix_ros_manipulators   # @ 0bb2b0e (also vx300s, px100)

``--repo`` is a checkout or a bare git directory (files are then read with ``git show REV:path``).

Each mesh is placed in its link's frame (the child frame of the joint named by ``frame``, as in the arm file) by
its URDF ``<collision><origin>`` (and any fixed joints between), optionally cut to a slab of one axis.  A box is
the bounding box; a capsule is the smallest by volume found along a fixed axis that encloses every vertex (the
segment trimmed from each end in 1 % steps of its length, up to 30 %), both grown by 0.5 mm.  Moving parts
(gripper fingers, jaws) are the union of the mesh over their travel.
"""

from __future__ import annotations

import argparse
import struct
import subprocess
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from math import pi
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from retarget.arm.kinematics import transform  # noqa: E402

MARGIN = 0.0005  # metres added to every radius and half size
Z90 = (0.0, 0.0, pi / 2)
Vec = tuple[float, float, float]


@dataclass(frozen=True)
class Mesh:
    """One mesh file placed in the link frame: ``pre @ transform(xyz, rpy)`` applied to its vertices."""

    path: str
    xyz: Vec = (0.0, 0.0, 0.0)
    rpy: Vec = (0.0, 0.0, 0.0)
    pre: Vec = (0.0, 0.0, 0.0)  # a translation applied after (a fixed joint or a finger's travel)
    scale: float = 0.001
    spin: tuple[Vec, Vec, float] | None = None  # (point, axis, angle): a rotation about a joint after placing


@dataclass(frozen=True)
class Part:
    name: str
    frame: str
    meshes: tuple[Mesh, ...]
    axis: Vec | None = None  # capsule axis; None = a box
    cut: tuple[int, float, float] | None = None  # keep vertices with lo <= p[axis] < hi (cuts of one
    # mesh overlap, so that a face crossing the cut has both ends in one part)
    note: str = ""


@dataclass
class Arm:
    repo: str
    parts: list[Part] = field(default_factory=list)


# -- the Interbotix X-series arms (interbotix_xsarm_descriptions, urdf/<arm>.urdf.xacro) --------------------------
def _interbotix(arm: str) -> Arm:
    d = f"interbotix_ros_xsarms/interbotix_xsarm_descriptions/meshes/{arm}_meshes/{arm}"
    out = Arm("Interbotix/interbotix_ros_manipulators @ 0bb2b0e")
    P = out.parts.append
    if arm == "px100":
        P(Part("base", "base", (Mesh(f"{d}_1_base.stl", rpy=Z90),)))
        P(Part("shoulder", "waist", (Mesh(f"{d}_2_shoulder.stl", (0, 0, -0.0022), Z90),)))
        P(Part("upper_arm", "shoulder", (Mesh(f"{d}_3_upper_arm.stl", rpy=Z90),), (0.15, 0, 1)))
        P(Part("forearm", "elbow", (Mesh(f"{d}_4_forearm.stl", rpy=Z90),), (1, 0, 0)))
        body = tuple(Mesh(f"{d}_{k}.stl", rpy=Z90) for k in ("5_gripper", "6_gripper_prop", "7_gripper_bar"))
        P(Part("gripper", "wrist_angle", body, (0, 1, 0)))
        fingers = (
            Mesh(f"{d}_8_gripper_finger.stl", (0, 0.005, 0), (pi, pi, 0), (0.086, 0.037, 0)),
            Mesh(f"{d}_8_gripper_finger.stl", (0, -0.005, 0), (0, pi, 0), (0.086, -0.037, 0)),
        )
        P(Part("fingers", "wrist_angle", fingers, (0, 1, 0)))
        return out
    wx = arm == "wx250s"
    ee, bar, fing = (0.043, 0.023, 0.037) if wx else (0.042825, 0.025875, 0.057)
    x0, zc = (-0.062, 0.2165) if wx else (-0.12, 0.262)
    base = (Mesh(f"{d}_1_base.stl", rpy=Z90),)
    P(Part("base", "base", base, cut=(0, x0, 1.0)))
    P(Part("base_rear", "base", base, cut=(0, -1.0, x0)))
    P(Part("shoulder", "waist", (Mesh(f"{d}_2_shoulder.stl", (0, 0, -0.003), Z90),)))
    ua = (Mesh(f"{d}_3_upper_arm.stl", rpy=Z90),)
    if wx:
        P(Part("upper_arm", "shoulder", ua, (0.04, 0, 1), cut=(2, -1.0, zc)))
        P(Part("elbow_bracket", "shoulder", ua, (0, 1, 0), cut=(2, zc, 1.0)))
    else:
        P(Part("shoulder_bracket", "shoulder", ua, (0, 1, 0), cut=(2, -1.0, 0.064)))
        P(Part("upper_arm", "shoulder", ua, (0.04, 0, 1), cut=(2, 0.02, zc)))
    P(Part("upper_forearm", "elbow", (Mesh(f"{d}_4_upper_forearm.stl"),), (1, 0, 0)))
    P(Part("lower_forearm", "forearm_roll", (Mesh(f"{d}_5_lower_forearm.stl", rpy=(pi, 0, 0)),), (1, 0, 0)))
    P(Part("wrist", "wrist_angle", (Mesh(f"{d}_6_wrist.stl", rpy=Z90),), (1, 0, 0)))
    body = tuple(Mesh(f"{d}_{k}.stl", (-0.02, 0, 0), Z90) for k in ("7_gripper", "8_gripper_prop", "9_gripper_bar"))
    P(Part("gripper", "wrist_rotate", body, (0, 1, 0)))
    f = f"{d}_10_gripper_finger.stl"
    if wx:
        fingers = (
            Mesh(f, (0, 0.005, 0), (pi, pi, 0), (ee + bar, fing, 0)),
            Mesh(f, (0, -0.005, 0), (0, pi, 0), (ee + bar, -fing, 0)),
        )
    else:
        fingers = (
            Mesh(f, (-0.0404, -0.0575, 0), (pi / 2, -pi, pi / 2), (ee + bar, fing, 0)),
            Mesh(f, (-0.0404, 0.0575, 0), (-pi / 2, pi, -pi / 2), (ee + bar, -fing, 0)),
        )
    P(Part("fingers", "wrist_rotate", fingers, (0, 1, 0), note="fully open"))
    return out


# -- ROBOTIS OpenMANIPULATOR-X (open_manipulator_description/urdf/open_manipulator_x/*.urdf.xacro) -------------------
def _omx() -> Arm:
    d = "open_manipulator_description/meshes/open_manipulator_x"
    out = Arm("ROBOTIS-GIT/open_manipulator @ 3fd6fa9")
    P = out.parts.append
    P(Part("base", "base", (Mesh(f"{d}/link1.stl"),)))
    P(Part("turntable", "joint1", (Mesh(f"{d}/link2.stl", (0, 0, 0.019)),)))
    link3 = (Mesh(f"{d}/link3.stl"),)  # the joint2 servo block (z < 0.042), then the rod and the joint3 servo
    P(Part("shoulder_bracket", "joint2", link3, (0, 1, 0), cut=(2, -1.0, 0.045)))
    P(Part("upper_arm", "joint2", link3, (0.2, 0, 1), cut=(2, 0.03, 1.0)))
    P(Part("forearm", "joint3", (Mesh(f"{d}/link4.stl"),), (1, 0, 0)))
    P(Part("wrist", "joint4", (Mesh(f"{d}/link5.stl"),), (0, 1, 0), cut=(0, -1.0, 0.032)))
    P(Part("gripper", "joint4", (Mesh(f"{d}/link5.stl"),), (0, 1, 0), cut=(0, 0.032, 1.0)))
    # gripper_{left,right}_joint: prismatic at (0.0817, +-0.021, 0), travel -0.011..0.02 m along +-y
    palms = tuple(
        Mesh(f"{d}/gripper_{side}_palm.stl", pre=(0.0817, s * (0.021 + t), 0))
        for side, s in (("left", 1), ("right", -1))
        for t in (-0.011, 0.02)
    )
    P(Part("fingers", "joint4", palms, (0, 1, 0), note="the palms over their travel"))
    return out


# -- Koch v1.1 follower (s1lent4gnt/koch-v1-1 simulation/follower.urdf; meshes in metres, all origins 0) -------------
def _koch() -> Arm:
    d = "simulation/meshes"
    out = Arm("s1lent4gnt/koch-v1-1 @ cc1a4eb")
    P = out.parts.append

    def m(name: str) -> tuple[Mesh, Mesh]:
        return (Mesh(f"{d}/{name}.STL", scale=1.0), Mesh(f"{d}/{name}_motor.STL", scale=1.0))

    P(Part("base_plate", "base", m("base_link")[:1]))
    P(Part("base", "base", m("base_link")[1:]))
    P(Part("shoulder", "shoulder_pan", m("link_1")))
    link2 = m("link_2")  # the bracket round the shoulder_lift servo (z < 0.042), the arm, the elbow servo
    P(Part("shoulder_bracket", "shoulder_lift", link2[:1], (0, 1, 0), cut=(2, -1.0, 0.045)))
    P(Part("upper_arm", "shoulder_lift", link2, (0, 0, 1), cut=(2, 0.03, 1.0)))
    P(Part("forearm", "elbow_flex", m("link_3"), (1, 0, 0)))
    P(Part("wrist", "wrist_flex", m("link_4"), (1, 0, 0)))
    P(Part("gripper", "wrist_roll", m("link_5"), (1, 0, 0)))
    # joint_6 (the jaw): axis 0 0 -1 at (-0.01315, -0.0075, 0.0145) in link_5, range -1.60..0.032 rad
    jaw = tuple(
        Mesh(f"{d}/link_6.STL", pre=(-0.01315, -0.0075, 0.0145), scale=1.0,
             spin=((-0.01315, -0.0075, 0.0145), (0, 0, -1), a))
        for a in np.linspace(-1.60, 0.032, 9)
    )  # fmt: skip
    P(Part("jaw", "wrist_roll", jaw, (1, 0, 0), note="the jaw over its travel"))
    return out


ARMS: dict[str, Callable[[], Arm]] = {"omx": _omx, "koch": _koch, "wx250s": lambda: _interbotix("wx250s"),
        "vx300s": lambda: _interbotix("vx300s"), "px100": lambda: _interbotix("px100")}  # fmt: skip


# -- mesh reading and fitting -----------------------------------------------------------------------------------
def read_bytes(repo: Path, rev: str, path: str) -> bytes:
    if (repo / path).is_file():
        return (repo / path).read_bytes()
    return subprocess.run(
        ["git", "--git-dir", str(repo), "show", f"{rev}:{path}"], check=True, capture_output=True
    ).stdout


def stl_vertices(data: bytes) -> np.ndarray:
    """The distinct vertices ``(n, 3)`` of a binary or ASCII STL, in the file's units."""
    n = struct.unpack("<I", data[80:84])[0] if len(data) >= 84 else -1
    if len(data) == 84 + 50 * n:
        rec = np.dtype([("n", "<f4", 3), ("v", "<f4", (3, 3)), ("x", "<u2")])
        v = np.frombuffer(data, dtype=rec, count=n, offset=84)["v"].reshape(-1, 3)
    else:
        rows = [line.split()[1:4] for line in data.decode("ascii").splitlines() if line.strip().startswith("vertex")]
        v = np.array(rows, dtype=np.float64)
    return np.asarray(np.unique(v.astype(np.float64), axis=0), dtype=np.float64)


def _rotation(axis: Vec, angle: float) -> np.ndarray:
    k = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    R: np.ndarray = np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K
    return R


def place(mesh: Mesh, data: bytes) -> np.ndarray:
    """The mesh's vertices ``(n, 3)`` in its link frame, metres."""
    v = stl_vertices(data) * mesh.scale
    T = transform(mesh.pre, (0, 0, 0)) @ transform(mesh.xyz, mesh.rpy)
    p = v @ T[:3, :3].T + T[:3, 3]
    if mesh.spin is not None:
        c, axis, angle = mesh.spin
        p = (p - c) @ _rotation(axis, angle).T + c
    return np.asarray(p, dtype=np.float64)


def fit_capsule(P: np.ndarray, axis: Vec) -> tuple[np.ndarray, np.ndarray, float]:
    """The smallest capsule (by volume) along ``axis`` enclosing every point of ``P``: ends a, b and radius."""
    c = P.mean(0)
    u = np.asarray(axis, float) / np.linalg.norm(axis)
    t = (P - c) @ u
    span = t.max() - t.min()
    best = (np.inf, c, c, 0.0)
    for s0 in np.linspace(0, 0.6, 61):
        for s1 in np.linspace(0, 0.6, 61):
            lo, hi = t.min() + s0 * span / 2, t.max() - s1 * span / 2
            if lo > hi:
                continue
            r = float(np.linalg.norm(P - (c + np.clip(t, lo, hi)[:, None] * u), axis=1).max())
            vol = pi * r * r * (hi - lo) + 4 / 3 * pi * r**3
            if vol < best[0]:
                best = (vol, c + lo * u, c + hi * u, r)
    return best[1], best[2], best[3]


def _fmt(v: np.ndarray) -> str:
    return "[" + ", ".join(f"{x:.4f}".replace("-0.0000", "0.0000") for x in v) + "]"


def part_toml(part: Part, points: np.ndarray) -> str:
    if part.cut is not None:
        k, lo, hi = part.cut
        points = points[(points[:, k] >= lo) & (points[:, k] < hi)]
    head = f'[[collision.links]]\nname = "{part.name}"\nframe = "{part.frame}"\n'
    if part.axis is None:
        lo3, hi3 = points.min(0), points.max(0)
        return head + f"box = {{ center = {_fmt((lo3 + hi3) / 2)}, half_size = {_fmt((hi3 - lo3) / 2 + MARGIN)} }}\n"
    a, b, r = fit_capsule(points, part.axis)
    return head + f"capsule = {{ a = {_fmt(a)}, b = {_fmt(b)}, radius = {r + MARGIN:.4f} }}\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], epilog=__doc__.split("\n\n", 1)[1],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)  # fmt: skip
    ap.add_argument("arm", choices=sorted(ARMS))
    ap.add_argument("--repo", type=Path, required=True, help="the vendor repository: a checkout or a bare git dir")
    ap.add_argument("--rev", default="HEAD", help="revision to read from a bare git dir (default HEAD)")
    args = ap.parse_args(argv)
    arm = ARMS[args.arm]()
    print(f"# fitted by scripts/fit_capsules.py {args.arm} from {arm.repo}\n")
    for part in arm.parts:
        points = np.concatenate([place(m, read_bytes(args.repo, args.rev, m.path)) for m in part.meshes])
        if part.note:
            print(f"# {part.note}")
        print(part_toml(part, points))
    return 0


if __name__ == "__main__":
    sys.exit(main())
