"""``retarget calibrate``: find a real arm's servo offsets and directions, check its ranges, verify, save.

The flow (:func:`~retarget.calibrate.flow.calibrate`) runs its steps (:mod:`~retarget.calibrate.steps`) against
the servos (:class:`~retarget.calibrate.servos.ServoLink`, raw pulses over the driver's link) and talks to the
user through an injectable :class:`~retarget.calibrate.prompts.Prompter`: a terminal
(:class:`~retarget.calibrate.prompts.TerminalPrompter`), or ``--yes``
(:class:`~retarget.calibrate.prompts.AutoPrompter`).
On a simulated bus, :class:`~retarget.calibrate.hands.SimHands` moves the limp joints as a user's hands would.
The result is a :class:`retarget.arm.calibration.Calibration`.
"""

from retarget.calibrate.flow import CalibrationResult, calibrate
from retarget.calibrate.hands import Hands, SimHands
from retarget.calibrate.prompts import AutoPrompter, Prompter, TerminalPrompter
from retarget.calibrate.servos import ServoLink

__all__ = [
    "AutoPrompter",
    "CalibrationResult",
    "Hands",
    "Prompter",
    "ServoLink",
    "SimHands",
    "TerminalPrompter",
    "calibrate",
]
