"""``retarget inspect``: what is in a BVH file.

Prints the joint tree with each joint's channels, the frame count, frame rate
and duration, the rotation orders used, a units guess from the skeleton's
height (and what the height was measured on), and the detected arm chains
(shoulder > elbow > wrist) with their bone lengths, how each was found (names,
structure, explicit) and the candidates not chosen with the reason, so a user
sees what to rename or which joints to name with ``--arm-joints``.  ``--json``
prints the same on stdout as one JSON object.
"""

from __future__ import annotations

import argparse
import sys
from collections import Counter
from pathlib import Path
from typing import Any

from retarget.bvh import DEMO_CLIP, Motion, load_bvh
from retarget.cli import print_json
from retarget.errors import BvhError

DESCRIPTION = (
    "Show what is in a BVH file: the joint tree with each joint's channels, frame count, frame rate and duration, "
    "the rotation orders used, a units guess from the skeleton's height, and the detected arm chains "
    "(shoulder > elbow > wrist) with their bone lengths, how each was found (names, structure, explicit) and why "
    "other candidates were not chosen. --json prints the same as one JSON object on stdout."
)

EXAMPLES = """\
examples:
  retarget inspect                                 the bundled demo clip
  retarget inspect dance.bvh                       joint tree, frames, fps, channel orders, units, arm chains
  retarget inspect dance.bvh --json | jq .arms     the same as JSON on stdout
  retarget inspect rig.bvh --side left --arm-joints upper_arm.L forearm.L "forearm.L/End Site"
"""

_UNIT_NAMES = {"m": "metres", "cm": "centimetres", "mm": "millimetres", "in": "inches", "unknown": "unknown"}
_BASIS = {"rest pose": "", "motion": " in the motion", "bone lengths": " from the bone lengths"}
#: At most this many candidates not chosen are printed per side in the text report (all are in the JSON).
SHOWN_REJECTED = 6


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    parser: argparse.ArgumentParser = subparsers.add_parser(
        "inspect",
        help="show a BVH file's skeleton, frame rate, units and arm chains",
        description=DESCRIPTION,
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("file", nargs="?", metavar="FILE", help="a .bvh file (default: the bundled demo clip)")
    parser.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    parser.add_argument(
        "--side", choices=("left", "right", "both"), default="both", help="which arm chains to show (default both)"
    )
    parser.add_argument(
        "--arm-joints",
        nargs=3,
        metavar=("SHOULDER", "ELBOW", "WRIST"),
        help="name the arm joints instead of detecting them (needs --side left or right); "
        "the wrist may be '<joint>/End Site'",
    )
    return parser


def run(args: argparse.Namespace) -> int:

    if args.arm_joints and args.side == "both":
        raise BvhError("Expected --side left or right with --arm-joints, got --side both", path=args.file)
    path = Path(args.file) if args.file else DEMO_CLIP
    motion = load_bvh(path)
    report = describe(motion, sides=("left", "right") if args.side == "both" else (args.side,), names=args.arm_joints)
    if args.json:
        print_json(report)
    else:
        sys.stdout.write(format_text(report))
    return 0


def describe(
    motion: Motion, *, sides: tuple[str, ...] = ("left", "right"), names: list[str] | None = None
) -> dict[str, Any]:
    """The inspect report of ``motion`` as plain JSON-able data."""
    units = motion.guess_units()
    joints = []
    for j, name in enumerate(motion.joint_names):
        lay = motion.layout[j]
        joints.append(
            {
                "name": name,
                "parent": int(motion.parents[j]),
                "offset": [float(v) for v in motion.offsets[j]],
                "channels": list(lay.names),
                "rotation_order": lay.rotation_order,
                "end_sites": [k for k, e in enumerate(motion.end_sites) if e.parent == j],
            }
        )
    explicit = (names[0], names[1], names[2]) if names else None  # argparse gives exactly 3 (nargs=3)
    arms = {side: describe_arm(motion, side, explicit) for side in sides}
    orders = Counter(j["rotation_order"] for j in joints if j["rotation_order"])
    return {
        "file": str(motion.path) if motion.path else None,
        "frames": motion.n_frames,
        "frame_time": motion.frame_time,
        "fps": motion.fps,
        "duration": motion.duration,
        "n_joints": motion.n_joints,
        "n_end_sites": len(motion.end_sites),
        "n_channels": int(motion.channels.shape[1]),
        "rotation_orders": dict(orders.most_common()),
        "units": {
            "guess": units.unit,
            "height": units.height,
            "up_axis": units.up_axis,
            "metres_per_unit": units.metres_per_unit,
            "basis": units.basis,
            "skeleton_height": motion.skeleton_height(),
        },
        "joints": joints,
        "end_sites": [{"parent": e.parent, "offset": list(e.offset)} for e in motion.end_sites],
        "arms": arms,
    }


def describe_arm(motion: Motion, side: str, names: tuple[str, str, str] | None = None) -> dict[str, Any]:
    """One side's arm report: the chain and its bone lengths, or ``error``; with ``how`` and ``rejected`` always.

    ``how`` says how the chain was found, or why none was; ``rejected`` lists the candidates not chosen as
    ``{"chain": [shoulder, elbow, wrist], "reason": ...}``; ``warnings`` the unusual bone lengths.  A chain found
    but degenerate (bones under 2 % or over 75 % of the skeleton's height) has its joints and ``error``.
    """
    try:
        search = motion.arm_search(side, names=names)
    except BvhError as exc:  # a bad explicit name
        return {"error": exc.message, "how": "named explicitly", "rejected": []}
    out: dict[str, Any] = {
        "how": search.detail,
        "rejected": [{"chain": list(r.names), "reason": r.reason} for r in search.rejected],
    }
    if search.found is None:
        return {"error": search.error, **out}
    try:
        chain = motion.arm_points(side, names=names)
    except BvhError as exc:  # a degenerate chain: found, but its bones are no arm's
        joints = dict(zip(("shoulder", "elbow", "wrist"), search.found.names, strict=True))
        return {"error": exc.message, **joints, "method": search.found.method, **out}
    upper, fore = chain.bone_lengths
    return {
        "shoulder": chain.names[0],
        "elbow": chain.names[1],
        "wrist": chain.names[2],
        "method": chain.method,
        "upper_arm_length": upper,
        "forearm_length": fore,
        "lengths_from": chain.lengths_from,
        "warnings": list(chain.warnings),
        **out,
    }


def format_text(report: dict[str, Any]) -> str:
    """The human-readable form of :func:`describe`'s report."""
    lines = []
    name = Path(report["file"]).name if report["file"] else "<bvh>"
    lines.append(f"{name}")
    lines.append(
        f"  frames     {report['frames']} at {report['fps']:.4g} fps (frame time {report['frame_time']:.7g} s), "
        f"{report['duration']:.2f} s"
    )
    lines.append(
        f"  skeleton   {report['n_joints']} joints, {report['n_end_sites']} End Sites, {report['n_channels']} channels"
    )
    orders = ", ".join(f"{o} ({n} joint{'s' if n != 1 else ''})" for o, n in report["rotation_orders"].items())
    lines.append(f"  rotations  {orders or 'none'} (intrinsic, in listed order)")
    u = report["units"]
    basis = _BASIS.get(u.get("basis", "rest pose"), "")
    if u["guess"] == "unknown":
        units = (
            f"unknown: {u['height']:.4g} units tall{basis} ({u['up_axis']} up); "
            f"{u['metres_per_unit']:.4g} m per unit would make it 1.7 m tall"
        )
    else:
        units = f"{_UNIT_NAMES[u['guess']]} ({u['height']:.4g} {u['guess']} tall{basis}, {u['up_axis']} up)"
    lines.append(f"  units      {units}")
    lines.append("")
    lines.append("joints:")
    children: dict[int, list[int]] = {}
    for j, joint in enumerate(report["joints"]):
        children.setdefault(joint["parent"], []).append(j)

    def walk(j: int, depth: int) -> None:
        joint = report["joints"][j]
        lay = _channel_summary(joint["channels"])
        lines.append(f"  {'  ' * depth}{joint['name']}  [{lay}]")
        for c in children.get(j, []):
            walk(c, depth + 1)
        for _ in joint["end_sites"]:
            lines.append(f"  {'  ' * (depth + 1)}End Site")

    for root in children.get(-1, []):
        walk(root, 0)
    lines.append("")
    lines.append("arm chains:")
    unit = u["guess"] if u["guess"] != "unknown" else "units"
    pad = " " * 9
    for side, arm in report["arms"].items():
        rejected = arm.get("rejected", [])
        if "error" in arm:
            if rejected and "shoulder" not in arm and arm.get("how"):  # none found: the reasons on their own lines
                lines.append(f"  {side:<6} none: {arm['how']}")
            else:  # a bad explicit name, or a degenerate chain (the message names its joints)
                lines.append(f"  {side:<6} none: {arm['error']}")
        else:
            rest = " (rest pose: no frames)" if arm.get("lengths_from") == "rest pose" else ""
            lines.append(
                f"  {side:<6} {arm['shoulder']} > {arm['elbow']} > {arm['wrist']}  "
                f"upper arm {arm['upper_arm_length']:.4g} {unit}, forearm {arm['forearm_length']:.4g} {unit}{rest} "
                f"(by {arm['method']})"
            )
            if arm.get("how"):
                lines.append(f"{pad}how: {arm['how']}")
            lines.extend(f"{pad}warning: {w}" for w in arm.get("warnings", []))
        for r in rejected[:SHOWN_REJECTED]:
            lines.append(f"{pad}not chosen: {' > '.join(r['chain'])} ({r['reason']})")
        if len(rejected) > SHOWN_REJECTED:
            lines.append(f"{pad}not chosen: {len(rejected) - SHOWN_REJECTED} more (see --json)")
    return "\n".join(lines) + "\n"


def _channel_summary(channels: list[str]) -> str:
    pos = "".join(c[0] for c in channels if c.endswith("position"))
    rot = "".join(c[0] for c in channels if c.endswith("rotation"))
    parts = []
    if pos:
        parts.append(f"pos {pos}")
    if rot:
        parts.append(f"rot {rot}")
    return ", ".join(parts) or "no channels"
