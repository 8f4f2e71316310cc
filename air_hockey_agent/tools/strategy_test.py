"""``air-hockey strategy-test``: Smash, Cut, Prepare and Repel success rates (thesis sec. 4.6, 5.4), and
ours beyond the thesis, Guard: the agent (nothing forced) keeping a puck left behind its ready line out of
its goal (only when asked for: the default is the thesis's four).

Each worker runs its own simulation and the agent of ``iiwa_front`` (``table_sim`` as fast as possible,
``puck_tracker``, ``tactics``, ``trajectory_generator``) and a ``strategy_test`` node that plays its
share of the trials, on its own ``ROS_DOMAIN_ID``; the opponent runs no agent and holds its home pose.
A trial's initial state depends only on the seed, the strategy and the trial's index, not on the
number of workers. Trials that a crashed or hung worker did not finish are run once more and then
counted as failures with their reason. Prints a table next to the thesis's fig. 5.7, or with
``--json`` exactly one JSON object (Ctrl-C or SIGTERM: every process stopped, then the report of the
trials finished so far, ``"interrupted": true``, and exit 130 / 143); ``--plot DIR`` writes the bar chart
(fig. 5.7) and the smash spread (fig. 5.8) as PNG. ``--in-process`` plays the trials without ROS
(:mod:`air_hockey_agent.sim.strategy_loop`; workers are processes of this tool): a run repeats exactly,
whatever the number of workers. ``--params-file FILE`` gives the agent a variant (its tactics' and
trajectory generator's parameters, as ``air-hockey game --versus``) on the same trials. ``--defended``: the
opponent runs the agent too (the defaults, or with ``--opponent-params FILE`` a variant), waits at its ready
point until the tested robot's hit and then defends (ours, beyond the thesis: how often a shot beats a defender).
``--table FILE``: on another simulated table (:mod:`air_hockey_agent.sim.table_file`; ``config/lab_table.yaml``
is the lab's), the agent deployed as on a real table.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import threading
import time
from pathlib import Path

from air_hockey_agent.core.game.strategy.report import summarise, table
from air_hockey_agent.core.game.strategy.scoring import TrialResult
from air_hockey_agent.core.game.strategy.trials import OPPONENT, ROBOT
from air_hockey_agent.node_graph import agent_nodes
from air_hockey_agent.sim.table_file import add_table_option, table_problem
from air_hockey_agent.tools import interrupt
from air_hockey_agent.tools.files import write_text_atomic
from air_hockey_agent.tools.game import prepare_for_nodes, process
from air_hockey_agent.tools.json_output import json_text
from air_hockey_agent.tools.launch import Launcher, ProcessSpec
from air_hockey_agent.tools.progress import Progress
from air_hockey_agent.tools.ros_env import node_executable, ros_environment
from air_hockey_agent.tools.argtypes import count, seed

GROUPS = {"smash": ("smash_straight", "smash_left", "smash_right"), "cut": ("cut",), "prepare": ("prepare",),
          "repel": ("repel",), "guard": ("guard",)}
THESIS_GROUPS = ("smash", "cut", "prepare", "repel")  # the default: thesis sec. 4.6 (and issue #12's 15 min)
RESULT, DONE = "TRIAL_RESULT ", "STRATEGY_DONE"
WORKER_GRACE = 5.0  # [s] per shutdown signal when a worker's processes are stopped
WORKER_POLL = 0.5  # [s] wall time between looks at a worker's processes, and the tool's at its interrupts


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("strategy-test", help="success rates of Smash, Cut, Prepare, Repel and Guard",
                                   description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--strategies", nargs="+", choices=sorted(GROUPS), default=sorted(THESIS_GROUPS),
                        help="strategies to test (smash = straight, left and right bank; guard = a puck left behind "
                             "the ready line, nothing forced; default: the thesis's, all but guard)")
    parser.add_argument("--trials", type=count(1), default=100, help="trials per reported strategy (default 100)")
    parser.add_argument("--seed", type=seed, default=0, help="random seed of the initial states (default 0)")
    parser.add_argument("--workers", type=count(1, 16), default=1, help="parallel simulations (default 1)")
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of the table")
    parser.add_argument("--plot", type=Path, default=None, metavar="DIR", help="write fig. 5.7/5.8-like PNGs here")
    parser.add_argument("--results", type=Path, default=None, metavar="FILE",
                        help="write every trial's result as one JSON line (initial state, hit, outcome, reason)")
    parser.add_argument("--log", type=Path, default=None, metavar="FILE", help="write every node's output to FILE")
    parser.add_argument("--domain-id", type=count(1, 101), default=None,
                        help="first ROS_DOMAIN_ID of the workers (1..101; default: derived from the process id)")
    parser.add_argument("--in-process", action="store_true",
                        help="play the trials without ROS (the same agent code; repeats exactly; no --log or "
                             "--domain-id)")
    parser.add_argument("--params-file", type=Path, default=None, metavar="FILE",
                        help="the agent's tactics, trajectory_generator and puck_tracker also read this ROS 2 "
                             "parameter YAML (only their parameters; the trials stay the defaults': a variant meets "
                             "the same pucks)")
    parser.add_argument("--defended", action="store_true",
                        help=f"{OPPONENT} runs the agent (the defaults): it waits at its ready point until the tested "
                             "robot's hit, then defends (default: it holds its home pose, as in the thesis)")
    parser.add_argument("--opponent-params", type=Path, default=None, metavar="FILE",
                        help="with --defended: the opponent's tactics, trajectory_generator and puck_tracker also "
                             "read this ROS 2 parameter YAML (as --params-file for the tested robot)")
    add_table_option(parser, "the agent's tracker and tactics", "; the strategy test FILE's strategy_test section")
    parser.set_defaults(run=run)


def worker_processes(trials: list[tuple[str, int]], seed: int, params_file: str = "",
                     defended: bool = False, opponent_file: str = "", table_file: str = "") -> list[ProcessSpec]:
    table = ["--params-file", table_file] if table_file else []  # rcl refuses an empty '-p table_file:='
    specs = [ProcessSpec("table_sim", [*node_executable("table_sim"), "--ros-args", *table, "-p",
                                       "real_time_factor:=0.0", "-p", "clock_rate:=100.0", "-p", f"seed:={seed}"])]
    specs += [process(n, label=n.executable) for n in agent_nodes(ROBOT, use_sim_time=True, sim_table=True,
                                                                        variant_file=params_file,
                                                                        table_file=table_file)]
    if defended:
        specs += [process(n) for n in agent_nodes(OPPONENT, use_sim_time=True, sim_table=True,
                                                  variant_file=opponent_file, table_file=table_file)]
    trial_list = ",".join(f"{s}:{i}" for s, i in trials)
    specs.append(ProcessSpec("strategy_test", [*node_executable("strategy_test"), "--ros-args", *table,
                                               "-p", f"seed:={seed}", "-p", f"trials:={trial_list}",
                                               "-p", f"defended:={str(defended).lower()}",
                                               *(["-p", f"table_file:={table_file}"] if table_file else [])]))
    return specs


class Worker(threading.Thread):
    """One simulation and agent on its own ROS domain, running a list of trials."""

    def __init__(self, domain: int, trials: list[tuple[str, int]], seed: int, results: dict, lock: threading.Lock,
                 on_result, log=None, variants: tuple[str, bool, str, str] = ("", False, "", "")) -> None:
        super().__init__(daemon=True)
        self.domain, self.trials, self.seed, self.log = domain, trials, seed, log
        self.variants = variants  # (params_file, defended, opponent_file, table_file): worker_processes' last four
        self.results, self.lock, self.on_result = results, lock, on_result
        self.error = ""
        self.stopping = threading.Event()  # set by the tool on Ctrl-C or SIGTERM: stop the processes now
        self.finished = threading.Event()  # its processes are stopped (Thread.join interrupted by a signal
        # marks a running thread as ended on Python 3.11, bpo-45274: is_alive() and join() no longer wait)

    def on_line(self, label: str, line: str) -> None:
        if self.log is not None:
            with self.lock:
                self.log.write(f"[{self.domain} {label}] {line}\n")
        if label == "strategy_test" and line.startswith(RESULT):
            record = json.loads(line[len(RESULT):])
            with self.lock:
                self.results[(record["strategy"], record["index"])] = record
            self.on_result()

    def run(self) -> None:
        try:
            self._play()
        finally:
            self.finished.set()

    def _play(self) -> None:
        with tempfile.TemporaryDirectory(prefix="air_hockey_strategy_") as tmp:
            env = ros_environment(domain_id=self.domain, ros_home=Path(tmp))
            with Launcher(env, echo=None, on_line=self.on_line) as launcher:
                for spec in worker_processes(self.trials, self.seed, *self.variants):
                    launcher.start(spec)
                while not self.stopping.is_set():
                    ended = launcher.wait_any_exit(timeout=WORKER_POLL)
                    if ended:
                        if "strategy_test" not in ended or ended["strategy_test"] != 0:
                            tail = {k: launcher.processes[k].lines[-1:] for k in ended}
                            self.error = f"worker on domain {self.domain}: {ended} {tail}"
                        break
                launcher.shutdown(WORKER_GRACE)


def _run_trials(pending: list[tuple[str, int]], args, results: dict, progress, total: int, domain0: int,
                log=None) -> list[str]:
    lock = threading.Lock()
    count = lambda: progress(len(results), total)  # noqa: E731
    shares = [pending[k::args.workers] for k in range(args.workers)]
    workers = [Worker(domain0 + k, share, args.seed, results, lock, count, log, _variants(args))
               for k, share in enumerate(shares) if share]
    for w in workers:
        w.start()
    try:
        for w in workers:
            while not w.finished.wait(WORKER_POLL):
                interrupt.check()
    except KeyboardInterrupt:  # the workers are daemon threads: left alone, their nodes would outlive the tool
        for w in workers:
            w.stopping.set()
        for w in workers:
            w.finished.wait()
        raise
    return [w.error for w in workers if w.error]


def _run_in_process(pending: list[tuple[str, int]], args, results: dict, progress, total: int) -> list[str]:
    """The trials in chunks on fresh tables (sim/strategy_loop.py), on ``--workers`` processes."""
    from air_hockey_agent.sim.strategy_loop import chunks, run_chunk
    from air_hockey_agent.tools.worker_pool import run_in_processes
    errors: list[str] = []
    jobs = [(args.seed, chunk, share, *_variants(args)) for chunk, share in chunks(pending)]

    def store(index: int, records) -> None:
        if isinstance(records, Exception):  # its trials are run once more, then counted as failures
            errors.append(f"{type(records).__name__}: {records}")
            return
        for (strategy, trial), record in zip(jobs[index][2], records):
            results[(strategy, trial)] = record
        progress(len(results), total)

    if args.workers == 1:
        for index, job in enumerate(jobs):
            store(index, run_chunk(*job))
            interrupt.check()  # a signal whose exception Python discarded: no further chunk
    else:
        run_in_processes(run_chunk, jobs, args.workers, store)
    return errors


def _variants(args) -> tuple[str, bool, str, str]:
    """The tested agent's variant file ('' for the defaults), whether the opponent defends, its file, and the
    table file ('' for config/sim.yaml's table)."""
    text = lambda path: "" if path is None else str(path)  # noqa: E731
    return text(args.params_file), args.defended, text(args.opponent_params), text(args.table)


def _check(args) -> str:
    if args.in_process and (args.log is not None or args.domain_id is not None):
        return "--log and --domain-id need the node graph: leave out --in-process (or them)"
    if args.domain_id is not None and not (1 <= args.domain_id and args.domain_id + args.workers - 1 <= 101):
        return f"--domain-id must leave room for {args.workers} domains in 1..101, got {args.domain_id}"
    if args.log is not None and not args.log.parent.is_dir():
        return f"--log {args.log}: directory {args.log.parent} does not exist"
    if args.results is not None and not args.results.parent.is_dir():
        return f"--results {args.results}: directory {args.results.parent} does not exist"
    if args.plot is not None and args.plot.exists() and not args.plot.is_dir():
        return f"--plot {args.plot}: exists and is not a directory"
    if args.opponent_params is not None and not args.defended:
        return "--opponent-params needs --defended (without it the opponent runs no agent)"
    from air_hockey_agent.agent_params import agent_variant_problem
    for path, option in ((args.params_file, "--params-file"), (args.opponent_params, "--opponent-params")):
        problem = agent_variant_problem(path, option) if path is not None else ""
        if problem:
            return problem
    return table_problem(args.table) if args.table is not None else ""


def run(args: argparse.Namespace) -> int:
    problem = _check(args)
    if problem:
        print(f"air-hockey strategy-test: error: {problem}", file=sys.stderr)
        return 2
    say = lambda text: print(f"[strategy-test] {text}", file=sys.stderr, flush=True)  # noqa: E731
    prepare_for_nodes(say)
    if args.params_file is not None:
        say(f"the agent also reads {args.params_file}")
    if args.table is not None:
        say(f"on the simulated table of {args.table} (the agent as on a real table: config/tracker.yaml and its "
            "puck_tracker section)")
    if args.defended:
        opponent = "defaults" if args.opponent_params is None else f"defaults and {args.opponent_params}"
        say(f"{OPPONENT} runs the agent's {opponent} and defends after the tested robot's hit")
    keys = [k for group in sorted(args.strategies) for k in GROUPS[group]]
    trials = [(k, i) for i in range(args.trials) for k in keys]
    domain0 = args.domain_id or 50 + os.getpid() % (52 - args.workers)
    results: dict = {}
    progress = Progress("[strategy-test] trials", args.json)
    start = time.monotonic()
    log = open(args.log, "w", buffering=1) if args.log is not None else None
    play = (lambda pending: _run_in_process(pending, args, results, progress, len(trials))) if args.in_process else \
        (lambda pending: _run_trials(pending, args, results, progress, len(trials), domain0, log))
    interrupted: KeyboardInterrupt | None = None
    try:
        errors = play(trials)
        missing = [t for t in trials if t not in results]
        if missing:
            say(f"{len(missing)} trials unfinished ({'; '.join(errors) or 'worker stopped'}); running them once more")
            errors += play(missing)
    except KeyboardInterrupt as exc:  # Ctrl-C or SIGTERM: the trials finished so far are reported, then its exit code
        interrupted = exc
    finally:
        if log is not None:
            log.close()
    if interrupted is None:
        for strategy, index in (t for t in trials if t not in results):
            results[(strategy, index)] = TrialResult(strategy, index, reason="not finished twice (worker failed)"
                                                     ).record(error=True, tactic="")
    else:
        asked, trials = len(trials), [t for t in trials if t in results]
        say(f"interrupted: {len(trials)} of {asked} trials finished")
        if not trials:
            return interrupt.exit_code(interrupted)
    _report(args, trials, results, time.monotonic() - start, say, interrupted is not None)
    return 0 if interrupted is None else interrupt.exit_code(interrupted)


def _report(args: argparse.Namespace, trials: list[tuple[str, int]], results: dict, seconds: float, say,
            interrupted: bool) -> None:
    """The table (or with --json the JSON object), --results and --plot of ``trials``: every trial asked
    for, or with ``interrupted`` the ones finished before Ctrl-C or SIGTERM (JSON: ``"interrupted": true``)."""
    summary = summarise((results[t] for t in trials), args.defended)
    if args.results is not None:
        write_text_atomic(args.results, "".join(json_text(results[t]) + "\n" for t in trials))
        say(f"wrote {args.results}")
    if args.plot is not None:
        from air_hockey_agent.tools.strategy_plots import write_plots
        for path in write_plots(summary, [results[t] for t in trials], args.plot, args.defended, _variants(args)[3]):
            say(f"wrote {path}")
    if args.json:
        report = {k: {f: v for f, v in e.items() if f != "failures"} for k, e in summary.items()}
        report["seconds"] = round(seconds, 1)
        if args.params_file is not None:
            report["params_file"] = str(args.params_file)
        if args.defended:
            report["defended"] = True
        if args.opponent_params is not None:
            report["opponent_params"] = str(args.opponent_params)
        if args.table is not None:
            report["table"] = str(args.table)
        if interrupted:
            report["interrupted"] = True
        print(json_text(report))
    else:
        on_table = f"\n  on the simulated table of {args.table}" if args.table is not None else ""
        print(table(summary, seconds) + on_table + ("\n  interrupted: the trials finished before it" if interrupted
                                                    else ""))
