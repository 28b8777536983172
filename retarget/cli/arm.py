"""``retarget arm``: show, check and query an arm description.

Loads a bundled arm, a TOML arm file or a URDF (with its .servos.toml file), which
validates it, and prints its joints with axes, limits, velocities and servos, the
gripper, the home and rest poses, the reach and the tool point at home.  --list
lists the bundled arms; --ik X,Y,Z solves the CCD IK for a point in the base
frame (metres) and prints the joint angles in degrees; --json prints JSON.
"""

from __future__ import annotations

import argparse
import math
import sys
from typing import Any

from retarget.arm.config import list_arms
from retarget.arm.load import load_arm
from retarget.cli import print_json
from retarget.cli._arm import load_arm_naming_links
from retarget.errors import ConfigError
from retarget.ik.ccd import CCDSolver
from retarget.mapping.config import MappingConfig

EXAMPLES = """\
examples:
  retarget arm                                   the default arm (wx250s)
  retarget arm --list                            the bundled arms
  retarget arm vx300s --json                     one arm as JSON on stdout
  retarget arm my_arm.toml                       check a TOML arm file
  retarget arm robot.urdf --tip ee_link          import a URDF chain (servos from robot.servos.toml)
  retarget arm wx250s --ik 0.35,0,0.25           solve IK for a point (metres, base frame), from home
  retarget arm wx250s --check 0,-100,90,0,45,0   each collision pair's clearance in a pose (degrees)
  retarget arm wx250s --check rest --json        the same for the rest pose, as JSON
"""


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    parser: argparse.ArgumentParser = subparsers.add_parser(
        "arm",
        help="show, check and query an arm description (TOML or URDF)",
        description=__doc__.split("\n\n")[1].replace("\n", " "),
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("arm", nargs="?", default="wx250s", help="bundled name, .toml or .urdf (default wx250s)")
    parser.add_argument("--base", help="URDF base link, when the URDF has several roots")
    parser.add_argument("--tip", help="URDF tip link (the tool point), when the chain has several leaves")
    parser.add_argument("--list", action="store_true", help="list the bundled arms and exit")
    parser.add_argument("--ik", metavar="X,Y,Z", help="solve IK for this point (metres, base frame)")
    parser.add_argument(
        "--from", dest="start", choices=("home", "rest"), default="home", help="IK start pose (default home)"
    )
    parser.add_argument(
        "--check", metavar="Q", help="print each collision pair's clearance in pose Q: degrees A,B,..., or home/rest"
    )
    parser.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    return parser


def parse_pose(arm: Any, text: str, option: str = "--check") -> list[float]:
    """``"home"``, ``"rest"`` or one angle per joint in degrees ``"A,B,..."`` -> radians; ConfigError otherwise."""
    if text in ("home", "rest"):
        return [float(v) for v in getattr(arm, text).tolist()]
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        values = []
    if len(values) != arm.n_joints or not all(math.isfinite(v) for v in values):
        raise ConfigError(f"expected home, rest or {arm.n_joints} finite angles in degrees", key=option, value=text)
    return [math.radians(v) for v in values]


def check(arm: Any, q: list[float]) -> dict[str, Any]:
    """Every collision pair's clearance (mm) in pose ``q`` radians, worst first."""
    from retarget.collision import CollisionModel

    model = CollisionModel.for_arm(arm)
    d = model.distances(q)
    pairs = sorted(zip(model.pair_names, d.tolist(), strict=True), key=lambda item: item[1])
    return {
        "q_deg": [round(math.degrees(v), 4) for v in q],
        "clearance_mm": round(model.clearance * 1e3, 3),
        "clear": model.is_clear(q),
        "within_limits": arm.within_limits(q, atol=1e-9),
        "pairs": [{"pair": name, "clearance_mm": round(v * 1e3, 3)} for name, v in pairs],
    }


def parse_point(text: str, option: str = "--ik") -> tuple[float, float, float]:
    """``"X,Y,Z"`` metres -> a finite 3-tuple; ConfigError naming the option otherwise."""
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        values = ()
    if len(values) != 3 or not all(math.isfinite(v) for v in values):
        raise ConfigError("expected three finite numbers X,Y,Z in metres", key=option, value=text)
    x, y, z = values
    return x, y, z


def run(args: argparse.Namespace) -> int:
    if args.list:
        names = list_arms()
        rows = [(n, load_arm(n).title) for n in names]
        if args.json:
            print_json([{"name": n, "title": t} for n, t in rows])
        else:
            for n, t in rows:
                print(f"{n:10s} {t}")
        return 0
    arm = load_arm_naming_links(args.arm, base=args.base, tip=args.tip)
    MappingConfig.from_table(arm.mapping, path=arm.source)  # the [mapping] table too: an arm that checks out runs
    report = describe(arm)
    if args.ik is not None:
        report["ik"] = solve(arm, parse_point(args.ik), args.start)
    if args.check is not None:
        report["check"] = check(arm, parse_pose(arm, args.check))
    if args.json:
        print_json(report)
    else:
        sys.stdout.write(format_text(report))
    return 0


def describe(arm: Any) -> dict[str, Any]:
    """The arm as plain JSON-able data; angles in degrees, lengths in metres."""
    T, _ = arm.fk(arm.home)
    joints = []
    for j in arm.joints:
        joints.append(
            {
                "name": j.name,
                "xyz": list(j.origin_xyz),
                "rpy_deg": [round(math.degrees(v), 6) for v in j.origin_rpy],
                "axis": [round(v, 9) for v in j.axis],
                "limits_deg": [round(math.degrees(j.lower), 4), round(math.degrees(j.upper), 4)],
                "max_velocity_dps": round(math.degrees(j.max_velocity), 3),
                "servos": [
                    {"id": s.id, "model": s.model, "direction": s.direction, "offset": s.offset} for s in j.servos
                ],
            }
        )
    gripper = None
    if arm.gripper is not None:
        g = arm.gripper
        gripper = {
            "name": g.name,
            "servo": {"id": g.servo.id, "model": g.servo.model, "direction": g.servo.direction},
            "limits_deg": [round(math.degrees(g.lower), 4), round(math.degrees(g.upper), 4)],
        }
    return {
        "name": arm.name,
        "title": arm.title,
        "source": None if arm.source is None else str(arm.source),
        "baud": arm.baud,
        "joints": joints,
        "gripper": gripper,
        "home_deg": [round(math.degrees(v), 4) for v in arm.home.tolist()],
        "rest_deg": [round(math.degrees(v), 4) for v in arm.rest.tolist()],
        "tool_xyz": list(arm.tool_xyz),
        "tool_at_home": [round(float(v), 6) for v in T[:3, 3]],
        "reach": round(CCDSolver(arm).reach, 6),
        "servo_ids": list(arm.servo_ids),
    }


def solve(arm: Any, target: tuple[float, float, float], start: str) -> dict[str, Any]:
    q0 = arm.home if start == "home" else arm.rest
    r = CCDSolver(arm).solve(target, q0)
    reached, _ = arm.fk(r.q)
    return {
        "target": list(target),
        "from": start,
        "q_deg": [round(math.degrees(v), 4) for v in r.q],
        "reached": [round(float(v), 6) for v in reached[:3, 3]],
        "error_mm": round(r.error * 1e3, 4),
        "sweeps": r.iterations,
        "restarts": r.restarts,
        "converged": r.converged,
    }


def _axis_name(axis: list[float]) -> str:
    for i, name in enumerate("xyz"):
        if abs(abs(axis[i]) - 1) < 1e-9:
            return ("-" if axis[i] < 0 else "") + name
    return "(" + ", ".join(f"{v:.3g}" for v in axis) + ")"


def format_text(report: dict[str, Any]) -> str:
    lines = [f"{report['name']}: {report['title']}"]
    if report["source"]:
        lines.append(f"  from {report['source']}")
    hx, hy, hz = report["tool_at_home"]
    lines.append(
        f"  baud {report['baud']}, reach {report['reach']:.3f} m, tool point at home ({hx:.4f}, {hy:.4f}, {hz:.4f}) m"
    )
    lines.append("")
    lines.append(f"  {'joint':16s} {'axis':6s} {'limits (deg)':>20s} {'vel (deg/s)':>12s}  servos")
    for j in report["joints"]:
        lo, hi = j["limits_deg"]
        servos = ", ".join(
            f"{s['id']} {s['model']}"
            + (" reverse" if s["direction"] < 0 else "")
            + (f" {s['offset']:+d}" if s["offset"] else "")
            for s in j["servos"]
        )
        axis = _axis_name(j["axis"])
        lines.append(f"  {j['name']:16s} {axis:6s} {lo:9.2f} .. {hi:7.2f} {j['max_velocity_dps']:12.1f}  {servos}")
    g = report["gripper"]
    if g:
        lo, hi = g["limits_deg"]
        lines.append(
            f"  {g['name']:16s} {'':6s} {lo:9.2f} .. {hi:7.2f} {'':12s}  {g['servo']['id']} {g['servo']['model']}"
        )
    lines.append("")
    lines.append("  home (deg) " + " ".join(f"{v:.2f}" for v in report["home_deg"]))
    lines.append("  rest (deg) " + " ".join(f"{v:.2f}" for v in report["rest_deg"]))
    ik = report.get("ik")
    if ik:
        x, y, z = ik["target"]
        rx, ry, rz = ik["reached"]
        state = "converged" if ik["converged"] else "NOT converged (closest pose)"
        lines.append("")
        lines.append(f"  ik to ({x}, {y}, {z}) from {ik['from']}: {state}, error {ik['error_mm']:.3f} mm, "
                     f"{ik['sweeps']} sweeps, {ik['restarts']} restarts")  # fmt: skip
        lines.append("  q (deg)    " + " ".join(f"{v:.2f}" for v in ik["q_deg"]))
        lines.append(f"  reached    ({rx:.4f}, {ry:.4f}, {rz:.4f}) m")
    c = report.get("check")
    if c:
        state = "clear" if c["clear"] else "NOT clear"
        limits = "" if c["within_limits"] else " (outside the joint limits)"
        lines.append("")
        lines.append(f"  check q (deg) {' '.join(f'{v:.2f}' for v in c['q_deg'])}{limits}: {state}, "
                     f"clearance {c['clearance_mm']:g} mm")  # fmt: skip
        for p in c["pairs"]:
            flag = "  <" if p["clearance_mm"] < c["clearance_mm"] else ""
            lines.append(f"    {p['pair']:32s} {p['clearance_mm']:9.1f} mm{flag}")
    return "\n".join(lines) + "\n"
