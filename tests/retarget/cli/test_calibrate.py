"""``retarget calibrate --yes`` on a simulated hand-built arm, end to end: the file it saves, and a replay through
it that drives the mounted arm's physical joints as a factory arm's; ``--calibration`` in replay, teleop and scan,
and every error: a Koch without a calibration, a malformed file, a calibration of another arm."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest

import sim
from retarget.arm.calibration import load_calibration
from retarget.arm.load import load_arm
from retarget.cli import main
from sim.transport import bus_from_url
from tests.helpers import calibration_truth, mount_query, random_mounting


@pytest.fixture(autouse=True)
def config_home(tmp_path, monkeypatch) -> Path:
    """A fresh user configuration folder: no calibration of the developer's own arm leaks in."""
    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path / "config"))
    return tmp_path / "config" / "retarget" / "calibration"


def cli(capsys, *args: str) -> tuple[int, str, str]:
    code = main(list(args))
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture
def koch_unit():
    """(arm, mounting, query): a seeded hand-built Koch: horns off, some servos reversed."""
    arm = load_arm("koch")
    mounting = random_mounting(arm, 18)
    assert mounting.reversed
    return arm, mounting, mount_query(mounting)


def registered(url: str):
    bus = bus_from_url(url)
    return bus, sim.attach(bus)


def test_calibrate_yes_saves_the_units_offsets(capsys, config_home, koch_unit):
    arm, mounting, query = koch_unit
    code, out, err = cli(capsys, "calibrate", "--arm", "koch", "--port", f"sim://koch?{query}", "--yes")
    assert code == 0, err
    path = config_home / "koch.toml"
    assert out == f"{path}\n" and err.splitlines()[0].startswith("retarget calibrate: Koch v1.1 follower as 'koch'")
    cal = load_calibration(path)
    truth = calibration_truth(arm, mounting)
    for s in cal.servos:
        assert s.direction == truth[s.id][0] and abs(s.offset - truth[s.id][1]) <= 2, s
    assert cal.date.startswith("20") and {s.firmware for s in cal.servos} == {46}
    assert [p.name for p in config_home.iterdir()] == ["koch.toml"]


def _replay(capsys, port: str, *extra: str) -> tuple[str, list[dict[str, str]], str]:
    telemetry = Path(port.replace("sim://@", "/tmp/").replace("/", "_") + ".csv")
    code, out, err = cli(capsys, "replay", "--arm", "koch", "--port", port, "--fast", "--end", "0.3", "--lead-in", "3",
                         "--shutdown", "hold", "--telemetry", str(telemetry), *extra)  # fmt: skip
    assert code == 0, err
    rows = list(csv.DictReader(telemetry.open()))
    telemetry.unlink()
    return out, rows, err


def test_a_replay_through_the_calibration_drives_the_joints_as_on_a_factory_arm(capsys, tmp_path, koch_unit):
    arm, mounting, query = koch_unit
    saved = tmp_path / "unit.toml"
    code, _, err = cli(capsys, "calibrate", "--arm", "koch", "--port", f"sim://koch?{query}", "--yes",
                       "-o", str(saved), "--name", "unit")  # fmt: skip
    assert code == 0, err
    mounted, mounted_url = registered(f"sim://koch?clock=virtual&{query}")
    factory, factory_url = registered("sim://koch?clock=virtual")
    try:
        _, calibrated_rows, err = _replay(capsys, mounted_url, "--calibration", str(saved))
        assert err.splitlines()[0] == f"retarget: calibration: unit ({saved}, {load_calibration(saved).date})"
        _, factory_rows, err = _replay(capsys, factory_url)
        assert not err.startswith("retarget: calibration")  # a simulated Koch needs none, and none is saved
        names = [f"{j}_cmd_rad" for j in arm.joint_names]
        q_cal = np.array([[float(r[n]) for n in names] for r in calibrated_rows])
        q_factory = np.array([[float(r[n]) for n in names] for r in factory_rows])
        np.testing.assert_allclose(q_cal, q_factory, atol=1e-9)  # the same joint commands
        # and the same physical shaft angles: the calibration turned the mounted servos' pulses into the same joints
        np.testing.assert_allclose(mounted.body.angles(), factory.body.angles(), atol=3 * 2 * math.pi / 4096)
        assert np.ptp(q_cal, axis=0).max() > 0.05  # the clip moved the arm
        # without the calibration the mounted arm ends elsewhere
        uncal, uncal_url = registered(f"sim://koch?clock=virtual&{query}")
        try:
            _replay(capsys, uncal_url, "--calibration", "none")
            assert np.abs(uncal.body.angles() - factory.body.angles()).max() > 0.1
        finally:
            sim.unregister(uncal_url)
    finally:
        sim.unregister(mounted_url)
        sim.unregister(factory_url)


def test_the_saved_default_is_used_by_name_and_by_path(capsys, config_home, koch_unit):
    _, _, query = koch_unit
    assert cli(capsys, "calibrate", "--arm", "koch", "--port", f"sim://koch?{query}", "--yes", "--name", "left",
               "--no-verify")[0] == 0  # fmt: skip
    for choice in ("left", str(config_home / "left.toml")):
        code, _, err = cli(capsys, "replay", "--arm", "koch", "--calibration", choice, "--dry-run", "--end", "0.05")
        assert code == 0 and err.startswith(f"retarget: calibration: left ({config_home / 'left.toml'}"), err


# ------------------------------------------------------------------------------------------ errors


@pytest.mark.parametrize("command", ["replay", "teleop"])
def test_a_koch_on_a_real_port_without_a_calibration_names_the_command_to_run(capsys, command, config_home):
    extra = ["--to", "0.2,0,0.1"] if command == "teleop" else []
    code, out, err = cli(capsys, command, "--arm", "koch", "--port", "/dev/ttyUSB7", *extra)
    assert code == 2 and out == ""
    assert err == (
        "retarget: --calibration: arm 'koch' needs a calibration: run `retarget calibrate --arm koch --port "
        f"/dev/ttyUSB7` first (or give --calibration PATH; looked for {config_home / 'koch.toml'})\n"
    )


def test_a_real_port_says_when_it_uses_no_calibration(capsys):
    code, _, err = cli(capsys, "replay", "--arm", "wx250s", "--port", "/dev/ttyUSB7-none")
    assert code == 4 and err.splitlines()[0] == "retarget: calibration: none, the arm file's offsets (none saved)"


def test_a_malformed_calibration_names_the_file_and_key(capsys, tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('arm = "koch"\nname = "bad"\ndate = "x"\n[[servos]]\nid = 1\njoint = "shoulder_pan"\noffset = 1.5\n')
    code, _, err = cli(capsys, "replay", "--arm", "koch", "--calibration", str(bad), "--fast")
    assert code == 2 and err == f"retarget: {bad}: servos[0].offset: expected an integer (got 1.5)\n"


def test_a_calibration_of_another_arm_is_refused(capsys, config_home, koch_unit):
    _, _, query = koch_unit
    assert cli(capsys, "calibrate", "--arm", "koch", "--port", f"sim://koch?{query}", "--yes", "--no-verify")[0] == 0
    code, _, err = cli(capsys, "teleop", "--arm", "wx250s", "--calibration", "koch", "--to", "0.3,0,0.2", "--fast")
    assert code == 2
    expected = "arm: Expected a calibration of arm 'wx250s', got one of 'koch'"
    assert err == f"retarget: {config_home / 'koch.toml'}: {expected}\n"


def test_a_missing_calibration_file_given_by_path(capsys, tmp_path):
    code, _, err = cli(capsys, "replay", "--calibration", str(tmp_path / "nope.toml"), "--fast")
    assert (
        code == 2 and err == f"retarget: --calibration: calibration file not found (got '{tmp_path / 'nope.toml'}')\n"
    )


@pytest.mark.parametrize(
    "argv,match",
    [
        pytest.param(["--name", "../x"], r"^retarget: --name: Expected a name of letters", id="name"),
        pytest.param(
            ["--port", "sim://koch?mount=9:1"], r"^retarget: mount: Expected joint servo IDs of koch", id="mount"
        ),
        pytest.param(
            ["--port", "sim://@nobody"], r"^retarget: --port: no SimBus registered as 'nobody'", id="registered"
        ),
    ],
)
def test_calibrate_bad_options(capsys, argv, match):
    args = ["calibrate", "--arm", "koch", "--port", "sim://koch", "--yes", *argv]
    code, out, err = cli(capsys, *args)
    assert code == 2 and out == "" and len(err.splitlines()) == 1
    assert __import__("re").match(match, err), err


def test_calibrate_yes_on_a_bus_of_other_servos_fails_on_the_bus(capsys, config_home):
    code, _, err = cli(capsys, "calibrate", "--arm", "koch", "--port", "sim://wx250s", "--yes")
    assert code == 4 and "servo 1 is a XM430-W350, the arm file says XL430-W250" in err
    assert not config_home.exists()


# ------------------------------------------------------------------------------------------ scan --arm


def test_scan_with_the_arm_shows_the_calibrated_angles_and_a_replaced_servo(capsys, config_home, koch_unit):
    arm, mounting, query = koch_unit
    assert cli(capsys, "calibrate", "--arm", "koch", "--port", f"sim://koch?{query}", "--yes", "--no-verify")[0] == 0
    path = config_home / "koch.toml"
    path.write_text(path.read_text().replace("firmware = 46", "firmware = 44", 1))  # servo 1 was swapped since
    port = f"sim://koch?clock=virtual&{query}"
    code, out, err = cli(capsys, "scan", "--port", port, "--arm", "koch", "--ids", "1-6", "--no-broadcast", "--json")
    assert code == 0 and err.splitlines()[0].startswith(f"retarget: calibration: koch ({path}")
    joints = json.loads(out)["joints"]
    assert [j["id"] for j in joints] == [1, 2, 3, 4, 5]
    np.testing.assert_allclose([j["angle_deg"] for j in joints], np.degrees(arm.rest), atol=0.2)
    assert joints[0]["note"] == "firmware 46, calibrated with 44: replaced? calibrate again"
    code, out, err = cli(capsys, "scan", "--port", port, "--arm", "koch", "--ids", "1-6", "--no-broadcast",
                         "--calibration", "none")  # fmt: skip
    assert code == 0 and err.splitlines()[0].startswith("retarget: calibration: none for koch (needs one")
    assert "JOINT" in out
