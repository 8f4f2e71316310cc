"""The process launcher stops everything it started, escalating signals when a process ignores SIGINT; the
tools' interrupts reach their waiting loops even where the signal handler's exception was swallowed."""
import os
import signal
import sys
import time

import pytest

from air_hockey_agent.tools import interrupt
from air_hockey_agent.tools.game import _wait_for_lineup
from air_hockey_agent.tools.launch import Launcher, ProcessSpec

STUBBORN = "import signal, time; signal.signal(signal.SIGINT, signal.SIG_IGN); print('up', flush=True); time.sleep(60)"


def test_shutdown_escalates_and_reaps_all_processes():
    with Launcher(dict(os.environ), echo=None) as launcher:
        launcher.start(ProcessSpec("polite", [sys.executable, "-c", "import time; print('up', flush=True); time.sleep(60)"]))
        launcher.start(ProcessSpec("stubborn", [sys.executable, "-c", STUBBORN]))
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline and not all(p.lines for p in launcher.processes.values()):
            time.sleep(0.05)
        codes = launcher.shutdown(grace=0.5)
    assert codes["polite"] != 0 and codes["stubborn"] == -15  # SIGINT ignored, SIGTERM ends it
    assert all(p.returncode is not None for p in launcher.processes.values())


def test_output_is_captured_per_process():
    with Launcher(dict(os.environ), echo=None) as launcher:
        proc = launcher.start(ProcessSpec("hello", [sys.executable, "-c", "print('hi there')"]))
        proc.popen.wait(timeout=20)
        proc.reader.join(timeout=5)
        assert proc.lines == ["hi there"] and launcher.exited() == {"hello": 0}


class _SignalledWhileFinalised:
    """Sends ``sig`` to this process from its finaliser, where Python discards the handler's exception (as in
    importlib's module-lock callback, where a SIGTERM during ``import rclpy`` was lost)."""

    def __init__(self, sig: int) -> None:
        self.sig = sig

    def __del__(self) -> None:
        os.kill(os.getpid(), self.sig)
        time.sleep(0.01)  # the handler runs here, inside the finaliser


@pytest.fixture
def tool_signals(monkeypatch):
    """The tools' handlers installed; Python's and a clean slate restored afterwards. Yields the exceptions
    Python discarded."""
    discarded = []
    monkeypatch.setattr(sys, "unraisablehook", lambda unraisable: discarded.append(unraisable.exc_type))
    previous = signal.getsignal(signal.SIGTERM), signal.getsignal(signal.SIGINT)
    interrupt.install()
    try:
        yield discarded
    finally:
        signal.signal(signal.SIGTERM, previous[0])
        signal.signal(signal.SIGINT, previous[1])
        interrupt._received.clear()


@pytest.mark.parametrize("sig, raised", [(signal.SIGTERM, interrupt.Terminated), (signal.SIGINT, KeyboardInterrupt)])
def test_a_signal_whose_exception_was_discarded_is_raised_by_check(tool_signals, sig, raised):
    interrupt.check()  # nothing came: nothing raised
    _SignalledWhileFinalised(sig)  # dropped at once
    assert tool_signals == [raised]  # the handler ran and its exception went nowhere
    for _ in range(2):  # and stays requested
        with pytest.raises(raised) as caught:
            interrupt.check()
        assert type(caught.value) is raised
        assert interrupt.exit_code(caught.value) == 128 + sig


def test_game_waiting_for_its_nodes_ends_on_a_discarded_sigterm(tool_signals):
    """`air-hockey game` waits for its nodes' ready lines; a SIGTERM whose exception was lost ends the wait (and
    so the game, with its nodes stopped) at the next look instead of after the start-up timeout."""
    with Launcher(dict(os.environ), echo=None) as launcher:
        launcher.start(ProcessSpec("never_ready", [sys.executable, "-c", "import time; time.sleep(60)"]))
        _SignalledWhileFinalised(signal.SIGTERM)
        with pytest.raises(interrupt.Terminated):  # not the GameError of a start-up timeout
            _wait_for_lineup(launcher, timeout=10.0)
    assert launcher.exited()["never_ready"] != 0
