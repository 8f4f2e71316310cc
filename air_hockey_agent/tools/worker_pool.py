"""Jobs on worker processes for the in-process tools (``game --in-process --workers``, ``strategy-test
--in-process --workers``), stopped at once on Ctrl-C or SIGTERM.

Workers are spawned (not forked: each builds its own pybullet world and solvers). A pool left to finish
on an interrupt would still start every queued job; here the tool's interrupt terminates the workers and
is raised on, so the tool's own Ctrl-C path runs.
"""
from __future__ import annotations

import multiprocessing
from typing import Any, Callable, Sequence

from air_hockey_agent.tools import interrupt

POLL = 0.5  # [s] wall time between looks at the tool's interrupts while a job runs


def run_in_processes(function: Callable[..., Any], jobs: Sequence[tuple], workers: int,
                     on_done: Callable[[int, Any], None] = lambda index, result: None) -> list:
    """``function(*job)`` for every job on ``workers`` processes; the results in job order (a job that
    raised gives its exception instead). ``on_done(index, result)`` is called in job order as they come."""
    pool = multiprocessing.get_context("spawn").Pool(workers)
    try:
        pending = [pool.apply_async(function, job) for job in jobs]
        results = []
        for index, job in enumerate(pending):
            while not job.ready():  # not job.get(): a signal whose exception was discarded must end the wait
                job.wait(POLL)
                interrupt.check()
            try:
                result = job.get()
            except Exception as exc:  # a worker's error is the job's result, not the tool's end
                result = exc
            results.append(result)
            on_done(index, result)
        pool.close()
        pool.join()
        return results
    except BaseException:
        pool.terminate()
        pool.join()
        raise
