"""How ``retarget calibrate`` talks to its user: a terminal, or ``--yes`` (every answer yes, a transcript).

A :class:`Prompter` says lines, waits for Enter, asks yes/no questions and shows a live line (the joint angles
while the user turns a joint) until Enter.  The flow's steps take one, so tests drive them without a terminal.
"""

from __future__ import annotations

import os
import select
import sys
from collections.abc import Callable
from typing import Protocol, TextIO

__all__ = ["AutoPrompter", "Prompter", "TerminalPrompter"]

Sample = Callable[[], str]  #: reads the servos once, returns the live line to show
Step = Callable[[], bool]  #: advances a scripted gesture by one sample period; False once it is over


class Prompter(Protocol):
    """The user's side of the calibration flow."""

    def say(self, text: str) -> None:
        """Show a line."""

    def enter(self, prompt: str) -> None:
        """Show ``prompt`` and wait until the user presses Enter."""

    def confirm(self, question: str, *, default: bool) -> bool:
        """Ask a yes/no question; Enter alone answers ``default``."""

    def watch(self, prompt: str, sample: Sample, step: Step | None = None) -> None:
        """Show ``prompt``, then ``sample()``'s line, refreshed, until Enter (a terminal) or until ``step()``
        returns False (a scripted gesture); ``sample`` runs at least once."""


class TerminalPrompter:
    """Prompts on a terminal: ``out`` for text, ``inp`` for the answers (line by line).

    >>> import io
    >>> p = TerminalPrompter(inp=io.StringIO("n\\n"), out=io.StringIO())
    >>> p.confirm("Save?", default=True)
    False
    """

    PERIOD = 0.05  #: seconds between two live readings

    def __init__(self, *, inp: TextIO | None = None, out: TextIO | None = None):
        self.inp = inp if inp is not None else sys.stdin
        self.out = out if out is not None else sys.stderr

    def say(self, text: str) -> None:
        print(text, file=self.out, flush=True)

    def _line(self) -> str:
        line = self.inp.readline()
        if not line:
            raise EOFError("no more input: run retarget calibrate in a terminal, or with --yes")
        return line.strip()

    def enter(self, prompt: str) -> None:
        self.out.write(f"{prompt} [Enter] ")
        self.out.flush()
        self._line()

    def confirm(self, question: str, *, default: bool) -> bool:
        choices = "[Y/n]" if default else "[y/N]"
        while True:
            self.out.write(f"{question} {choices} ")
            self.out.flush()
            answer = self._line().lower()
            if not answer:
                return default
            if answer in ("y", "yes", "n", "no"):
                return answer.startswith("y")
            self.say("Please answer y or n.")

    def watch(self, prompt: str, sample: Sample, step: Step | None = None) -> None:
        self.say(f"{prompt} [Enter when done]")
        live = self._can_poll()
        while True:
            line = sample()
            self.out.write("\r\x1b[K" + line if live else line + "\n")
            self.out.flush()
            if step is not None and not step():
                break
            if step is None and (not live or self._ready(self.PERIOD)):
                break
        self.out.write("\n" if live else "")
        if step is None:
            self._line()

    def _can_poll(self) -> bool:
        try:
            return os.name == "posix" and self.inp.isatty() and self.out.isatty()
        except (AttributeError, ValueError):
            return False

    def _ready(self, timeout: float) -> bool:
        readable, _, _ = select.select([self.inp], [], [], timeout)
        return bool(readable)


class AutoPrompter:
    """``--yes``: every question answered yes, every Enter pressed; the prompts are written to ``out`` as a
    transcript (``?`` marks a prompt, ``>`` the answer given).

    >>> import io
    >>> out = io.StringIO()
    >>> AutoPrompter(out=out).confirm("Save?", default=False), out.getvalue()
    (True, '? Save? > yes (--yes)\\n')
    """

    def __init__(self, *, out: TextIO | None = None):
        self.out = out if out is not None else sys.stderr

    def say(self, text: str) -> None:
        print(text, file=self.out, flush=True)

    def enter(self, prompt: str) -> None:
        self.say(f"? {prompt} > Enter (--yes)")

    def confirm(self, question: str, *, default: bool) -> bool:
        self.say(f"? {question} > yes (--yes)")
        return True

    def watch(self, prompt: str, sample: Sample, step: Step | None = None) -> None:
        self.say(f"? {prompt}")
        line = sample()
        while step is not None and step():
            line = sample()
        self.say(f"  {line.strip()}")
