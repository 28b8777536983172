"""Fit the ``[collision]`` shapes of a bundled arm file to its vendor's meshes (prints TOML to paste).

Usage (the meshes are read from the vendor's repository, never committed here)::

    git clone https://github.com/ROBOTIS-GIT/open_manipulator            # @ 3fd6fa9
    python scripts/fit_capsules.py omx --repo open_manipulator
    python scripts/fit_capsules.py wx250s --repo interbotix_ros_manipulators   # @ 0bb2b0e (also vx300s, px100)
    git clone --bare https://github.com/s1lent4gnt/koch-v1-1              # community URDF and meshes
    python scripts/fit_capsules.py koch --repo koch-v1-1.git --rev cc1a4eb   # ~10 s; its check's report on stderr

``--repo`` is a checkout or a bare git directory (files are then read with ``git show REV:path``); a checkout is
read as it is, so check out the commit named above first.  The output is the arm file's ``[[collision.links]]``.

Each mesh is placed in its link's frame (the child frame of the joint named by ``frame``, as in the arm file) by
its URDF ``<collision><origin>`` (and any fixed joints between), optionally cut to a slab of one axis.  A box is
the bounding box; a capsule is the smallest by volume found along a fixed axis that encloses every vertex (the
segment trimmed from each end by 0 to 30 % of the points' span, 61 trims a side), both grown by 0.5 mm.  Moving
parts (gripper fingers, jaws) are the union of the mesh over their travel.

The Koch (``Fit(centre="circle", trims=41, grid=0.0001)``, the only arm fitted so) differs: the axis line passes
through the centre of the smallest circle holding the part's points seen along the axis, not through their
centroid; the capsule of least volume over the part's candidate axes wins; 41 trims a side.  Then each link
frame's capsules are grown alike until every triangle of the frame's meshes lies in one of them or, sampled on a
1/8 barycentric grid, in their union (by the excess + 0.01 mm); a part's ``shrink`` is taken off (a capsule that
its neighbours mostly cover); the ends are rounded to 0.1 mm and each radius + 0.087 mm (the farthest that moves
a point of the segment) rounded up to 0.1 mm; and the frame is checked again on a 1/64 grid, its capsules grown
in 0.1 mm steps until it passes.
"""

from __future__ import annotations

import argparse
import math
import struct
import subprocess
import sys
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from functools import cache
from math import pi
from pathlib import Path
from typing import Literal

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from retarget.arm.kinematics import transform  # noqa: E402

MARGIN = 0.0005  # metres added to every radius and half size
Z90 = (0.0, 0.0, pi / 2)
Vec = tuple[float, float, float]
X, Y, Z = (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)
Capsule = tuple[np.ndarray, np.ndarray, float]  # ends a, b (3,) and radius, metres, in the link frame


@dataclass(frozen=True)
class Mesh:
    """One mesh file placed in the link frame: ``pre @ transform(xyz, rpy)`` applied to its vertices."""

    path: str
    xyz: Vec = (0.0, 0.0, 0.0)
    rpy: Vec = (0.0, 0.0, 0.0)
    pre: Vec = (0.0, 0.0, 0.0)  # a translation applied after (a fixed joint or a finger's travel)
    scale: float = 0.001
    hub: tuple[float, float] | None = None  # keep vertices lo <= hypot(x, y) < hi (metres) in the mesh's own frame:
    # their distance from its joint's z axis (for fitting only; the Koch check takes the whole mesh)


@dataclass(frozen=True)
class Part:
    name: str
    frame: str
    meshes: tuple[Mesh, ...]
    axis: Vec | None = None  # capsule axis; None (and no axes) = a box
    cut: tuple[int, float, float] | None = None  # keep vertices with lo <= p[axis] < hi (cuts of one
    # mesh overlap, so that a face crossing the cut has both ends in one part)
    note: str = ""
    axes: tuple[Vec, ...] = ()  # more candidate axes: the capsule of least volume wins
    shrink: float = 0.0  # metres off the radius before rounding (with Fit.grid only; the frame's check must pass)

    @property
    def candidates(self) -> tuple[Vec, ...]:
        return ((self.axis,) if self.axis is not None else ()) + self.axes


@dataclass(frozen=True)
class Fit:
    """How an arm's capsules are fitted (the default is the first arms', kept so that they print the same)."""

    centre: Literal["mean", "circle"] = "mean"  # the axis line through the points' centroid or smallest circle
    trims: int = 61  # trims tried from each end, 0 to 30 % of the span
    grid: float = 0.0  # metres: ends rounded to it, radii up, each frame checked (0 = printed as fitted)


@dataclass
class Arm:
    repo: str
    parts: list[Part] = field(default_factory=list)
    fit: Fit = Fit()


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
PIVOT = (-0.01315, -0.0075, 0.0145)  # joint_6 (the jaw) origin in link_5; its axis 0 0 -1
TRAVEL = (-1.60, 0.032)  # the jaw's range, radians (MuJoCo Menagerie; the URDF says -2.45..0.032)
PLANE = tuple((float(np.cos(t)), float(np.sin(t)), 0.0) for t in np.linspace(0, pi, 12, endpoint=False))  # 15 deg


def _koch() -> Arm:
    d = "simulation/meshes"
    out = Arm("s1lent4gnt/koch-v1-1 @ cc1a4eb", fit=Fit(centre="circle", trims=41, grid=0.0001))
    P = out.parts.append

    def m(name: str) -> tuple[Mesh, Mesh]:
        return (Mesh(f"{d}/{name}.STL", scale=1.0), Mesh(f"{d}/{name}_motor.STL", scale=1.0))

    def jaw(lo: float, hi: float, n: int, hub: tuple[float, float]) -> tuple[Mesh, ...]:
        """link_6 turned by joint_6 to n angles lo..hi (radians, about -z: rpy yaw -angle)."""
        return tuple(Mesh(f"{d}/link_6.STL", PIVOT, (0, 0, -a), scale=1.0, hub=hub) for a in np.linspace(lo, hi, n))

    P(Part("base_plate", "base", m("base_link")[:1]))
    P(Part("base", "base", m("base_link")[1:]))
    P(Part("shoulder", "shoulder_pan", m("link_1")))
    link2 = m("link_2")  # the bracket round the shoulder_lift servo (z < 0.042), the arm, the elbow servo (z > 0.098)
    P(Part("shoulder_bracket", "shoulder_lift", link2[:1], Y, cut=(2, -1.0, 0.045)))
    P(Part("upper_arm", "shoulder_lift", link2, Z, cut=(2, 0.03, 1.0)))
    P(Part("forearm", "elbow_flex", m("link_3"), X))
    P(Part("wrist", "wrist_flex", m("link_4"), X))
    body = m("link_5") + jaw(*TRAVEL, 65, (0.0, 0.014))  # the hub's points all lie at x > -0.024
    note = "the jaw servo, the plate behind it and the jaw's hub (within 14 mm of its pivot) over its travel"
    P(Part("gripper", "wrist_roll", body, X, cut=(0, -0.026, 1.0), note=note, axes=(Y, Z)))
    P(Part("finger", "wrist_roll", m("link_5"), X, cut=(0, -1.0, -0.024), note="the fixed finger", axes=PLANE))
    edges = np.linspace(*TRAVEL, 4)
    for i, (lo, hi) in enumerate(zip(edges[:-1], edges[1:], strict=True)):
        note = f"the jaw beyond 12 mm of its pivot over {lo:.3f}..{hi:.3f} rad"
        note += "; 6 mm thinner: jaw0 and jaw2 hold most of it" if i == 1 else ""
        P(Part(f"jaw{i}", "wrist_roll", jaw(lo, hi, 23, (0.012, 1.0)), note=note, axes=PLANE, shrink=0.006 * (i == 1)))
    return out


ARMS: dict[str, Callable[[], Arm]] = {"omx": _omx, "koch": _koch, "wx250s": lambda: _interbotix("wx250s"),
        "vx300s": lambda: _interbotix("vx300s"), "px100": lambda: _interbotix("px100")}  # fmt: skip


# -- mesh reading --------------------------------------------------------------------------------------------------
@cache
def read_bytes(repo: Path, rev: str, path: str) -> bytes:
    if (repo / path).is_file():
        return (repo / path).read_bytes()
    return subprocess.run(
        ["git", "--git-dir", str(repo), "show", f"{rev}:{path}"], check=True, capture_output=True
    ).stdout


def stl_triangles(data: bytes) -> np.ndarray:
    """The triangles ``(n, 3, 3)`` of a binary or ASCII STL, in the file's units."""
    n = struct.unpack("<I", data[80:84])[0] if len(data) >= 84 else -1
    if len(data) == 84 + 50 * n:
        rec = np.dtype([("n", "<f4", 3), ("v", "<f4", (3, 3)), ("x", "<u2")])
        v = np.frombuffer(data, dtype=rec, count=n, offset=84)["v"]
    else:
        rows = [line.split()[1:4] for line in data.decode("ascii").splitlines() if line.strip().startswith("vertex")]
        v = np.array(rows, dtype=np.float64)
    return np.asarray(v, dtype=np.float64).reshape(-1, 3, 3)


def stl_vertices(data: bytes) -> np.ndarray:
    """The distinct vertices ``(n, 3)`` of a binary or ASCII STL, in the file's units."""
    return np.asarray(np.unique(stl_triangles(data).reshape(-1, 3), axis=0), dtype=np.float64)


def place(mesh: Mesh, v: np.ndarray) -> np.ndarray:
    """Vertices ``(..., 3)`` of ``mesh`` (the file's units) in its link frame, metres."""
    T = transform(mesh.pre, (0, 0, 0)) @ transform(mesh.xyz, mesh.rpy)
    return np.asarray((v * mesh.scale) @ T[:3, :3].T + T[:3, 3], dtype=np.float64)


def part_points(part: Part, read: Callable[[str], bytes]) -> np.ndarray:
    """The vertices ``(n, 3)`` of a part in its link frame (metres), hubs and the cut applied."""
    pieces = []
    for mesh in part.meshes:
        v = stl_vertices(read(mesh.path))
        if mesh.hub is not None:
            rho = np.hypot(v[:, 0], v[:, 1]) * mesh.scale
            v = v[(rho >= mesh.hub[0]) & (rho < mesh.hub[1])]
        pieces.append(place(mesh, v))
    points = np.concatenate(pieces)
    if part.cut is not None:
        k, lo, hi = part.cut
        points = points[(points[:, k] >= lo) & (points[:, k] < hi)]
    return points


def frame_triangles(parts: list[Part], read: Callable[[str], bytes]) -> np.ndarray:
    """Every triangle ``(n, 3, 3)`` of the parts' meshes, whole (no cut, no hub), each mesh once; metres."""
    meshes = dict.fromkeys(replace(mesh, hub=None) for part in parts for mesh in part.meshes)
    return np.concatenate([place(mesh, stl_triangles(read(mesh.path))) for mesh in meshes])


# -- fitting -------------------------------------------------------------------------------------------------------
def _trim(t: np.ndarray, radius: Callable[[np.ndarray], float], trims: int) -> tuple[float, float, float, float]:
    """The capsule of least volume over trims of 0 to 30 % of the span of ``t`` (the points along the axis) from
    each end: its volume, ends ``lo <= hi`` along the axis and ``radius(t clipped to lo..hi)``."""
    span = t.max() - t.min()
    best = (np.inf, 0.0, 0.0, 0.0)
    for s0 in np.linspace(0, 0.6, trims):
        for s1 in np.linspace(0, 0.6, trims):
            lo, hi = t.min() + s0 * span / 2, t.max() - s1 * span / 2
            if lo > hi:
                continue
            r = radius(np.clip(t, lo, hi))
            vol = pi * r * r * (hi - lo) + 4 / 3 * pi * r**3
            if vol < best[0]:
                best = (vol, lo, hi, r)
    return best


def fit_capsule(P: np.ndarray, axis: Vec, trims: int = 61) -> tuple[float, np.ndarray, np.ndarray, float]:
    """The smallest capsule (by volume) along ``axis`` through the centroid enclosing every point of ``P``
    ``(n, 3)``: its volume, ends a, b and radius."""
    c = P.mean(0)
    u = np.asarray(axis, float) / np.linalg.norm(axis)
    vol, lo, hi, r = _trim((P - c) @ u, lambda s: float(np.linalg.norm(P - (c + s[:, None] * u), axis=1).max()), trims)
    return vol, c + lo * u, c + hi * u, r


def smallest_circle(Q: np.ndarray) -> np.ndarray:
    """The centre ``(2,)`` of the smallest circle holding the points ``Q`` ``(n, 2)``: 4000 Badoiu-Clarkson steps
    from the bounding box's centre, then a pattern search on the radius down to 0.1 um steps.  (Approximate, but its
    radius is within 3 um of the least on the Koch's parts; the centre of a nearly flat optimum may sit up to 0.03 mm
    from the exact one, and the arm file's rounded ends are those of this search: an exact circle moves one
    coordinate of 6 of the Koch's capsule ends by 0.1 mm.)"""
    Q = Q[_hull(Q)]  # the same search, faster: the point farthest from any centre is a corner of the hull
    c = (Q.min(0) + Q.max(0)) / 2
    for k in range(1, 4000):
        c = c + (Q[np.linalg.norm(Q - c, axis=1).argmax()] - c) / (k + 1)
    step = float(np.linalg.norm(Q.max(0) - Q.min(0))) * 0.01
    best = np.linalg.norm(Q - c, axis=1).max()
    while step > 1e-7:
        moved = False
        for dv in ((1, 0), (-1, 0), (0, 1), (0, -1), (1, 1), (1, -1), (-1, 1), (-1, -1)):
            cc = c + step * np.array(dv, float)
            r = np.linalg.norm(Q - cc, axis=1).max()
            if r < best:
                best, c, moved = r, cc, True
        if not moved:
            step /= 2
    return np.asarray(c, dtype=np.float64)


def _hull(Q: np.ndarray) -> np.ndarray:
    """The indices, ascending, of the corners of the convex hull of ``Q`` ``(n, 2)`` (Andrew's monotone chain)."""
    p = Q.tolist()

    def left(o: int, a: int, b: int) -> bool:  # o -> a -> b turns counter-clockwise
        return bool((p[a][0] - p[o][0]) * (p[b][1] - p[o][1]) > (p[a][1] - p[o][1]) * (p[b][0] - p[o][0]))

    order = np.lexsort((Q[:, 1], Q[:, 0])).tolist()
    corners: list[int] = []
    for chain in (order, order[::-1]):
        h: list[int] = []
        for i in chain:
            while len(h) >= 2 and not left(h[-2], h[-1], i):
                h.pop()
            h.append(i)
        corners += h[:-1]
    return np.unique(corners)


def fit_capsule_circle(P: np.ndarray, axis: Vec, trims: int) -> tuple[float, np.ndarray, np.ndarray, float]:
    """As :func:`fit_capsule`, the axis line through the centre of the smallest circle holding the points of ``P``
    ``(n, 3)`` seen along it."""
    u = np.asarray(axis, float)
    u /= np.linalg.norm(u)
    e1 = np.cross(u, [1, 0, 0]) if abs(u[0]) < 0.9 else np.cross(u, [0, 1, 0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(u, e1)
    Q = np.unique(P, axis=0)
    across = np.stack([Q @ e1, Q @ e2], 1)
    c = smallest_circle(across)
    base, off2 = c[0] * e1 + c[1] * e2, ((across - c) ** 2).sum(1)
    t = Q @ u
    vol, lo, hi, r = _trim(t, lambda s: float(np.sqrt(off2 + (t - s) ** 2).max()), trims)
    return vol, base + lo * u, base + hi * u, r


def fit_part(part: Part, points: np.ndarray, how: Fit) -> Capsule:
    """The capsule of least volume over the part's candidate axes, its radius grown by the margin."""
    if how.centre == "mean":
        fits = [fit_capsule(points, axis, how.trims) for axis in part.candidates]
    else:
        fits = [fit_capsule_circle(points, axis, how.trims) for axis in part.candidates]
    _, a, b, r = min(fits, key=lambda f: f[0])
    return a, b, r + MARGIN


# -- the Koch's rounding and check (Fit.grid) ----------------------------------------------------------------------
def _distance(P: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The distance ``(n,)`` of each point of ``P`` ``(n, 3)`` from the segment a-b."""
    ab = b - a
    t = np.clip(((P - a) @ ab) / max(float(ab @ ab), 1e-18), 0, 1)
    return np.asarray(np.linalg.norm(P - (a + t[:, None] * ab), axis=1), dtype=np.float64)


def excess(tris: np.ndarray, caps: list[Capsule], n: int) -> tuple[float, int]:
    """How far (m) the triangles ``(t, 3, 3)`` reach outside the capsules, and how many lie in one capsule (its
    three corners do): the others are sampled on a 1/n barycentric grid against the capsules' union.  0 when every
    triangle lies in one capsule; below 0 when the sampled points all lie inside."""
    one = np.zeros(len(tris), dtype=bool)
    for a, b, r in caps:
        one |= (_distance(tris.reshape(-1, 3), a, b) <= r + 1e-9).reshape(-1, 3).all(1)
    rest = tris[~one]
    if not len(rest):
        return 0.0, len(tris)
    W = np.array([(1 - i / n - j / n, i / n, j / n) for i in range(n + 1) for j in range(n + 1 - i)])
    P = np.einsum("kw,twc->tkc", W, rest).reshape(-1, 3)
    return float(np.min([_distance(P, a, b) - r for a, b, r in caps], axis=0).max()), int(one.sum())


def grow(tris: np.ndarray, caps: dict[str, Capsule], n: int, step: float) -> tuple[dict[str, Capsule], str]:
    """The capsules grown alike until :func:`excess` on a 1/n grid is at most 0: by the excess + 0.01 mm (step 0),
    else by whole steps; and a line saying what was checked."""
    grown = 0.0
    while (worst := excess(tris, list(caps.values()), n))[0] > 0:
        by = math.ceil(worst[0] / step) * step if step else worst[0] + 1e-5
        caps, grown = {k: (a, b, r + by) for k, (a, b, r) in caps.items()}, grown + by
    held = f"{worst[1]} in one capsule, the rest on a 1/{n} grid {worst[0] * 1000:+.3f} mm"
    return caps, f"{len(tris)} triangles: {held}; grown {grown * 1000:.3f} mm"


def settle(parts: list[Part], caps: dict[str, Capsule], tris: np.ndarray, grid: float) -> dict[str, Capsule]:
    """One link frame's capsules checked against its triangles ``(n, 3, 3)``, shrunk, rounded to ``grid`` and
    checked again (see the module's docstring); the checks reported on stderr."""
    caps, coarse = grow(tris, caps, 8, 0.0)
    pad = grid * math.sqrt(3) / 2  # the farthest rounding moves an end, so a point of the segment
    shrink = {part.name: part.shrink for part in parts}
    caps = {
        k: (np.round(a / grid) * grid, np.round(b / grid) * grid, math.ceil((r - shrink[k] + pad) / grid) * grid)
        for k, (a, b, r) in caps.items()
    }
    caps, fine = grow(tris, caps, 64, grid)
    print(f"# [{parts[0].frame}] fitted: {coarse}\n#   rounded: {fine}", file=sys.stderr)
    return caps


# -- output --------------------------------------------------------------------------------------------------------
def _fmt(v: np.ndarray) -> str:
    return "[" + ", ".join(f"{x:.4f}".replace("-0.0000", "0.0000") for x in v) + "]"


def part_toml(part: Part, points: np.ndarray, capsule: Capsule | None) -> str:
    head = f'[[collision.links]]\nname = "{part.name}"\nframe = "{part.frame}"\n'
    if capsule is None:
        lo3, hi3 = points.min(0), points.max(0)
        return head + f"box = {{ center = {_fmt((lo3 + hi3) / 2)}, half_size = {_fmt((hi3 - lo3) / 2 + MARGIN)} }}\n"
    a, b, r = capsule
    return head + f"capsule = {{ a = {_fmt(a)}, b = {_fmt(b)}, radius = {r:.4f} }}\n"


def fit_arm(arm: Arm, read: Callable[[str], bytes]) -> list[tuple[Part, np.ndarray, Capsule | None]]:
    """Each part with its points and capsule (None for a box)."""
    points = {part.name: part_points(part, read) for part in arm.parts}
    caps = {part.name: fit_part(part, points[part.name], arm.fit) for part in arm.parts if part.candidates}
    if arm.fit.grid:
        for frame in dict.fromkeys(part.frame for part in arm.parts if part.name in caps):
            parts = [part for part in arm.parts if part.frame == frame and part.name in caps]
            tris = frame_triangles(parts, read)
            caps |= settle(parts, {part.name: caps[part.name] for part in parts}, tris, arm.fit.grid)
    return [(part, points[part.name], caps.get(part.name)) for part in arm.parts]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], epilog=__doc__.split("\n\n", 1)[1],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)  # fmt: skip
    ap.add_argument("arm", choices=sorted(ARMS))
    ap.add_argument("--repo", type=Path, required=True, help="the vendor repository: a checkout or a bare git dir")
    ap.add_argument("--rev", default="HEAD", help="revision to read from a bare git dir (default HEAD)")
    args = ap.parse_args(argv)
    arm = ARMS[args.arm]()
    print(f"# fitted by scripts/fit_capsules.py {args.arm} from {arm.repo}\n")
    for part, points, capsule in fit_arm(arm, lambda path: read_bytes(args.repo, args.rev, path)):
        if part.note:
            print(f"# {part.note}")
        print(part_toml(part, points, capsule))
    return 0


if __name__ == "__main__":
    sys.exit(main())
