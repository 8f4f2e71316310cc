"""``prediction_optimizer`` node: system identification through a running puck_tracker's services.

Loads recorded trajectories (parameter ``bags``, preprocessed like ``air-hockey sysid``), then for each
HEBO candidate sets the tracker's physical parameters (``set_physical_params``), and replays every
training trajectory frame by frame through ``reset`` and ``kalman_step`` (thesis sec. 4.1.1), comparing
the returned prediction with the measurement ``horizon`` later. Logs the loss before and after, writes
the winning parameters to ``out`` (parameter YAML) and leaves them set in the tracker, then exits.
Each frame is one service call, so this is far slower than the offline ``air-hockey sysid`` (same
objective, same optimiser); use it to tune a tracker in place.
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
from air_hockey_msgs.srv import KalmanStep, ResetFilter, SetPhysicalParams

from air_hockey_agent.bags.trajectories import load_trajectories, split_train_validation
from air_hockey_agent.core.estimation.ekf import PuckEKF
from air_hockey_agent.core.estimation.evaluation import valid_poses
from air_hockey_agent.core.identification.sysid import PHYSICAL, errors_through_steps, identify
from air_hockey_agent.nodes.messages import to_stamp
from air_hockey_agent.nodes.runtime import AirHockeyNode, NodeFailure, NodeStartupError, run
from air_hockey_agent.sysid_params import bounds
from air_hockey_agent.tool_node_params import OPTIMIZER_PARAMS
from air_hockey_agent.tools.sysid_report import write_params_yaml
from air_hockey_agent.tracker_params import load_tracker_params


class PredictionOptimizerNode(AirHockeyNode):
    NAME = "prediction_optimizer"
    DESCRIPTION = __doc__
    PARAM_FILES = ("prediction_optimizer.yaml", "sysid.yaml")
    PARAMS = OPTIMIZER_PARAMS

    def __init__(self) -> None:
        super().__init__()
        p = self.params
        paths = [Path(b.strip()) for b in p["bags"].split(",") if b.strip()]
        if not paths:
            raise NodeStartupError("no recordings given: set the parameter bags (-p bags:=DIR)")
        self.tracker_defaults = load_tracker_params()
        loaded = load_trajectories(paths, p["topic"], self.tracker_defaults, p, frame=p["frame"],
                                   table_frame=p["table_frame"])
        for message in loaded.errors:
            self.get_logger().error(message)
        if len(loaded.trajectories) < 2:
            raise NodeStartupError(f"need at least 2 usable trajectories, found {len(loaded.trajectories)}"
                                   + loaded.why_none(p))
        train_idx, _ = split_train_validation(len(loaded.trajectories), p["split"], p["seed"])
        self.train = [loaded.trajectories[i] for i in train_idx]
        # which poses count as ground truth (the evaluation's definition, on the tracker's table)
        reference = PuckEKF.from_params(self.tracker_defaults)
        self.train_valid = [(traj, valid_poses(list(traj.frames()), reference)) for traj in self.train]
        prefix = p["tracker"].rstrip("/")
        self.set_params = self.create_client(SetPhysicalParams, f"{prefix}/set_physical_params")
        self.reset = self.create_client(ResetFilter, f"{prefix}/reset")
        self.step = self.create_client(KalmanStep, f"{prefix}/kalman_step")
        self.get_logger().info(f"{len(self.train)} training trajectories from {loaded.bags} bag(s); "
                               f"tracker services under '{prefix or '/'}'")

    def call(self, client, request):
        if not client.wait_for_service(timeout_sec=self.params["service_timeout"]):
            raise RuntimeError(f"service {client.srv_name} not available")
        future = client.call_async(request)
        # spin_once rather than spin_until_future_complete: the latter adds a wake-up callback to the
        # future on every turn, and over thousands of calls rclpy's executor ends up spinning thousands
        # of times per call (measured: 150 ms per kalman_step instead of 2.5 ms)
        deadline = time.monotonic() + self.params["service_timeout"]
        while not future.done() and time.monotonic() < deadline:
            self.executor_.spin_once(timeout_sec=0.05)
        if not future.done():
            raise RuntimeError(f"service {client.srv_name} did not answer")
        return future.result()

    def kalman_step(self, t: float, z, horizon: float):
        request = KalmanStep.Request(stamp=to_stamp(t), has_measurement=z is not None, prediction_horizon=horizon)
        if z is not None:
            request.x, request.y, request.theta = (float(v) for v in z)
        response = self.call(self.step, request)
        flags = response.estimate.flags if response.success else 0
        return flags, (response.prediction.x, response.prediction.y)

    def objective(self, candidates: list[dict]) -> list[float]:
        values = []
        for candidate in candidates:
            answer = self.call(self.set_params, SetPhysicalParams.Request(**candidate))
            if not answer.success:
                raise RuntimeError(f"tracker refused parameters: {answer.message}")
            errors = []
            for traj, valid in self.train_valid:
                self.call(self.reset, ResetFilter.Request())
                errors.extend(errors_through_steps(traj, self.params["horizon"], self.kalman_step, valid))
            values.append(float(np.mean(errors)) if errors else float("inf"))
        return values

    def spin(self) -> None:
        p = self.params
        log = self.get_logger()
        initial = {n: self.tracker_defaults[n] for n in PHYSICAL}

        def progress(done: int, total: int, best: float) -> None:
            log.info(f"{done}/{total} evaluations, best loss {best * 1e3:.2f} mm")

        try:
            result = identify(self.objective, bounds(p), initial, p["iterations"], p["batch"], p["seed"],
                              p["random_samples"], p["polish_evaluations"], progress)
        except RuntimeError as exc:
            raise NodeFailure(f"optimisation stopped: {exc}") from None
        self.call(self.set_params, SetPhysicalParams.Request(**result.best))
        log.info(f"loss at {p['horizon']} s: {result.initial_objective * 1e3:.2f} mm -> "
                 f"{result.best_objective * 1e3:.2f} mm; identified "
                 + ", ".join(f"{k} {v:.6g}" for k, v in result.best.items()) + " (set in the tracker)")
        if p["out"]:
            write_params_yaml(Path(p["out"]), result.best,
                              f"identified by the prediction_optimizer node through the tracker's services "
                              f"(position loss, horizon {p['horizon']} s, {len(self.train)} trajectories)")
            log.info(f"wrote {p['out']}")


def main(argv: list[str] | None = None) -> int:
    return run(PredictionOptimizerNode, argv)


if __name__ == "__main__":
    sys.exit(main())
