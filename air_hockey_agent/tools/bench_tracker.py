"""``air-hockey bench tracker``: EKF update time and prediction time (stepwise vs fast), in microseconds.

Random puck states on the table (speeds up to 3 m/s, spins up to 20 rad/s), parameters and noise from
``config/tracker.yaml`` (and ``--params-file``); the same states go through both predictors in one run.
Thesis table 5.1: one 180-step prediction took 75.7 us mean (C++, without covariance). The fast predictor is
the same steps compiled (:mod:`air_hockey_agent.core.puck.prediction_kernel`); with a table acceleration
(``table_acceleration`` not zero) every step searches for its rim contact, so its ratio is lower.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Sequence

import numpy as np

from air_hockey_agent.core.estimation.ekf import PuckEKF
from air_hockey_agent.core.puck.prediction import predict_fast, predict_stepwise, prepare_prediction
from air_hockey_agent.params import ParameterFileError, ParameterValueError, check_files_read
from air_hockey_agent.tools.json_output import json_text
from air_hockey_agent.tracker_params import FILTER_KINDS, load_tracker_params
from air_hockey_agent.tools.argtypes import count, seed

HORIZONS = (0.5, 1.0, 1.5)


def _stats(samples_s: list[float]) -> dict[str, float]:
    us = np.array(samples_s) * 1e6
    return {"mean": round(float(us.mean()), 2), "p99": round(float(np.percentile(us, 99)), 2)}


def _timed(fn, *args) -> float:
    start = time.perf_counter()
    fn(*args)
    return time.perf_counter() - start


def run_benchmark(n: int, seed: int, params_files: Sequence[Path] = ()) -> dict:
    params = load_tracker_params(params_files)
    check_files_read(params_files, ("puck_tracker",))
    ekf = PuckEKF.from_params(params)
    model, settings, table = ekf.model, ekf.settings, ekf.model.table
    prepare_prediction()  # the compiled prediction is loaded before the timing, as the node does
    rng = np.random.default_rng(seed)
    states = [np.array([rng.uniform(-table.x_limit, table.x_limit), rng.uniform(-table.y_limit, table.y_limit),
                        *rng.uniform(-3.0, 3.0, 2), rng.uniform(-np.pi, np.pi), rng.uniform(-20, 20)])
              for _ in range(n)]
    p0 = settings.p0 * 1e-2
    update = []
    for s in states:
        ekf.reset(s, 0.0)
        z = s[[0, 1, 4]] + rng.normal(0.0, 1e-4, 3)
        update.append(_timed(ekf.update, z))
    result = {"update_us": _stats(update), "predict_us": {"stepwise": {}, "fast": {}, "fast_mean_only": {}},
              "ratio_stepwise_over_fast": {},
              "frame_us": _frame_costs(params, states, rng), "table_learning": _adaptation_cost(params, states, rng)}
    paired = max(50, n // 10)  # the stepwise prediction is slow: timed on the first states only
    for h in HORIZONS:
        step, fast, mean_only = [], [], []
        for i, s in enumerate(states):  # interleaved, so a change in the machine's load hits both alike
            if i < paired:
                step.append(_timed(predict_stepwise, model, s, p0, h, settings.dt, settings.q))
            fast.append(_timed(predict_fast, model, s, p0, h, settings.dt, settings.q))
            mean_only.append(_timed(predict_fast, model, s, None, h, settings.dt, settings.q))
        result["predict_us"]["stepwise"][str(h)] = _stats(step)
        result["predict_us"]["fast"][str(h)] = _stats(fast)
        result["predict_us"]["fast_mean_only"][str(h)] = _stats(mean_only)
        # the ratio on the same states (their impacts set both costs)
        result["ratio_stepwise_over_fast"][str(h)] = round(float(np.sum(step) / np.sum(fast[:paired])), 1)
    return result


TRACK_FRAMES = 60  # frames of each track of the stream timing (0.5 s at 120 Hz: rim impacts included)


def _adaptation_cost(params: dict, states: list, rng: np.random.Generator) -> dict:
    """A mocap stream through the whole frame handling (``PuckEKF.process``) with the table and the noise
    learned online (rim law, table acceleration, marker noise, flight process noise) and without, on the
    same tracks (flown by the model from the first states, noisy poses), alternated so the machine's load
    hits both alike: the options' own cost, issue #13."""
    ekfs = {on: PuckEKF.from_params({**params, "rim_adaptation.enabled": on, "acceleration_adaptation.enabled": on,
                                     "noise_adaptation.enabled": on, "process_noise_adaptation.enabled": on})
            for on in (False, True)}
    model, dt = ekfs[False].model, ekfs[False].settings.dt
    times = {False: 0.0, True: 0.0}
    frames = 0
    for i, s in enumerate(states[:max(10, len(states) // 20)]):
        track, state = [], s
        for k in range(TRACK_FRAMES):
            state = model.step(state, dt, with_jacobian=False).state
            track.append(((i * TRACK_FRAMES * 2 + k) * dt, state[[0, 1, 4]] + rng.normal(0.0, 1e-4, 3)))
        frames += len(track)
        for on, ekf in ekfs.items():
            ekf.reset()
            times[on] += _timed(_stream, ekf, track)
    return {"off_us": round(times[False] / frames * 1e6, 2), "on_us": round(times[True] / frames * 1e6, 2),
            "ratio": round(times[True] / times[False], 3)}


def _stream(ekf: PuckEKF, track: list) -> None:
    for t, z in track:
        ekf.process(t, z)


def _frame_costs(params: dict, states: list, rng: np.random.Generator) -> dict:
    """One frame (predict one model step, then fuse) per filter kind on the same states, with its
    ratio to the EKF's in this run (the filter option's own cost, issue #13)."""
    zs = [s[[0, 1, 4]] + rng.normal(0.0, 1e-4, 3) for s in states]
    out = {}
    for kind in FILTER_KINDS:
        ekf = PuckEKF.from_params({**params, "filter": kind})
        p0 = ekf.settings.p0 * 1e-2
        times = []
        for s, z in zip(states, zs):
            ekf.reset(s, 0.0)
            ekf.P = p0.copy()
            times.append(_timed(_frame, ekf, z))
        out[kind] = _stats(times)
    for kind in FILTER_KINDS:
        out[kind]["ratio_to_ekf"] = round(out[kind]["mean"] / out["ekf"]["mean"], 2)
    return out


def _frame(ekf: PuckEKF, z: np.ndarray) -> None:
    ekf.predict_to(ekf.settings.dt)
    ekf.update(z)


def add_parser(bench_subparsers: argparse._SubParsersAction) -> None:
    parser = bench_subparsers.add_parser("tracker", help="EKF update and prediction timing", description=__doc__,
                                         formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--samples", type=count(1), default=2000, help="random states (default 2000)")
    parser.add_argument("--seed", type=seed, default=0)
    parser.add_argument("--params-file", type=Path, action="append", default=[],
                        help="tracker parameter YAML (e.g. sysid's output); may be repeated")
    parser.add_argument("--json", action="store_true", help="print one JSON object")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    try:
        result = run_benchmark(args.samples, args.seed, args.params_file)
    except (ParameterFileError, ParameterValueError) as exc:
        print(f"air-hockey bench tracker: error: {exc}", file=sys.stderr)
        return 2
    if args.json:
        print(json_text(result))
        return 0
    print(f"EKF update: mean {result['update_us']['mean']} us, p99 {result['update_us']['p99']} us")
    print(f"{'horizon':>8} {'stepwise mean/p99 [us]':>24} {'fast mean/p99 [us]':>20} {'ratio':>6} "
          f"{'mean only, fast [us]':>21}")
    for h in HORIZONS:
        sw, fa = result["predict_us"]["stepwise"][str(h)], result["predict_us"]["fast"][str(h)]
        mo = result["predict_us"]["fast_mean_only"][str(h)]
        print(f"{h:>7.1f}s {sw['mean']:>12.1f} / {sw['p99']:<9.1f} {fa['mean']:>9.1f} / {fa['p99']:<8.1f} "
              f"{result['ratio_stepwise_over_fast'][str(h)]:>6.1f} {mo['mean']:>10.1f} / {mo['p99']:<8.1f}")
    print("(thesis table 5.1: one 180-step prediction, 1.5 s, without covariance, 75.7 us mean in C++)")
    frames = result["frame_us"]
    print("one frame (predict + update) per filter: " + ", ".join(
        f"{kind} {frames[kind]['mean']} us ({frames[kind]['ratio_to_ekf']}x)" for kind in FILTER_KINDS))
    adapt = result["table_learning"]
    print(f"one mocap frame through the EKF's frame handling: {adapt['off_us']} us with the configured physics, "
          f"{adapt['on_us']} us learning the table and the marker noise online (rim, acceleration and noise "
          f"adaptation, {adapt['ratio']}x)")
    return 0
