"""``retarget calibrate`` in a real terminal (tmux): the prompts as a user sees them, a whole interactive run
against ``retarget sim`` (a hand-built Koch; the test's "hands" turn the joints through the sim's control socket),
and Ctrl-C at each step: torque off on every servo (asked through the control socket), no file written."""

from __future__ import annotations

import math
import shlex
import signal
import sys
import time
from pathlib import Path

import pytest

from retarget.arm.calibration import load_calibration
from retarget.arm.load import load_arm
from tests.helpers import Tmux, sim_control, start_sim_server

REPO = Path(__file__).resolve().parents[3]
MOUNT = {1: 300, 2: -150, 3: 0, 4: 77, 5: -40}
REVERSED = {3}


def serve_koch():
    args = [a for i, m in MOUNT.items() for a in ("--mount", f"{i}:{m:+d}")] + ["--reverse", "3"]
    proc, url, control = start_sim_server("--arm", "koch", *args)
    yield url, control
    proc.send_signal(signal.SIGTERM)
    proc.wait(timeout=10)


#: one simulator for the Ctrl-C cases, which move nothing; a run that turns joints gets its own
shared_server = pytest.fixture(scope="module")(serve_koch)
koch_server = pytest.fixture(serve_koch)


def calibrate_line(url: str, out: Path, *extra: str) -> str:
    argv = [sys.executable, "-m", "retarget", "calibrate", "--arm", "koch", "--port", url, "-o", str(out), *extra]
    return " ".join(shlex.quote(a) for a in argv)


def torque_states(control: str) -> list[bool]:
    return [s["torque"] for s in sim_control(control, "status")["servos"]]


@pytest.fixture
def tmux(request):
    t = Tmux(request.node.name.replace("[", "-").replace("]", ""))
    yield t
    t.close()


RANGES = ["Turn shoulder_pan through", "Turn shoulder_lift through", "Turn elbow_flex through",
          "Turn wrist_flex through", "Turn wrist_roll through"]  # fmt: skip

#: (options, the prompts answered with Enter on the way, the prompt to press Ctrl-C at).  Steps 1 to 3 wait in the
#: same line read (1 stands for them here; tests/retarget/calibrate/test_flow.py interrupts every step's prompt);
#: step 4 polls the terminal while it shows the live angle; step 5 has torque on.
STEPS = [
    pytest.param([], [], "Hold the arm", id="1-connect"),
    pytest.param(["--no-directions"], ["Hold the arm", "Hold it there"], "Turn shoulder_pan through", id="4-range"),
    pytest.param(["--no-directions"], ["Hold the arm", "Hold it there", *RANGES, "Keep clear"], "Move to home",
                 id="5-torque-on"),
]  # fmt: skip


@pytest.mark.parametrize("options,on_the_way,prompt", STEPS)
def test_ctrl_c_at_each_step_leaves_torque_off_and_no_file(tmux, shared_server, tmp_path, options, on_the_way, prompt):
    url, control = shared_server
    out = tmp_path / "koch.toml"
    tmux.start(calibrate_line(url, out, *options), cwd=REPO)
    for wait in on_the_way:
        tmux.wait_for(wait)
        tmux.keys("Enter")
    tmux.wait_for(prompt)
    if prompt == "Move to home":
        assert all(torque_states(control))  # step 5 turned torque on
    tmux.keys("C-c")
    screen = tmux.wait_for("EXIT=")
    assert "retarget: interrupted" in screen and "EXIT=130" in screen, screen
    assert not any(torque_states(control)) and list(tmp_path.iterdir()) == []


def nudge(control: str, joint_ids: list[int], pulses: int) -> None:
    """The test's hand turns each servo ``pulses`` from its calibration-pose position the joint's positive way."""
    for i in joint_ids:
        sign = -1 if i in REVERSED else 1
        answer = sim_control(control, f"hand {i} to {2048 + MOUNT[i] + sign * pulses} 0.02")
        assert answer["ok"], answer
    time.sleep(0.1)


def test_a_whole_interactive_run_saves_the_units_calibration(tmux, koch_server, tmp_path):
    url, control = koch_server
    arm = load_arm("koch")
    out = tmp_path / "koch.toml"
    tmux.start(calibrate_line(url, out), cwd=REPO)
    tmux.wait_for("Hold the arm: its torque goes off next and it goes limp [Enter]")
    tmux.keys("Enter")
    screen = tmux.wait_for("Hold it there, still [Enter]")
    assert "  shoulder_lift     +0.0 deg  (upper arm vertical)" in screen
    tmux.keys("Enter")
    for joint in arm.joints:  # the test's hand turns each joint a little its positive way, then back
        tmux.wait_for(f"Turn {joint.name} 10-30 deg towards its upper limit")
        nudge(control, [joint.servos[0].id], 150)
        tmux.keys("Enter")
        tmux.wait_for(f"  {joint.name}: servo {joint.servos[0].id} ")
        nudge(control, [joint.servos[0].id], 0)
    for joint in arm.joints:
        tmux.wait_for(f"Turn {joint.name} through its whole range, both ways [Enter when done]")
        tmux.wait_for(f"limits {math.degrees(joint.lower):+.1f} .. ")  # the live line
        tmux.keys("Enter")
    tmux.wait_for("Keep clear of the arm")
    tmux.keys("Enter")
    for pose in ("home", "calibration", "rest"):
        tmux.wait_for(f"Move to {pose} (")
        tmux.keys("Enter")
        tmux.wait_for(f"Does the arm look like its {pose} pose? [Y/n]")
        tmux.keys("y", "Enter")
    screen = tmux.wait_for("EXIT=")
    assert "EXIT=0" in screen and f"saved {out}" in screen, screen
    assert "shoulder_pan: hardly turned" in screen  # nobody swept it: the range is not checked
    cal = load_calibration(out)
    for s in cal.servos:
        direction = -1 if s.id in REVERSED else 1
        assert s.direction == direction and abs(s.offset - direction * MOUNT[s.id]) <= 2, s
    assert cal.joints == () and not any(torque_states(control))
