"""What the tactics see (ROS-free): the tracker's estimate and prediction in the robot's own frame.

Own frame (README "Frames and units"): x toward the opponent, origin at the table centre; the own goal
line is x = -L/2. ``iiwa_front``'s own frame is the table frame; ``iiwa_back``'s is rotated by pi.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from air_hockey_agent.core.frames import ROBOT_YAW
from air_hockey_agent.core.puck.model import PuckParams


def to_own_frame(states: np.ndarray, robot: str) -> np.ndarray:
    """Puck states (..., 6) = (x, y, vx, vy, theta, omega) from the table frame to ``robot``'s frame."""
    out = np.array(states, float, copy=True)
    if ROBOT_YAW[robot] != 0.0:  # rotation by pi: x, y, vx, vy change sign; theta turns by pi
        out[..., :4] *= -1.0
        out[..., 4] = (out[..., 4] + 2 * math.pi) % (2 * math.pi) - math.pi
    return out


def own_frame_physics(params: PuckParams, robot: str) -> PuckParams:
    """Puck physics (table frame) in ``robot``'s frame: only the table acceleration [m/s^2] has a
    direction (rotated by pi for ``iiwa_back``)."""
    if ROBOT_YAW[robot] == 0.0:
        return params
    gx, gy = params.table_acceleration
    return params.with_values(table_acceleration=(-gx, -gy))


@dataclass(frozen=True)
class DefendCrossing:
    """A predicted first crossing of a line x = const toward the own goal: absolute time [s], y [m],
    velocity [m/s] (own frame), and how many rim impacts the puck makes before it."""

    time: float
    y: float
    vx: float
    vy: float
    impacts_before: int


@dataclass
class Situation:
    """Estimate at ``t`` and predicted states at ``times`` (absolute [s], increasing), own frame."""

    t: float
    puck: np.ndarray                 # (6,) estimate
    times: np.ndarray                # (n,) prediction sample times, after t
    states: np.ndarray               # (n, 6)
    impact_times: np.ndarray = field(default_factory=lambda: np.empty(0))  # absolute [s], predicted rim impacts
    # (2, 2) [m^2/s^2] the estimate's velocity covariance (own frame); zero when the tracker gave none
    velocity_covariance: np.ndarray = field(default_factory=lambda: np.zeros((2, 2)))

    @property
    def speed(self) -> float:
        return math.hypot(self.puck[2], self.puck[3])

    @property
    def speed_std(self) -> float:
        """Standard deviation [m/s] of the estimate's velocity along its direction (for a puck estimated
        at rest, along the most uncertain direction): how much of :attr:`speed` may be noise."""
        cov = self.velocity_covariance
        speed = self.speed
        if speed > 0.0:
            u = self.puck[2:4] / speed
            return math.sqrt(max(float(u @ cov @ u), 0.0))
        return math.sqrt(max(float(np.linalg.eigvalsh(cov)[-1]), 0.0))

    def resting(self, rest_speed: float, significance: float = 0.0) -> bool:
        """The puck is taken as at rest where it lies: its estimated speed is at most ``rest_speed`` [m/s]
        or at most ``significance`` standard deviations of itself (:attr:`speed_std`), i.e. not told apart
        from rest. Right after the tracker restarts, or while it follows a hand (its hand regime), the
        velocity's std is about 0.02 m/s instead of about 0.001."""
        speed = self.speed
        return speed <= rest_speed or speed <= significance * self.speed_std

    def approaching(self, threshold: float) -> bool:
        return self.puck[2] < -threshold

    def leaving(self, threshold: float) -> bool:
        """The puck moves away from the own goal: own-frame vx above ``threshold`` [m/s]."""
        return self.puck[2] > threshold

    def samples_until(self, end: float) -> tuple[np.ndarray, np.ndarray]:
        """The estimate and the predicted samples up to ``end`` [s]: their times (m,) [s, absolute] and
        states (m, 6)."""
        keep = self.times <= end
        return np.concatenate([[self.t], self.times[keep]]), np.vstack([self.puck[None, :], self.states[keep]])

    def samples_from(self, start: float, end: float) -> tuple[np.ndarray, np.ndarray]:
        """The predicted state at ``start`` [s] (:meth:`at`) and the samples after it up to ``end`` [s]: their
        times (m,) [s, absolute] and states (m, 6); :meth:`samples_until` when ``start`` is not after the
        estimate. What to compare with a mallet whose way begins now: a sample older than now met a mallet
        extrapolated back along its present velocity (after a 0.9 s mocap dropout, 0.9 s of a mallet that
        was not moving that way)."""
        if start <= self.t:
            return self.samples_until(end)
        keep = (self.times > start) & (self.times <= end)
        return np.concatenate([[start], self.times[keep]]), np.vstack([self.at(start)[None, :], self.states[keep]])

    def at(self, t: float) -> np.ndarray:
        """Predicted state at ``t`` [s]: linear between samples (the estimate is the first), the last
        sample beyond the horizon."""
        if t <= self.t or not len(self.times):
            return self.puck.copy()
        if t >= self.times[-1]:
            return self.states[-1].copy()
        i = int(np.searchsorted(self.times, t))
        t0, s0 = (self.t, self.puck) if i == 0 else (self.times[i - 1], self.states[i - 1])
        w = (t - t0) / (self.times[i] - t0)
        return (1.0 - w) * s0 + w * self.states[i]

    def expected(self, t: float, rest_speed: float, significance: float = 0.0) -> np.ndarray:
        """The state to plan a hit at ``t`` [s] for: a puck :meth:`resting` (``rest_speed`` [m/s],
        ``significance``) is at rest where it is (extrapolating its estimate's velocity noise would move it
        by centimetres), else :meth:`at`, and beyond the horizon the last sample carried on at its velocity
        (a slow puck still drifts there: holding it at the last sample would move the hit point with every
        new prediction)."""
        if self.resting(rest_speed, significance):
            state = self.puck.copy()
            state[2:4] = 0.0
            return state
        if len(self.times) and t > self.times[-1]:
            state = self.states[-1].copy()
            state[:2] += state[2:4] * (t - self.times[-1])
            return state
        return self.at(t)

    def crossing(self, line_x: float) -> DefendCrossing | None:
        """First predicted crossing of x = ``line_x`` toward the own goal (x decreasing), interpolated
        between samples; None when it does not happen within the horizon."""
        xs = np.concatenate([[self.puck[0]], self.states[:, 0]])
        hits = np.nonzero((xs[:-1] > line_x) & (xs[1:] <= line_x))[0]
        if not len(hits):
            return None
        i = int(hits[0])
        t0, s0 = (self.t, self.puck) if i == 0 else (self.times[i - 1], self.states[i - 1])
        t1, s1 = self.times[i], self.states[i]
        w = (s0[0] - line_x) / (s0[0] - s1[0])
        t = t0 + w * (t1 - t0)
        return DefendCrossing(float(t), float(s0[1] + w * (s1[1] - s0[1])), float(s1[2]), float(s1[3]),
                              int(np.count_nonzero(self.impact_times < t)))


def build_situation(robot: str, t: float, estimate: Sequence[float], sample_times: Sequence[float],
                    samples: np.ndarray, impacts: Sequence[tuple[float, float, float]] = (),
                    covariance: Sequence[float] | np.ndarray | None = None) -> Situation:
    """A :class:`Situation` from table-frame tracker output (thesis sec. 4.2).

    ``sample_times``: absolute [s]; ``samples`` (n, 6): predicted states; ``impacts``: predicted rim
    impacts as (absolute time [s], x, y). The impact points are merged into the samples (with the
    velocity of the next sample), so that interpolating between samples follows the bounce.
    ``covariance``: the estimate's 6 x 6 covariance (or its 36 values row by row), SI units, table
    frame; its velocity block is kept (a rotation by pi leaves it as it is).

    Raises ValueError naming the part that is not finite, not increasing or of the wrong size: a
    malformed prediction is refused here rather than deep inside a tactic.
    """
    times, samples, estimate = np.asarray(sample_times, float), np.asarray(samples, float), np.asarray(estimate, float)
    impacts = np.asarray(impacts, float).reshape(-1, 3)
    _check_prediction(t, estimate, times, samples, impacts)
    velocity_covariance = _velocity_block(covariance)
    states = to_own_frame(samples.reshape(-1, 6), robot)
    impact_times = impacts[:, 0].copy()
    if len(impacts) and len(times):
        extra_t, extra = [], []
        for ti, x, y in impacts:
            j = int(np.searchsorted(times, ti))
            if j < len(times) and ti > t:
                xy = to_own_frame(np.array([x, y, 0.0, 0.0, 0.0, 0.0]), robot)[:2]
                extra_t.append(ti)
                extra.append(np.concatenate([xy, states[j, 2:]]))
        if extra_t:
            times = np.concatenate([times, extra_t])
            order = np.argsort(times, kind="stable")
            times, states = times[order], np.vstack([states, extra])[order]
    return Situation(t, to_own_frame(estimate, robot), times, states, impact_times, velocity_covariance)


def _velocity_block(covariance: Sequence[float] | np.ndarray | None) -> np.ndarray:
    """The (2, 2) velocity block of a 6 x 6 covariance (or its 36 values), symmetrised; zeros for None.
    ValueError unless it is 36 finite values."""
    if covariance is None:
        return np.zeros((2, 2))
    cov = np.asarray(covariance, float)
    if cov.size != 36 or not np.all(np.isfinite(cov)):
        raise ValueError(f"the covariance must be 36 finite values (6 x 6), got {cov.size}")
    block = cov.reshape(6, 6)[2:4, 2:4]
    return 0.5 * (block + block.T)


def _check_prediction(t: float, estimate: np.ndarray, times: np.ndarray, samples: np.ndarray,
                      impacts: np.ndarray) -> None:
    """ValueError unless the stamp, estimate (6), samples (n x 6), their times (n, increasing, after ``t``)
    and the impacts (time, x, y) are finite and fit together."""
    if not math.isfinite(t):
        raise ValueError(f"stamp {t} is not finite")
    if estimate.shape != (6,) or not np.all(np.isfinite(estimate)):
        raise ValueError(f"the estimate must be 6 finite values, got {estimate.tolist()}")
    if samples.size % 6 or samples.size // 6 != times.size:
        raise ValueError(f"{times.size} sample times for {samples.size / 6:g} samples of 6 values")
    if not (np.all(np.isfinite(samples)) and np.all(np.isfinite(times)) and np.all(np.isfinite(impacts))):
        raise ValueError("a sample, sample time or impact is not finite")
    if times.size and (times[0] <= t or np.any(np.diff(times) <= 0.0)):
        raise ValueError("the sample times do not increase from the stamp")


def situation_from_prediction(robot: str, estimate: Sequence[float], prediction,
                              covariance: np.ndarray | None = None) -> Situation:
    """:func:`build_situation` from a tracker's
    :class:`~air_hockey_agent.core.estimation.agent_prediction.AgentPrediction` (what ``puck/prediction``
    carries) and the ``estimate`` it starts from, with its ``covariance``; table frame in, ``robot``'s
    own frame out."""
    t0, pred = prediction.stamp, prediction.prediction
    times = [t0 + t for t, _, _ in pred.samples]
    samples = np.array([s for _, s, _ in pred.samples], float).reshape(-1, 6)
    impacts = [(t0 + t, x, y) for t, _, x, y, _ in pred.impacts]
    return build_situation(robot, t0, estimate, times, samples, impacts, covariance)
