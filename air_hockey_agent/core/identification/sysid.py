"""System identification of the puck model's physical parameters (thesis sec. 3.3, 4.3, 5.2).

The objective for one parameter set: run the EKF with those parameters over every trajectory and
compare the position predicted ``h`` seconds ahead with the measurement there (:mod:`.evaluation`),
either as the mean distance (``position``) or as the mean negative log-likelihood of the measurement
under the predicted covariance (``loglik``), thesis sec. 4.3.1. Reported like thesis tables 5.2-5.4:
``loss`` (mean distance over all comparisons), ``min`` and ``median`` of the per-trajectory means.

:func:`identify` minimises the objective with HEBO over the table 4.1 box, batch by batch, starting
from the current parameters, then polishes the best point with a bounded Nelder-Mead simplex.
"""
from __future__ import annotations

import contextlib
import sys

from dataclasses import dataclass, field
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from air_hockey_agent.core.estimation.ekf import PuckEKF
from air_hockey_agent.core.estimation.evaluation import EvaluationTotals, evaluate_stream, horizon_key
from air_hockey_agent.core.identification.preprocess import GridTrajectory

PHYSICAL = ("friction_surface", "damping", "restitution", "friction_rim")  # identified by default (thesis)
IDENTIFIABLE = PHYSICAL + ("restitution_slope", "restitution_min", "restitution_knee",
                           "tangential_restitution")  # HEBO's choices
LOSSES = ("position", "loglik")


@dataclass
class LossReport:
    """Prediction error of one parameter set at one horizon (thesis table 5.2 columns)."""

    objective: float      # what the optimiser minimises
    loss: float           # [m] mean distance over all comparisons
    min: float            # [m] best trajectory's mean distance
    median: float         # [m] median of the per-trajectory mean distances
    comparisons: int

    def as_dict(self) -> dict:
        return {"objective": self.objective, "loss_m": self.loss, "min_m": self.min, "median_m": self.median,
                "n": self.comparisons}


@dataclass
class PartialLoss:
    """Sums over some trajectories, to be combined with the rest (evaluation split across processes)."""

    error_sum: float = 0.0
    nll_sum: float = 0.0
    count: int = 0
    trajectory_means: list = field(default_factory=list)

    def add(self, errors: Sequence[float], nll: Sequence[float] = ()) -> None:
        """One trajectory's comparisons: position errors [m] and, for the loglik loss, their -ln p."""
        if errors:
            self.trajectory_means.append(float(np.mean(errors)))
            self.error_sum += float(np.sum(errors))
            self.nll_sum += float(np.sum(nll))
            self.count += len(errors)


def partial_loss(params: Mapping[str, Any], trajectories: Sequence[GridTrajectory], horizon: float,
                 loss: str = "position", stride: int = 1) -> PartialLoss:
    """Filter and predict ``trajectories`` with tracker parameters ``params`` at ``horizon`` [s]."""
    ekf = PuckEKF.from_params(params)
    key = horizon_key(horizon)
    part = PartialLoss()
    for traj in trajectories:
        totals = EvaluationTotals((horizon,), loglik=loss == "loglik", stride=stride)
        evaluate_stream(ekf, traj.frames(), totals)
        part.add(totals.errors[key], totals.nll[key])
    return part


def nis_median(params: Mapping[str, Any], trajectories: Sequence[GridTrajectory]) -> float | None:
    """Median normalised innovation squared of the filter with tracker parameters ``params`` over every
    gated frame of ``trajectories`` (3 dof: 2.37 when the filter is calibrated), None without any."""
    return filter_pass_totals(params, trajectories).summary()["nis"]["median"]


def filter_pass_totals(params: Mapping[str, Any], trajectories: Sequence[GridTrajectory],
                       rest_speed: float | None = None) -> EvaluationTotals:
    """The stream counts and NIS (by regime with ``rest_speed``) of the filter with tracker parameters
    ``params`` over ``trajectories``, without predictions."""
    ekf = PuckEKF.from_params(params)
    totals = EvaluationTotals((), rest_speed=rest_speed)
    for traj in trajectories:
        evaluate_stream(ekf, traj.frames(), totals)
    return totals


def combine(parts: Sequence[PartialLoss], loss: str = "position") -> LossReport:
    """One report from the partial sums of disjoint sets of trajectories."""
    count = sum(p.count for p in parts)
    means = [m for p in parts for m in p.trajectory_means]
    if count == 0:
        return LossReport(float("inf"), float("inf"), float("inf"), float("inf"), 0)
    mean_error = sum(p.error_sum for p in parts) / count
    objective = mean_error if loss == "position" else sum(p.nll_sum for p in parts) / count
    return LossReport(objective, mean_error, float(np.min(means)), float(np.median(means)), count)


def loss_report(params: Mapping[str, Any], trajectories: Sequence[GridTrajectory], horizon: float,
                loss: str = "position", stride: int = 1) -> LossReport:
    """Filter and predict every trajectory with tracker parameters ``params`` at ``horizon`` [s]."""
    return combine([partial_loss(params, trajectories, horizon, loss, stride)], loss)


def position_loss_reports(params: Mapping[str, Any], trajectories: Sequence[GridTrajectory],
                          horizons: Sequence[float]) -> dict[str, LossReport]:
    """:func:`loss_report` (position loss) at several horizons [s] from one filter pass per trajectory;
    keyed by :func:`horizon_key`."""
    ekf = PuckEKF.from_params(params)
    parts = {horizon_key(h): PartialLoss() for h in horizons}
    for traj in trajectories:
        totals = EvaluationTotals(tuple(horizons))
        evaluate_stream(ekf, traj.frames(), totals)
        for key, part in parts.items():
            part.add(totals.errors[key])
    return {key: combine([part]) for key, part in parts.items()}


@dataclass
class Identification:
    best: dict            # parameter name -> value
    best_objective: float
    initial_objective: float
    evaluations: int
    history: list         # (parameters, objective) in evaluation order


Objective = Callable[[list[dict]], list[float]]  # a batch of parameter sets -> their objectives


def on_bounds(values: Mapping[str, float], bounds: Mapping[str, Sequence[float]], margin: float) -> list[str]:
    """One phrase per value within ``margin`` (a share of its range) of a search bound, e.g.
    'damping 0.2003 at its lower bound 0.2': the search ended on the edge of its box."""
    out = []
    for name, (low, high) in bounds.items():
        value, room = values[name], margin * (high - low)
        for side, bound in (("lower", low), ("upper", high)):
            if abs(value - bound) <= room:
                out.append(f"{name} {value:.4g} at its {side} bound {bound:g}")
    return out


def identify(objective: Objective, bounds: Mapping[str, Sequence[float]], initial: Mapping[str, float],
             iterations: int, batch: int, seed: int, random_samples: int, polish_evaluations: int,
             progress: Callable[[int, int, float], None] = lambda done, total, best: None) -> Identification:
    """HEBO over ``bounds`` (``iterations`` x ``batch`` suggestions), then a Nelder-Mead polish."""
    import pandas as pd
    import torch
    from hebo.design_space.design_space import DesignSpace
    from hebo.optimizers.hebo import HEBO

    np.random.seed(seed)
    torch.manual_seed(seed)
    names = list(bounds)
    space = DesignSpace().parse([{"name": n, "type": "num", "lb": float(bounds[n][0]), "ub": float(bounds[n][1])}
                                 for n in names])
    optimiser = HEBO(space, rand_sample=random_samples, scramble_seed=seed)
    start = {n: float(np.clip(initial[n], *bounds[n])) for n in names}
    history = [(start, objective([start])[0])]
    optimiser.observe(pd.DataFrame([start]), np.array([[history[0][1]]]))
    total = iterations * batch + polish_evaluations
    for _ in range(iterations):
        # HEBO's GP prints its Cholesky jitter retries ("jitter = 1e-07") on stdout, where --json promises
        # exactly one object: they go to stderr
        with contextlib.redirect_stdout(sys.stderr):
            suggestions = optimiser.suggest(n_suggestions=batch)
        candidates = [{n: float(row[n]) for n in names} for _, row in suggestions.iterrows()]
        values = objective(candidates)
        optimiser.observe(suggestions, np.array(values, float).reshape(-1, 1))
        history.extend(zip(candidates, values))
        progress(len(history) - 1, total, min(v for _, v in history))
    best, best_value = min(history, key=lambda item: item[1])
    if polish_evaluations > 0:
        best, best_value = polish(objective, bounds, best, best_value, polish_evaluations, history, progress, total)
    return Identification(best, best_value, history[0][1], len(history), history)


def polish(objective: Objective, bounds, best: dict, best_value: float, budget: int, history: list,
           progress=lambda done, total, best: None, total: int = 0) -> tuple[dict, float]:
    """Bounded Nelder-Mead from ``best`` in coordinates scaled to [0, 1] per parameter."""
    from scipy.optimize import minimize

    names = list(bounds)
    lo, hi = np.array([bounds[n][0] for n in names], float), np.array([bounds[n][1] for n in names], float)

    def f(u: np.ndarray) -> float:
        candidate = {n: float(v) for n, v in zip(names, lo + np.clip(u, 0.0, 1.0) * (hi - lo))}
        value = objective([candidate])[0]
        history.append((candidate, value))
        progress(len(history) - 1, total, min(v for _, v in history))
        return value

    u0 = (np.array([best[n] for n in names]) - lo) / (hi - lo)
    simplex = [u0] + [u0 + np.where(np.arange(len(names)) == i, 0.05 if u0[i] < 0.95 else -0.05, 0.0)
                      for i in range(len(names))]
    minimize(f, u0, method="Nelder-Mead", bounds=list(zip(np.zeros(len(names)), np.ones(len(names)))),
             options={"maxfev": budget, "initial_simplex": np.array(simplex), "xatol": 1e-4, "fatol": 1e-12})
    return min(((c, v) for c, v in history), key=lambda item: item[1])


StepFn = Callable[[float, "np.ndarray | None", float], "tuple[int, tuple[float, float]]"]


def errors_through_steps(traj: GridTrajectory, horizon: float, step: StepFn, valid: Sequence[bool]) -> list[float]:
    """Prediction errors of one trajectory computed through a filter behind ``step`` (e.g. the tracker's
    ``kalman_step`` service): ``step(t, z, horizon) -> (flags, predicted (x, y) at t + horizon)``.

    The same comparison as :func:`loss_report` (:mod:`.evaluation`): from every frame after which the
    filter has a state (it fused, rejected or bridged the frame) to the pose ``horizon`` later on the
    model grid, when ``valid`` (:func:`~air_hockey_agent.core.estimation.evaluation.valid_poses` of
    ``traj.frames()``) says that pose is ground truth.
    """
    from air_hockey_agent.core.estimation.ekf import FLAG_MEASUREMENT_USED, FLAG_PREDICTED
    steps = int(round(horizon / traj.dt))
    predictions: dict[int, tuple[float, float]] = {}
    errors = []
    for row, (t, z) in enumerate(traj.frames()):
        flags, predicted = step(t, z, horizon)
        if row in predictions and valid[row]:
            px, py = predictions.pop(row)
            errors.append(float(np.hypot(px - z[0], py - z[1])))
        if flags & (FLAG_MEASUREMENT_USED | FLAG_PREDICTED):
            predictions[row + steps] = predicted
    return errors
