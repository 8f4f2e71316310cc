"""SIGTERM handled like Ctrl-C in the ``air-hockey`` tools, so every process a tool started is stopped.

Python's default SIGTERM action ends the process at once: a tool killed that way (``kill``, ``timeout``, a
CI runner) left its node processes running in their own process groups. :func:`install` turns SIGTERM into
:class:`Terminated`, a ``KeyboardInterrupt``, so the tools' Ctrl-C paths (the launcher's shutdown, the
recorder's close) run for it too; :func:`exit_code` is then 128 + 15 instead of Ctrl-C's 128 + 2.

The exception a signal handler raises can be lost: where the signal lands in Python code run by something
that discards exceptions, importlib's module-lock callback ("Exception ignored in ... cb") or a C
extension's module initialisation (silently), the tool carried on (a SIGTERM probe during ``import rclpy,
numpy``: 3 of 420 lost; ``air-hockey game`` then played its 600 s). So the handlers also remember the
signal, and the tools' waiting loops call :func:`check`, which raises it again.
"""
from __future__ import annotations

import signal

_received: list[int] = []  # the signals received since install(), in order


class Terminated(KeyboardInterrupt):
    """The tool received SIGTERM."""


def _raise_terminated(signum, frame) -> None:
    _received.append(signum)
    raise Terminated()


def _raise_interrupt(signum, frame) -> None:
    _received.append(signum)
    raise KeyboardInterrupt()


def install() -> None:
    """Raise :class:`Terminated` on SIGTERM and ``KeyboardInterrupt`` on SIGINT, remembering either (call from
    the main thread)."""
    _received.clear()
    signal.signal(signal.SIGTERM, _raise_terminated)
    signal.signal(signal.SIGINT, _raise_interrupt)


def check() -> None:
    """Raise the interrupt again if a SIGTERM or SIGINT came since :func:`install` (main thread, in waiting
    loops: the handler's own exception may have been lost). Once a signal came, every call raises."""
    if signal.SIGTERM in _received:
        raise Terminated()
    if _received:
        raise KeyboardInterrupt()


def exit_code(exc: KeyboardInterrupt) -> int:
    """The shell's convention: 128 + the signal's number."""
    return 128 + (signal.SIGTERM if isinstance(exc, Terminated) else signal.SIGINT)
