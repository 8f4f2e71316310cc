"""A small process supervisor for ROS nodes (``launch`` is not available as a wheel).

Starts node processes, prefixes their output with their name, reports exits, and shuts every
process down on request: SIGINT (SIGTERM for one that is not ready yet), then SIGTERM, then SIGKILL, so
nothing is left running.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from typing import Callable, Mapping, Sequence, TextIO

from air_hockey_agent.start_up import READY_MARKER


@dataclass
class ProcessSpec:
    """One process to launch: a label for its output and the full command."""

    label: str
    command: Sequence[str]


@dataclass
class RunningProcess:
    spec: ProcessSpec
    popen: subprocess.Popen
    reader: threading.Thread
    lines: list[str] = field(default_factory=list)

    @property
    def returncode(self) -> int | None:
        return self.popen.poll()

    @property
    def ready(self) -> bool:
        """The node logged that it stands (``READY_MARKER``). Asked during shutdown, which may follow a SIGTERM
        that interrupted the game's own import of rclpy (its monitor's): importing the marker from
        nodes/runtime.py here imported rclpy again over the half-loaded C extension ("type Destroyable is
        already registered", a traceback and exit 1 instead of 143; CI, 2026-12-05)."""
        return any(READY_MARKER in line for line in list(self.lines))

    @property
    def stop_signal(self) -> int:
        """SIGINT for a node that said it is ready (its handlers shut it down cleanly); SIGTERM before that,
        which ends a process still importing silently where SIGINT printed a KeyboardInterrupt traceback."""
        return signal.SIGINT if self.ready else signal.SIGTERM


class Launcher:
    """Start and supervise a set of processes; use as a context manager so shutdown always runs."""

    def __init__(self, env: Mapping[str, str], echo: TextIO | None = sys.stdout,
                 on_line: Callable[[str, str], None] | None = None) -> None:
        self._env = dict(env)
        self._echo = echo
        self._on_line = on_line
        self._lock = threading.Lock()
        self.processes: dict[str, RunningProcess] = {}

    def __enter__(self) -> "Launcher":
        return self

    def __exit__(self, *exc: object) -> None:
        self.shutdown()

    def start(self, spec: ProcessSpec) -> RunningProcess:
        popen = subprocess.Popen(list(spec.command), env=self._env, stdout=subprocess.PIPE,
                                 stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, text=True, bufsize=1,
                                 start_new_session=True)
        running = RunningProcess(spec, popen, threading.Thread(daemon=True))
        running.reader = threading.Thread(target=self._pump, args=(running,), daemon=True)
        running.reader.start()
        self.processes[spec.label] = running
        return running

    def _pump(self, running: RunningProcess) -> None:
        assert running.popen.stdout is not None
        for line in running.popen.stdout:
            line = line.rstrip("\n")
            with self._lock:
                running.lines.append(line)
                if self._echo is not None:
                    print(f"[{running.spec.label}] {line}", file=self._echo, flush=True)
            if self._on_line is not None:
                self._on_line(running.spec.label, line)

    def exited(self) -> dict[str, int]:
        """Labels and exit codes of the processes that have ended."""
        return {label: p.returncode for label, p in self.processes.items() if p.returncode is not None}

    def wait_any_exit(self, timeout: float, poll: float = 0.05) -> dict[str, int]:
        """Wait until at least one process ended or ``timeout`` passed; return those that ended."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            done = self.exited()
            if done:
                return done
            time.sleep(poll)
        return self.exited()

    def stop(self, label: str, grace: float = 5.0) -> int:
        """Stop one process (SIGINT, SIGTERM, SIGKILL, each after ``grace`` seconds); return its exit code."""
        running = self.processes[label]
        for sig in dict.fromkeys((running.stop_signal, signal.SIGTERM, signal.SIGKILL)):
            if running.returncode is not None:
                break
            try:
                os.killpg(running.popen.pid, sig)
            except ProcessLookupError:
                break
            try:
                running.popen.wait(timeout=grace)
            except subprocess.TimeoutExpired:
                continue
        running.popen.wait()
        running.reader.join(timeout=2.0)
        return running.popen.returncode

    def shutdown(self, grace: float = 5.0) -> dict[str, int]:
        """Stop every process; return all exit codes."""
        for label in list(self.processes):
            if self.processes[label].returncode is None:
                try:
                    os.killpg(self.processes[label].popen.pid, self.processes[label].stop_signal)
                except ProcessLookupError:
                    pass
        return {label: self.stop(label, grace) for label in list(self.processes)}
