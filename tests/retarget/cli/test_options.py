"""The one table from library fields to CLI options: every option it names exists, and errors are renamed by it."""

from __future__ import annotations

import argparse

import pytest

from retarget.cli import build_parser, named_command
from retarget.cli.options import OPTIONS, option_error
from retarget.errors import ConfigError


def every_option() -> set[str]:
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return {flag for command in sub.choices.values() for action in command._actions for flag in action.option_strings}


def test_every_option_in_the_table_exists_in_some_command():
    assert set(OPTIONS.values()) - every_option() == set()


@pytest.mark.parametrize(
    ("error", "expected"),
    [
        (ConfigError("Expected a joint speed >= 0 rad/s", key="lead_in_speed", value=-1.0), "--lead-in: Expected"),
        (ConfigError("Expected a number > 0", key="mapping.arm_scale", value=0.0), "--arm-scale: Expected"),
        (ConfigError("Expected a number > 0", path="a.toml", key="mapping.arm_scale", value=0), "a.toml: mapping"),
        (ConfigError("unknown arm", key="arm"), "arm: unknown arm"),
    ],
    ids=["loop-field", "mapping-flag", "file-key-stays", "not-in-the-table"],
)
def test_option_error_names_the_option_of_a_field_only(error, expected):
    assert str(option_error(error)).startswith(expected)


def test_the_renamed_error_keeps_message_and_value():
    renamed = option_error(ConfigError("Expected a tick rate > 0 Hz", key="rate", value=0.0))
    assert (renamed.key, renamed.message, renamed.value) == ("--rate", "Expected a tick rate > 0 Hz", 0.0)
    assert str(option_error(ConfigError("no value", key="rate"))) == "--rate: no value"


@pytest.mark.parametrize(
    "argv",
    [
        ["export", "clip.bvh", "--arm", "koch", "--side", "left", "-o", "t.csv"],
        ["-v", "replay", "--fast", "--rate", "50"],
        ["teleop", "--to", "0.3,0,0.2", "-v"],
        ["arm", "wx250s", "--check", "0,0,0,0,0,0", "--json"],
    ],
    ids=["export", "verbose-first", "verbose-after", "arm-check"],
)
def test_the_named_command_alone_parses_as_the_whole_parser(argv):
    def parsed(parser: argparse.ArgumentParser) -> dict[str, object]:
        values = vars(parser.parse_args(argv))
        return {**values, "_run": values["_run"].__module__}

    assert parsed(build_parser(named_command(argv))) == parsed(build_parser())
    sub = next(a for a in build_parser(named_command(argv))._actions if isinstance(a, argparse._SubParsersAction))
    assert list(sub.choices) == [named_command(argv)]
