"""``air-hockey game``: the simulated two-robot game (headless by default).

Starts the node graph of README "Architecture", each node in its own process: ``table_sim`` and
``referee``, and for each robot its ``puck_tracker``, ``tactics`` and ``trajectory_generator`` in the
robot's namespace, all on simulated time; with ``--record`` or ``--markers`` also the ``visualizer``
(``/visualization/markers`` for Foxglove and RViz; recorded). Starts the game through the referee and follows it: a
progress line while it runs (sim time, score, hits), and at the end the score, the hits per robot
(mallet-puck contacts reported by the simulation), the referee's faults by reason and how often each
tactic was entered. ``--json`` prints exactly one JSON object instead. Every process it started is
stopped at the end, on Ctrl-C, or when any node dies.

``--in-process`` plays the same game without ROS in this process (:mod:`air_hockey_agent.sim.game_loop`:
the same agent, simulation, tracker and referee code called in a fixed order), so a seed repeats a
game exactly, and faster; nothing is published, and ``--record`` writes the same topics as the node graph's
(:mod:`air_hockey_agent.sim.game_record`).

``--versus FILE`` plays head to head: one robot's tactics, trajectory generator and tracker also read FILE (a
ROS 2 parameter YAML), the other robot plays the defaults; with ``--in-process --games N`` each seed is played
twice, the variant once on each side, and the summary adds the goals, hits and games won of each agent and
a sign test of the goals (:mod:`air_hockey_agent.core.game.versus`).

``--table FILE`` plays on another simulated table (:mod:`air_hockey_agent.sim.table_file`;
``config/lab_table.yaml`` is the lab's), both agents deployed as on a real table.
"""
from __future__ import annotations

import argparse
import math
import sys
import tempfile
import time
from pathlib import Path

from air_hockey_agent.core.game.versus import VersusTally, variant_robot, versus_games
from air_hockey_agent.node_graph import NodeRun, game_nodes
from air_hockey_agent.params import ParamSpec, load_defaults
from air_hockey_agent.paths import config_file
from air_hockey_agent.tools import interrupt
from air_hockey_agent.tools.files import output_bag_directory
from air_hockey_agent.tools.json_output import json_text
from air_hockey_agent.tools.launch import Launcher, ProcessSpec
from air_hockey_agent.tools.ros_env import display_available, node_executable, ros_environment
from air_hockey_agent.tools.argtypes import SEED_MAX, count
from air_hockey_agent.sim.game_topics import MARKER_TOPICS, RECORDED_TOPICS
from air_hockey_agent.sim.params import ROBOTS
from air_hockey_agent.sim.table_file import add_table_option, table_problem

KERNEL_COMPILE_NOTICE = 3.0  # [s] a kernel warm-up longer than this was a compilation: say so (a load takes ~1 s)

GAME_PARAMS = (
    ParamSpec("startup_timeout", float, "[s] time for all nodes to come up", 1.0, 600.0),
    ParamSpec("shutdown_grace", float, "[s] grace per shutdown signal", 0.1, 60.0),
    ParamSpec("progress_period", float, "[s] wall time between progress lines", 0.1, 3600.0),
    ParamSpec("start_timeout", float, "[s] wall time to wait for the referee's start service", 1.0, 600.0),
)


class GameError(Exception):
    """The game cannot run; the message is one line. ``code``: 2 for a bad argument, 1 for a failure."""

    def __init__(self, message: str, code: int = 1) -> None:
        super().__init__(message)
        self.code = code


def process(node: NodeRun, label: str | None = None) -> ProcessSpec:
    """A node of :mod:`air_hockey_agent.node_graph` as a process of this package's launcher."""
    return ProcessSpec(label or node.label, [*node_executable(node.executable), *node.ros_arguments()])


def game_processes(gui: bool, real_time_factor: float, seed: int, markers: bool = False,
                   versus: tuple[str, str] | None = None, table: str = "") -> list[ProcessSpec]:
    """The node processes of one game (:func:`air_hockey_agent.node_graph.game_nodes`)."""
    return [process(node) for node in game_nodes(gui, real_time_factor, seed, markers, versus, table)]


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("game", help="run the simulated two-robot game (headless by default)",
                                   description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--duration", type=float, default=60.0,
                        help="seconds of simulated time to play (default 60)")
    parser.add_argument("--goals", type=int, default=0,
                        help="also stop after this many goals, whichever comes first (0: off)")
    parser.add_argument("--real-time-factor", type=float, default=None,
                        help="simulation speed: 1 watchable, >1 faster, 0 as fast as possible "
                             "(default: 1 with --gui, else 0)")
    parser.add_argument("--seed", type=int, default=0, help="random seed of the simulation and the referee (default 0)")
    parser.add_argument("--gui", action="store_true", help="open the pybullet window (table seen from above)")
    parser.add_argument("--record", type=Path, default=None, metavar="OUT.mcap",
                        help="record the game's topics and markers to this MCAP bag (Foxglove opens it)")
    parser.add_argument("--markers", action="store_true",
                        help="publish /visualization/markers for RViz or Foxglove while the game runs "
                             "(on with --record)")
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of the summary table")
    parser.add_argument("--log", type=Path, default=None, metavar="FILE",
                        help="write every node's output to FILE (default: only errors, on stderr)")
    parser.add_argument("--domain-id", type=count(1, 101), default=None, help="ROS_DOMAIN_ID (1..101; default: inherited)")
    parser.add_argument("--games", type=count(1), default=1,
                        help="with --in-process: play this many games, seeds SEED, SEED+1, ..., and add them up "
                             "(with --versus each seed twice; default 1)")
    parser.add_argument("--workers", type=count(1, 16), default=1,
                        help="with --in-process --games: games played at once, each in its own process (default 1)")
    parser.add_argument("--in-process", action="store_true",
                        help="play without ROS in this process: a seed repeats the game exactly (--record "
                             "records it; with --games, OUT is a directory of one bag per game, seed_<SEED>; "
                             "no --markers, --log or --domain-id)")
    parser.add_argument("--versus", type=Path, default=None, metavar="FILE",
                        help="head to head: one robot's tactics, trajectory_generator and puck_tracker also read "
                             "this ROS 2 parameter YAML (only their parameters), the other plays the defaults; the "
                             f"variant plays {ROBOTS[0]}; with --games (even) each seed is played twice, the variant "
                             "once on each side; the summary adds each agent's goals, hits and games won and a sign "
                             "test of the goals")
    add_table_option(parser, "both agents' trackers and tactics")
    parser.set_defaults(run=run)


def _check_args(args: argparse.Namespace) -> None:
    if not (math.isfinite(args.duration) and args.duration > 0.0):
        raise GameError(f"--duration must be a positive number of seconds, got {args.duration}", 2)
    if args.goals < 0:
        raise GameError(f"--goals must be 0 (off) or more, got {args.goals}", 2)
    if args.real_time_factor is not None and not (math.isfinite(args.real_time_factor) and args.real_time_factor >= 0):
        raise GameError(f"--real-time-factor must be 0 or more, got {args.real_time_factor}", 2)
    if not 0 <= args.seed <= SEED_MAX:
        raise GameError(f"--seed must be in 0..{SEED_MAX}, got {args.seed}", 2)
    if args.games > 1 and not args.in_process:
        raise GameError("--games needs --in-process (the node graph plays one game per run)", 2)
    if args.workers > 1 and not (args.in_process and args.games > 1):
        raise GameError("--workers needs --in-process and --games (each game on its own process)", 2)
    if args.workers > 1 and args.gui:
        raise GameError("--workers and --gui: one window per game is not offered; leave one out", 2)
    if args.versus is not None and args.games > 1 and args.games % 2:
        raise GameError(f"--versus with --games {args.games}: an even number (each seed is played twice, the "
                        "variant once on each side)", 2)
    if not 0 <= args.seed + args.games - 1 < 2 ** 31:
        raise GameError(f"--seed {args.seed} with --games {args.games}: the seeds must stay in 0..{2 ** 31 - 1}", 2)
    if args.in_process:
        ros_only = [flag for flag, value in (("--markers", args.markers or None), ("--log", args.log),
                                             ("--domain-id", args.domain_id)) if value is not None]
        if ros_only:
            raise GameError(f"{', '.join(ros_only)} need{'s' if len(ros_only) == 1 else ''} the node graph: leave out "
                            "--in-process (or them)", 2)
    if args.log is not None and not args.log.parent.is_dir():
        raise GameError(f"--log {args.log}: directory {args.log.parent} does not exist", 2)
    if args.versus is not None:
        from air_hockey_agent.agent_params import agent_variant_problem
        problem = agent_variant_problem(args.versus, "--versus")
        if problem:
            raise GameError(problem, 2)
    if args.table is not None:
        problem = table_problem(args.table)
        if problem:
            raise GameError(problem, 2)
    if args.record is not None:
        bag = output_bag_directory(args.record)
        if bag.exists():
            raise GameError(f"--record {args.record}: {bag} exists already, not overwriting", 2)
        if not bag.parent.is_dir():
            raise GameError(f"--record {args.record}: directory {bag.parent} does not exist", 2)


def prepare_for_nodes(say) -> None:
    """Build the tactics' fastest-hit table and compile (or load) the numba kernels once here (the motion
    layer's with the planner, the puck prediction's), so the nodes, which start at once, do not each
    build or compile them within ``startup_timeout``."""
    from air_hockey_agent.agent_params import load_agent_params
    from air_hockey_agent.core.game.speed_map import load_or_build
    from air_hockey_agent.core.puck.prediction import prepare_prediction
    from air_hockey_agent.motion_params import build_planner, load_motion_params
    motion = load_motion_params()
    load_or_build(build_planner(motion, ROBOTS[0]), motion, load_agent_params()["speed_map_grid"], log=say)
    start = time.monotonic()
    prepare_prediction()
    if time.monotonic() - start > KERNEL_COMPILE_NOTICE:
        say(f"compiled the puck prediction kernel in {time.monotonic() - start:.0f} s (once per change of "
            "core/puck/prediction_kernel.py; make setup does it)")


def run(args: argparse.Namespace) -> int:
    say = (lambda text: print(f"[game] {text}", file=sys.stderr, flush=True)) if args.json else \
        (lambda text: print(f"[game] {text}", flush=True))
    try:
        _check_args(args)
        settings = load_defaults([config_file("game.yaml")], "/game", GAME_PARAMS)
        if args.gui and not display_available():
            raise GameError("--gui needs a display (DISPLAY is not set); leave --gui out to play headless", 2)
        rtf = args.real_time_factor if args.real_time_factor is not None else (1.0 if args.gui else 0.0)
        prepare_for_nodes(say)
        if args.in_process:
            result = _play_in_process(args, settings, rtf, say)
        else:
            with tempfile.TemporaryDirectory(prefix="air_hockey_game_") as tmp:
                env = ros_environment(domain_id=args.domain_id, ros_home=Path(tmp))
                result = _play(args, settings, env, rtf, say)
    except GameError as exc:
        print(f"air-hockey game: error: {exc}", file=sys.stderr)
        return exc.code
    except KeyboardInterrupt as exc:
        print("\n[game] interrupted", file=sys.stderr)
        return interrupt.exit_code(exc)
    if args.json:
        print(json_text({**result, "table": str(args.table)} if args.table is not None else result))
    return 0


def _play(args, settings, env: dict, rtf: float, say) -> dict:
    from air_hockey_agent.tools.game_monitor import GameMonitor
    errors: list[str] = []
    log = open(args.log, "w", buffering=1) if args.log is not None else None

    def on_line(label: str, line: str) -> None:
        if log is not None:
            log.write(f"[{label}] {line}\n")
        if "[ERROR]" in line or "[FATAL]" in line or "Traceback" in line:
            errors.append(f"[{label}] {line}")
            print(f"[{label}] {line}", file=sys.stderr, flush=True)

    markers = args.markers or args.record is not None
    versus = (variant_robot(ROBOTS, 0), str(args.versus)) if args.versus is not None else None
    specs = game_processes(args.gui, rtf, args.seed, markers, versus, _table(args))
    say(f"starting {len(specs)} nodes (real-time factor {rtf:g}, seed {args.seed})"
        + (f"; {versus[0]} plays {versus[1]}" if versus else "") + _table_note(args))
    with Launcher(env, echo=None, on_line=on_line) as launcher:
        for spec in specs:
            launcher.start(spec)
        _wait_for_lineup(launcher, settings["startup_timeout"])
        topics = {**RECORDED_TOPICS, **MARKER_TOPICS} if markers else RECORDED_TOPICS
        monitor = GameMonitor(env, ROBOTS, args.record, topics)
        try:
            monitor.start_game(settings["start_timeout"])
            say(f"game started: {args.duration:g} s of simulated time" + (f" or {args.goals} goals" if args.goals else ""))
            ended = monitor.follow(args.duration, args.goals, settings["progress_period"], launcher, say,
                                   tty=not args.json and sys.stdout.isatty())
        finally:
            recording = monitor.close()
        codes = launcher.shutdown(settings["shutdown_grace"])
    if log is not None:
        log.close()
    if ended:
        raise GameError(f"node ended during the game: {ended} (exit codes); every other process was stopped")
    bad = {label: code for label, code in codes.items() if code not in (0, -2, 130)}
    if bad:
        say(f"nodes that did not exit cleanly: {bad}")
    result = monitor.board.result(str(recording) if recording else None)
    if not args.json:
        print(monitor.board.table(result["recording"]), flush=True)
        if result["recording"] is None:
            print("  to watch one: add --record OUT.mcap and open it in Foxglove (README \"Watching a game\")")
    return _with_versus(args, [result], result, [versus[0]] if versus else [])


def _play_in_process(args, settings, rtf: float, say) -> dict:
    """One game, or with ``--games`` several, on ``--workers`` processes (one JSON object: ``{"games":
    [...], "total": {...}}``, each game's result with its ``"seed"``, in seed order)."""
    from air_hockey_agent.core.game.scoreboard import Scoreboard
    from air_hockey_agent.sim.game_loop import play_game
    if args.versus is None:
        seeds, variants = list(range(args.seed, args.seed + args.games)), [None] * args.games
    else:
        pairs = versus_games(args.seed, args.games, ROBOTS)
        seeds, variants = [seed for seed, _ in pairs], [(robot, str(args.versus)) for _, robot in pairs]
    say(f"in process, without ROS (real-time factor {rtf:g}, seed{'s' if len(seeds) > 1 else ''} "
        f"{seeds[0]}{f'-{seeds[-1]}' if len(seeds) > 1 else ''}"
        + (f", {args.workers} workers" if args.workers > 1 else "") + f"): {args.duration:g} s of simulated time"
        + (f" or {args.goals} goals" if args.goals else "") + " per game" + _table_note(args))
    if args.versus is not None:
        say(f"versus: {ROBOTS[0]} plays {args.versus}" + (f", then {ROBOTS[1]} on the same seed, and so on for each "
                                                         "seed" if args.games > 1 else ""))
    run_args = (args.duration, args.goals, args.gui, rtf, settings["progress_period"])
    names = [f"seed_{seed}" + (f"_{v[0]}" if v else "") for seed, v in zip(seeds, variants)]
    bags = _game_bags(args.record, names)
    if args.workers == 1:
        results = []
        for seed, bag, variant in zip(seeds, bags, variants):
            results.append(play_game(seed, *run_args, progress=say, record=bag, versus=variant, table=_table(args),
                                     check=interrupt.check))
            if args.games > 1:  # an interrupt ended that game: the run stops there, as on several workers
                interrupt.check()
    else:
        from air_hockey_agent.tools.worker_pool import run_in_processes

        def done(index: int, result) -> None:
            if isinstance(result, Exception):
                raise GameError(f"game {names[index]} failed: {type(result).__name__}: {result}")
            variant = f" ({variants[index][0]} the variant)" if variants[index] else ""
            say(f"seed {seeds[index]}{variant}: {Scoreboard.total(ROBOTS, [result]).progress()}")
        jobs = [(seed, *run_args, None, bag, variant, _table(args))
                for seed, bag, variant in zip(seeds, bags, variants)]
        results = run_in_processes(play_game, jobs, args.workers, done)
    if not args.json:
        for r in results:
            print(Scoreboard.total(ROBOTS, [r]).table(r.get("recording")), flush=True)
    if args.games == 1:
        return _with_versus(args, results, results[0], [v[0] for v in variants if v])
    games = [{"seed": seed, **r, **({"versus_robot": v[0]} if v else {})}
             for seed, r, v in zip(seeds, results, variants)]
    total = Scoreboard.total(ROBOTS, games)  # the games' seeds go with their goals
    if not args.json:
        print(f"{args.games} games, seeds {seeds[0]}-{seeds[-1]}: "
              + total.table(None).replace("game over after", "in all", 1), flush=True)
    return {"games": games, "total": _with_versus(args, results, total.result(None), [v[0] for v in variants if v])}


def _table(args) -> str:
    """The ``--table`` file ('' for config/sim.yaml's table)."""
    return "" if args.table is None else str(args.table)


def _table_note(args) -> str:
    return f"; on the simulated table of {args.table}" if args.table is not None else ""


def _with_versus(args, results: list[dict], summary: dict, variant_robots: list[str]) -> dict:
    """``summary`` with the head-to-head tally of ``results`` under "versus" (with --versus; printed as a line
    without --json): the variant played robot ``variant_robots[k]`` in game k."""
    if args.versus is None:
        return summary
    tally = VersusTally.from_results(results, variant_robots)
    if not args.json:
        print(tally.line(str(args.versus)), flush=True)
    return {**summary, "versus": tally.result(str(args.versus))}


def _game_bags(record: Path | None, names: list[str]) -> list[Path | None]:
    """Where each in-process game is recorded: nowhere without ``--record``; one game in ``OUT``; several
    in the new directory ``OUT``, one bag per game, named ``names[k]`` (``seed_<SEED>``, with --versus
    ``seed_<SEED>_<ROBOT>``: the variant's robot; the games already played stay when the run is interrupted)."""
    if record is None:
        return [None] * len(names)
    out = output_bag_directory(record)
    if len(names) == 1:
        return [out]
    out.mkdir()
    return [out / name for name in names]


def _wait_for_lineup(launcher: Launcher, timeout: float) -> None:
    """Wait until every process logged that it is ready; a process that exits first fails the game."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        dead = launcher.exited()
        if dead:
            tail = "; ".join(f"{label} exit {code}: {launcher.processes[label].lines[-1:] or ''}"
                             for label, code in dead.items())
            raise GameError(f"nodes failed to start: {tail}")
        if all(p.ready for p in launcher.processes.values()):
            return
        time.sleep(0.1)
        interrupt.check()
    missing = [label for label, p in launcher.processes.items() if not p.ready]
    raise GameError(f"nodes not ready after {timeout:g} s: {', '.join(missing)}")


if __name__ == "__main__":  # pragma: no cover
    sys.exit(run(argparse.Namespace(duration=60.0, goals=0, real_time_factor=None, seed=0, gui=False, record=None,
                                    json=False, log=None, domain_id=None, markers=False, in_process=False, games=1,
                                    workers=1, versus=None)))
