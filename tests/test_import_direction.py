"""Imports go one way (the design card): the math and the control loop know no driver, simulator or serial
library, and the simulator knows the driver only through the shared register tables.

Checked in a fresh interpreter, so what another test imported cannot hide or fake a dependency.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent
FORBIDDEN = ("drivers", "sim", "serial", "dynamixel_sdk")

#: retarget's math modules, and the control loop that only knows the ``retarget.control.bus.Bus`` protocol:
#: every module of these subpackages (found on disk, so a new module is checked without editing this list)
PURE_PACKAGES = ("bvh", "arm", "ik", "mapping", "control", "teleop", "collision", "rig")
PURE = tuple(
    sorted(
        ".".join(p.relative_to(REPO).with_suffix("").parts).removesuffix(".__init__")
        for package in PURE_PACKAGES
        for p in (REPO / "retarget" / package).glob("*.py")
    )
)


def test_the_pure_list_holds_every_layer():
    assert {"retarget.bvh.parse", "retarget.arm.urdf", "retarget.ik.ccd", "retarget.mapping.targets"} <= set(PURE)
    assert {"retarget.control.loop", "retarget.control.replay", "retarget.teleop.follower"} <= set(PURE)


def loaded_after_import(module: str) -> set[str]:
    """Top-level packages in ``sys.modules`` after importing ``module`` in a fresh interpreter."""
    code = f"import sys, {module}; print(' '.join(sorted({{m.split('.')[0] for m in sys.modules}})))"
    out = subprocess.run(
        [sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, timeout=60, check=True
    ).stdout
    return set(out.split())


@pytest.mark.parametrize("module", PURE, ids=[m.removeprefix("retarget.") for m in PURE])
def test_math_and_control_modules_load_no_driver_simulator_or_serial_code(module):
    loaded = loaded_after_import(module)
    assert not loaded & set(FORBIDDEN), f"{module} loads {sorted(loaded & set(FORBIDDEN))}"


def test_the_check_sees_a_driver_import():
    assert {"drivers", "dynamixel_sdk", "serial"} <= loaded_after_import("drivers.dynamixel_bus")


def imported_names(path: Path) -> set[str]:
    names: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names.add(node.module)
    return names


@pytest.mark.parametrize("path", sorted((REPO / "sim").rglob("*.py")), ids=lambda p: p.name)
def test_the_simulator_uses_only_the_shared_register_tables_of_the_driver(path):
    from_drivers = {n for n in imported_names(path) if n == "drivers" or n.startswith("drivers.")}
    assert from_drivers <= {"drivers.control_table"}, f"{path.name} imports {sorted(from_drivers)}"
