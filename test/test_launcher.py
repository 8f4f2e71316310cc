"""The process launcher stops everything it started, escalating signals when a process ignores SIGINT."""
import os
import sys
import time

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
