"""Write small BVH files in tests: a joint tree and a frame array -> BVH text."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

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
