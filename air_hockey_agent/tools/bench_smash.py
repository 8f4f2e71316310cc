"""``air-hockey bench smash``: how accurate the smash is without ROS, shot by shot.

For random pucks at rest in the smash area (the strategy test's initial states) and each smash variant,
the tactics' own proposal (forced variant) is planned by the motion layer from the posture at the
tactics' ready point, with the selector's own answers to a refusal (later, slower) as in the nodes, and
executed in the pybullet table with one arm, as fast as possible; no nodes, no tracker (the puck
position is exact). Per variant: how many shots were planned, how many scored, where the puck reached
the opponent's goal line (offset from the centre), and the angle between the aimed direction and the
direction the puck actually left in. A reference for the strategy test, which runs the same tactics
through the nodes.
"""
from __future__ import annotations

import argparse
import math
from dataclasses import replace

import numpy as np

from air_hockey_agent.tools.json_output import json_text
from air_hockey_agent.tools.progress import Progress
from air_hockey_agent.tools.argtypes import count, seed

VARIANTS = {"smash_straight": "straight", "smash_left": "left_bank", "smash_right": "right_bank"}
ROBOT = "iiwa_front"
ASKS = 8             # commands per shot at most (the first and the selector's answers to refusals)
FLIGHT = 2.5         # [s] simulated after the hit time


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("smash", help="smash accuracy in the pybullet table without ROS",
                                   description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--shots", type=count(1), default=20, help="pucks per variant (default 20)")
    parser.add_argument("--seed", type=seed, default=0, help="random seed of the puck positions (default 0)")
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of the table")
    parser.set_defaults(run=run)


def _stats(values: list[float]) -> dict:
    if not values:
        return {"mean": None, "std": None}
    return {"mean": float(np.mean(values)), "std": float(np.std(values))}


def _plan(selector, planner, situation, mallet: np.ndarray, start):
    """(plan, command) of the forced smash: the selector's command planned from ``start``, its refusals
    answered as the tactics node answers them (TrajectoryStatus -> on_status); (None, None) when the
    selector sends nothing."""
    from air_hockey_agent.core.game.tactics.selector import RUNNING
    from air_hockey_agent.core.motion.planner import Command
    plan = cmd = None
    for _ in range(ASKS):
        command = selector.step(start.t, RUNNING, situation, mallet).command
        if command is None:
            break
        cmd = Command(command.point, command.velocity, command.time)
        plan = planner.plan(cmd, start)
        if plan.ok:
            break
        selector.on_status(start.t, plan.outcome, plan.max_speed, start.t)
    return plan, cmd


def run(args: argparse.Namespace) -> int:
    from air_hockey_agent.agent_params import build_selector, load_agent_params
    from air_hockey_agent.core.game.situation import build_situation
    from air_hockey_agent.core.game.strategy.trials import make_trial
    from air_hockey_agent.core.game.tactics.base import SMASH
    from air_hockey_agent.core.motion.joint_trajectory import JointTrajectory
    from air_hockey_agent.core.motion.planner import ArmState
    from air_hockey_agent.motion_params import build_planner, load_motion_params
    from air_hockey_agent.sim.params import load_sim_params
    from air_hockey_agent.sim.world import ARM_JOINTS, SimSettings, TableWorld
    from air_hockey_agent.strategy_params import trial_settings
    from air_hockey_agent.tools.bench_planner import ready_state
    planner = build_planner(load_motion_params(), ROBOT)
    from air_hockey_agent.paths import config_file
    from air_hockey_agent.tracker_params import SIM_TABLE_FILE
    agent = load_agent_params()
    agent["puck_params_file"] = str(config_file(SIM_TABLE_FILE))  # the shots fly in the simulated world
    selector, kin = build_selector(agent, ROBOT)
    trials = trial_settings()  # the strategy test's: no puck on the waiting mallet
    start = ready_state(planner, selector.s.point(selector.s.ready_point))  # iiwa_front: own frame = table frame
    sim = SimSettings.from_params(load_sim_params())
    world = TableWorld(replace(sim, robot_bases={ROBOT: sim.robot_bases[ROBOT]}))
    line = sim.table.length / 2 - sim.table.puck_radius - 0.005
    progress = Progress("[bench smash] shots", args.json)
    result, done = {}, 0
    try:
        for key, variant in VARIANTS.items():
            planned, goals, offsets, errors = 0, 0, [], []
            for i in range(args.shots):
                x, y = make_trial(key, i, args.seed, trials).state[:2]
                world.set_joint_positions(ROBOT, start.q)
                world.move_puck([x, y, 0.0, 0.0, 0.0, 0.0])
                world.step(50)
                world.take_contacts()
                t0 = world.time
                sit = build_situation(ROBOT, t0, [x, y, 0, 0, 0, 0], t0 + np.arange(1, 21) * 0.05,
                                      np.tile([x, y, 0, 0, 0, 0], (20, 1)))
                selector.force(SMASH, variant)
                plan, cmd = _plan(selector, planner, sit, kin.position(start.q)[:2], ArmState(t0, start.q, start.dq))
                done += 1
                progress(done, len(VARIANTS) * args.shots)
                if plan is None or not plan.ok:
                    continue
                planned += 1
                world.follow(ROBOT, JointTrajectory.from_points(ARM_JOINTS, t0, plan.times - t0, plan.q, plan.dq,
                                                                start.q, start.dq))
                offset = None
                for _ in range(int((cmd.time - t0 + FLIGHT) / world.dt)):
                    world.step()
                    p = world.puck_state()
                    if p[0] >= line:
                        offset = float(p[1])
                        break
                contacts = world.take_contacts()
                if contacts:
                    aimed = math.atan2(cmd.velocity[1], cmd.velocity[0])
                    errors.append(math.degrees(math.atan2(contacts[0].vy, contacts[0].vx) - aimed))
                if offset is not None:
                    offsets.append(offset)
                    goals += abs(offset) < sim.table.goal_mouth
            result[key] = {"shots": args.shots, "planned": planned, "goal_rate": goals / args.shots,
                           "offset_m": _stats(offsets), "direction_error_deg": _stats(errors)}
    finally:
        world.close()
    if args.json:
        print(json_text(result))
        return 0
    for key, r in result.items():
        o, e = r["offset_m"], r["direction_error_deg"]
        offset = "-" if o["mean"] is None else f"{o['mean'] * 100:+.1f} +- {o['std'] * 100:.1f} cm"
        error = "-" if e["mean"] is None else f"{e['mean']:+.2f} +- {e['std']:.2f} deg"
        print(f"{key:<16} planned {r['planned']}/{r['shots']}, goals {r['goal_rate'] * 100:5.1f} %, "
              f"offset {offset}, puck direction - aim {error}")
    return 0
