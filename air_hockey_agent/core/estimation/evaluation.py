"""Offline prediction accuracy of the puck tracker on a recorded mocap stream (thesis sec. 4.3).

The stream goes through the same :class:`~air_hockey_agent.core.estimation.ekf.PuckEKF` as the live node, frame
by frame. From every frame whose measurement the filter fused (not a re-initialisation), the mean is
predicted ``h`` seconds ahead and compared with the measurement of the frame nearest to ``t + h``
(within half a frame period; the prediction runs to that frame's exact stamp). Frames the filter
rejected as outliers are not used as ground truth. The error is the planar distance [m].
"""
from __future__ import annotations

import bisect
from dataclasses import dataclass, field
from typing import Iterable, Sequence

import numpy as np

from air_hockey_agent.core.estimation.ekf import FLAG_MEASUREMENT_USED, FLAG_REINITIALISED, FilterStats, PuckEKF
from air_hockey_agent.core.puck.prediction import predict_fast

Frame = tuple[float, "Sequence[float] | None"]  # (stamp [s], table-frame (x, y, theta) or None if lost)


def horizon_key(horizon: float) -> str:
    """Key of a horizon in reports: ``0.5 -> "0.5"``, ``1 -> "1.0"``."""
    return str(float(horizon))


def count_lost_frames(stamps: Sequence[float], frame_period: float, max_gap: float) -> int:
    """Nominal frames missing from a stream: each interval of ``k`` periods hides ``k - 1`` frames.

    Intervals longer than ``max_gap`` [s] end a track (the filter restarts) and are not counted.
    """
    intervals = np.diff(np.asarray(stamps, float))
    intervals = intervals[(intervals > 0.0) & (intervals <= max_gap)]
    return int(np.maximum(np.rint(intervals / frame_period) - 1.0, 0.0).sum())


@dataclass
class EvaluationTotals:
    """Errors per horizon and stream counts, summed over any number of recordings."""

    horizons: tuple[float, ...]
    loglik: bool = False        # also collect the negative log-likelihood of each comparison (sec. 4.3.1)
    stride: int = 1             # predict from every stride-th fused frame only (faster, for optimisation)
    errors: dict = field(default_factory=dict)  # horizon key -> list of errors [m]
    nll: dict = field(default_factory=dict)     # horizon key -> list of -ln N(z_xy; x_xy, P_xy + R_xy)
    frames: int = 0
    lost_frames: int = 0
    outliers_rejected: int = 0
    recordings: int = 0

    def __post_init__(self) -> None:
        for h in self.horizons:
            self.errors.setdefault(horizon_key(h), [])
            self.nll.setdefault(horizon_key(h), [])

    def summary(self) -> dict:
        """Per horizon mean / median / p95 [m] and count, plus the stream counts (JSON-ready)."""
        table = {}
        for key, values in self.errors.items():
            v = np.asarray(values, float)
            stats = (float(v.mean()), float(np.median(v)), float(np.percentile(v, 95))) if v.size else (None,) * 3
            table[key] = {"mean_m": stats[0], "median_m": stats[1], "p95_m": stats[2], "n": int(v.size)}
        return {"horizons": table, "bags": self.recordings, "frames": self.frames,
                "lost_frames": self.lost_frames, "outliers_rejected": self.outliers_rejected}


@dataclass
class _FusedFrame:
    t: float
    z: np.ndarray               # the fused measurement (x, y, theta)
    x: np.ndarray               # filter state after the frame
    P: np.ndarray | None        # its covariance (kept only when asked for)
    reinitialised: bool


def _filter_pass(ekf: PuckEKF, frames: Iterable[Frame], keep_cov: bool) -> tuple[list[_FusedFrame], list[float], int]:
    """Run ``ekf`` (reset first) over a recording: the fused frames, every stamp, and frames without a pose."""
    ekf.reset()
    fused, stamps, invalid = [], [], 0
    for t, z in frames:
        stamps.append(t)
        invalid += z is None
        flags = ekf.process(t, z)
        if flags & FLAG_MEASUREMENT_USED:
            fused.append(_FusedFrame(t, np.asarray(z, float), ekf.x.copy(), ekf.P.copy() if keep_cov else None,
                                     bool(flags & FLAG_REINITIALISED)))
    return fused, stamps, invalid


def evaluate_stream(ekf: PuckEKF, frames: Iterable[Frame], totals: EvaluationTotals) -> None:
    """Filter one recording with ``ekf`` (reset first) and add its prediction errors to ``totals``."""
    ekf.stats = FilterStats()
    fused, stamps, invalid = _filter_pass(ekf, frames, keep_cov=totals.loglik)
    truth_t = [f.t for f in fused]
    starts = [f for f in fused if not f.reinitialised]
    tolerance = 0.5 * ekf.settings.dt
    for h in totals.horizons:
        errors, nll = totals.errors[horizon_key(h)], totals.nll[horizon_key(h)]
        for start in starts[::totals.stride]:
            j = _nearest(truth_t, start.t + h)
            if j is None or abs(truth_t[j] - (start.t + h)) > tolerance or truth_t[j] <= start.t:
                continue
            pred = predict_fast(ekf.model, start.x, start.P, truth_t[j] - start.t, ekf.settings.dt, ekf.settings.q)
            residual = fused[j].z[:2] - pred.state[:2]
            errors.append(float(np.hypot(*residual)))
            if totals.loglik:
                nll.append(_neg_log_likelihood(residual, pred.covariance[:2, :2] + ekf.settings.r[:2, :2]))
    totals.frames += ekf.stats.frames  # lost = missing from the stream + arrived without a usable pose
    totals.lost_frames += count_lost_frames(sorted(stamps), ekf.settings.dt, ekf.settings.max_prediction_gap) + invalid
    totals.outliers_rejected += ekf.stats.outliers_rejected
    totals.recordings += 1


def _neg_log_likelihood(residual: np.ndarray, cov: np.ndarray) -> float:
    """-ln of the 2-D normal density of ``residual`` with covariance ``cov`` (thesis sec. 4.3.1)."""
    (a, b), (_, d) = cov
    det = a * d - b * b
    quad = (d * residual[0] ** 2 - 2 * b * residual[0] * residual[1] + a * residual[1] ** 2) / det
    return float(0.5 * (quad + np.log(det)) + np.log(2 * np.pi))


def _nearest(times: list[float], t: float) -> int | None:
    if not times:
        return None
    i = bisect.bisect_left(times, t)
    candidates = [k for k in (i - 1, i) if 0 <= k < len(times)]
    return min(candidates, key=lambda k: abs(times[k] - t))


@dataclass
class PredictionSeries:
    """One recording, frame by frame: what was measured, estimated, and predicted ``horizon`` before."""

    horizon: float
    t: np.ndarray           # (n,) stamps [s] of fused frames
    measured: np.ndarray    # (n, 3) x, y, theta
    estimated: np.ndarray   # (n, 6) filter state after the frame
    predicted: np.ndarray   # (n, 6) state predicted from the fused frame nearest t - horizon (NaN if none)


def prediction_series(ekf: PuckEKF, frames: Iterable[Frame], horizon: float) -> PredictionSeries:
    """Filter a recording and, for every fused frame, the prediction made ``horizon`` [s] earlier (fig. 5.2-5.4)."""
    fused, _, _ = _filter_pass(ekf, frames, keep_cov=False)
    t = [f.t for f in fused]
    predicted = np.full((len(t), 6), np.nan)
    tolerance = 0.5 * ekf.settings.dt
    for k, stamp in enumerate(t):
        j = _nearest(t, stamp - horizon)
        if j is not None and j < k and abs(t[j] - (stamp - horizon)) <= tolerance:
            predicted[k] = predict_fast(ekf.model, fused[j].x, None, stamp - t[j], ekf.settings.dt,
                                        ekf.settings.q).state
    return PredictionSeries(horizon, np.array(t), np.array([f.z for f in fused]).reshape(-1, 3),
                            np.array([f.x for f in fused]).reshape(-1, 6), predicted)
