"""``air-hockey bench tactics``: how long one tactics decision takes (issue #11 target: p99 <= 1 ms).

Plays random puck episodes through the tactics of one robot the way the node does: at every mocap
frame (120 Hz) the tracker's 1 s prediction of the puck model (what ``puck/prediction`` carries) is
turned into a situation and the state machine decides; every command is answered "accepted" at once,
and the mallet is taken to be at rest where the last one put it (at the ready point when an episode
starts), so the checks that need the mallet (a strike's approach, Ready's way) are timed too.
Episodes: a puck at rest or slow on the own half (Smash, Prepare), shots at the own goal straight and
off the rims (Repel, Cut), and pucks leaving (Ready). Prints the decision time (mean, p99, max), the
situation building time, the decisions per tactic, and, as a machine-independent figure, the p99 in
units of one tracker prediction timed in the same process.
"""
from __future__ import annotations

import argparse
import math
import time
from collections import Counter

import numpy as np

from air_hockey_agent.tools.json_output import json_text
from air_hockey_agent.tools.progress import Progress
from air_hockey_agent.tools.argtypes import count, seed

FRAME = 1.0 / 120.0       # [s] mocap frame period (thesis sec. 4.5)
EPISODE = 1.5             # [s] simulated time per episode
HORIZON, SAMPLE_EVERY = 1.0, 6  # the tracker's published prediction (config/tracker.yaml: 1 s, 0.05 s)
ROBOT = "iiwa_front"


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("tactics", help="tactics decision time per frame (mean, p99)",
                                   description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--episodes", type=count(1), default=200, help="random puck episodes of 1.5 s (default 200)")
    parser.add_argument("--seed", type=seed, default=0, help="random seed (default 0)")
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of the table")
    parser.set_defaults(run=run)


def random_episode(rng: np.random.Generator, length: float, width: float) -> np.ndarray:
    """A table-frame puck state from one of the situations thesis sec. 4.6 describes."""
    kind = rng.integers(4)
    if kind == 0:  # at rest or slow on the own half
        speed, heading = rng.uniform(0.0, 0.3), rng.uniform(-math.pi, math.pi)
        return np.array([rng.uniform(-0.85, -0.1), rng.uniform(-0.45, 0.45),
                         speed * math.cos(heading), speed * math.sin(heading), 0.0, 0.0])
    if kind == 3:  # leaving toward the opponent
        return np.array([rng.uniform(-0.6, 0.2), rng.uniform(-0.4, 0.4), rng.uniform(0.5, 2.0),
                         rng.uniform(-0.8, 0.8), 0.0, rng.uniform(-5, 5)])
    # a shot from the opponent's defend line (thesis sec. 4.6: 2 m/s) at the goal (1) or a rim (2)
    x, y = length / 2 - 0.2, rng.uniform(-0.4, 0.4)
    aim_y = rng.uniform(-0.1, 0.1) if kind == 1 else rng.choice([-1.0, 1.0]) * 2 * (width / 2 - 0.032) + rng.uniform(-0.2, 0.2)
    d = np.array([-length + 0.2, aim_y - y])
    v = rng.uniform(1.0, 2.5) * d / np.linalg.norm(d)
    return np.array([x, y, v[0], v[1], 0.0, 0.0])


def run(args: argparse.Namespace) -> int:
    from air_hockey_agent.agent_params import build_selector, load_agent_params
    from air_hockey_agent.core.game.situation import build_situation
    from air_hockey_agent.core.game.tactics.base import NAMES
    from air_hockey_agent.core.game.tactics.selector import ACCEPTED, RUNNING
    from air_hockey_agent.core.puck.prediction import predict_fast
    from air_hockey_agent.core.estimation.ekf import PuckEKF
    from air_hockey_agent.start_up import freeze_start_up
    from air_hockey_agent.tracker_params import load_tracker_params
    selector, _ = build_selector(load_agent_params(), ROBOT)
    model, ready = selector.shots.model, selector.s.point(selector.s.ready_point)
    settings = PuckEKF.from_params(load_tracker_params()).settings  # the tracker's prediction, as it publishes it
    rng = np.random.default_rng(args.seed)
    freeze_start_up()  # as the tactics node does once it stands
    step_ms, build_ms, predict_ms, tactics, commands = [], [], [], Counter(), 0
    progress = Progress("[bench tactics] episodes", args.json)
    for e in range(args.episodes):
        state = random_episode(rng, model.table.length, model.table.width)
        selector.force(None)  # a fresh episode: nothing sent, nothing blocked
        mallet, t = ready.copy(), 0.0
        while t < EPISODE:
            w0 = time.perf_counter()
            pred = predict_fast(model, state, settings.p0, HORIZON, FRAME, settings.q, sample_every=SAMPLE_EVERY,
                                impact_noise=settings.impact_noise,
                                impact_contact_time=settings.impact_contact_time)
            w1 = time.perf_counter()
            sit = build_situation(ROBOT, t, state, [t + s[0] for s in pred.samples], np.array([s[1] for s in pred.samples]),
                                  [(t + i[0], i[2], i[3]) for i in pred.impacts])
            w2 = time.perf_counter()
            decision = selector.step(t, RUNNING, sit, mallet, np.zeros(2))
            w3 = time.perf_counter()
            predict_ms.append((w1 - w0) * 1e3)
            build_ms.append((w2 - w1) * 1e3)
            step_ms.append((w3 - w2) * 1e3)
            tactics[NAMES[decision.tactic]] += 1
            if decision.command is not None:
                commands += 1
                selector.on_status(t, ACCEPTED, math.nan, t)
                mallet = selector.reach.clamp(decision.command.point)
            state = model.step(state, FRAME, with_jacobian=False).state
            t += FRAME
        progress(e + 1, args.episodes)
    step, build = np.array(step_ms), np.array(build_ms)
    p99 = float(np.percentile(step, 99))
    result = {"frames": int(len(step)), "commands": commands, "decisions": dict(tactics),
              "decision_ms": {"mean": float(step.mean()), "p99": p99, "max": float(step.max())},
              "situation_ms": {"mean": float(build.mean()), "p99": float(np.percentile(build, 99))},
              "tracker_prediction_ms": float(np.median(predict_ms)),
              "p99_in_tracker_predictions": p99 / float(np.median(predict_ms))}
    if args.json:
        print(json_text(result))
    else:
        print(f"frames decided        {result['frames']} ({args.episodes} episodes of {EPISODE:g} s at 120 Hz), "
              f"{commands} commands")
        print("decisions             " + ", ".join(f"{k} {v}" for k, v in tactics.most_common()))
        d, s = result["decision_ms"], result["situation_ms"]
        print(f"decision time         mean {d['mean']:.3f} ms, p99 {d['p99']:.3f} ms, max {d['max']:.3f} ms")
        print(f"situation from a prediction message: mean {s['mean']:.3f} ms, p99 {s['p99']:.3f} ms")
        print(f"reference             one 1 s tracker prediction {result['tracker_prediction_ms']:.3f} ms; "
              f"decision p99 = {result['p99_in_tracker_predictions']:.1f} of them")
    return 0
