"""Progress of a long job on stderr, shared by the command-line tools."""
from __future__ import annotations

import sys
import time


class Progress:
    """One line on stderr: a bar when stderr is a terminal, else a line every 10 %; nothing with
    ``quiet`` (e.g. ``--json``) unless stderr is a terminal."""

    def __init__(self, label: str, quiet: bool = False) -> None:
        self.label, self.quiet, self.tty, self.shown = label, quiet, sys.stderr.isatty(), -1
        self.start = time.monotonic()

    def __call__(self, done: int, total: int, detail: str = "") -> None:
        if self.quiet and not self.tty:
            return
        tenth = 10 * done // max(total, 1)
        bar = "#" * (30 * done // max(total, 1))
        line = (f"{self.label} [{bar:<30}] {done}/{total}{' ' + detail if detail else ''}, "
                f"{time.monotonic() - self.start:.0f} s")
        if self.tty:
            print("\r" + line, end="\n" if done >= total else "", file=sys.stderr, flush=True)
        elif tenth != self.shown:
            self.shown = tenth
            print(line, file=sys.stderr, flush=True)
