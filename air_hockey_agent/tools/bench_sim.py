"""``air-hockey bench sim``: real-time factor of the table simulation, as fast as possible.

Three runs of the same simulated duration, each including the OptiTrack stand-in and the output
schedule of the ``table_sim`` node (:class:`~air_hockey_agent.sim.runner.SimRunner`), without ROS
publishing: the puck alone (no arms loaded), both arms loaded and holding their home pose, and both
arms following joint trajectories (a sweep of all seven joints, re-sent every second). The puck is shot
around the table in every run. Real-time factor = simulated seconds / wall seconds.
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from air_hockey_agent.core.motion.joint_trajectory import JointTrajectory
from air_hockey_agent.core.estimation.synthetic import MocapImperfections
from air_hockey_agent.sim.params import load_sim_params
from air_hockey_agent.tools.argtypes import number
from air_hockey_agent.tools.json_output import json_text

# pybullet prints a banner when imported: the simulation modules load only when this benchmark runs,
# so that other `air-hockey` commands keep a clean stderr.
SWEEP = np.array([0.4, 0.3, -0.4, 0.3, 0.4, -0.3, 0.5])  # [rad] joint offsets of the arm motion


def _sweep(world, name: str, sign: float) -> JointTrajectory:
    """One second out to home + sign * SWEEP through a midpoint, from the current state."""
    from air_hockey_agent.sim.world import ARM_JOINTS
    q, dq = world.joint_state(name)
    target = np.asarray(world.settings.home) + sign * SWEEP
    return JointTrajectory.from_points(ARM_JOINTS, world.time, [0.5, 1.0], [0.5 * (q + target), target], None, q, dq)


def measure(params: dict, duration: float, arms: str) -> float:
    """Real-time factor of ``duration`` simulated seconds; ``arms``: "none", "idle" or "moving"."""
    from air_hockey_agent.sim.runner import SimRunner
    from air_hockey_agent.sim.world import SimSettings, TableWorld
    settings = SimSettings.from_params(params)
    if arms == "none":
        settings = settings.puck_only()
    world = TableWorld(settings)
    runner = SimRunner(world, params["mocap_rate"], MocapImperfections.from_params(params),
                       np.random.default_rng(0), params["clock_rate"], params["joint_state_rate"],
                       params["mocap_table_pose"])
    steps_per_second = round(1.0 / world.dt)
    start = time.perf_counter()
    for second in range(int(duration)):
        world.set_puck_state([0.0, 0.0, 2.0 * np.cos(second), 2.0 * np.sin(second), 0.0, 5.0])
        if arms == "moving":
            for name in world.robots:
                world.follow(name, _sweep(world, name, 1.0 if second % 2 == 0 else -1.0))
        for _ in range(steps_per_second):
            out = runner.step()
            if out.joint_states:
                for name in world.robots:
                    world.joint_state(name)  # what the node reads to publish joint states
    elapsed = time.perf_counter() - start
    world.close()
    return int(duration) / elapsed


def add_parser(bench_subparsers: argparse._SubParsersAction) -> None:
    parser = bench_subparsers.add_parser("sim", help="real-time factor of the table simulation", description=__doc__,
                                         formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--duration", type=number(0.0, low_open=True), default=10.0, help="simulated seconds per run (default 10)")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    params = load_sim_params()
    result = {}
    for key, arms in (("rtf_puck_only", "none"), ("rtf_arms_idle", "idle"), ("rtf_with_arms", "moving")):
        if not args.json:
            print(f"running {arms} arms for {args.duration:g} simulated seconds ...", flush=True)
        result[key] = round(measure(params, max(1.0, args.duration), arms), 2)
    if args.json:
        print(json_text(result))
    else:
        print(f"real-time factor at {params['physics_rate']:.0f} Hz physics: puck only {result['rtf_puck_only']}, "
              f"arms holding {result['rtf_arms_idle']}, arms following trajectories {result['rtf_with_arms']}")
    return 0
