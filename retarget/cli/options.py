"""The one table from the library's field names to the CLI's options.

The library speaks in fields: its errors name the field or parameter that holds a bad value
(``ConfigError(key="rate")``, ``key="mapping.floor"``) and never a flag.  The CLI set those fields from
its options, so before it prints an error it renames the key to the option (:func:`option_error`): one
table here, no message rewriting anywhere.  An error with a file path names a key in that file and is
left as it is.
"""

from __future__ import annotations

from retarget.errors import ConfigError

__all__ = ["OPTIONS", "option_error"]

#: library field (a ConfigError's key) -> the option that sets it, in every command that has it
OPTIONS: dict[str, str] = {
    # retarget.control.LoopConfig
    "rate": "--rate",
    "speed": "--speed",
    "start": "--start",
    "end": "--end",
    "max_ticks": "--max-ticks",
    "velocity_scale": "--velocity-scale",
    "lead_in_speed": "--lead-in",
    "jerk_cost": "--jerk-cost",
    # retarget.control.ControlLoop: play a clip's plan made ahead (off: causal, IK in each tick)
    "look_ahead": "--no-look-ahead",
    # retarget.cli._gripper: what drives the gripper (replay), its starting closure (teleop)
    "gripper": "--gripper",
    # retarget.mapping.MappingConfig (an arm file's [mapping] table; the flags override it)
    "mapping.side": "--side",
    "mapping.forward": "--forward",
    "mapping.up": "--up",
    "mapping.robot_forward": "--robot-forward",
    "mapping.arm_scale": "--arm-scale",
    "mapping.origin": "--origin",
    "mapping.floor": "--floor",
    "mapping.orientation_weight": "--orientation-weight",
    "mapping.cutoff_hz": "--filter-cutoff",  # the zero-phase low-pass of a clip's targets (--no-filter: 0)
    # retarget.collision.CollisionModel (the CLI takes the clearance in mm and checks it first)
    "clearance": "--clearance",
    # retarget.arm.load_arm: the ends of a URDF chain
    "base": "--base",
    "tip": "--tip",
    # retarget.teleop: Follower, TargetBounds, TargetGate, the sources
    "max_speed": "--max-speed",
    "tolerance": "--tolerance",
    "timeout": "--timeout",
    "max_lag": "--max-lag",
    "margin": "--margin",
    "box": "--box",
    "max_bytes": "--max-bytes",
    "position": "--to",
    "rpy": "--rpy",
    "address": "--udp",
    "base_pose": "--base-pose",
    # retarget.mapping.filter.OneEuro: teleop's stream filter
    "min_cutoff": "--filter-min-cutoff",
    "beta": "--filter-beta",
    # drivers.control_table.parse_ids; sim.Faults.from_options (retarget sim's fault options)
    "ids": "--ids",
    "drop": "--drop",
    "corrupt": "--corrupt",
    "delay_ms": "--delay-ms",
    "unplug": "--unplug",
    "hwerror": "--hwerror",
    "seed": "--seed",
    "wire": "--wire",
}


def option_error(exc: ConfigError, *, keyed_in_file: bool = False) -> ConfigError:
    """``exc`` about the option that set its field (same message and value), or ``exc`` itself.

    Only an error without a file path names a field; ``keyed_in_file`` maps one that carries a path too (the
    URDF chain's ``base``/``tip`` are arguments that go with the file, not keys in it).

    >>> print(option_error(ConfigError("Expected a tick rate > 0 Hz", key="rate", value=0.0)))
    --rate: Expected a tick rate > 0 Hz (got 0.0)
    >>> print(option_error(ConfigError("Expected a number", path="arm.toml", key="rate", value="x")))
    arm.toml: rate: Expected a number (got 'x')
    """
    if exc.key in OPTIONS and (exc.path is None or keyed_in_file):
        return exc.with_key(OPTIONS[exc.key])
    return exc
