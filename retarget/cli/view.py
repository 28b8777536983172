"""``retarget view``: show a clip's retargeting: the skeleton, the targets and the posed arm on one timeline.

The clip is solved as ``retarget export`` solves it (no bus: IK warm-started tick by tick at ``--rate``, joint
and velocity limits applied, from the first target's solution), then logged to Rerun: a native viewer by
default, ``--record`` an .rrd file, ``--web`` the browser viewer on 127.0.0.1; ``--png`` draws a contact sheet
of evenly spaced moments instead (matplotlib, no GUI).  ``retarget view run.rrd --web`` serves a saved recording
to the browser.  ``--rig NAME|FILE`` shows every arm of a rig at its base pose in the rig's world frame, the
skeleton placed there as the rig's mapping places it (the clip solved as ``retarget export --rig`` solves it), with
the same outputs.  Needs ``pip install 'retarget[viz]'``.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from retarget.cli._rig_run import RigInputs, add_rig_option, load_rig_inputs, refuse_arm_options, rig_replay
from retarget.cli._view import add_view_arguments, outputs, serve_until_interrupted, start_web
from retarget.cli.export import offline_loop
from retarget.cli.replay import Inputs, add_clip_arguments, add_mapping_arguments, loop_config, mapping_overrides
from retarget.control import TickRecord
from retarget.control.clock import VirtualClock
from retarget.errors import ConfigError
from retarget.rig import RigReplay

if TYPE_CHECKING:
    from retarget.view.sinks import Outputs

EXAMPLES = """\
examples:
  retarget view                                   the demo clip on wx250s in a native Rerun viewer
  retarget view dance.bvh --record dance.rrd      save the timeline; open later with `rerun dance.rrd`
  retarget view dance.bvh --web                   serve the browser viewer on 127.0.0.1:9090 and print its URL;
                                                  from another machine: ssh -L 9090:127.0.0.1:9090
                                                  -L 9876:127.0.0.1:9876 HOST, then open the URL there
  retarget view dance.rrd --web                   serve a saved recording to the browser the same way
  retarget view dance.bvh --layout overlay        the human drawn in the robot's frame, wrist on the target
  retarget view dance.bvh --side left --start 2 --end 6 --png sheet.png   a contact sheet, no GUI
  retarget view dance.bvh --rig aloha --png rig.png   both arms of a rig in its world frame, each hand on its arm
  retarget view dance.bvh --rig wx250s-pair --record pair.rrd   the rig's timeline (also --web, or native)
"""


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    parser: argparse.ArgumentParser = subparsers.add_parser(
        "view",
        help="show a clip's skeleton, targets and solved arm on one timeline (Rerun), or a contact sheet PNG",
        description=__doc__.split("\n\n")[0].split(": ", 1)[1],
        epilog=EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_clip_arguments(parser)
    parser.add_argument(
        "--layout",
        default=None,
        choices=("side", "overlay"),
        help="human beside the robot (default) or in its frame (--rig: always in the rig's frame)",
    )
    parser.add_argument("--png", default=None, metavar="PNG", help="draw a contact sheet of the clip instead")
    parser.add_argument("--moments", default="6", metavar="N", help="moments on the contact sheet (default 6)")
    add_view_arguments(parser, live=False)
    add_mapping_arguments(parser)
    add_rig_option(parser)
    return parser


def solve(args: argparse.Namespace) -> tuple[Inputs, list[TickRecord]]:
    """The clip's ticks as ``retarget export`` computes them (its own inputs, config, loop and start pose)."""
    inputs, loop = offline_loop(args)
    records: list[TickRecord] = []
    loop.on_tick = records.append
    loop.run(None, q_start=loop.initial_pose())
    return inputs, records


def solve_rig(args: argparse.Namespace) -> tuple[RigInputs, RigReplay, list[TickRecord]]:
    """The rig's ticks as ``retarget export --rig`` computes them: :class:`~retarget.rig.RigReplay` dry run on a
    virtual clock from every arm's first pose (``--no-look-ahead`` is honoured here)."""
    inputs = load_rig_inputs(args, mapping_overrides(args))
    replay = rig_replay(
        inputs, loop_config(args, inputs.motion), clock=VirtualClock(), look_ahead=not args.no_look_ahead
    )
    records: list[TickRecord] = []
    replay.on_tick = records.append
    replay.run(None, q_start=replay.initial_pose())
    return inputs, replay, records


def run(args: argparse.Namespace) -> int:
    from retarget.view import require

    if args.rig is not None:
        return _run_rig(args)
    if args.clip is not None and Path(args.clip).suffix.lower() == ".rrd":
        return _serve_recording(args)
    if args.png is not None:
        require("--png", "matplotlib")
        moments = _moments(args.moments)
    else:
        out = outputs(args, spawn=True)
    inputs, records = solve(args)
    from retarget.view.columns import TickColumns
    from retarget.view.scene import Layout, Scene

    scene = Scene.for_clip(inputs.motion, inputs.arm, inputs.targets, layout=Layout(args.layout or "side"))
    columns = TickColumns.of(records)
    if args.png is not None:
        from retarget.view.sheet import contact_sheet

        contact_sheet(scene, columns, Path(args.png), moments=moments, title=inputs.clip.name)
        print(f"retarget: {len(records)} ticks of {inputs.clip.name} -> {args.png}", file=sys.stderr)
        return 0
    from retarget.view.rerun_log import log_ticks

    what = f"{len(records)} ticks of {inputs.clip.name} on {inputs.arm.name}"
    return _record(out, scene, inputs.clip.name, lambda rec: log_ticks(rec, scene, columns), what)


def _record(out: Outputs, scene: Any, name: str, log: Callable[[Any], None], what: str) -> int:
    """Log a solved clip's ``scene`` and ticks (``log(recording)``) to the Rerun outputs ``out``, say ``what`` was
    logged on stderr, then serve the web viewer (if asked) until Ctrl-C (exit 130)."""
    from retarget.view.sinks import open_recording

    web = start_web(out)
    try:
        with open_recording(scene, out, name=name, web=web) as rec:
            log(rec)
        print(f"retarget: {what}" + (f" -> {out.record}" if out.record is not None else ""), file=sys.stderr)
        if web is not None:
            serve_until_interrupted(web)
    finally:
        if web is not None:
            web.close()
    return 0


def _run_rig(args: argparse.Namespace) -> int:
    """``retarget view --rig``: the contact sheet or the Rerun outputs of the clip on every arm of the rig."""
    from retarget.view import require

    refuse_arm_options(args)
    if args.clip is not None and Path(args.clip).suffix.lower() == ".rrd":
        raise ConfigError("Expected a BVH clip with --rig (a saved recording is served without --rig)", key="--rig",
                          value=args.rig)  # fmt: skip
    if args.layout == "side":
        raise ConfigError("Expected no --layout side with --rig (the rig's view draws the skeleton in its frame)",
                          key="--layout", value=args.layout)  # fmt: skip
    if args.png is not None:
        require("--png", "matplotlib")
        moments = _moments(args.moments)
    else:
        out = outputs(args, spawn=True)
    inputs, replay, records = solve_rig(args)
    from retarget.view.rig import RigScene, arm_columns

    table = any(m.world.table for m in inputs.models.values())
    scene = RigScene.for_clip(inputs.motion, inputs.rig, inputs.targets, table=table)
    columns = arm_columns(records, replay.arm_record, inputs.rig, rate=replay.config.rate)
    what = f"{len(records)} ticks of {inputs.clip.name} on rig {inputs.rig.name}"
    if args.png is not None:
        from retarget.view.rig_sheet import rig_contact_sheet

        rig_contact_sheet(scene, columns, Path(args.png), moments=moments, title=inputs.clip.name)
        print(f"retarget: {what} -> {args.png}", file=sys.stderr)
        return 0
    from retarget.view.rerun_log import log_rig_ticks

    name = f"{inputs.clip.name} on {inputs.rig.name}"
    return _record(out, scene, name, lambda rec: log_rig_ticks(rec, scene, columns), what)


def _serve_recording(args: argparse.Namespace) -> int:
    """``retarget view run.rrd --web``: the saved recording in the browser viewer, until Ctrl-C."""
    path = Path(args.clip)
    if not args.web:
        raise ConfigError(f"Expected --web to serve the recording {path} (or open it with `rerun {path}`)",
                          key="--web", value=False)  # fmt: skip
    if not path.is_file():
        raise ConfigError("Expected a Rerun recording file", key="CLIP", value=str(path))
    web = start_web(outputs(args, spawn=False), files=(path.resolve(),))
    assert web is not None
    serve_until_interrupted(web)
    return 0


def _moments(text: str) -> int:
    try:
        n = int(text)
    except ValueError:
        raise ConfigError("Expected a whole number of moments", key="--moments", value=text) from None
    if not 1 <= n <= 24:
        raise ConfigError("Expected 1 to 24 moments", key="--moments", value=n)
    return n
