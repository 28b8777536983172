"""Helpers shared by the tests: small BVH files, the real clips, reference FK, circle targets, the
simulated wire decoded, and a dynamixel-sdk port on the simulator.  Fixtures stay in the ``conftest.py`` files;
test modules import helpers from here, never from each other.
"""

from __future__ import annotations

import collections
import json
import math
import os
import random
import signal
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest
import serial
from dynamixel_sdk import PacketHandler, PortHandler

import sim
from drivers.control_table import Instruction, common_register
from drivers.units import pulses_to_rad
from retarget.bvh import parse_bvh
from retarget.control.clock import VirtualClock
from retarget.mapping import MappingConfig, Targets, Workspace, retarget_targets
from sim.bus import LogEntry
from sim.server import PtyServer

# ------------------------------------------------------------------ small BVH files
ROT_ZXY = ("Zrotation", "Xrotation", "Yrotation")
POS_XYZ = ("Xposition", "Yposition", "Zposition")


@dataclass
class J:
    """A joint for :func:`bvh_text`: name, OFFSET, CHANNELS, children and an optional End Site OFFSET."""

    name: str
    offset: Sequence[float] = (0.0, 0.0, 0.0)
    channels: Sequence[str] = ROT_ZXY
    children: list[J] = field(default_factory=list)
    end: Sequence[float] | None = None


def joints_in_order(root: J) -> list[J]:
    out = [root]
    for c in root.children:
        out += joints_in_order(c)
    return out


def n_channels(root: J) -> int:
    return sum(len(j.channels) for j in joints_in_order(root))


def bvh_text(
    root: J,
    frames: np.ndarray | Sequence[Sequence[float]] | None = None,
    *,
    frame_time: float = 1 / 30,
    n_frames: int | None = None,
    newline: str = "\n",
    indent: str = "  ",
    fmt: str = "{:.10g}",
) -> str:
    """BVH text of ``root``; ``frames`` ``(n, n_channels)`` (default: one frame of zeros)."""
    if frames is None:
        frames = np.zeros((1, n_channels(root)))
    frames = np.asarray(frames, dtype=np.float64)
    lines = ["HIERARCHY"]

    def emit(j: J, depth: int) -> None:
        pad = indent * depth
        lines.append(f"{pad}{'ROOT' if depth == 0 else 'JOINT'} {j.name}")
        lines.append(f"{pad}{{")
        lines.append(f"{pad}{indent}OFFSET {' '.join(fmt.format(float(v)) for v in j.offset)}")
        lines.append(f"{pad}{indent}CHANNELS {len(j.channels)} {' '.join(j.channels)}")
        for c in j.children:
            emit(c, depth + 1)
        if j.end is not None:
            lines.append(f"{pad}{indent}End Site")
            lines.append(f"{pad}{indent}{{")
            lines.append(f"{pad}{indent * 2}OFFSET {' '.join(fmt.format(float(v)) for v in j.end)}")
            lines.append(f"{pad}{indent}}}")
        lines.append(f"{pad}}}")

    emit(root, 0)
    lines += ["MOTION", f"Frames: {len(frames) if n_frames is None else n_frames}", f"Frame Time: {frame_time:.10g}"]
    lines += [" ".join(fmt.format(float(v)) for v in row) for row in frames]
    return newline.join(lines) + newline


def arm_skeleton(
    names: dict[str, str], *, prefix: str = "", wrist_end_site: bool = False, extra: Sequence[J] = ()
) -> J:
    """A small humanoid whose arm joints are named by ``names`` (keys: clavicle, upper, fore, hand, with
    ``{side}`` placeholders filled with the values of ``names['left']`` / ``names['right']``)."""

    def arm(side_key: str, s: float) -> J:
        side = names[side_key]
        hand = (
            None if wrist_end_site else J(prefix + names["hand"].format(side=side), (s * 25, 0, 0), end=(s * 8, 0, 0))
        )
        fore = J(
            prefix + names["fore"].format(side=side),
            (s * 28, 0, 0),
            children=[hand] if hand else [],
            end=(s * 25, 0, 0) if wrist_end_site else None,
        )
        upper = J(prefix + names["upper"].format(side=side), (s * 15, 2, 0), children=[fore])
        if names.get("clavicle"):
            return J(prefix + names["clavicle"].format(side=side), (s * 2, 15, 0), children=[upper])
        return upper

    chest = J(
        prefix + "Chest",
        (0, 30, 0),
        children=[J(prefix + "Neck", (0, 20, 0), end=(0, 20, 0)), arm("left", 1.0), arm("right", -1.0), *extra],
    )
    legs = [
        J(prefix + "LeftUpLeg", (9, -4, 0), children=[J(prefix + "LeftLeg", (0, -43, 0), end=(0, -45, 0))]),
        J(prefix + "RightUpLeg", (-9, -4, 0), children=[J(prefix + "RightLeg", (0, -43, 0), end=(0, -45, 0))]),
    ]
    return J(prefix + "Hips", (0, 0, 0), ("Xposition", "Yposition", "Zposition", *ROT_ZXY), children=[chest, *legs])


# ------------------------------------------------------------------ the real clips
REPO = Path(__file__).resolve().parent.parent


SHARED_BVH = Path(os.environ.get("RETARGET_SHARED_BVH", REPO.parent / "shared" / "bvh"))


def shared_clips() -> list[Path]:
    """The real clips, sorted by name; empty when the folder is absent."""
    return sorted(SHARED_BVH.glob("*.bvh")) if SHARED_BVH.is_dir() else []


def shared_clip_params() -> list:
    """``shared_clips()`` for ``parametrize``: one skipped case, with the reason, when the folder is absent."""
    clips = shared_clips()
    if clips:
        return [pytest.param(c, id=c.stem) for c in clips]
    reason = f"real BVH clips not found at {SHARED_BVH} (set RETARGET_SHARED_BVH)"
    return [pytest.param(None, id="no-shared-clips", marks=pytest.mark.skip(reason=reason))]


# ------------------------------------------------------------------ reference BVH FK
UNIT = {"X": np.array([1.0, 0, 0]), "Y": np.array([0, 1.0, 0]), "Z": np.array([0, 0, 1.0])}


def rodrigues(axis: np.ndarray, angle: float) -> np.ndarray:
    k = axis / np.linalg.norm(axis)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


def reference_fk(root: J, frames: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """World rotations, joint positions and End Site positions, one frame and one joint at a time, from 4x4
    homogeneous transforms: T_local = translate(offset with position channels substituted) @ rotations."""
    joints = joints_in_order(root)
    parent = {}
    for j in joints:
        for c in j.children:
            parent[c.name] = j.name
    n = len(frames)
    rot = np.zeros((n, len(joints), 3, 3))
    pos = np.zeros((n, len(joints), 3))
    ends = []
    for f in range(n):
        col = 0
        world: dict[str, np.ndarray] = {}
        sites = []
        for k, j in enumerate(joints):
            t = np.array(j.offset, dtype=float)
            R = np.eye(3)
            for ch in j.channels:
                value = frames[f, col]
                col += 1
                if ch.endswith("position"):
                    t["XYZ".index(ch[0])] = value
                else:
                    R = R @ rodrigues(UNIT[ch[0]], np.radians(value))
            T = np.eye(4)
            T[:3, :3] = R
            T[:3, 3] = t
            W = world[parent[j.name]] @ T if j.name in parent else T
            world[j.name] = W
            rot[f, k] = W[:3, :3]
            pos[f, k] = W[:3, 3]
            if j.end is not None:
                sites.append((W @ np.append(np.array(j.end, dtype=float), 1.0))[:3])
        ends.append(sites)
    return rot, pos, np.array(ends).reshape(n, -1, 3)


def random_frames(root: J, n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    out = []
    for j in joints_in_order(root):
        for ch in j.channels:
            out.append(rng.uniform(-40, 40, n) if ch.endswith("position") else rng.uniform(-180, 180, n))
    return np.array(out).T


# ------------------------------------------------------------------ targets for the control loop
def circle_targets(arm, *, n_frames: int = 61, frame_time: float = 1 / 30, radius: float = 0.08) -> Targets:
    """A circle in front of the arm, 2 s at 30 fps, well inside the workspace."""
    t = np.arange(n_frames) * frame_time
    phase = 2 * np.pi * t / (t[-1] or 1.0)
    raw = np.stack([0.35 + 0 * t, radius * np.sin(phase), 0.25 + radius * np.cos(phase)], axis=-1)
    return Targets.from_raw(raw, frame_time=frame_time, workspace=Workspace.for_arm(arm))


def servo_angles(simbus, arm) -> np.ndarray:
    """Joint angles read from the primary simulated servos' Present Position, radians."""

    return np.array(
        [
            pulses_to_rad(simbus.servo(j.servos[0].id).get("Present Position"), offset=j.servos[0].offset)
            for j in arm.joints
        ]
    )


def torque(simbus, arm) -> list[int]:
    return [
        simbus.servo(i).get("Torque Enable") for i in arm.servo_ids if arm.gripper is None or i != arm.gripper.servo.id
    ]


# ------------------------------------------------------------------ the simulated wire
def address(name: str) -> int:
    """The address of register ``name``, the same on every X model (``drivers.control_table.common_register``)."""
    return common_register(name).address


GOAL = address("Goal Position")  #: 4 bytes
PRESENT = address("Present Position")  #: 4 bytes
TORQUE = address("Torque Enable")  #: 1 byte
PROFILE_VELOCITY = address("Profile Velocity")  #: 4 bytes
PROFILE_ACCELERATION = address("Profile Acceleration")  #: 4 bytes


def goal_writes(sim_bus: sim.SimBus) -> list[dict[int, int]]:
    """Every Goal Position SYNC_WRITE the simulated wire carried, decoded: [{id: pulses}, ...]."""
    out = []
    for entry in sim_bus.log:
        p = entry.params
        if entry.instruction != Instruction.SYNC_WRITE or int.from_bytes(p[0:2], "little") != GOAL:
            continue
        size = int.from_bytes(p[2:4], "little")
        body = p[4:]
        out.append(
            {
                body[k]: int.from_bytes(body[k + 1 : k + 1 + size], "little", signed=True)
                for k in range(0, len(body), size + 1)
            }
        )
    return out


def torques(sim_bus: sim.SimBus) -> dict[int, int]:
    return {s.id: s.get("Torque Enable") for s in sim_bus.servos}


# ------------------------------------------------------------------ an SDK port on the simulator
class UrlPortHandler(PortHandler):
    """The SDK port, opening any pyserial URL (the same seam drivers.port uses)."""

    def setupPort(self, cflag_baud):  # noqa: N802 - the SDK's name
        if self.is_open:
            self.closePort()
        self.ser = serial.serial_for_url(self.port_name, baudrate=self.baudrate, bytesize=serial.EIGHTBITS, timeout=0)
        self.is_open = True
        self.ser.reset_input_buffer()
        self.tx_time_per_byte = (1000.0 / self.baudrate) * 10.0
        return True


@dataclass
class Rig:
    """A simulated bus and an open dynamixel-sdk port on it."""

    bus: sim.SimBus
    clock: VirtualClock
    port: PortHandler
    ph: object
    transport: str


def open_rig(bus: sim.SimBus, transport: str) -> tuple[Rig, object]:
    """Open ``bus`` over ``transport`` ("inproc" or "pty"); returns the rig and the resource to close."""
    if transport == "inproc":
        url = sim.attach(bus)
        port = UrlPortHandler(url)
        assert port.openPort()
        return Rig(bus, bus.clock, port, PacketHandler(2.0), transport), url
    server = PtyServer(bus).start()
    port = PortHandler(server.path)  # the plain SDK class
    assert port.setBaudRate(bus.baud)
    return Rig(bus, bus.clock, port, PacketHandler(2.0), transport), server


def close_rig(rig: Rig, resource: object) -> None:
    rig.port.closePort()
    if isinstance(resource, PtyServer):
        resource.close()
    else:
        sim.unregister(str(resource))


needs_pty = pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs a POSIX pseudo-terminal")


TRANSPORTS = [
    pytest.param("inproc", id="inproc"),
    pytest.param("pty", id="pty", marks=[pytest.mark.pty, needs_pty]),
]


# ------------------------------------------------------------------ teleop: an independent wx250s FK
RAD_PER_PULSE = 2 * math.pi / 4096


def _rot(axis: str, a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    R = {
        "x": [[1, 0, 0], [0, c, -s], [0, s, c]],
        "y": [[c, 0, s], [0, 1, 0], [-s, 0, c]],
        "z": [[c, -s, 0], [s, c, 0], [0, 0, 1]],
    }
    T = np.eye(4)
    T[:3, :3] = R[axis]
    return T


def _trans(x: float, y: float, z: float) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = (x, y, z)
    return T


WX250S = [
    ((0, 0, 0.072), "z"),  # waist
    ((0, 0, 0.03865), "y"),  # shoulder
    ((0.04975, 0, 0.25), "y"),  # elbow
    ((0.175, 0, 0), "x"),  # forearm_roll
    ((0.075, 0, 0), "y"),  # wrist_angle
    ((0.065, 0, 0), "x"),  # wrist_rotate
]


WX250S_TOOL = (0.093575, 0, 0)  # ee_gripper_link


def wx250s_tool(q: np.ndarray) -> np.ndarray:
    """Tool point (3,) metres of joint angles (6,) radians, by a plain chain of 4x4 transforms."""
    T = np.eye(4)
    for (xyz, axis), angle in zip(WX250S, q, strict=True):
        T = T @ _trans(*xyz) @ _rot(axis, angle)
    return (T @ _trans(*WX250S_TOOL))[:3, 3]


def servo_joint_angles(simbus, arm) -> np.ndarray:
    """Joint angles from the primary servos' Present Position registers: (ticks - 2048) x 2 pi / 4096.

    The driver reverses servos with Drive Mode, so the registers already read in the joint's sense."""
    assert all(j.servos[0].offset == 0 for j in arm.joints)
    return np.array([(simbus.servo(j.servos[0].id).get("Present Position") - 2048) * RAD_PER_PULSE for j in arm.joints])


def goal_registers(simbus) -> dict[int, int]:
    return {s.id: s.get("Goal Position") for s in simbus.servos}


# ------------------------------------------------------------------ garbage target messages
def garbage(rng: random.Random, n: int) -> list[bytes]:
    """``n`` seeded garbage messages, none blank: random bytes, NaN/inf, huge numbers, partial/bad JSON, oversize."""
    out: list[bytes] = []
    while len(out) < n:
        kind = rng.randrange(8)
        if kind == 0:
            m = b"!" + bytes(rng.randrange(256) for _ in range(rng.randrange(0, 64)))  # "!": never blank
        elif kind == 1:
            m = f"{rng.choice(['nan', 'NaN', 'inf', '-inf', '1e999'])} {rng.random()} {rng.random()}".encode()
        elif kind == 2:
            m = " ".join(f"{rng.uniform(-1, 1) * 10 ** rng.randrange(3, 300):g}" for _ in range(3)).encode()
        elif kind == 3:
            full = json.dumps({"x": rng.random(), "y": rng.random(), "z": rng.random()})
            m = full[: rng.randrange(1, len(full) - 1)].encode()
        elif kind == 4:
            m = rng.choice([b'{"x": NaN, "y": 0, "z": 0.2}', b'{"x": 0.3}', b'{"x": [], "y": 0, "z": 0}', b"null"])
        elif kind == 5:
            m = b"0.3 0 0.2 " * rng.randrange(120, 300)  # oversize
        elif kind == 6:
            m = f"{rng.random()} {rng.random()}".encode()  # two numbers
        else:
            m = f"0.3 0 {-rng.uniform(0.01, 1)}".encode()  # below the floor
        m = m.replace(b"\n", b"").replace(b"\r", b"")
        if m.strip() and not m.strip().startswith(b"#"):
            out.append(m)
    return out


# ------------------------------------------------------------------ URDF text
def urdf_text(joints, links=None, name="robot") -> str:
    if links is None:
        links = sorted({j[2] for j in joints} | {j[3] for j in joints})
    out = [f'<?xml version="1.0"?>\n<robot name="{name}">']
    out += [f'  <link name="{link}"/>' for link in links]
    for jname, kind, parent, child, xyz, axis, limit, *rest in joints:
        rpy = rest[0] if rest else "0 0 0"
        out.append(f'  <joint name="{jname}" type="{kind}">')
        out.append(f'    <parent link="{parent}"/>\n    <child link="{child}"/>')
        out.append(f'    <origin xyz="{xyz}" rpy="{rpy}"/>')
        if axis:
            out.append(f'    <axis xyz="{axis}"/>')
        if limit:
            out.append(f'    <limit lower="{limit[0]}" upper="{limit[1]}" effort="1" velocity="3.14159"/>')
        out.append("  </joint>")
    out.append("</robot>\n")
    return "\n".join(out)


# ------------------------------------------------------------------ generated skeletons for arm-chain detection
#: Arm naming conventions: role -> the word the side marker goes with (see ``retarget.bvh.names``'s table).
ARM_WORDS: dict[str, dict[str, str]] = {
    "cmu": {"clavicle": "Shoulder", "upper": "Arm", "fore": "ForeArm", "hand": "Hand"},
    "collar": {"clavicle": "Collar", "upper": "Shoulder", "fore": "Elbow", "hand": "Wrist"},
    "biped": {"clavicle": "Clavicle", "upper": "UpperArm", "fore": "Forearm", "hand": "Hand"},
    "poser": {"clavicle": "Collar", "upper": "Shldr", "fore": "ForeArm", "hand": "Hand"},
    "genesis": {"clavicle": "Collar", "upper": "ShldrBend", "fore": "ForearmBend", "hand": "Hand"},
    "mhx": {"clavicle": "Clavicle", "upper": "UpArm", "fore": "LoArm", "hand": "Hand"},
    "optitrack": {"clavicle": "Shoulder", "upper": "UArm", "fore": "FArm", "hand": "Hand"},
    "rigify": {"clavicle": "shoulder", "upper": "upper_arm", "fore": "forearm", "hand": "hand"},
    "makehuman": {"clavicle": "clavicle", "upper": "upperarm01", "fore": "lowerarm01", "hand": "wrist"},
    "unreal": {"clavicle": "clavicle", "upper": "upperarm", "fore": "lowerarm", "hand": "hand"},
    "asf": {"clavicle": "clavicle", "upper": "humerus", "fore": "radius", "hand": "wrist"},
}
#: How each convention names the twist bones of the upper arm and the forearm (``{}``: the suffix).
TWIST_STEMS: dict[str, tuple[str, str]] = {
    "genesis": ("Shldr{}", "Forearm{}"),
    "makehuman": ("upperarm0{}", "lowerarm0{}"),  # numbered segments: upperarm02, upperarm03
}
TWIST_SUFFIXES = ("Twist", "Roll", "_twist_01", "Twist1")
#: Side styles: Left/Right before or after the word, a capital or small letter before it, a separated suffix,
#: or Biped's " L " (after a "Bip01 " prefix).
SIDE_STYLES = ("Word", "WordAfter", "L", "l", ".L", "_L", " L ")
PREFIXES = ("", "mixamorig:", "Skeleton1_", "Bip01 ", "DEF-")
CASES = ("keep", "lower", "upper")


@dataclass(frozen=True)
class ArmNaming:
    """How a generated skeleton spells its joints: prefix, convention, side style, separator, case, twist suffix."""

    prefix: str = ""
    convention: str = "cmu"
    side_style: str = "Word"
    separator: str = ""  # between a side word and the role word ("Left_Arm")
    case: str = "keep"
    twist: str = "Twist"

    def name(self, word: str, side: str | None) -> str:
        """``word`` with this naming's prefix, side marker and case (no side marker when ``side`` is None)."""
        if side is None:
            text = word
        else:
            long, short = ("Left", "L") if side == "left" else ("Right", "R")
            text = {
                "Word": long + self.separator + word,
                "WordAfter": word + self.separator + long,
                "L": short + word[:1].upper() + word[1:],
                "l": short.lower() + word[:1].upper() + word[1:],
                ".L": word + "." + short,
                "_L": word + "_" + short,
                " L ": short + " " + word,
            }[self.side_style]
        text = self.prefix + text
        return text.lower() if self.case == "lower" else text.upper() if self.case == "upper" else text

    def role(self, role: str, side: str) -> str:
        """The joint name of arm ``role`` (``clavicle``, ``upper``, ``fore``, ``hand``) on ``side``."""
        return self.name(ARM_WORDS[self.convention][role], side)

    def twist_name(self, role: str, side: str, k: int) -> str:
        """The ``k``-th (0-based) twist bone after the ``upper`` or ``fore`` joint."""
        stems = TWIST_STEMS.get(self.convention)
        if self.convention == "makehuman" and stems:
            return self.name(stems[role == "fore"].format(k + 2), side)
        word = stems[role == "fore"] if stems else ARM_WORDS[self.convention][role] + "{}"
        return self.name(word.format(self.twist + ("" if k == 0 else str(k + 1))), side)


def random_arm_naming(rng: random.Random) -> ArmNaming:
    """A seeded random :class:`ArmNaming`."""
    style = rng.choice(SIDE_STYLES)
    return ArmNaming(
        prefix="Bip01 " if style == " L " and rng.random() < 0.7 else rng.choice(PREFIXES),
        convention=rng.choice(sorted(ARM_WORDS)),
        side_style=style,
        separator=rng.choice(("", "_", ".")) if style in ("Word", "WordAfter") else "",
        case=rng.choice(CASES),
        twist=rng.choice(TWIST_SUFFIXES),
    )


def named_humanoid(
    naming: ArmNaming,
    *,
    upper_twists: int = 0,
    fore_twists: int = 0,
    fingers: bool = False,
    wrist_end_site: bool = False,
    clavicle: bool = True,
) -> J:
    """A 170-unit humanoid (T pose, Y up, facing +Z, cm) whose joints are named by ``naming``.

    Upper arm 28 and forearm 25 units, split evenly over ``upper_twists`` / ``fore_twists`` twist bones after
    the joint; ``fingers`` adds five three-bone fingers to each hand; ``wrist_end_site`` ends the forearm in
    an End Site instead of a hand joint (no twist bones after the forearm then).  Legs and spine are named with
    the same prefix, side style and case: Hips, Spine, Chest, Neck, Head, UpLeg, Leg, Foot, Toe.
    """

    def twisted(role: str, side: str, s: float, length: float, n: int, below: J) -> J:
        """The ``role`` joint, then ``n`` twist bones, then ``below``, ``length`` units apart in equal steps."""
        step = (s * length / (n + 1), 0.0, 0.0)
        below.offset = step
        joint = below
        for k in reversed(range(n)):
            joint = J(naming.twist_name(role, side, k), step, children=[joint])
        return J(naming.role(role, side), (0, 0, 0), children=[joint])

    def arm(side: str, s: float) -> J:
        if wrist_end_site:
            fore = J(naming.role("fore", side), (0, 0, 0), end=(s * 25, 0, 0))
        else:
            hand = J(naming.role("hand", side), (0, 0, 0), end=None if fingers else (s * 8, 0, 0))
            if fingers:
                for k, finger in enumerate(("Thumb", "Index", "Middle", "Ring", "Pinky")):
                    tip = J(naming.name(f"Hand{finger}3", side), (s * 2, 0, 0), end=(s * 2, 0, 0))
                    mid = J(naming.name(f"Hand{finger}2", side), (s * 3, 0, 0), children=[tip])
                    hand.children.append(J(naming.name(f"Hand{finger}1", side), (s * 8, 0, 2 - k), children=[mid]))
            fore = twisted("fore", side, s, 25.0, fore_twists, hand)
        upper = twisted("upper", side, s, 28.0, upper_twists, fore)
        upper.offset = (s * 15, 2, 0)
        if not clavicle:
            return upper
        return J(naming.role("clavicle", side), (s * 2, 15, 0), children=[upper])

    def leg(side: str, s: float) -> J:
        toe = J(naming.name("Toe", side), (0, -4, 12), end=(0, 0, 5))
        foot = J(naming.name("Foot", side), (0, -43, 0), children=[toe])
        knee = J(naming.name("Leg", side), (0, -43, 0), children=[foot])
        return J(naming.name("UpLeg", side), (s * 9, -4, 0), children=[knee])

    head = J(naming.name("Neck", None), (0, 20, 0), children=[J(naming.name("Head", None), (0, 10, 0), end=(0, 20, 0))])
    chest = J(naming.name("Chest", None), (0, 15, 0), children=[head, arm("left", 1.0), arm("right", -1.0)])
    spine = J(naming.name("Spine", None), (0, 15, 0), children=[chest])
    channels = ("Xposition", "Yposition", "Zposition", *ROT_ZXY)
    return J(naming.name("Hips", None), (0, 98, 0), channels, children=[spine, leg("left", 1.0), leg("right", -1.0)])


def expected_arm(naming: ArmNaming, side: str, *, wrist_end_site: bool = False) -> tuple[str, str, str]:
    """The shoulder, elbow and wrist names :func:`named_humanoid` gives the ``side`` arm."""
    fore = naming.role("fore", side)
    wrist = fore + "/End Site" if wrist_end_site else naming.role("hand", side)
    return naming.role("upper", side), fore, wrist


def renamed(root: J, fmt: str = "bone{:02d}") -> J:
    """``root`` with every joint renamed ``fmt.format(k)`` in file order (names that say nothing); in place."""
    for k, joint in enumerate(joints_in_order(root)):
        joint.name = fmt.format(k)
    return root


def lafan_like(n_frames: int = 0) -> tuple[J, np.ndarray]:
    """A CMU-named 180-cm humanoid whose zero-rotation pose lays every bone along +X (LAFAN's rest pose).

    Left is +Z in the rest pose; ``n_frames`` frames stand it upright (Y up): the root turned 90 degrees about
    Z, the legs turned back down, the clavicles out to the sides.  Returns the root and the frames
    ``(n_frames, n_channels)``.
    """

    def arm(side: str, z: float) -> J:
        hand = J(f"{side}Hand", (25, 0, 0), end=(18, 0, 0))
        fore = J(f"{side}ForeArm", (30, 0, 0), children=[hand])
        upper = J(f"{side}Arm", (11, 0, 0), children=[fore])
        return J(f"{side}Shoulder", (20, 0, z), children=[upper])

    def leg(side: str, z: float) -> J:
        toe = J(f"{side}Toe", (15, 0, 0), end=(5, 0, 0))
        foot = J(f"{side}Foot", (42, 0, 0), children=[toe])
        return J(f"{side}UpLeg", (0, 0, z), children=[J(f"{side}Leg", (43, 0, 0), children=[foot])])

    head = J("Neck", (25, 0, 0), children=[J("Head", (12, 0, 0), end=(18, 0, 0))])
    chest = J("Spine2", (12, 0, 0), children=[head, arm("Left", 6.0), arm("Right", -6.0)])
    spine = J("Spine", (8, 0, 0), children=[J("Spine1", (12, 0, 0), children=[chest])])
    channels = ("Xposition", "Yposition", "Zposition", *ROT_ZXY)
    root = J("Hips", (0, 0, 0), channels, children=[leg("Left", 9.0), leg("Right", -9.0), spine])
    names = [j.name for j in joints_in_order(root)]
    frames = np.zeros((n_frames, n_channels(root)))
    frames[:, 1] = 105.0  # hips height, cm
    frames[:, 3] = 90.0  # root Zrotation: +X (the spine) up
    for leg_name in ("LeftUpLeg", "RightUpLeg"):
        frames[:, 6 + 3 * (names.index(leg_name) - 1)] = 180.0  # Zrotation: back down
    for clavicle, yaw in (("LeftShoulder", -90.0), ("RightShoulder", 90.0)):
        frames[:, 6 + 3 * (names.index(clavicle) - 1) + 2] = yaw  # Yrotation: out to +Z / -Z
    return root, frames


def with_face(root: J) -> J:
    """``root`` with a jaw, a three-bone tongue, a lower lip and two eyes under its ``Head`` joint; in place.

    The head then has three children, deeper than the chest: the joint a "deepest branching" rule takes."""
    head = next(j for j in joints_in_order(root) if j.name.lower().endswith("head"))
    tip = J("Tongue3", (0, 0, 2), end=(0, 0, 1))
    tongue = J("Tongue1", (0, -3, 4), children=[J("Tongue2", (0, 0, 2), children=[tip])])
    jaw = J("Jaw", (0, -2, 2), children=[tongue, J("LowerLip", (0, -1, 5), end=(0, 0, 1))])
    head.children = [jaw, J("LeftEye", (3, 6, 8), end=(0, 0, 1)), J("RightEye", (-3, 6, 8), end=(0, 0, 1))]
    return root


def left_hand_rig() -> J:
    """A left hand alone (a glove's rig): ``LeftHand`` at x = 40 with five three-bone fingers along +X."""
    fingers = []
    for k, finger in enumerate(("Thumb", "Index", "Middle", "Ring", "Pinky")):
        tip = J(f"LeftHand{finger}3", (2, 0, 0), end=(2, 0, 0))
        mid = J(f"LeftHand{finger}2", (3, 0, 0), children=[tip])
        fingers.append(J(f"LeftHand{finger}1", (8, 0, 2 - k), children=[mid]))
    return J("LeftHand", (40, 140, 0), ("Xposition", "Yposition", "Zposition", *ROT_ZXY), children=fingers)


def staggered_arm_rig(leg_prefix: str = "bone") -> J:
    """Arms named ``Arm_L_01 > Arm_L_02 > Arm_L_03`` branching off two different spine joints (Spine1 the left,
    Spine2 the right), legs named ``{leg_prefix}1a > 1b > 1c``: the hips are the only joint with three children."""

    def arm(s: str, x: float) -> J:
        hand = J(f"Arm_{s}_03", (x * 25, 0, 0), end=(x * 8, 0, 0))
        return J(f"Arm_{s}_01", (x * 17, 12, 0), children=[J(f"Arm_{s}_02", (x * 28, 0, 0), children=[hand])])

    def leg(k: int, x: float) -> J:
        foot = J(f"{leg_prefix}{k}c", (0, -43, 0), end=(0, -4, 12))
        return J(f"{leg_prefix}{k}a", (x * 9, -4, 0), children=[J(f"{leg_prefix}{k}b", (0, -43, 0), children=[foot])])

    neck = J("Neck", (0, 10, 0), children=[J("Head", (0, 10, 0), end=(0, 20, 0))])
    spine2 = J("Spine2", (0, 5, 0), children=[neck, arm("R", -1)])
    spine1 = J("Spine1", (0, 25, 0), children=[spine2, arm("L", 1)])
    channels = ("Xposition", "Yposition", "Zposition", *ROT_ZXY)
    return J("Hips", (0, 98, 0), channels, children=[spine1, leg(1, 1), leg(2, -1)])


# ------------------------------------------------------------------ mapping: a CMU-named clip, rigs for the fallbacks
# A small CMU-named skeleton, cm, facing +Z, Y up.  Root channels put Yrotation first, so adding to it turns
# the whole body about the vertical through the root.
CMU_JOINTS = [  # name, parent, offset (cm)
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
CMU_ROOT_CHANNELS = "Xposition Yposition Zposition Yrotation Xrotation Zrotation"
CMU_CHANNELS = "Zrotation Xrotation Yrotation"


def cmu_bvh_text(frames: np.ndarray, *, scale: float = 1.0, frame_time: float = 1 / 60) -> str:
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
        channels = CMU_ROOT_CHANNELS if parent is None else CMU_CHANNELS
        lines.append(f"{pad}  CHANNELS {len(channels.split())} {channels}")
        children = [j for j in CMU_JOINTS if j[1] == name]
        for child in children:
            emit(*child)
        if not children:
            lines.extend([f"{pad}  End Site", f"{pad}  {{", f"{pad}    OFFSET 0 0 0", f"{pad}  }}"])
        lines.append(pad + "}")

    emit(*CMU_JOINTS[0])
    lines += ["MOTION", f"Frames: {len(frames)}", f"Frame Time: {frame_time:.9g}"]
    for row in frames:
        values = np.concatenate([row[:3] * scale, row[3:]])
        lines.append(" ".join(f"{v:.12g}" for v in values))
    return "\n".join(lines) + "\n"


def cmu_random_frames(seed: int, n: int = 90) -> np.ndarray:
    """Smooth random motion: the root walks and turns, every joint rotates a little, the arms a lot."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 1.5, n)[:, None]
    cols = 6 + 3 * (len(CMU_JOINTS) - 1)
    amp = np.full(cols, 15.0)
    amp[:3] = 20.0  # cm
    amp[3] = 90.0  # root yaw
    arm_cols = [6 + 3 * (i - 1) + k for i, (name, _, _) in enumerate(CMU_JOINTS) if "Arm" in name for k in range(3)]
    amp[arm_cols] = 60.0
    freq = rng.uniform(0.3, 1.5, cols)
    phase = rng.uniform(0, 2 * np.pi, cols)
    frames = amp * np.sin(2 * np.pi * freq * t + phase)
    frames[:, 1] += 95.0  # hips height
    return frames


def targets_of(frames: np.ndarray, arm, config: MappingConfig | None = None, *, scale: float = 1.0) -> Targets:
    return retarget_targets(parse_bvh(cmu_bvh_text(frames, scale=scale)), arm, config or MappingConfig())


def t_pose(n: int = 3) -> np.ndarray:
    frames = np.zeros((n, 6 + 3 * (len(CMU_JOINTS) - 1)))
    frames[:, 1] = 95.0
    return frames


#: tests.helpers.arm_skeleton names: Hips > Chest > Neck, {Left,Right}Shoulder (clavicle) > Arm > ForeArm > Hand
RIG_NAMES = {
    "left": "Left",
    "right": "Right",
    "clavicle": "{side}Shoulder",
    "upper": "{side}Arm",
    "fore": "{side}ForeArm",
}
RIG_NAMES["hand"] = "{side}Hand"


def rig(*, arms: tuple[str, ...] = ("left", "right"), positions: tuple[str, ...] = (), legs: bool = True) -> J:
    """``arm_skeleton`` with only the arms of ``arms``, position channels on the joints named in ``positions``
    (as some exporters write every joint), and with or without legs."""
    root = arm_skeleton(RIG_NAMES)
    chest = root.children[0]
    gone = {f"{RIG_NAMES[s]}Shoulder" for s in ("left", "right") if s not in arms}
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


def angles(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Degrees between rotations ``a`` and ``b`` ``(n, 3, 3)``."""
    m = np.einsum("nji,njk->nik", a, b)
    return np.degrees(np.arccos(np.clip((np.trace(m, axis1=1, axis2=2) - 1) / 2, -1.0, 1.0)))


# ---------------------------------------------------------------------------------------------- a noisy bus

#: The SDK's LATENCY_TIMER (ms) for fault tests on the in-process simulated bus: each lost reply costs the SDK's
#: timeout (2 x LATENCY_TIMER + 2 ms) in real time, while an in-process reply is there at once.
LOSSY_LATENCY_TIMER_MS = 0


def lossy_sdk_timeout(monkeypatch: pytest.MonkeyPatch) -> None:
    """Shorten the SDK's reply timeout for tests that lose many replies on the in-process bus (not over a pty)."""
    import dynamixel_sdk.port_handler

    monkeypatch.setattr(dynamixel_sdk.port_handler, "LATENCY_TIMER", LOSSY_LATENCY_TIMER_MS)


def sync_read_ids(entries: Sequence[LogEntry]) -> list[list[int]]:
    """The IDs each SYNC_READ / FAST_SYNC_READ among ``entries`` (the simulator's log) asked, in order."""
    reads = (Instruction.SYNC_READ, Instruction.FAST_SYNC_READ)
    return [list(e.params[4:]) for e in entries if e.instruction in reads]


# ------------------------------------------------------------------ a small valid BVH file for error tests
#: two joints and an End Site, two frames; lines: 1 HIERARCHY, 2 ROOT, 5 root CHANNELS, 6 JOINT Arm, 8 its OFFSET,
#: 9 its CHANNELS, 16 MOTION, 17 Frames, 18 Frame Time, 19-20 frames
SMALL_BVH = """\
HIERARCHY
ROOT Hips
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT Arm
  {
    OFFSET 1 0 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    End Site
    {
      OFFSET 0 1 0
    }
  }
}
MOTION
Frames: 2
Frame Time: 0.0333333
1 2 3 4 5 6 7 8 9
9 8 7 6 5 4 3 2 1
"""


def brute_force_min_clearance(arm, q, world=None, samples: int = 24) -> dict[str, float]:
    """Independent check of ``retarget.collision``: every pair's clearance (metres) in pose ``q`` (radians), by
    sampling points on each capsule's axis and every box's volume grid (``samples`` per axis) and taking the
    smallest distance; pairs named as ``CollisionModel.pair_names``.  Uses only the arm's joint data and this
    module's own FK (``_rot``/``_trans`` style, per joint), not the model's code."""
    from retarget.arm.kinematics import axis_angle_matrix, transform
    from retarget.collision import Box, CollisionModel

    model = CollisionModel.for_arm(arm, world=world)
    frames = [np.eye(4)]
    for joint, angle in zip(arm.joints, q, strict=True):
        spin = np.eye(4)
        spin[:3, :3] = axis_angle_matrix(np.asarray(joint.axis), angle)
        frames.append(frames[-1] @ transform(joint.origin_xyz, joint.origin_rpy) @ spin)
    t = np.linspace(0.0, 1.0, samples)

    def cloud(link):  # (k, 3) axis points (base frame) and the radius to subtract
        T = frames[link.frame]
        if isinstance(link.shape, Box):
            c, h = np.asarray(link.shape.center), np.asarray(link.shape.half_size)
            g = np.stack(np.meshgrid(*[c[k] + h[k] * (2 * t - 1) for k in range(3)]), -1).reshape(-1, 3)
            return g @ T[:3, :3].T + T[:3, 3], 0.0
        a, b = np.asarray(link.shape.a), np.asarray(link.shape.b)
        pts = a + t[:, None] * (b - a)
        return pts @ T[:3, :3].T + T[:3, 3], link.shape.radius

    shapes = {link.name: cloud(link) for link in model.geometry.links}
    out = {}
    for name in model.pair_names:
        u, v = name.split("/")
        pu, ru = shapes[u]
        if v == "table":
            out[name] = float(pu[:, 2].min() - ru)
            continue
        if v.startswith("keep_out["):
            zone = model.world.keep_out[int(v[9:-1])]
            if isinstance(zone, Box):
                c, h = np.asarray(zone.center), np.asarray(zone.half_size)
                q_ = np.abs(pu - c) - h
                sd = np.linalg.norm(np.maximum(q_, 0), axis=1) + np.minimum(q_.max(axis=1), 0)
                out[name] = float(sd.min() - ru)
            else:
                out[name] = float(np.linalg.norm(pu - np.asarray(zone.center), axis=1).min() - ru - zone.radius)
            continue
        pv, rv = shapes[v]
        gaps = np.linalg.norm(pu[:, None] - pv[None], axis=2).min()
        out[name] = float(gaps - ru - rv + model.geometry.nest_depth(u, v))  # nest: counted from -depth
    return out


def brute_force_min_clearances(arm, Q, world=None, spacing: float = 0.008, chunk: int = 500) -> np.ndarray:
    """Independent check of ``retarget.collision`` over many poses: the smallest pair clearance (metres) of each
    pose of ``Q`` ``(n_poses, n_joints)`` radians, ``(n_poses,)``; pairs as ``CollisionModel.pair_names``.

    Its own FK, vectorised over the poses (``chunk`` at a time: the property tests check ten thousand).  A capsule
    is points on its axis at most ``spacing`` metres apart, and its radius; a box is a 5 x 5 x 5 grid of points and,
    against points, its exact signed distance in its own frame.  Sampling can only over-estimate a positive
    distance, so a pose found within the clearance truly is (depths of overlap are measured unlike the model's).
    Resolution: exact against the table (a capsule's lowest point is an end); at most ``spacing / 2`` (4 mm) too
    far for a capsule against a box link or a keep-out zone; at most ``spacing`` (8 mm) for two capsules; box
    against box to its 5-point grid.  So, with the 10 mm clearance, a pose with a capsule touching anything (or
    within 2 mm of it) is always caught."""
    from retarget.arm.kinematics import axis_angle_matrix, transform
    from retarget.collision import Box, CollisionModel

    Q = np.atleast_2d(np.asarray(Q, dtype=np.float64))
    model = CollisionModel.for_arm(arm, world=world)
    links = {link.name: link for link in model.geometry.links}
    g = np.linspace(-1.0, 1.0, 5)
    grid = np.stack(np.meshgrid(g, g, g), -1).reshape(-1, 3)

    def box_sdf(p, center, half):  # p (..., 3) in the box's frame
        q_ = np.abs(p - np.asarray(center)) - np.asarray(half)
        return np.linalg.norm(np.maximum(q_, 0), axis=-1) + np.minimum(q_.max(axis=-1), 0)

    def worst_of(Qc):
        frames = [np.broadcast_to(np.eye(4), (len(Qc), 4, 4))]
        for i, joint in enumerate(arm.joints):
            spin = np.zeros((len(Qc), 4, 4))
            spin[:, :3, :3] = axis_angle_matrix(np.asarray(joint.axis, dtype=np.float64), Qc[:, i])
            spin[:, 3, 3] = 1.0
            frames.append(frames[-1] @ transform(joint.origin_xyz, joint.origin_rpy) @ spin)
        clouds = {}  # name -> (points (n, k, 3) base frame, radius)
        for name, link in links.items():
            T = frames[link.frame]
            if isinstance(link.shape, Box):
                local, r = np.asarray(link.shape.center) + grid * np.asarray(link.shape.half_size), 0.0
            else:
                a, b = np.asarray(link.shape.a), np.asarray(link.shape.b)
                t = np.linspace(0.0, 1.0, max(2, math.ceil(np.linalg.norm(b - a) / spacing) + 1))
                local, r = a + t[:, None] * (b - a), link.shape.radius
            clouds[name] = (np.matmul(local, T[:, :3, :3].transpose(0, 2, 1)) + T[:, None, :3, 3], r)  # R @ local

        squares = {name: np.einsum("nki,nki->nk", p, p) for name, (p, _) in clouds.items()}

        def to_box(points, name):  # signed distance of base-frame points to box link `name`
            T, box = frames[links[name].frame], links[name].shape
            local = np.matmul(points - T[:, None, :3, 3], T[:, :3, :3])  # R^T @ (p - t), per point
            return box_sdf(local, box.center, box.half_size)

        worst = np.full(len(Qc), np.inf)
        for pair in model.pair_names:
            u, v = pair.split("/")
            if isinstance(links[u].shape, Box) and v in links and not isinstance(links[v].shape, Box):
                u, v = v, u
            pu, ru = clouds[u]
            if v == "table":
                d = pu[..., 2].min(axis=1) - ru
            elif v.startswith("keep_out["):
                zone = model.world.keep_out[int(v[9:-1])]
                if isinstance(zone, Box):
                    d = box_sdf(pu, zone.center, zone.half_size).min(axis=1) - ru
                else:
                    d = np.linalg.norm(pu - np.asarray(zone.center), axis=-1).min(axis=1) - ru - zone.radius
            elif isinstance(links[v].shape, Box):
                d = to_box(pu, v).min(axis=1) - ru
            else:  # every point pair's squared distance, |a|^2 + |b|^2 - 2 a.b, batched over the poses
                pv, rv = clouds[v]
                d2 = squares[u][:, :, None] + squares[v][:, None] - 2 * np.matmul(pu, pv.transpose(0, 2, 1))
                d = np.sqrt(np.maximum(d2.min(axis=(1, 2)), 0.0)) - ru - rv
            worst = np.minimum(worst, d + model.geometry.nest_depth(u, v))
        return worst

    return np.concatenate([worst_of(Q[i : i + chunk]) for i in range(0, len(Q), chunk)]) if len(Q) else np.empty(0)


# ------------------------------------------------------------------ ROBOTIS-style example programs (issue 17)
# DynamixelSDK's own Python examples (ROBOTIS-GIT/DynamixelSDK, python/tests/protocol2_0/ping.py, read_write.py,
# sync_read_write.py; Apache-2.0, (c) ROBOTIS) are not shipped in the dynamixel-sdk wheel, and copying them here
# would take the licence's full terms (its text and change notices), so these programs are written for this
# repository after their structure: a module-level getch() that puts the terminal on stdin in raw mode (termios),
# "Press any key to continue! (or press ESC to quit!)" prompts, PortHandler/PacketHandler(2.0) on DEVICENAME at
# 57600 baud, the X-series addresses, and the same calls and printed lines.  Set RETARGET_ROBOTIS_EXAMPLES to a
# DynamixelSDK checkout's python/tests/protocol2_0 folder to run ROBOTIS's files themselves (DEVICENAME replaced).

_ROBOTIS_PROLOGUE = """
import sys, tty, termios
fd = sys.stdin.fileno()
old_settings = termios.tcgetattr(fd)
def getch():
    try:
        tty.setraw(sys.stdin.fileno())
        ch = sys.stdin.read(1)
    finally:
        termios.tcsetattr(fd, termios.TCSADRAIN, old_settings)
    return ch
from dynamixel_sdk import *
ADDR_TORQUE_ENABLE = 64
ADDR_GOAL_POSITION = 116
ADDR_PRESENT_POSITION = 132
DXL_MINIMUM_POSITION_VALUE = 0
DXL_MAXIMUM_POSITION_VALUE = 4095
BAUDRATE = 57600
PROTOCOL_VERSION = 2.0
DEVICENAME = '/dev/ttyUSB0'
TORQUE_ENABLE, TORQUE_DISABLE = 1, 0
DXL_MOVING_STATUS_THRESHOLD = 20
portHandler = PortHandler(DEVICENAME)
packetHandler = PacketHandler(PROTOCOL_VERSION)
if portHandler.openPort():
    print("Succeeded to open the port")
else:
    print("Failed to open the port"); getch(); quit()
if portHandler.setBaudRate(BAUDRATE):
    print("Succeeded to change the baudrate")
else:
    print("Failed to change the baudrate"); getch(); quit()
def report(result, error, ok=None):
    if result != COMM_SUCCESS:
        print("%s" % packetHandler.getTxRxResult(result))
    elif error != 0:
        print("%s" % packetHandler.getRxPacketError(error))
    elif ok:
        print(ok)
"""

ROBOTIS_EXAMPLES: dict[str, str] = {
    "ping": _ROBOTIS_PROLOGUE
    + """
DXL_ID = 1
model_number, result, error = packetHandler.ping(portHandler, DXL_ID)
report(result, error, "[ID:%03d] ping Succeeded. Dynamixel model number : %d" % (DXL_ID, model_number))
portHandler.closePort()
""",
    "read_write": _ROBOTIS_PROLOGUE
    + """
DXL_ID = 1
index = 0
goals = [DXL_MINIMUM_POSITION_VALUE, DXL_MAXIMUM_POSITION_VALUE]
result, error = packetHandler.write1ByteTxRx(portHandler, DXL_ID, ADDR_TORQUE_ENABLE, TORQUE_ENABLE)
report(result, error, "Dynamixel has been successfully connected")
while 1:
    print("Press any key to continue! (or press ESC to quit!)")
    if getch() == chr(0x1b):
        break
    result, error = packetHandler.write4ByteTxRx(portHandler, DXL_ID, ADDR_GOAL_POSITION, goals[index])
    report(result, error)
    while 1:
        present, result, error = packetHandler.read4ByteTxRx(portHandler, DXL_ID, ADDR_PRESENT_POSITION)
        report(result, error)
        print("[ID:%03d] GoalPos:%03d  PresPos:%03d" % (DXL_ID, goals[index], present))
        if not abs(goals[index] - present) > DXL_MOVING_STATUS_THRESHOLD:
            break
    index = 1 - index
result, error = packetHandler.write1ByteTxRx(portHandler, DXL_ID, ADDR_TORQUE_ENABLE, TORQUE_DISABLE)
report(result, error)
portHandler.closePort()
""",
    "sync_read_write": _ROBOTIS_PROLOGUE
    + """
DXL1_ID, DXL2_ID = 1, 2
LEN = 4
index = 0
goals = [DXL_MINIMUM_POSITION_VALUE, DXL_MAXIMUM_POSITION_VALUE]
groupSyncWrite = GroupSyncWrite(portHandler, packetHandler, ADDR_GOAL_POSITION, LEN)
groupSyncRead = GroupSyncRead(portHandler, packetHandler, ADDR_PRESENT_POSITION, LEN)
for dxl_id in (DXL1_ID, DXL2_ID):
    result, error = packetHandler.write1ByteTxRx(portHandler, dxl_id, ADDR_TORQUE_ENABLE, TORQUE_ENABLE)
    report(result, error, "Dynamixel#%d has been successfully connected" % dxl_id)
    if groupSyncRead.addParam(dxl_id) != True:
        print("[ID:%03d] groupSyncRead addparam failed" % dxl_id); quit()
while 1:
    print("Press any key to continue! (or press ESC to quit!)")
    if getch() == chr(0x1b):
        break
    goal = goals[index]
    param = [DXL_LOBYTE(DXL_LOWORD(goal)), DXL_HIBYTE(DXL_LOWORD(goal)),
             DXL_LOBYTE(DXL_HIWORD(goal)), DXL_HIBYTE(DXL_HIWORD(goal))]
    for dxl_id in (DXL1_ID, DXL2_ID):
        if groupSyncWrite.addParam(dxl_id, param) != True:
            print("[ID:%03d] groupSyncWrite addparam failed" % dxl_id); quit()
    result = groupSyncWrite.txPacket()
    if result != COMM_SUCCESS:
        print("%s" % packetHandler.getTxRxResult(result))
    groupSyncWrite.clearParam()
    while 1:
        result = groupSyncRead.txRxPacket()
        if result != COMM_SUCCESS:
            print("%s" % packetHandler.getTxRxResult(result))
        for dxl_id in (DXL1_ID, DXL2_ID):
            if groupSyncRead.isAvailable(dxl_id, ADDR_PRESENT_POSITION, LEN) != True:
                print("[ID:%03d] groupSyncRead getdata failed" % dxl_id); quit()
        p1 = groupSyncRead.getData(DXL1_ID, ADDR_PRESENT_POSITION, LEN)
        p2 = groupSyncRead.getData(DXL2_ID, ADDR_PRESENT_POSITION, LEN)
        print("[ID:%03d] GoalPos:%03d  PresPos:%03d\\t[ID:%03d] GoalPos:%03d  PresPos:%03d"
              % (DXL1_ID, goal, p1, DXL2_ID, goal, p2))
        if not ((abs(goal - p1) > DXL_MOVING_STATUS_THRESHOLD) and (abs(goal - p2) > DXL_MOVING_STATUS_THRESHOLD)):
            break
    index = 1 - index
groupSyncRead.clearParam()
for dxl_id in (DXL1_ID, DXL2_ID):
    result, error = packetHandler.write1ByteTxRx(portHandler, dxl_id, ADDR_TORQUE_ENABLE, TORQUE_DISABLE)
    report(result, error)
portHandler.closePort()
""",
}


def robotis_example(name: str, device: str) -> str:
    """The source of example ``name`` ("ping", "read_write", "sync_read_write") with DEVICENAME = ``device``:
    ROBOTIS's own file when RETARGET_ROBOTIS_EXAMPLES names a folder holding it, else the program above."""
    import re

    folder = os.environ.get("RETARGET_ROBOTIS_EXAMPLES")
    source = ROBOTIS_EXAMPLES[name]
    if folder and (Path(folder) / f"{name}.py").is_file():
        source = (Path(folder) / f"{name}.py").read_text()
    changed, n = re.subn(r"^DEVICENAME(\s*)=.*$", f"DEVICENAME\\1= {device!r}", source, count=1, flags=re.M)
    assert n == 1, f"no DEVICENAME line in example {name}"
    return changed


def run_with_keys(script: Path, keys: Sequence[bytes], *, prompt: bytes, timeout: float = 30.0) -> str:
    """Run ``python script`` with a terminal on stdin (a pty, as the examples' getch needs) and type ``keys``, one
    per ``prompt`` it prints; returns everything it printed.  Fails after ``timeout`` seconds.

    getch() sets raw mode with TCSAFLUSH, which discards a key typed before it: a key that brought no new output
    within 0.2 s (the program was not reading yet) is typed again.
    """
    import select
    import subprocess
    import sys
    import time

    master, slave = os.openpty()
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen([sys.executable, str(script)], stdin=slave, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, env=env)  # fmt: skip
    os.close(slave)
    assert proc.stdout is not None
    out, typed, deadline = b"", 0, time.monotonic() + timeout
    sent: tuple[float, int] | None = None  #: (when, len(out) then) of the key typed last, until output confirms it
    try:
        while True:
            if time.monotonic() > deadline:
                proc.kill()
                raise AssertionError(f"{script.name} still running after {timeout} s:\n{out.decode(errors='replace')}")
            if select.select([proc.stdout], [], [], 0.02)[0]:
                chunk = os.read(proc.stdout.fileno(), 65536)
                if not chunk:
                    break
                out += chunk
            if sent is not None and out[sent[1] :].strip():
                sent, typed = None, typed + 1  # the program answered the key
            if typed < len(keys) and out.count(prompt + b"\n") > typed:
                if sent is None or time.monotonic() - sent[0] > 0.2:
                    if proc.poll() is None:
                        os.write(master, keys[typed])
                        sent = (time.monotonic(), len(out))
    finally:
        proc.wait(timeout=10)
        os.close(master)
    return out.decode(errors="replace")


# ------------------------------------------------------------------------------------------ calibration (issue 18)


def random_mounting(arm, seed: int, *, reverse: bool = True, spread: int = 400):
    """A seeded :class:`sim.mount.Mounting` for ``arm``: every joint servo's horn up to ``spread`` pulses off, and
    (``reverse``) about a third of the primary servos turned round (shadows keep their primary's way)."""
    from sim.mount import Mounting

    rng = random.Random(seed)
    offsets = {s.id: rng.randint(-spread, spread) for j in arm.joints for s in j.servos}
    turned: set[int] = set()
    if reverse:
        for j in arm.joints:
            if rng.random() < 0.35:
                turned.update(s.id for s in j.servos)
    return Mounting(offsets, frozenset(turned))


def mount_query(mounting) -> str:
    """``mount=...&reverse=...`` of a Mounting, for a ``sim://ARM?`` URL."""
    parts = ["mount=" + ",".join(f"{i}:{m:+d}" for i, m in sorted(mounting.offsets.items()))]
    if mounting.reversed:
        parts.append("reverse=" + ",".join(map(str, sorted(mounting.reversed))))
    return "&".join(parts)


def calibration_truth(arm, mounting) -> dict[int, tuple[int, int]]:
    """Servo ID -> the (direction, offset) a calibration of the mounted ``arm`` must find."""
    return {s.id: mounting.truth(s.id, s.direction, s.offset) for j in arm.joints for s in j.servos}


class ScriptedPrompter:
    """A :class:`retarget.calibrate.prompts.Prompter` for tests: records every prompt, answers confirmations from
    ``answers`` (question substring -> answer; default yes), and raises KeyboardInterrupt at the first prompt that
    contains ``interrupt_on``, as a Ctrl-C there would."""

    def __init__(self, *, answers: dict[str, bool] | None = None, interrupt_on: str | None = None):
        self.prompts: list[str] = []
        self.lines: list[str] = []
        self.answers = answers or {}
        self.interrupt_on = interrupt_on

    def _prompt(self, text: str) -> None:
        self.prompts.append(text)
        if self.interrupt_on is not None and self.interrupt_on in text:
            raise KeyboardInterrupt

    def say(self, text: str) -> None:
        self.lines.append(text)

    def enter(self, prompt: str) -> None:
        self._prompt(prompt)

    def confirm(self, question: str, *, default: bool) -> bool:
        self._prompt(question)
        return next((v for k, v in self.answers.items() if k in question), True)

    def watch(self, prompt, sample, step=None) -> None:
        self._prompt(prompt)
        self.lines.append(sample())
        while step is not None and step():
            self.lines.append(sample())


class Tmux:
    """A private tmux server (its own socket, killed on close) running one command in a wide window, for tests of
    interactive prompts in a real terminal: :meth:`wait_for` text on the screen, :meth:`keys` to type."""

    def __init__(self, name: str):
        import shutil

        if shutil.which("tmux") is None:
            pytest.skip("tmux is not installed (apt-get install -y tmux)")
        self.socket = f"retarget-test-{os.getpid()}-{name}"
        self.target = "t"

    def _run(self, *args: str) -> str:
        import subprocess

        done = subprocess.run(["tmux", "-L", self.socket, *args], capture_output=True, text=True, timeout=10)
        return done.stdout

    def start(self, command: str, *, cwd: Path) -> None:
        """Run ``command`` (a shell line) in a new 200 x 50 window; ``EXIT=<status>`` is printed when it ends."""
        self._run("new-session", "-d", "-s", self.target, "-x", "200", "-y", "50", "-c", str(cwd),
                  f"{command}; echo EXIT=$?; sleep 30")  # fmt: skip

    def screen(self) -> str:
        return self._run("capture-pane", "-p", "-J", "-S", "-200", "-t", self.target)

    def wait_for(self, text: str, *, timeout: float = 20.0, count: int = 1) -> str:
        """The screen once ``text`` is on it ``count`` times; fails after ``timeout`` s with the screen."""
        import time

        deadline = time.monotonic() + timeout
        while True:
            screen = self.screen()
            if screen.count(text) >= count:
                return screen
            if time.monotonic() > deadline:
                raise AssertionError(f"{text!r} not on the screen after {timeout} s:\n{screen}")
            time.sleep(0.03)

    def keys(self, *keys: str) -> None:
        """Type ``keys`` (tmux key names: "Enter", "C-c", or literal text)."""
        self._run("send-keys", "-t", self.target, *keys)

    def close(self) -> None:
        self._run("kill-server")


def start_sim_server(*argv: str):
    """``retarget sim --tcp 127.0.0.1:0 --control 127.0.0.1:0 --no-wire *argv`` as a process: (process, the
    socket:// URL to open, the control address)."""
    import select
    import subprocess
    import sys

    proc = subprocess.Popen(
        [sys.executable, "-m", "retarget", "sim", "--tcp", "127.0.0.1:0", "--control", "127.0.0.1:0", "--no-wire",
         *argv],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, bufsize=0,
    )  # fmt: skip
    data = b""
    assert proc.stdout is not None
    while data.count(b"\n") < 2:  # unbuffered: select sees what readline would have kept in a buffer
        if not select.select([proc.stdout], [], [], 30.0)[0]:
            proc.kill()
            pytest.fail(f"retarget sim printed nothing in 30 s: {proc.communicate()[1]!r}")
        data += os.read(proc.stdout.fileno(), 4096)
    url, control = data.decode().split("\n")[:2]
    return proc, url.strip(), control.strip()


def sim_control(address: str, command: str) -> dict:
    """One command on a ``retarget sim --control HOST:PORT`` socket; its JSON answer."""
    import socket

    host, _, port = address.rpartition(":")
    with socket.create_connection((host, int(port)), timeout=10) as s:
        s.sendall(command.encode() + b"\n")
        data = b""
        while not data.endswith(b"\n"):
            chunk = s.recv(65536)
            if not chunk:
                break
            data += chunk
    return json.loads(data)


# ------------------------------------------------------------------ a hand that pinches (gripper from the clip)
PINCH_ANGLE = 48.59  #: degrees each of thumb and index turns (about Y) until their tips meet


def pinching_hand_bvh(closed: np.ndarray, *, thumb: bool = True, frame_time: float = 1 / 30) -> str:
    """BVH text of ``rig()`` whose left hand has a thumb (``LeftHandThumb1 > 2``, 6 units to +Z) and an index
    (``LeftHandIndex1 > 2``, 6 units to -Z), each 8 units to the tip along +X, on a 25-unit forearm: open, the tips
    are 12 apart; at ``closed[k]`` = 1 both turn ``PINCH_ANGLE`` toward each other and the tips meet.  ``closed``:
    ``(n_frames,)`` 0..1.  ``thumb=False``: a middle and an index finger 2 units either side of the hand's axis
    instead, which fold 170 degrees back toward the wrist at ``closed`` = 1 (a fist, for the curl rule)."""
    root = rig()
    hand = joints_in_order(root)[[j.name for j in joints_in_order(root)].index("LeftHand")]
    first, side = ("LeftHandThumb", 6) if thumb else ("LeftHandMiddle", 2)
    hand.children = [
        J(f"{first}1", (3, 0, side), children=[J(f"{first}2", (5, 0, 0), end=(3, 0, 0))]),
        J("LeftHandIndex1", (3, 0, -side), children=[J("LeftHandIndex2", (5, 0, 0), end=(3, 0, 0))]),
    ]
    c = np.asarray(closed, dtype=np.float64)
    if thumb:
        values = {(f"{first}1", "Yrotation"): PINCH_ANGLE * c, ("LeftHandIndex1", "Yrotation"): -PINCH_ANGLE * c}
    else:
        values = {(f"{first}1", "Zrotation"): 170.0 * c, ("LeftHandIndex1", "Zrotation"): 170.0 * c}
    return bvh_text(root, pose(root, len(c), values), frame_time=frame_time)


# ------------------------------------------------------------------ rigs
def sampled_min_clearance(rig, poses, spacing=0.004):
    """The arm-arm clearance by brute force: points every ``spacing`` m along each capsule's segment (a box's
    bounding sphere is one point), each arm's shapes placed by its own FK chain product written here."""
    clouds = []
    for rig_arm in rig.arms:
        arm, q = rig_arm.arm, np.asarray(poses[rig_arm.name], dtype=np.float64)
        frames = [np.eye(4)]
        for joint, angle in zip(arm.joints, q, strict=True):
            x, y, z = joint.origin_xyz
            r, p, w = joint.origin_rpy
            cr, sr, cp, sp, cw, sw = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(w), np.sin(w)
            origin = np.eye(4)
            origin[:3, :3] = [[cw * cp, cw * sp * sr - sw * cr, cw * sp * cr + sw * sr],
                              [sw * cp, sw * sp * sr + cw * cr, sw * sp * cr - cw * sr],
                              [-sp, cp * sr, cp * cr]]  # fmt: skip
            origin[:3, 3] = (x, y, z)
            k = np.asarray(joint.axis, dtype=np.float64) / np.linalg.norm(joint.axis)
            K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
            spin = np.eye(4)
            spin[:3, :3] = np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K
            frames.append(frames[-1] @ origin @ spin)
        place = rig_arm.placement.matrix
        points, radii = [], []
        for link in arm.geometry.links:
            shape, T = link.shape, place @ frames[link.frame]
            if hasattr(shape, "radius"):
                a, b = np.asarray(shape.a), np.asarray(shape.b)
                n = max(2, int(np.ceil(np.linalg.norm(b - a) / spacing)) + 1)
                local = a + np.linspace(0, 1, n)[:, None] * (b - a)
                radius = shape.radius
            else:
                local, radius = np.asarray(shape.center)[None], float(np.linalg.norm(shape.half_size))
            points.append(local @ T[:3, :3].T + T[:3, 3])
            radii.append(np.full(len(local), radius))
        clouds.append((np.concatenate(points), np.concatenate(radii)))
    (pa, ra), (pb, rb) = clouds
    gaps = np.linalg.norm(pa[:, None] - pb[None], axis=-1) - ra[:, None] - rb[None]
    return float(gaps.min())


class SignalAfterSyncWrites(collections.deque):  # type: ignore[type-arg]
    """A simulator log (``simbus.log``) that sends ``signum`` (default SIGINT, as Ctrl-C) to this process when the
    ``n``-th SYNC_WRITE is logged: counted as each instruction is appended, under the simulator's lock, so nothing
    iterates the log while the loop appends to it, and no watcher thread can be starved (or die) and leave a run
    going.  The signal is handled in the main thread, as from a terminal."""

    def __init__(self, n: int, signum: int = signal.SIGINT, *, maxlen: int | None):
        super().__init__(maxlen=maxlen)
        self.n, self.signum, self.sync_writes = n, signum, 0

    def append(self, entry: LogEntry) -> None:
        super().append(entry)
        if entry.instruction == Instruction.SYNC_WRITE:
            self.sync_writes += 1
            if self.sync_writes == self.n:
                os.kill(os.getpid(), self.signum)
