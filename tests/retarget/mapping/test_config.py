"""The mapping's configuration: the ``[mapping]`` table parsed, CLI overrides, every bad value naming file and key."""

from __future__ import annotations

import pytest

from retarget.errors import ConfigError
from retarget.mapping.config import Axis, MappingConfig, Side


def test_config_from_table_and_overrides():
    config = MappingConfig.from_table(
        {"side": "left", "forward": "z", "origin": [0.2, 0.0, 0.3], "floor": 0.05},
        overrides={"side": "right", "floor": None, "arm_scale": "0.6"},
    )
    assert config.side is Side.RIGHT and config.forward is Axis.PZ
    assert config.origin == (0.2, 0.0, 0.3) and config.floor == 0.05 and config.arm_scale == 0.6
    assert config.with_overrides(origin="0.1,0.2,0.3", side=None).origin == (0.1, 0.2, 0.3)


@pytest.mark.parametrize(
    ("table", "match"),
    [
        ({"sides": "left"}, r"arm\.toml: mapping\.sides: unknown key; expected one of .*side"),
        ({"side": "up"}, r"mapping\.side: Expected 'left' or 'right' \(got 'up'\)"),
        ({"forward": "+q"}, r"mapping\.forward: Expected one of auto, \+x.* \(got '\+q'\)"),
        ({"up": "auto"}, r"mapping\.up: Expected one of \+y"),
        ({"arm_scale": 0}, r"mapping\.arm_scale: Expected a number > 0 \(got 0\.0\)"),
        ({"arm_scale": True}, r"mapping\.arm_scale: Expected a number > 0 \(got True\)"),
        ({"origin": [1, 2]}, r"mapping\.origin: Expected three numbers x,y,z in metres"),
        ({"origin": ["a", 1, 2]}, r"mapping\.origin: Expected three numbers"),
        ({"max_reach": 1.5}, r"mapping\.max_reach: Expected a fraction in \(0, 1\]"),
        ({"min_reach": 0.6, "max_reach": 0.5}, r"mapping\.min_reach: Expected min_reach < max_reach \(0\.5\)"),
        ({"floor": float("nan")}, r"mapping\.floor: Expected a finite number of metres"),
        ({"orientation_weight": -1}, r"mapping\.orientation_weight: Expected a number >= 0"),
        ({"joint_weights": {"waist": 2}}, r"mapping\.joint_weights: Expected weights in \(0, 1\]"),
        ({"joint_weights": []}, r"mapping\.joint_weights: Expected weights"),
    ],
    ids=lambda v: str(v)[:40],
)
def test_bad_mapping_tables_name_the_file_and_key(table, match):
    with pytest.raises(ConfigError, match=match) as info:
        MappingConfig.from_table(table, path="arm.toml")
    assert info.value.path == "arm.toml"
    assert info.value.key.startswith("mapping.")


def test_robot_forward_must_be_horizontal():
    with pytest.raises(
        ConfigError, match=r"mapping\.robot_forward: Expected one of auto, \+x, -x, \+y, -y \(got '\+z'\)"
    ):
        MappingConfig.from_table({"robot_forward": "+z"})
