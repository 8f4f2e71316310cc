"""``air-hockey game``: launch the simulated two-robot game (headless by default).

The node graph is the one in README "Architecture": one table simulation and referee, and per robot
a puck tracker, tactics and trajectory generator, each robot in its own namespace. The launcher
starts every node, reports which are running and which are not implemented yet, and never pretends
a game is being played when a node it needs is missing.
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

from air_hockey_agent.nodes.runtime import EXIT_NOT_IMPLEMENTED, READY_MARKER
from air_hockey_agent.params import ParamSpec, load_defaults
from air_hockey_agent.paths import config_file
from air_hockey_agent.tools.launch import Launcher, ProcessSpec
from air_hockey_agent.tools.ros_env import node_executable, ros_environment

ROBOTS = ("iiwa_front", "iiwa_back")
SHARED_NODES = ("table_sim", "referee")
PER_ROBOT_NODES = ("puck_tracker", "tactics", "trajectory_generator")

GAME_PARAMS = (
    ParamSpec("startup_timeout", float, "[s] time for all nodes to come up", 1.0, 600.0),
    ParamSpec("shutdown_grace", float, "[s] grace per shutdown signal", 0.1, 60.0),
)


def game_processes(gui: bool, real_time_factor: float) -> list[ProcessSpec]:
    """The node processes of one game, all on sim time."""
    specs = []
    for node in SHARED_NODES:
        extra = ["-p", f"gui:={str(gui).lower()}", "-p", f"real_time_factor:={real_time_factor}"] \
            if node == "table_sim" else ["-p", "use_sim_time:=true"]
        specs.append(ProcessSpec(node, [*node_executable(node), "--ros-args", *extra]))
    for robot in ROBOTS:
        for node in PER_ROBOT_NODES:
            specs.append(ProcessSpec(f"{robot}/{node}", [*node_executable(node), "--ros-args", "-r",
                                                         f"__ns:=/{robot}", "-p", "use_sim_time:=true",
                                                         "-p", f"robot:={robot}"]))
    return specs


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("game", help="run the simulated two-robot game (headless by default)",
                                   description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--gui", action="store_true", help="open the pybullet window (table seen from above)")
    parser.add_argument("--real-time-factor", type=float, default=1.0,
                        help="simulation speed: 1.0 watchable, >1 faster, 0 as fast as possible (default 1.0)")
    parser.add_argument("--duration", type=float, default=0.0,
                        help="stop after this many seconds of wall time (default 0: until Ctrl-C)")
    parser.add_argument("--domain-id", type=int, default=None, help="ROS_DOMAIN_ID (1..101; default: inherited)")
    parser.set_defaults(run=run)


def _summarise(launcher: Launcher) -> tuple[list[str], list[str], list[str]]:
    running, pending, failed = [], [], []
    for label, proc in launcher.processes.items():
        code = proc.returncode
        (running if code is None else pending if code == EXIT_NOT_IMPLEMENTED else failed).append(
            label if code is None or code == EXIT_NOT_IMPLEMENTED else f"{label} (exit {code})")
    return running, pending, failed


def _wait_for_lineup(launcher: Launcher, timeout: float) -> None:
    """Wait until every process has either exited or logged that it is ready, or timeout."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if all(p.returncode is not None or any(READY_MARKER in line for line in p.lines)
               for p in launcher.processes.values()):
            return
        time.sleep(0.1)


def run(args: argparse.Namespace) -> int:
    settings = load_defaults([config_file("game.yaml")], "/game", GAME_PARAMS)
    with tempfile.TemporaryDirectory(prefix="air_hockey_game_") as tmp:
        env = ros_environment(domain_id=args.domain_id, ros_home=Path(tmp))
        specs = game_processes(args.gui, args.real_time_factor)
        print(f"[game] starting {len(specs)} nodes: {', '.join(s.label for s in specs)}", flush=True)
        with Launcher(env) as launcher:
            for spec in specs:
                launcher.start(spec)
            _wait_for_lineup(launcher, settings["startup_timeout"])
            running, pending, failed = _summarise(launcher)
            print(f"[game] running: {', '.join(running) or 'none'}", flush=True)
            if pending:
                print(f"[game] not implemented yet: {', '.join(pending)}", flush=True)
            if failed:
                print(f"[game] failed: {', '.join(failed)}", flush=True)
            if pending or failed:
                print("[game] cannot play a game: the nodes above are missing. Nothing was simulated; "
                      "shutting down.", flush=True)
                launcher.shutdown(settings["shutdown_grace"])
                return EXIT_NOT_IMPLEMENTED if pending and not failed else 1
            return _play(launcher, args.duration, settings["shutdown_grace"])


def _play(launcher: Launcher, duration: float, grace: float) -> int:
    print("[game] all nodes running" + (f" for {duration:.0f} s" if duration > 0 else "; Ctrl-C to stop"), flush=True)
    start = time.monotonic()
    try:
        while duration <= 0 or time.monotonic() - start < duration:
            ended = launcher.wait_any_exit(timeout=0.5)
            if ended:
                print(f"[game] node ended unexpectedly: {ended}; stopping the game", flush=True)
                launcher.shutdown(grace)
                return 1
    except KeyboardInterrupt:
        print("\n[game] interrupted; shutting down", flush=True)
    launcher.shutdown(grace)
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(run(argparse.Namespace(gui=False, real_time_factor=1.0, duration=0.0, domain_id=None)))
