"""Offline prediction accuracy of the puck tracker on a recorded mocap stream (thesis sec. 4.3).

The stream goes through the same :class:`~air_hockey_agent.core.estimation.ekf.PuckEKF` as the live node, frame
by frame. From every frame at which the filter has a state (fused, rejected or lost frames alike, and
re-initialisations: the live node publishes a prediction from each), the mean is predicted ``h`` seconds
ahead and compared with the *valid measurement* nearest to ``t + h`` (within half a frame period; the
prediction runs to that frame's exact stamp). A valid measurement is any finite pose on the table, whether
the filter fused it or not, so a filter that rejects more frames does not look better. The error is the
planar distance [m] between the measured position and the one the prediction says the mocap measures: the
disc's centre, or with a marker offset (the mocap pivot off the centre, :mod:`.marker_offset`) the pivot
at the predicted angle, as the filter knew the offset at the prediction's start. A pose that jumps from
both neighbouring poses faster than ``glitch_speed`` (config/tracker.yaml) is a marker glitch and no
ground truth. Alongside: the fraction of poses the filter
rejected, its re-initialisations per second of recording (beyond the first of each recording) and the
normalised innovation squared (NIS) of every frame that reached the gate (3 degrees of freedom: median
2.37 and mean 3 when consistent), also by regime (issue #13: is the noise right at rest, in flight and at
the rims?): *impact* when the model puts a rim impact in the step to the frame or the one before it,
*rest* when the previous estimate is slower than ``rest_speed``, *flight* otherwise. eval-prediction,
sysid, prediction_optimizer and plot all use this definition. The filter may also be the reference
filter (:mod:`.reference_filter`, ``eval-prediction --reference``), which offers the same interface
(``process``, ``reset``, ``predict_from`` and the state they leave), so both are judged alike.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Iterable, Sequence

import numpy as np

from air_hockey_agent.core.estimation.ekf import FilterStats, PuckEKF
from air_hockey_agent.core.estimation.marker_offset import centre_of, pivot_shift
from air_hockey_agent.core.puck.model import PuckModel

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


PERIOD_MATCH = 0.01  # a stream within 1 % of the model's frame period runs on the model's clock


def stream_frame_period(stamps: Sequence[float], max_gap: float, default: float) -> float:
    """A stream's own frame period [s], from the intervals between consecutive distinct stamps within a
    track (up to ``max_gap`` [s]): each a whole number of frames of their median, the period fitted to
    all. ``default`` (the model's period) for a stream without intervals or within ``PERIOD_MATCH`` of it.
    The mocap's rate need not be the model's (``frequency``): a 100 Hz or 240 Hz recording counts its own
    lost frames."""
    intervals = np.diff(np.sort(np.asarray(stamps, float)))
    intervals = intervals[(intervals > 0.0) & (intervals <= max_gap)]
    if not intervals.size:
        return default
    rough = float(np.median(intervals))
    # refined over every interval as a whole number of frames (least squares): the median of jittered
    # stamps is off by parts per thousand, which a 0.9 s dropout would turn into a miscounted frame
    frames = np.maximum(np.rint(intervals / rough), 1.0)
    period = float(intervals.sum() / frames.sum())
    return default if abs(period - default) < PERIOD_MATCH * default else period


@dataclass
class EvaluationTotals:
    """Errors per horizon and stream counts, summed over any number of recordings."""

    horizons: tuple[float, ...]
    loglik: bool = False        # also collect the negative log-likelihood of each comparison (sec. 4.3.1)
    stride: int = 1             # predict from every stride-th frame with a state only (faster, for optimisation)
    errors: dict = field(default_factory=dict)  # horizon key -> list of errors [m]
    nll: dict = field(default_factory=dict)     # horizon key -> list of -ln N(z_xy; x_xy, P_xy + R_xy)
    nis: list = field(default_factory=list)     # NIS of every gated frame
    # [m/s] below it a frame's NIS counts as at rest (tracker's regime_rest_speed); None: no NIS by regime
    # (classifying costs sysid's objective 8 % and it does not read it)
    rest_speed: float | None = None
    nis_regimes: list = field(default_factory=list)  # the regime of each entry of nis (REGIMES), with rest_speed
    paths: dict = field(default_factory=dict)   # horizon key -> the PATHS entry of each error, with rest_speed
    frames: int = 0
    poses: int = 0              # frames that carried a pose
    lost_frames: int = 0
    outliers_rejected: int = 0  # poses on the table the filter's gate rejected
    off_table: int = 0          # poses beyond the table's margin, dropped before the gate (not counted as rejected)
    reinitialisations: int = 0  # beyond the first of each recording
    hand_regimes: int = 0       # times the filter's hand regime started (a hand or mallet moving the puck)
    hand_frames: int = 0        # frames it handled in that regime
    seconds: float = 0.0        # [s] recorded time, first to last stamp of each recording
    recordings: int = 0

    def __post_init__(self) -> None:
        for h in self.horizons:
            self.errors.setdefault(horizon_key(h), [])
            self.nll.setdefault(horizon_key(h), [])
            self.paths.setdefault(horizon_key(h), [])

    def empty_like(self) -> "EvaluationTotals":
        """New totals with the same horizons and settings, nothing collected."""
        return EvaluationTotals(self.horizons, loglik=self.loglik, stride=self.stride, rest_speed=self.rest_speed)

    def absorb(self, other: "EvaluationTotals") -> None:
        """Add what ``other`` (same horizons and settings) collected, as if its recordings had been added here."""
        for key in self.errors:
            self.errors[key] += other.errors[key]
            self.nll[key] += other.nll[key]
            self.paths[key] += other.paths[key]
        self.nis += other.nis
        self.nis_regimes += other.nis_regimes
        for name in ("frames", "poses", "lost_frames", "outliers_rejected", "off_table", "reinitialisations",
                     "hand_regimes", "hand_frames", "seconds", "recordings"):
            setattr(self, name, getattr(self, name) + getattr(other, name))

    def summary(self) -> dict:
        """Per horizon mean / median / p95 [m] and count, plus the stream counts and the filter's
        consistency (JSON-ready)."""
        table = {}
        for key, values in self.errors.items():
            v = np.asarray(values, float)
            stats = (float(v.mean()), float(np.median(v)), float(np.percentile(v, 95))) if v.size else (None,) * 3
            table[key] = {"mean_m": stats[0], "median_m": stats[1], "p95_m": stats[2], "n": int(v.size)}
        nis = np.asarray(self.nis, float)
        summary = {"horizons": table, "bags": self.recordings, "frames": self.frames,
                   "lost_frames": self.lost_frames, "outliers_rejected": self.outliers_rejected,
                   "off_table_poses": self.off_table,
                   "rejected_fraction": (self.outliers_rejected / (self.poses - self.off_table)
                                         if self.poses > self.off_table else None),
                   "reinit_per_s": self.reinitialisations / self.seconds if self.seconds > 0 else None,
                   "nis": {k: v for k, v in _nis_stats(nis).items() if k != "n"},  # issue #13's keys
                   "hand": {"regimes": self.hand_regimes, "frames": self.hand_frames}}
        if self.rest_speed is not None:
            regimes = np.asarray(self.nis_regimes)
            summary["nis_by_regime"] = {r: _nis_stats(nis[regimes == r]) for r in REGIMES}
            summary["by_path"] = {key: self._by_path(key) for key in self.errors}
        return summary

    def _by_path(self, key: str) -> dict:
        errors, paths = np.asarray(self.errors[key], float), np.asarray(self.paths[key])
        return {p: {"median_m": float(np.median(errors[paths == p])) if np.any(paths == p) else None,
                    "mean_m": float(np.mean(errors[paths == p])) if np.any(paths == p) else None,
                    "n": int(np.sum(paths == p))} for p in PATHS}


REGIMES = ("rest", "flight", "impact")
# What a prediction went through (eval-prediction's errors by path): it started at rest (a later motion is a
# hit no model foresees), it ended in a goal (behind a goal line: a puck the model lets past the posts may
# meet the goal's sides, or a post's other side, instead), or it flew with no, one, or two and more rim impacts
PATHS = ("rest", "no_impact", "one_impact", "impacts", "goal")


def _path(start_state: np.ndarray, end_state: np.ndarray, impacts: int, rest_speed: float, x_limit: float) -> str:
    if np.hypot(start_state[2], start_state[3]) < rest_speed:
        return "rest"
    if abs(end_state[0]) > x_limit:  # behind a short rim line: only a goal opening lets the model's puck there
        return "goal"
    return PATHS[1 + min(impacts, 2)]


def _nis_stats(nis: np.ndarray) -> dict:
    return {"median": float(np.median(nis)) if nis.size else None, "mean": float(nis.mean()) if nis.size else None,
            "n": int(nis.size)}


def _regime(earlier: "_FrameRecord | None", before: "_FrameRecord | None", t: float,
            rest_speed: float) -> str:
    """The regime of a gated frame at ``t`` [s] from the estimates of the two frames before it: *impact*
    when the model puts a rim impact in either of the two steps (the frame after an impact is where the
    velocity's impact noise first moves the position), else by the speed of the frame ``before``."""
    if before is None or before.x is None:
        return "flight"
    for start, end in ((earlier, before.t), (before, t)):
        if start is not None and start.x is not None and start.t < end:
            x, y, vx, vy = start.x[:4]
            if start.model.first_impact(x, y, vx, vy, end - start.t) is not None:
                return "impact"
    return "rest" if np.hypot(before.x[2], before.x[3]) < rest_speed else "flight"


@dataclass
class _FrameRecord:
    t: float
    z: np.ndarray | None        # the valid measurement (x, y, theta) of the frame, None if it had none
    x: np.ndarray | None        # filter state at the frame's stamp, None if the filter had none there
    P: np.ndarray | None        # its covariance (kept only when asked for)
    nis: float | None           # the frame's NIS when it reached the gate
    model: PuckModel            # the filter's model after the frame (its rim law as learned by then)
    offset: tuple = (0.0, 0.0)  # [m] the marker offset the filter takes positions back by after the frame


def valid_poses(frames: Sequence[Frame], ekf: PuckEKF) -> list[bool]:
    """For each frame, whether its pose is ground truth: plausible to ``ekf`` (:meth:`PuckEKF.plausible`)
    and not a marker glitch (:func:`marker_glitches`), whatever the filter makes of it."""
    s = ekf.settings
    poses = [None if z is None else np.asarray(z, float) for _, z in frames]
    ok = [z is not None and ekf.plausible(z) for z in poses]
    if s.glitch_speed is not None:
        for k in marker_glitches([t for t, _ in frames], poses, ok, s.glitch_speed, s.max_prediction_gap):
            ok[k] = False
    return ok


def marker_glitches(stamps: Sequence[float], poses: list, ok: list[bool], speed: float, max_gap: float) -> list[int]:
    """Indices of poses that jump faster than ``speed`` [m/s] from every neighbouring pose (the previous
    and the next within ``max_gap`` [s]): marker glitches. (Array arithmetic over the links between
    consecutive poses: the same rates, to the bit, as a loop over the poses, in a tenth of the time.)"""
    posed = np.flatnonzero(np.asarray(ok, bool))
    if len(posed) < 2:
        return []
    gaps = np.abs(np.diff(np.asarray(stamps, float)[posed]))
    jumps = np.hypot(*np.diff(np.array([poses[k][:2] for k in posed], float), axis=0).T)
    usable = (gaps > 0.0) & (gaps <= max_gap)
    rates = np.full(len(gaps), np.nan)
    rates[usable] = jumps[usable] / gaps[usable]
    before, after = np.concatenate([[np.nan], rates]), np.concatenate([rates, [np.nan]])
    slowest = np.fmin(before, after)  # NaN only where neither neighbour is usable
    return posed[slowest > speed].tolist()


def _filter_pass(ekf: PuckEKF, frames: Iterable[Frame], keep_cov: bool) -> tuple[list[_FrameRecord], list[float], int]:
    """Run ``ekf`` (reset first) over a recording: a record of every frame, every stamp, and the number of
    frames without a pose."""
    frames = list(frames)
    valid = valid_poses(frames, ekf)
    ekf.reset()
    records, stamps, invalid = [], [], 0
    for (t, z), good in zip(frames, valid):
        stamps.append(t)
        invalid += z is None
        ekf.process(t, z)
        has_state = ekf.initialised and ekf.stamp is not None and ekf.stamp == t
        records.append(_FrameRecord(t, np.asarray(z, float) if good else None, ekf.x.copy() if has_state else None,
                                    ekf.P.copy() if has_state and keep_cov else None, ekf.last_nis, ekf.model,
                                    ekf.marker_offset))
    return records, stamps, invalid


def evaluate_stream(ekf: PuckEKF, frames: Iterable[Frame], totals: EvaluationTotals) -> None:
    """Filter one recording with ``ekf`` (reset first) and add its prediction errors to ``totals``."""
    ekf.stats = FilterStats()
    records, stamps, invalid = _filter_pass(ekf, frames, keep_cov=totals.loglik)
    truth = [r for r in records if r.z is not None]
    truth_t = [r.t for r in truth]
    starts = [r for r in records if r.x is not None][::totals.stride]
    period = stream_frame_period(stamps, ekf.settings.max_prediction_gap, ekf.settings.dt)
    tolerance = 0.5 * period  # the valid pose nearest t + h lies within half a frame of it
    start_t = np.array([start.t for start in starts], float)
    for h in totals.horizons:
        errors, nll, paths = totals.errors[horizon_key(h)], totals.nll[horizon_key(h)], totals.paths[horizon_key(h)]
        for start, j in zip(starts, nearest_indices(truth_t, start_t + h).tolist()):
            if j < 0 or abs(truth_t[j] - (start.t + h)) > tolerance or truth_t[j] <= start.t:
                continue
            pred = ekf.predict_from(start.model, start.x, start.P, truth_t[j] - start.t)
            residual = truth[j].z[:2] - pred.state[:2] - pivot_shift(float(pred.state[4]), start.offset)
            errors.append(float(np.hypot(*residual)))
            if totals.rest_speed is not None:
                paths.append(_path(start.x, pred.state, len(pred.impacts), totals.rest_speed,
                                   start.model.table.x_limit))
            if totals.loglik:
                nll.append(_neg_log_likelihood(residual, pred.covariance[:2, :2] + ekf.settings.r[:2, :2]))
    totals.nis.extend(r.nis for r in records if r.nis is not None)
    if totals.rest_speed is not None:
        totals.nis_regimes.extend(_regime(earlier, before, record.t, totals.rest_speed) for earlier, before, record
                                  in zip([None, None] + records[:-2], [None] + records[:-1], records)
                                  if record.nis is not None)
    totals.frames += ekf.stats.frames  # lost = missing from the stream + arrived without a usable pose
    totals.poses += len(records) - invalid
    totals.lost_frames += count_lost_frames(sorted(stamps), period, ekf.settings.max_prediction_gap) + invalid
    totals.outliers_rejected += ekf.stats.outliers_rejected
    totals.off_table += ekf.stats.off_table
    totals.reinitialisations += max(0, ekf.stats.reinitialisations - 1)
    totals.hand_regimes += ekf.stats.hand_regimes
    totals.hand_frames += ekf.stats.hand_frames
    totals.seconds += (max(stamps) - min(stamps)) if stamps else 0.0
    totals.recordings += 1


def _neg_log_likelihood(residual: np.ndarray, cov: np.ndarray) -> float:
    """-ln of the 2-D normal density of ``residual`` with covariance ``cov`` (thesis sec. 4.3.1)."""
    (a, b), (_, d) = cov
    det = a * d - b * b
    quad = (d * residual[0] ** 2 - 2 * b * residual[0] * residual[1] + a * residual[1] ** 2) / det
    return float(0.5 * (quad + np.log(det)) + np.log(2 * np.pi))


def nearest_indices(times: Sequence[float], targets: np.ndarray) -> np.ndarray:
    """For each of ``targets`` [s], the index of the nearest of the ascending ``times`` [s] (the earlier on a
    tie, as bisecting for each would); -1 for every target when ``times`` is empty."""
    times = np.asarray(times, float)
    if len(times) == 0:
        return np.full(len(targets), -1)
    i = np.searchsorted(times, targets, side="left")  # as bisect.bisect_left
    before, after = np.clip(i - 1, 0, len(times) - 1), np.clip(i, 0, len(times) - 1)
    earlier = np.abs(times[before] - targets) <= np.abs(times[after] - targets)
    return np.where(earlier, before, after)


@dataclass
class PredictionSeries:
    """One recording, frame by frame: what was measured, estimated, and predicted ``horizon`` before."""

    horizon: float
    t: np.ndarray           # (n,) stamps [s] of the valid measurements
    measured: np.ndarray    # (n, 3) x, y, theta, the position taken back to the disc's centre by the marker offset
    estimated: np.ndarray   # (n, 6) filter state after the frame (NaN where the filter had none)
    predicted: np.ndarray   # (n, 6) state predicted from the frame nearest t - horizon (NaN if none)


def prediction_series(ekf: PuckEKF, frames: Iterable[Frame], horizon: float) -> PredictionSeries:
    """Filter a recording and, for every valid measurement, the estimate there and the prediction made
    ``horizon`` [s] earlier from the frame nearest ``t - horizon`` at which the filter had a state
    (fig. 5.2-5.4; the definition of :func:`evaluate_stream`)."""
    records, _, _ = _filter_pass(ekf, frames, keep_cov=False)
    measured = [r for r in records if r.z is not None]
    starts = [r for r in records if r.x is not None]
    start_t = [r.t for r in starts]
    t = [r.t for r in measured]
    predicted = np.full((len(t), 6), np.nan)
    estimated = np.array([r.x if r.x is not None else np.full(6, np.nan) for r in measured]).reshape(-1, 6)
    tolerance = 0.5 * ekf.settings.dt
    for k, (stamp, j) in enumerate(zip(t, nearest_indices(start_t, np.array(t, float) - horizon).tolist())):
        if j >= 0 and start_t[j] < stamp and abs(start_t[j] - (stamp - horizon)) <= tolerance:
            predicted[k] = ekf.predict_from(starts[j].model, starts[j].x, None, stamp - start_t[j]).state
    centres = [centre_of(r.z, r.offset) for r in measured]  # as the estimates and predictions: the disc's centre
    return PredictionSeries(horizon, np.array(t), np.array(centres).reshape(-1, 3),
                            estimated, predicted)
