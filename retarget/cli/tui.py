"""The interactive teleop mode: keys nudge the target, the screen shows target, reached point and joints.

The testable core is :class:`Jog` (key name -> new target, no terminal) and :class:`KeySource` (a
target source fed by it, keeping only the newest target so a held key never builds a backlog); for a rig,
:class:`RigKeys` (one KeySource per arm, Tab selects the arm the keys move).  :class:`TerminalUI` (one arm) and
:class:`RigTerminalUI` (a rig) draw with ``curses`` (stdlib) from the control loop's ``on_tick`` callback: they
poll keys without blocking and redraw about ten times a second, so the loop stays single-threaded.

Keys (one arm: its base frame; a rig: the rig's world frame; x forward, y left, z up)::

    w / s, Up / Down           +x / -x          +  /  -     double / halve the step
    a / d, Left / Right        +y / -y          h           back to the home pose's tool point
    r / f, PgUp / PgDn         +z / -z          q, Esc      quit (the bus's shutdown sequence runs)
    Tab / Shift-Tab            a rig: the next / previous arm is the one the keys move
"""

from __future__ import annotations

import enum
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from itertools import zip_longest
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from retarget.arm import Arm
from retarget.control.loop import TickRecord
from retarget.teleop import tool_point
from retarget.teleop.gate import BasePose, Target, TargetBounds, TargetGate, TargetRejected
from retarget.teleop.sources import Source

if TYPE_CHECKING:
    from retarget.rig.messages import RigGate
    from retarget.rig.plant import RigPlant
    from retarget.rig.spec import RigArm
    from retarget.teleop.follower import Follower

__all__ = ["Action", "GRIPPER_KEYS", "Jog", "KeySource", "RigKeys", "RigTerminalUI", "TerminalUI", "KEYS"]

Array = npt.NDArray[np.float64]

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
#: a rig's keys that select the arm the others move: the next one, the previous one
SELECT_KEYS: dict[str, int] = {"TAB": 1, "BTAB": -1}


class Action(enum.Enum):
    """What a key press did."""

    MOVE = "move"  #: the target moved
    BLOCKED = "blocked"  #: the nudge would leave the bounds; the target stayed
    STEP = "step"  #: the step size changed
    HOME = "home"  #: the target went back home
    GRIPPER = "gripper"  #: the gripper's closure changed (``Jog.gripper``)
    SELECT = "select"  #: a rig: another arm is the one the keys move (:attr:`RigKeys.selected`)
    QUIT = "quit"
    NONE = "none"  #: not a key of the map


@dataclass
class Jog:
    """Key -> target logic: ``target`` ``(3,)`` metres, moved by ``step`` metres per press, in the base frame, or
    with ``frame`` (the base's pose in another frame, e.g. a rig's world) in that frame (``target``, ``home`` and
    the nudges); the ``bounds`` are the base frame's either way (:meth:`base_target`)."""

    target: np.ndarray
    home: np.ndarray
    bounds: TargetBounds
    step: float = 0.01
    #: the gripper's closure 0 (open) .. 1 (closed) the keys asked for; None: no gripper key yet
    gripper: float | None = None
    frame: BasePose | None = None
    message: str = field(default="", init=False)  #: the last press's effect, for the screen

    def base_target(self, target: Array | None = None) -> Array:
        """``target`` (default :attr:`target`) in the base frame, ``(3,)`` metres."""
        point = np.array(self.target if target is None else target, dtype=np.float64)
        return point if self.frame is None else self.frame.to_base(point)[0]

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
            self.bounds.check(self.base_target(candidate))
        except TargetRejected as exc:
            self.message = f"blocked: {exc.reason.value}"
            return Action.BLOCKED
        self.target = candidate
        self.message = ""
        return Action.MOVE


class KeySource(Source):
    """A target source fed by a :class:`Jog`: holds only the newest target (a queue of one), base frame."""

    name = "keys"

    def __init__(self, gate: TargetGate, jog: Jog):
        super().__init__(gate, queue_length=1)
        self.jog = jog
        self._seq = 0

    def press(self, key: str) -> Action:
        """Apply ``key`` to the jog; a new target is queued when it moved or went home."""
        action = self.jog.press(key)
        if action in (Action.MOVE, Action.HOME):
            self._push(Target(self.jog.base_target(), None, self.gate.clock.now(), self._seq))
            self._seq += 1
        elif action is Action.GRIPPER:
            self.gate.gripper = self.jog.gripper  # the teleop loop sends the gate's latest closure each tick
        elif action is Action.QUIT:
            self._finish()
        return action


class RigKeys:
    """A rig's keys: one :class:`KeySource` per arm (``sources``, by arm name, in rig order), each with its own
    :class:`Jog` in the rig's WORLD frame; :data:`SELECT_KEYS` (Tab, Shift-Tab) select the arm the other keys
    move (:attr:`selected`, the first arm at the start); the step is one for every arm; ``q`` ends every source.
    The gripper keys do nothing (a rig's teleop drives no gripper).

    >>> from retarget.control.clock import VirtualClock
    >>> from retarget.rig import RigGate, load_rig
    >>> rig = load_rig("wx250s-pair")
    >>> start = {"left": np.array([0.3, 0.35, 0.2]), "right": np.array([0.3, -0.35, 0.2])}
    >>> keys = RigKeys.for_gate(RigGate.for_rig(rig, clock=VirtualClock()), start=start, home=start)
    >>> [keys.press(k).value for k in ("w", "TAB", "a", "a")], keys.selected
    (['move', 'select', 'move', 'move'], 'right')
    >>> {name: jog.target.round(6).tolist() for name, jog in keys.jogs.items()}  # world frame
    {'left': [0.31, 0.35, 0.2], 'right': [0.3, -0.33, 0.2]}
    >>> keys.sources["right"].drain()[0].position.round(6).tolist()  # what the follower gets: its base frame
    [0.3, -0.03, 0.2]
    """

    def __init__(self, sources: Mapping[str, KeySource]):
        if not sources:
            raise ValueError("Expected the key source of at least one arm, got none")
        self.sources = dict(sources)
        self.names = tuple(self.sources)
        self.selected = self.names[0]
        self.message = ""  #: the last press's effect, for the screen

    @classmethod
    def for_gate(cls, gate: RigGate, *, start: Mapping[str, Array], home: Mapping[str, Array]) -> RigKeys:
        """Each arm's key source on its gate of ``gate`` (targets stamped on its clock, bounds checked in its base
        frame), its jog starting at ``start`` and going home to ``home`` (arm name -> ``(3,)`` m, world frame)."""
        sources = {}
        for name, arm_gate in gate.gates.items():
            jog = Jog(target=np.array(start[name], dtype=np.float64), home=np.array(home[name], dtype=np.float64),
                      bounds=arm_gate.bounds, frame=arm_gate.frame_pose)  # fmt: skip
            sources[name] = KeySource(arm_gate, jog)
        return cls(sources)

    @property
    def jogs(self) -> dict[str, Jog]:
        """Each arm's jog, by arm name."""
        return {name: source.jog for name, source in self.sources.items()}

    def press(self, key: str) -> Action:
        """Apply ``key``: select another arm, quit every arm, or move the selected arm's target; what it did."""
        if key in SELECT_KEYS:
            i = (self.names.index(self.selected) + SELECT_KEYS[key]) % len(self.names)
            self.selected = self.names[i]
            self.message = f"the keys move {self.selected}"
            return Action.SELECT
        if key in GRIPPER_KEYS:
            self.message = "no gripper keys with --rig"
            return Action.NONE
        if key in ("q", "ESC"):
            for source in self.sources.values():
                source.press(key)
            return Action.QUIT
        jog = self.sources[self.selected].jog
        action = self.sources[self.selected].press(key)
        if action is Action.STEP:  # one step for every arm
            for other in self.jogs.values():
                other.step = jog.step
        self.message = f"{self.selected}: {jog.message}" if jog.message else ""
        return action


_CURSES_KEYS = {
    "KEY_UP": "UP",
    "KEY_DOWN": "DOWN",
    "KEY_LEFT": "LEFT",
    "KEY_RIGHT": "RIGHT",
    "KEY_PPAGE": "PGUP",
    "KEY_NPAGE": "PGDN",
    "KEY_BTAB": "BTAB",
    "\x1b": "ESC",
    "\t": "TAB",
}


class _Screen:
    """The curses plumbing of both screens: non-blocking key names (:meth:`keys`), a redraw about ten times a
    second (:meth:`due`), and a screen of text lines (:meth:`paint`)."""

    def __init__(self, screen: Any):
        import curses  # only --interactive needs it; Windows Pythons have none (see retarget.cli.teleop)

        self.curses = curses
        self.screen = screen
        self._next_draw = -1.0
        screen.nodelay(True)
        screen.keypad(True)
        try:
            curses.curs_set(0)
        except curses.error:
            pass

    def keys(self) -> Iterator[str]:
        """The names of the keys waiting (those of :data:`KEYS`, ``TAB``, ``ESC``..., else the character)."""
        while True:
            try:
                key = self.screen.get_wch()
            except self.curses.error:  # no key waiting
                return
            name = self.curses.keyname(key).decode() if isinstance(key, int) else key
            yield _CURSES_KEYS.get(name, name)

    def due(self, time: float) -> bool:
        """True when the screen should be redrawn at loop time ``time`` s (every 0.1 s)."""
        if time < self._next_draw:
            return False
        self._next_draw = time + 0.1
        return True

    def paint(self, lines: list[str]) -> None:
        self.screen.erase()
        height, width = self.screen.getmaxyx()
        for row, text in enumerate(lines[: max(0, height - 1)]):
            self.screen.addnstr(row, 0, text, max(0, width - 1))
        self.screen.refresh()


def _point(label: str, p: Array) -> str:
    return f"{label:<8} x {p[0]:+.3f}  y {p[1]:+.3f}  z {p[2]:+.3f} m"


def _joints(names: tuple[str, ...] | list[str], q: Array) -> list[str]:
    return [f"  {name:<14} {np.degrees(angle):+8.2f} deg" for name, angle in zip(names, q, strict=True)]


def _footer(record: TickRecord) -> str:
    return f"t {record.time:8.2f} s   IK {record.ik_error * 1e3:5.2f} mm   sweeps {record.ik_sweeps}"


class TerminalUI(_Screen):
    """Curses screen driven from the loop's ``on_tick``; ``stop`` is called when the user quits (after the
    key source closed)."""

    def __init__(self, screen: Any, source: KeySource, arm: Arm, stop: Callable[[], None]):
        super().__init__(screen)
        self.source = source
        self.arm = arm
        self.joint_names = arm.joint_names
        self.stop = stop
        self.reached: np.ndarray | None = None

    def poll_keys(self) -> None:
        for key in self.keys():
            if self.source.press(key) is Action.QUIT:
                self.stop()

    def __call__(self, record: TickRecord) -> None:
        self.poll_keys()
        if self.due(record.time):
            q = record.q_present if record.q_present is not None else record.q_cmd
            self.reached = tool_point(self.arm, q)
            self.draw(record)

    def draw(self, record: TickRecord) -> None:
        jog = self.source.jog
        lines = [
            "retarget teleop (interactive)   w/s a/d r/f or arrows+PgUp/PgDn: move   +/-: step   h: home   q: quit",
            "                                o/c: open/close the gripper   [/]: by 0.1",
            "",
            f"{_point('target', jog.target)}   step {jog.step * 1e3:.1f} mm   {jog.message}",
        ]
        if self.reached is not None:
            r = self.reached
            err = float(np.linalg.norm(r - jog.target)) * 1e3
            lines.append(f"{_point('reached', r)}   ({err:.1f} mm from the target)")
        lines.append("")
        q = record.q_present if record.q_present is not None else record.q_cmd
        lines += _joints(self.joint_names, q)
        lines += ["", _footer(record)]
        self.paint(lines)


class RigTerminalUI(_Screen):
    """A rig's curses screen, driven from the rig loop's ``on_tick``: the keys go to ``keys`` (:class:`RigKeys`);
    each arm's column shows its target and reached point (WORLD frame, as the keys move them), its follower's phase
    (``followers``, by arm name) and its joints; ``stop`` is called when the user quits (after every key source
    closed)."""

    WIDTH = 46  #: characters per arm's column

    def __init__(
        self, screen: Any, keys: RigKeys, plant: RigPlant, followers: Mapping[str, Follower], stop: Callable[[], None]
    ):
        super().__init__(screen)
        self.rig_keys, self.plant, self.followers, self.stop = keys, plant, dict(followers), stop

    def __call__(self, record: TickRecord) -> None:
        for key in self.keys():
            if self.rig_keys.press(key) is Action.QUIT:
                self.stop()
        if self.due(record.time):
            self.draw(record)

    def draw(self, record: TickRecord) -> None:
        keys = self.rig_keys
        step = keys.jogs[keys.selected].step
        lines = [
            f"retarget teleop --rig {self.plant.name} (interactive)   keys move the SELECTED arm's target, world frame "
            "(x forward, y left, z up)",
            "  w/s a/d r/f or arrows+PgUp/PgDn: move   +/-: step   h: home   Tab: next arm   q: quit",
            f"  selected: {keys.selected}   step {step * 1e3:.1f} mm   {keys.message}",
            "",
        ]
        q = record.q_present if record.q_present is not None else record.q_cmd
        parts = self.plant.split(q)
        columns = [self._column(a.name, parts[a.name], a) for a in self.plant.rig.arms]
        for row in zip_longest(*columns, fillvalue=""):
            lines.append("".join(cell.ljust(self.WIDTH) for cell in row).rstrip())
        lines += ["", _footer(record)]
        self.paint(lines)

    def _column(self, name: str, q: Array, rig_arm: RigArm) -> list[str]:
        jog, follower = self.rig_keys.jogs[name], self.followers[name]
        reached = rig_arm.placement.to_world(tool_point(rig_arm.arm, q))
        err = float(np.linalg.norm(reached - jog.target)) * 1e3
        mark = ">> " if name == self.rig_keys.selected else "   "
        return [
            f"{mark}{name}  ({follower.phase.value})",
            _point("target", jog.target),
            _point("reached", reached),
            f"         ({err:.1f} mm from the target)",
            *_joints(rig_arm.arm.joint_names, q),
        ]
