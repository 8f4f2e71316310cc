"""The prediction a tracker hands the agents at every frame (ROS-free; thesis sec. 4.2).

``puck_tracker`` publishes it as ``puck/prediction``; the in-process game (:mod:`air_hockey_agent.sim.game_loop`)
hands it to the tactics directly. Table frame: ``iiwa_front`` defends x = -L/2, ``iiwa_back`` x = +L/2.
"""
from __future__ import annotations

from dataclasses import dataclass

from air_hockey_agent.core.estimation.ekf import PuckEKF
from air_hockey_agent.core.puck.prediction import Prediction


@dataclass
class AgentPrediction:
    """The estimate at ``stamp`` [s] and its prediction, sampled every ``sample_period`` [s], with the
    first crossing of each robot's defend line and of the goal lines."""

    stamp: float
    prediction: Prediction
    sample_period: float
    defend_lines: dict          # robot -> line x [m]
    goal_lines: tuple           # (-L/2, L/2) [m]


def defend_lines(ekf: PuckEKF, offset: float) -> dict[str, float]:
    """Each robot's defend line x [m], ``offset`` [m] in front of its own short rim."""
    half = ekf.model.table.length / 2
    return {"iiwa_front": -half + offset, "iiwa_back": half - offset}


def predict_for_agents(ekf: PuckEKF, horizon: float, sample_period: float, defend_line_offset: float) -> AgentPrediction:
    """Predict ``horizon`` [s] from the filter's state, sampled every whole number of model steps nearest
    ``sample_period`` [s] (at least one)."""
    every = max(1, round(sample_period / ekf.settings.dt))
    lines = defend_lines(ekf, defend_line_offset)
    half = ekf.model.table.length / 2
    goal_lines = (-half, half)
    pred = ekf.predict(horizon, list(lines.values()) + list(goal_lines), every)
    return AgentPrediction(ekf.stamp, pred, every * ekf.settings.dt, lines, goal_lines)
