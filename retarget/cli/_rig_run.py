"""``--rig``: a clip on every arm of a rig (``retarget export --rig``, ``retarget replay --rig``), both hands in one
world frame.

The rig file names each arm, its base pose, port and the human side that drives it, so ``--arm`` and ``--side``
do not apply.  The mapping flags (``--arm-scale``, ``--filter-cutoff``, ...), the clip window, ``--rate`` and the
collision flags (``--clearance`` between the arms too, ``--keep-out`` in each arm's base frame, ``--no-table``)
apply to every arm.  This module never imports the commands (``replay``, ``export``) whose options it works with:
they hand it the values (the mapping overrides, the loop config, their trajectory writer).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import retarget
from retarget.bvh import DEMO_CLIP
from retarget.bvh.motion import Motion
from retarget.cli._arm import DEFAULT_ARM, collision_model
from retarget.collision import CollisionModel
from retarget.control.clock import Clock, VirtualClock
from retarget.control.loop import LoopConfig, TickRecord
from retarget.errors import ConfigError
from retarget.mapping.config import MappingConfig
from retarget.mapping.filter import AUTO, CAUSAL_CUTOFF_HZ
from retarget.rig import Rig, RigReplay, RigSummary, RigTargets, load_rig, rig_targets

__all__ = ["add_rig_option", "arm_lines", "export_rig", "load_rig_inputs", "refuse_arm_options", "rig_replay"]

#: ``play(on_tick)``: runs a rig replay with that ``on_tick`` and returns its summary
Play = Callable[[Callable[[TickRecord], None]], RigSummary]
#: ``write(output, joint_names, play)``: runs ``play`` writing each tick as a CSV row (``replay.write_trajectory``)
Writer = Callable[[str, Sequence[str], Play], RigSummary]


def add_rig_option(parser: argparse.ArgumentParser) -> None:
    """``--rig NAME|FILE``."""
    parser.add_argument(
        "--rig",
        default=None,
        metavar="NAME|FILE",
        help="play the clip on every arm of a rig (bundled: aloha, wx250s-pair; see 'retarget rig'); "
        "each arm follows its own side, both hands in one frame",
    )


@dataclass(frozen=True)
class RigInputs:
    """What a rig command works on: the clip, the rig, each arm's collision model, the mapped targets."""

    clip: Path
    motion: Motion
    rig: Rig
    models: dict[str, CollisionModel]
    targets: RigTargets


def refuse_arm_options(args: argparse.Namespace) -> None:
    """``--arm``, ``--base``, ``--tip``, ``--side`` name one arm: a ConfigError with ``--rig``."""
    arm = None if args.arm == DEFAULT_ARM else args.arm
    for option, value in (("--arm", arm), ("--base", args.base), ("--tip", args.tip), ("--side", args.side)):
        if value is not None:
            raise ConfigError("Expected no arm or side with --rig (the rig file names its arms and sides)",
                              key=option, value=value)  # fmt: skip


def played_mapping(config: MappingConfig, args: argparse.Namespace) -> MappingConfig:
    """``config`` as the run plays it: a cutoff of ``"auto"`` is :data:`~retarget.mapping.filter.CAUSAL_CUTOFF_HZ`
    when the clip plays causally (``--loop``, ``--no-look-ahead``), where no plan starts early for a fast move."""
    causal = getattr(args, "loop", False) or getattr(args, "no_look_ahead", False)
    return replace(config, cutoff_hz=CAUSAL_CUTOFF_HZ) if causal and config.cutoff_hz == AUTO else config


def load_rig_inputs(args: argparse.Namespace, overrides: Mapping[str, Any]) -> RigInputs:
    """The clip, the rig of ``--rig``, each arm's collision model (the collision flags) and the targets mapped with
    the mapping flags' ``overrides`` (``replay.mapping_overrides``)."""
    refuse_arm_options(args)
    rig = load_rig(args.rig)
    clip = Path(DEMO_CLIP) if args.clip is None else Path(args.clip)
    first = rig.arms[0].arm
    table = MappingConfig.from_table(first.mapping, path=first.source, overrides=dict(overrides))
    config = played_mapping(table, args)
    motion = retarget.load_bvh(clip)
    models = {a.name: collision_model(args, a.arm) for a in rig.arms}
    targets = rig_targets(motion, rig, config, collision=models)
    return RigInputs(clip=clip, motion=motion, rig=rig, models=models, targets=targets)


def rig_replay(inputs: RigInputs, config: LoopConfig, *, clock: Clock, look_ahead: bool = True) -> RigReplay:
    """The :class:`~retarget.rig.RigReplay` of ``inputs`` on ``clock``: each arm checked against its own collision
    model, the arms kept apart by the least of their ``--clearance``."""
    clearance = min(m.clearance for m in inputs.models.values())
    return RigReplay(inputs.rig, inputs.targets, config=config, models=inputs.models, clearance=clearance,
                     clock=clock, clip_name=inputs.clip.name, look_ahead=look_ahead)  # fmt: skip


def arm_lines(summary: RigSummary) -> list[str]:
    """One stderr line per arm of a rig run: IK, velocity limits, tracking and acceleration (export and replay)."""
    return [
        f"  {name}: IK {s.ik_converged_pct:.1f}% converged, velocity-limited {s.velocity_limited_ticks}, "
        f"tracking error p95 {s.tracking_p95_mm or 0:.1f} mm, joint acceleration peak "
        f"{s.accel_peak_rad_s2 or 0:.0f} rad/s^2"
        for name, s in summary.arms.items()
    ]


def export_rig(args: argparse.Namespace, inputs: RigInputs, config: LoopConfig, write: Writer) -> int:
    """``retarget export --rig``: every arm's trajectory in one CSV, ``time_s`` then ``<arm>/<joint>_rad``, written
    by ``write`` (``replay.write_trajectory``) with the loop's ``config`` (``replay.loop_config``)."""
    replay = rig_replay(inputs, config, clock=VirtualClock(), look_ahead=not args.no_look_ahead)
    q0 = replay.initial_pose()

    def play(on_tick: Callable[[TickRecord], None]) -> RigSummary:
        replay.on_tick = on_tick
        return replay.run(None, q_start=q0)

    summary = write(args.output, replay.plant.joint_names, play)
    rig = summary.rig
    print(
        f"retarget: {rig.ticks} ticks of rig {inputs.rig.name} ({rig.duration_s:.2f} s of {inputs.clip.name}) "
        f"-> {args.output}; blocked {rig.blocked_ticks}, min clearance {rig.min_clearance_mm or 0:.1f} mm",
        file=sys.stderr,
    )
    print("\n".join(arm_lines(summary)), file=sys.stderr)
    return 0
