"""Measurement and process noise estimation (thesis sec. 3.2.2 eq. 3.12-3.13, sec. 4.4).

With the filter's own estimates standing in for the true states:

* R (eq. 3.12): covariance of ``z_k - h(x_k|k)`` over every fused frame (angle residual wrapped);
* Q (eq. 3.13): covariance of ``f(x_k|k) - x_k+1|k+1`` over consecutive fused model steps;

both without correlation terms (diagonal, thesis sec. 4.4). The estimates change the filter, which
changes the estimates, so the procedure is iterated (5 times in the thesis). Either matrix can be kept
fixed while the other is estimated.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np

from air_hockey_agent.core.estimation.ekf import FLAG_MEASUREMENT_USED, FLAG_REINITIALISED, PuckEKF
from air_hockey_agent.core.identification.preprocess import GridTrajectory
from air_hockey_agent.core.puck.model import wrap_angle


@dataclass
class NoiseEstimate:
    r: np.ndarray        # (3,) diagonal of R: x, y [m^2], theta [rad^2]
    q: np.ndarray        # (6,) diagonal of Q per model step
    r_samples: int
    q_samples: int


def estimate_once(params: Mapping[str, Any], trajectories: Sequence[GridTrajectory]) -> NoiseEstimate:
    """One pass of eq. 3.12 and 3.13 with the filter configured by ``params``."""
    ekf = PuckEKF.from_params(params)
    meas_res, proc_res = [], []
    for traj in trajectories:
        ekf.reset()
        previous = None  # (row, posterior state) of the last fused frame
        for row, (t, z) in enumerate(traj.frames()):
            flags = ekf.process(t, z)
            fused = bool(flags & FLAG_MEASUREMENT_USED) and not flags & FLAG_REINITIALISED
            if not fused:
                if flags & FLAG_REINITIALISED or not ekf.initialised:
                    previous = None  # the track restarted: no model step links it to the last estimate
                continue
            meas_res.append(ekf.residual(z))  # eq. 3.12 with the posterior standing in for the truth
            if previous is not None and previous[0] == row - 1:
                step = ekf.model.step(previous[1], traj.dt, with_jacobian=False).state - ekf.x
                step[4] = wrap_angle(step[4])
                proc_res.append(step)
            previous = (row, ekf.x.copy())
    r = np.var(np.array(meas_res), axis=0, ddof=1) if len(meas_res) > 1 else np.full(3, np.nan)
    q = np.var(np.array(proc_res), axis=0, ddof=1) if len(proc_res) > 1 else np.full(6, np.nan)
    return NoiseEstimate(r, q, len(meas_res), len(proc_res))


def iterate(params: Mapping[str, Any], trajectories: Sequence[GridTrajectory], iterations: int,
            fix: Sequence[str] = ()) -> list[NoiseEstimate]:
    """Repeat the estimate ``iterations`` times, feeding each result back (``fix``: "R" and/or "Q" kept)."""
    current = dict(params)
    history = []
    for _ in range(iterations):
        est = estimate_once(current, trajectories)
        history.append(est)
        if "R" not in fix and np.all(np.isfinite(est.r)) and np.all(est.r > 0):
            current["measurement_noise"] = est.r.tolist()
        if "Q" not in fix and np.all(np.isfinite(est.q)) and np.all(est.q > 0):
            current["process_noise"] = est.q.tolist()
    return history
