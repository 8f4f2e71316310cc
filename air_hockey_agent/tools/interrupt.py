"""SIGTERM handled like Ctrl-C in the ``air-hockey`` tools, so every process a tool started is stopped.

Python's default SIGTERM action ends the process at once: a tool killed that way (``kill``, ``timeout``, a
CI runner) left its node processes running in their own process groups. :func:`install` turns SIGTERM into
:class:`Terminated`, a ``KeyboardInterrupt``, so the tools' Ctrl-C paths (the launcher's shutdown, the
recorder's close) run for it too; :func:`exit_code` is then 128 + 15 instead of Ctrl-C's 128 + 2.
"""
from __future__ import annotations

import signal


class Terminated(KeyboardInterrupt):
    """The tool received SIGTERM."""


def _raise_terminated(signum, frame) -> None:
    raise Terminated()


def install() -> None:
    """Raise :class:`Terminated` on SIGTERM (call from the main thread)."""
    signal.signal(signal.SIGTERM, _raise_terminated)


def exit_code(exc: KeyboardInterrupt) -> int:
    """The shell's convention: 128 + the signal's number."""
    return 128 + (signal.SIGTERM if isinstance(exc, Terminated) else signal.SIGINT)
