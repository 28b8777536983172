"""The calibration flow on the simulated bus: a hand-built arm (seeded random horn offsets, reversed servos) is
calibrated unattended by the simulator's hands; the offsets and directions found are the mounting's truth within
2 pulses; ranges, refusals, Ctrl-C at every step (torque stays off), the errors."""

from __future__ import annotations

import io
import math

import numpy as np
import pytest

import sim
from retarget.arm.load import load_arm
from retarget.calibrate import AutoPrompter, SimHands, TerminalPrompter, calibrate
from retarget.calibrate.steps import CalibrationError
from retarget.errors import BusError
from sim.transport import bus_from_url
from tests.helpers import ScriptedPrompter, calibration_truth, mount_query, random_mounting, torques


@pytest.fixture
def mounted(request):
    """(arm, simbus, url, mounting) for request.param = (arm name, seed, reverse): a registered virtual-clock bus."""
    name, seed, reverse = request.param
    arm = load_arm(name)
    mounting = random_mounting(arm, seed, reverse=reverse)
    simbus = bus_from_url(f"sim://{name}?clock=virtual&{mount_query(mounting)}")
    url = sim.attach(simbus)
    yield arm, simbus, url, mounting
    sim.unregister(url)


def run(arm, simbus, url, prompter=None, **kwargs):
    hands = kwargs.pop("hands", None) or SimHands(simbus.body, simbus.clock)
    prompter = prompter if prompter is not None else AutoPrompter(out=io.StringIO())
    return calibrate(arm, url, prompter, hands=hands, clock=simbus.clock, auto=True, **kwargs)


CASES = [
    pytest.param(("koch", 1, True), id="koch-1"),
    pytest.param(("koch", 2, True), id="koch-2"),
    pytest.param(("omx", 3, True), id="omx-3"),
    pytest.param(("wx250s", 4, False), id="wx250s-shadows-4"),
]


@pytest.mark.parametrize("mounted", CASES, indirect=True)
def test_the_flow_recovers_every_servos_offset_and_direction(mounted):
    arm, simbus, url, mounting = mounted
    assert mounting.offsets and (mounting.reversed or not arm.calibrate_directions)
    result = run(arm, simbus, url, name="unit")
    truth = calibration_truth(arm, mounting)
    found = {s.id: (s.direction, s.offset) for s in result.calibration.servos}
    assert set(found) == set(truth)
    for sid, (direction, offset) in truth.items():
        assert found[sid][0] == direction, sid
        assert abs(found[sid][1] - offset) <= 2, (sid, found[sid], truth[sid])
    assert result.verified is True and result.calibration.name == "unit"
    assert all(s.firmware == 46 for s in result.calibration.servos)
    # the verification drove the arm, calibrated, to its rest pose: the physical joints are there, torque off
    np.testing.assert_allclose(simbus.body.angles(), arm.rest, atol=math.radians(2.5))
    assert set(torques(simbus).values()) == {0}


@pytest.mark.parametrize("mounted", [pytest.param(("wx250s", 5, True), id="wx250s-reversed")], indirect=True)
def test_directions_on_request_for_an_arm_that_fixes_them(mounted):
    arm, simbus, url, mounting = mounted
    result = run(arm, simbus, url, directions=True, verify=False)
    truth = calibration_truth(arm, mounting)
    assert {s.id: s.direction for s in result.calibration.servos} == {i: d for i, (d, _) in truth.items()}
    assert result.verified is None


@pytest.mark.parametrize("mounted", [pytest.param(("koch", 6, True), id="koch")], indirect=True)
@pytest.mark.parametrize("agree", [True, False], ids=["narrowed", "kept"])
def test_a_limit_the_arm_cannot_reach_is_reported_and_narrowed_if_the_user_agrees(mounted, agree):
    arm, simbus, url, _ = mounted
    lift = arm.joints[1]
    reach = (lift.lower + 0.4, lift.upper)
    hands = SimHands(simbus.body, simbus.clock, reach={1: reach})
    prompter = ScriptedPrompter(answers={"Narrow": agree})
    result = run(arm, simbus, url, prompter, hands=hands, verify=False)
    assert any("warning: shoulder_lift reached only" in line for line in prompter.lines)
    joint = result.calibration.joint("shoulder_lift")
    assert joint.measured == pytest.approx(reach, abs=math.radians(0.2))
    assert joint.limits == (pytest.approx(reach, abs=math.radians(0.2)) if agree else None)
    assert result.calibration.joint("elbow_flex").limits is None


@pytest.mark.parametrize("mounted", [pytest.param(("koch", 7, True), id="koch")], indirect=True)
def test_a_pose_that_looks_wrong_ends_unverified_with_torque_off(mounted):
    arm, simbus, url, _ = mounted
    prompter = ScriptedPrompter(answers={"look like its calibration pose": False})
    result = run(arm, simbus, url, prompter)
    assert result.verified is False and set(torques(simbus).values()) == {0}
    assert prompter.prompts[-1] == "Does the arm look like its calibration pose?"


STEPS = [
    pytest.param("Hold the arm", id="1-connect"),
    pytest.param("Hold it there", id="2-pose"),
    pytest.param("Turn elbow_flex 10-30", id="3-direction"),
    pytest.param("Turn wrist_flex through", id="4-range"),
    pytest.param("Keep clear", id="5-before-torque"),
    pytest.param("Move to calibration", id="5-torque-on"),
    pytest.param("look like its rest", id="5-last"),
]


@pytest.mark.parametrize("mounted", [pytest.param(("koch", 8, True), id="koch")], indirect=True)
@pytest.mark.parametrize("where", STEPS)
def test_ctrl_c_at_every_step_leaves_torque_off(mounted, where):
    arm, simbus, url, _ = mounted
    prompter = ScriptedPrompter(interrupt_on=where)
    with pytest.raises(KeyboardInterrupt):
        run(arm, simbus, url, prompter)
    assert where in prompter.prompts[-1]
    assert set(torques(simbus).values()) == {0}


class StuckHands(SimHands):
    def nudge(self, joint: int, angle: float) -> None:  # the joint does not turn
        pass


@pytest.mark.parametrize("mounted", [pytest.param(("koch", 9, True), id="koch")], indirect=True)
def test_a_joint_that_does_not_turn_when_asked_is_an_error(mounted):
    arm, simbus, url, _ = mounted
    hands = StuckHands(simbus.body, simbus.clock)
    with pytest.raises(CalibrationError, match="^shoulder_pan did not turn when asked: cannot tell its servos"):
        run(arm, simbus, url, hands=hands)
    assert set(torques(simbus).values()) == {0}


@pytest.mark.parametrize("mounted", [pytest.param(("koch", 10, True), id="koch")], indirect=True)
def test_a_horn_far_off_centre_is_reported(mounted):
    arm, _, _, _ = mounted
    simbus = bus_from_url("sim://koch?clock=virtual&mount=1:+1500")
    url = sim.attach(simbus)
    try:
        result = run(arm, simbus, url, verify=False)
    finally:
        sim.unregister(url)
    assert result.calibration.servo(1).offset == 1500
    assert any("shoulder_pan: servo 1's single turn covers only" in w for w in result.warnings)


@pytest.mark.parametrize(
    "url,match",
    [
        pytest.param(
            "sim://wx250s?clock=virtual", r"servo 1 is a XM430-W350, the arm file says XL430-W250", id="model"
        ),
        pytest.param(
            "sim://?ids=1-2&model=XL430-W250&clock=virtual", r"servo\(s\) 3, 4, 5, 6 did not answer", id="missing"
        ),
    ],
)
def test_servos_that_are_not_the_arm_files(url, match):
    with pytest.raises(BusError, match=match):
        calibrate(load_arm("koch"), url, AutoPrompter(out=io.StringIO()), auto=True)


# ------------------------------------------------------------------------------------------ the terminal prompter


def test_the_terminal_prompter_asks_again_until_it_gets_y_or_n():
    out = io.StringIO()
    p = TerminalPrompter(inp=io.StringIO("maybe\nY\n"), out=out)
    assert p.confirm("Save?", default=False) is True
    assert out.getvalue().count("Save? [y/N]") == 2 and "Please answer y or n." in out.getvalue()
    assert TerminalPrompter(inp=io.StringIO("\n"), out=io.StringIO()).confirm("Go?", default=True) is True
    assert TerminalPrompter(inp=io.StringIO("no\n"), out=io.StringIO()).confirm("Go?", default=True) is False


def test_the_terminal_prompter_without_a_terminal_shows_one_reading_then_waits_for_enter():
    out = io.StringIO()
    p = TerminalPrompter(inp=io.StringIO("\n"), out=out)
    readings = iter(["a", "b"])
    p.watch("Turn it", lambda: next(readings))
    assert out.getvalue() == "Turn it [Enter when done]\na\n"
    with pytest.raises(EOFError, match="no more input: run retarget calibrate in a terminal, or with --yes"):
        p.enter("More")
