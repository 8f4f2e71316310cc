"""The spin's decay in free flight from the recorded angles: split sysid's ``spin_damping`` (issue #13).

Thesis eq. 3.1 keeps the spin constant in flight; the model's ``spin_damping`` k lets it decay. A uniform
viscous air film would damp it at the velocity's own rate d (its shear torque mu pi r^4 omega / 2h over the disc's
inertia m r^2 / 2 is mu A / (h m) = d), and a MuJoCo table damps it as its hinge is set; where the spin
decays, the filter's angle innovations grow (issue #13: on the lab's recordings most rejections left by
a larger velocity noise came from the angle). This measures the decay rate from the recordings:

in the free-flight windows of the flight fit (:func:`.flight_fit.free_flight_windows`) the unwrapped
angle gets a quadratic, giving the spin w and its rate of change wdot at the window's centre; a decay
``wdot = -k w`` is a line through the origin, fitted by weighted least squares (each window weighted by
the inverse variance of its wdot under the angle noise), windows whose residual is an outlier (a hand,
a marker flip) dropped. A rate of zero within its error says a constant spin holds.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from air_hockey_agent.core.identification.flight_fit import FlightSettings, free_flight_windows
from air_hockey_agent.core.identification.local_fit import smooth_fits, spin_quadratic
from air_hockey_agent.core.identification.preprocess import GridTrajectory
from air_hockey_agent.core.table import TableGeometry


@dataclass(frozen=True)
class SpinDecay:
    rate: float         # k [1/s]: wdot = -k w
    std: float          # [1/s] its standard error (scaled by the fit's residual)
    windows: int        # windows in the fit
    dropped: int        # windows dropped as outliers
    rms_spin: float     # [rad/s] RMS spin of those windows (a rate is only seen where the puck spins)


def spin_windows(trajectories: Sequence[GridTrajectory], table: TableGeometry,
                 settings: FlightSettings) -> list[tuple[float, float, float]]:
    """(w [rad/s], wdot [rad/s^2], variance gain of wdot [1/s^4] per rad^2 of angle noise) of every
    free-flight window."""
    out = []
    for traj in trajectories:
        for rows, _ in free_flight_windows(traj, table, settings):
            fit = spin_quadratic(rows * traj.dt, traj.z[rows, 2])
            if fit is not None:
                out.append((fit.spin, fit.rate, fit.gain))
    return out


def fit_spin_decay(windows: Sequence[tuple[float, float, float]], angle_variance: float,
                   outlier_factor: float) -> SpinDecay | None:
    """k of ``wdot = -k w`` over ``windows`` (:func:`spin_windows`), the angle's noise ``angle_variance``
    [rad^2]; None without windows that spin."""
    if not windows:
        return None
    w, wdot, gain = (np.array(c, float) for c in zip(*windows))
    weight = 1.0 / (gain * angle_variance)
    rate = _rate(w, wdot, weight)  # all windows, then without the outlying residuals
    if rate is None:
        return None
    keep = smooth_fits(np.abs(wdot + rate * w) * np.sqrt(weight), outlier_factor)
    rate, n = _rate(w[keep], wdot[keep], weight[keep]), int(keep.sum())
    if rate is None or n < 2:
        return None
    information = float(np.sum(weight[keep] * w[keep] ** 2))
    chi2 = float(np.sum(weight[keep] * (wdot[keep] + rate * w[keep]) ** 2)) / (n - 1)
    return SpinDecay(rate, math.sqrt(max(chi2, 1.0) / information), n, len(w) - n,
                     math.sqrt(float(np.mean(w[keep] ** 2))))


def _rate(w: np.ndarray, wdot: np.ndarray, weight: np.ndarray) -> float | None:
    """Weighted least squares of ``wdot = -k w`` (None when no window spins)."""
    information = float(np.sum(weight * w ** 2))
    return None if information <= 0.0 else -float(np.sum(weight * w * wdot)) / information
