"""The interactive teleop mode: keys nudge the target, the screen shows target, reached point and joints.

The testable core is :class:`Jog` (key name -> new target, no terminal) and :class:`KeySource` (a
target source fed by it, keeping only the newest target so a held key never builds a backlog).
:class:`TerminalUI` draws with ``curses`` (stdlib) from the control loop's ``on_tick`` callback: it
polls keys without blocking and redraws about ten times a second, so the loop stays single-threaded.

Keys (base frame: x forward, y left, z up)::

    w / s, Up / Down           +x / -x          +  /  -     double / halve the step
    a / d, Left / Right        +y / -y          h           back to the home pose's tool point
    r / f, PgUp / PgDn         +z / -z          q, Esc      quit (the bus's shutdown sequence runs)
"""

from __future__ import annotations

import enum
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from retarget.arm import Arm
from retarget.control.loop import TickRecord
from retarget.teleop import tool_point
from retarget.teleop.gate import Target, TargetBounds, TargetGate, TargetRejected
from retarget.teleop.sources import Source

__all__ = ["Action", "GRIPPER_KEYS", "Jog", "KeySource", "TerminalUI", "KEYS"]

#: key name -> (axis, sign) for the nudges
KEYS: dict[str, tuple[int, int]] = {
    "w": (0, 1),
    "s": (0, -1),
    "UP": (0, 1),
    "DOWN": (0, -1),
    "a": (1, 1),
    "d": (1, -1),
    "LEFT": (1, 1),
    "RIGHT": (1, -1),
    "r": (2, 1),
    "f": (2, -1),
    "PGUP": (2, 1),
    "PGDN": (2, -1),
}
MIN_STEP = 0.001  #: m
MAX_STEP = 0.1  #: m
#: gripper keys -> closure (0 open .. 1 closed): a value to go to, or a step of it
GRIPPER_KEYS: dict[str, tuple[str, float]] = {"o": ("to", 0.0), "c": ("to", 1.0), "[": ("by", -0.1), "]": ("by", 0.1)}


class Action(enum.Enum):
    """What a key press did."""

    MOVE = "move"  #: the target moved
    BLOCKED = "blocked"  #: the nudge would leave the bounds; the target stayed
    STEP = "step"  #: the step size changed
    HOME = "home"  #: the target went back home
    GRIPPER = "gripper"  #: the gripper's closure changed (``Jog.gripper``)
    QUIT = "quit"
    NONE = "none"  #: not a key of the map


@dataclass
class Jog:
    """Key -> target logic: ``target`` ``(3,)`` metres, base frame, moved by ``step`` metres per press."""

    target: np.ndarray
    home: np.ndarray
    bounds: TargetBounds
    step: float = 0.01
    #: the gripper's closure 0 (open) .. 1 (closed) the keys asked for; None: no gripper key yet
    gripper: float | None = None
    message: str = field(default="", init=False)  #: the last press's effect, for the screen

    def press(self, key: str) -> Action:
        """Apply one key (a name of :data:`KEYS` or :data:`GRIPPER_KEYS`, ``+``, ``-``, ``h``, ``q``, ``ESC``);
        return what it did."""
        if key in ("q", "ESC"):
            return Action.QUIT
        if key in ("+", "="):
            self.step = min(self.step * 2, MAX_STEP)
            self.message = f"step {self.step * 1e3:.0f} mm"
            return Action.STEP
        if key in ("-", "_"):
            self.step = max(self.step / 2, MIN_STEP)
            self.message = f"step {self.step * 1e3:.1f} mm"
            return Action.STEP
        if key in GRIPPER_KEYS:
            how, value = GRIPPER_KEYS[key]
            closure = value if how == "to" else (self.gripper or 0.0) + value
            self.gripper = min(1.0, max(0.0, round(closure, 6)))
            self.message = f"gripper {self.gripper:.1f} (0 open .. 1 closed)"
            return Action.GRIPPER
        if key == "h":
            self.target = np.array(self.home, dtype=np.float64)
            self.message = "home"
            return Action.HOME
        move = KEYS.get(key)
        if move is None:
            return Action.NONE
        axis, sign = move
        candidate = np.array(self.target, dtype=np.float64)
        candidate[axis] += sign * self.step
        try:
            self.bounds.check(candidate)
        except TargetRejected as exc:
            self.message = f"blocked: {exc.reason.value}"
            return Action.BLOCKED
        self.target = candidate
        self.message = ""
        return Action.MOVE


class KeySource(Source):
    """A target source fed by a :class:`Jog`: holds only the newest target (a queue of one)."""

    name = "keys"

    def __init__(self, gate: TargetGate, jog: Jog):
        super().__init__(gate, queue_length=1)
        self.jog = jog
        self._seq = 0

    def press(self, key: str) -> Action:
        """Apply ``key`` to the jog; a new target is queued when it moved or went home."""
        action = self.jog.press(key)
        if action in (Action.MOVE, Action.HOME):
            self._push(Target(self.jog.target.copy(), None, self.gate.clock.now(), self._seq))
            self._seq += 1
        elif action is Action.GRIPPER:
            self.gate.gripper = self.jog.gripper  # the teleop loop sends the gate's latest closure each tick
        elif action is Action.QUIT:
            self._finish()
        return action


_CURSES_KEYS = {
    "KEY_UP": "UP",
    "KEY_DOWN": "DOWN",
    "KEY_LEFT": "LEFT",
    "KEY_RIGHT": "RIGHT",
    "KEY_PPAGE": "PGUP",
    "KEY_NPAGE": "PGDN",
    "\x1b": "ESC",
}


class TerminalUI:
    """Curses screen driven from the loop's ``on_tick``; ``stop`` is called when the user quits (after the
    key source closed)."""

    def __init__(self, screen: Any, source: KeySource, arm: Arm, stop: Callable[[], None]):
        import curses  # only --interactive needs it; Windows Pythons have none (see retarget.cli.teleop)

        self.curses = curses
        self.screen = screen
        self.source = source
        self.arm = arm
        self.joint_names = arm.joint_names
        self.stop = stop
        self.reached: np.ndarray | None = None
        self._next_draw = -1.0
        screen.nodelay(True)
        screen.keypad(True)
        try:
            curses.curs_set(0)
        except curses.error:
            pass

    def poll_keys(self) -> None:
        while True:
            try:
                key = self.screen.get_wch()
            except self.curses.error:  # no key waiting
                return
            name = self.curses.keyname(key).decode() if isinstance(key, int) else key
            if self.source.press(_CURSES_KEYS.get(name, name)) is Action.QUIT:
                self.stop()

    def __call__(self, record: TickRecord) -> None:
        self.poll_keys()
        if record.time >= self._next_draw:
            self._next_draw = record.time + 0.1
            q = record.q_present if record.q_present is not None else record.q_cmd
            self.reached = tool_point(self.arm, q)
            self.draw(record)

    def draw(self, record: TickRecord) -> None:
        jog = self.source.jog
        lines = [
            "retarget teleop (interactive)   w/s a/d r/f or arrows+PgUp/PgDn: move   +/-: step   h: home   q: quit",
            "                                o/c: open/close the gripper   [/]: by 0.1",
            "",
            f"target   x {jog.target[0]:+.3f}  y {jog.target[1]:+.3f}  z {jog.target[2]:+.3f} m   "
            f"step {jog.step * 1e3:.1f} mm   {jog.message}",
        ]
        if self.reached is not None:
            r = self.reached
            err = float(np.linalg.norm(r - jog.target)) * 1e3
            lines.append(f"reached  x {r[0]:+.3f}  y {r[1]:+.3f}  z {r[2]:+.3f} m   ({err:.1f} mm from the target)")
        lines.append("")
        q = record.q_present if record.q_present is not None else record.q_cmd
        for name, angle in zip(self.joint_names, q, strict=True):
            lines.append(f"  {name:<14} {np.degrees(angle):+8.2f} deg")
        lines.append("")
        lines.append(f"t {record.time:8.2f} s   IK {record.ik_error * 1e3:5.2f} mm   sweeps {record.ik_sweeps}")
        self.screen.erase()
        height, width = self.screen.getmaxyx()
        for row, text in enumerate(lines[: max(0, height - 1)]):
            self.screen.addnstr(row, 0, text, max(0, width - 1))
        self.screen.refresh()
