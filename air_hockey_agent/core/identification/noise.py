"""Measurement and process noise estimation (thesis sec. 3.2.2 eq. 3.12-3.13, sec. 4.4).

With the filter's own estimates standing in for the true states:

* R (eq. 3.12): covariance of ``z_k - h(x_k|k)`` over every fused frame (angle residual wrapped; the
  measured position taken back from the mocap pivot to the disc's centre by the filter's marker offset,
  :mod:`~air_hockey_agent.core.estimation.marker_offset`, as the filter takes it);
* Q (eq. 3.13): covariance of ``f(x_k|k) - x_k+1|k+1`` over consecutive fused model steps;

both without correlation terms (diagonal, thesis sec. 4.4). :func:`calibrate_by_regime` sets the noise by
regime instead (issue #13): Q in flight, Q at rest and the rim impacts' ``impact_noise``, each scaled until
the NIS median of its regime's frames (:mod:`~air_hockey_agent.core.estimation.evaluation`) is a consistent
filter's. (Eq. 3.13 split by regime was tried first: its posterior corrections overstate Q several
hundred times, and on a held-out test-bed bag the filter's NIS median fell to 1.1.) With ``by_speed`` the
position part of R is
the noise at rest plus a growth with speed (issue #13: the lab's marker noise grows from 0.15 mm at rest
to 1.5 mm at 2-5 m/s), fitted to the same residuals against the filter's speed estimate. The estimates
change the filter, which changes the estimates, so the procedure is iterated (5 times in the thesis).
Either matrix can be kept fixed while the other is estimated.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np

from air_hockey_agent.core.estimation.ekf import FLAG_MEASUREMENT_USED, FLAG_REINITIALISED, PuckEKF
from air_hockey_agent.core.estimation.evaluation import REGIMES
from air_hockey_agent.core.estimation.marker_offset import centre_of
from air_hockey_agent.core.identification.preprocess import GridTrajectory
from air_hockey_agent.core.identification.sysid import filter_pass_totals
from air_hockey_agent.core.puck.model import wrap_angle


@dataclass
class NoiseEstimate:
    r: np.ndarray        # (3,) diagonal of R: x, y [m^2], theta [rad^2]
    q: np.ndarray        # (6,) diagonal of Q per model step
    r_samples: int
    q_samples: int
    # with by_speed: R's position terms are the variance at rest, and the std grows by this [s] per m/s
    r_per_speed: float | None = None


def position_noise_by_speed(residuals: np.ndarray, speeds: np.ndarray, rounds: int = 3) -> tuple[float, float]:
    """Position noise variance at rest [m^2] and its growth with speed [s]: the fit of
    ``(rx^2 + ry^2) / 2 = R0 + (k v)^2`` over the fused frames (the noise model of the filter's
    ``measurement_noise_per_speed``), both kept non-negative. The squares' own spread grows with the
    variance, so the fit is weighted by the inverse square of the variance it predicts (iteratively
    reweighted; the first round is ordinary least squares)."""
    per_frame = 0.5 * (residuals[:, 0] ** 2 + residuals[:, 1] ** 2)
    design = np.column_stack([np.ones_like(speeds), speeds ** 2])
    weights = np.ones_like(per_frame)
    r0, k2 = float(np.mean(per_frame)), 0.0
    for _ in range(rounds):
        w = np.sqrt(weights)
        (r0, k2), *_ = np.linalg.lstsq(design * w[:, None], per_frame * w, rcond=None)
        r0, k2 = max(float(r0), 0.0), max(float(k2), 0.0)
        predicted = r0 + k2 * speeds ** 2
        if np.any(predicted <= 0.0):
            break
        weights = 1.0 / predicted ** 2
    return r0, float(np.sqrt(k2))


def fixed_noise(params: Mapping[str, Any]) -> dict:
    """``params`` with the noise as set (``noise_adaptation`` and ``process_noise_adaptation`` off): the
    noise being estimated or calibrated here is the iteration's, not one the filter learns underneath it."""
    return {**params, "noise_adaptation.enabled": False, "process_noise_adaptation.enabled": False}


def estimate_once(params: Mapping[str, Any], trajectories: Sequence[GridTrajectory],
                  by_speed: bool = False) -> NoiseEstimate:
    """One pass of eq. 3.12 and 3.13 with the filter configured by ``params``; with ``by_speed`` the
    position noise is split into its value at rest and its growth with the filter's speed estimate."""
    ekf = PuckEKF.from_params(fixed_noise(params))
    meas_res, proc_res, speeds = [], [], []
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
            # eq. 3.12 with the posterior standing in for the truth, the pivot taken back to the centre as
            # the filter took it (a pivot off the centre would count its circles as noise)
            meas_res.append(ekf.residual(centre_of(np.asarray(z, float), ekf.marker_offset)))
            speeds.append(float(np.hypot(ekf.x[2], ekf.x[3])))
            if previous is not None and previous[0] == row - 1:
                step = ekf.model.step(previous[1], traj.dt, with_jacobian=False).state - ekf.x
                step[4] = wrap_angle(step[4])
                proc_res.append(step)
            previous = (row, ekf.x.copy())
    r = np.var(np.array(meas_res), axis=0, ddof=1) if len(meas_res) > 1 else np.full(3, np.nan)
    q = np.var(np.array(proc_res), axis=0, ddof=1) if len(proc_res) > 1 else np.full(6, np.nan)
    per_speed = None
    if by_speed and len(meas_res) > 2:
        r0, per_speed = position_noise_by_speed(np.array(meas_res), np.array(speeds))
        r[0] = r[1] = r0
    return NoiseEstimate(r, q, len(meas_res), len(proc_res), per_speed)


def iterate(params: Mapping[str, Any], trajectories: Sequence[GridTrajectory], iterations: int,
            fix: Sequence[str] = (), by_speed: bool = False) -> list[NoiseEstimate]:
    """Repeat the estimate ``iterations`` times, feeding each result back (``fix``: "R" and/or "Q" kept;
    ``by_speed``: R's position terms at rest plus ``measurement_noise_per_speed``)."""
    current = dict(params)
    history = []
    for _ in range(iterations):
        est = estimate_once(current, trajectories, by_speed and "R" not in fix)
        history.append(est)
        if "R" not in fix and np.all(np.isfinite(est.r)) and np.all(est.r > 0):
            current["measurement_noise"] = est.r.tolist()
            if est.r_per_speed is not None:
                current["measurement_noise_per_speed"] = est.r_per_speed
        if "Q" not in fix and np.all(np.isfinite(est.q)) and np.all(est.q > 0):
            current["process_noise"] = est.q.tolist()
    return history


CONSISTENT_NIS_MEDIAN = 2.366  # [-] median of the chi-square distribution with 3 degrees of freedom
MIN_REGIME_FRAMES = 20         # fewer gated frames in a regime leave its noise as it was


@dataclass
class RegimeCalibration:
    values: dict          # process_noise, process_noise_rest, impact_noise (as calibrated, or as given)
    nis_median: dict      # regime -> NIS median with the calibrated values (None without frames)
    frames: dict          # regime -> gated frames
    passes: int           # filter passes over the trajectories
    on_bound: list        # regimes whose search ended at an end of its range (the NIS could not be met)


def regime_nis(params: Mapping[str, Any], trajectories: Sequence[GridTrajectory]) -> dict:
    """NIS of every gated frame of ``trajectories``, by regime (rest / flight / impact)."""
    totals = filter_pass_totals(fixed_noise(params), trajectories, params["regime_rest_speed"])
    nis, regimes = np.asarray(totals.nis, float), np.asarray(totals.nis_regimes)
    return {r: nis[regimes == r] for r in REGIMES}


def calibrate_by_regime(params: Mapping[str, Any], trajectories: Sequence[GridTrajectory], rounds: int = 2,
                        steps: int = 12) -> RegimeCalibration:
    """Scale Q in flight (``process_noise``), Q at rest (``process_noise_rest``) and set ``impact_noise`` so
    that each regime's NIS median is CONSISTENT_NIS_MEDIAN: a bisection per regime (the NIS falls as the
    noise grows) over a factor 1e-3 to 1e3 of Q, and 0 to 3 for the impact noise, ``rounds`` times over the
    regimes because they share frames' histories. R stays as given."""
    current = dict(params)
    passes = [0]
    on_bound = set()

    def median(candidate: dict, regime: str) -> float | None:
        passes[0] += 1
        nis = regime_nis(candidate, trajectories)[regime]
        return float(np.median(nis)) if nis.size >= MIN_REGIME_FRAMES else None

    for _ in range(rounds):
        for regime, name in (("flight", "process_noise"), ("rest", "process_noise_rest")):
            base = np.asarray(current[name], float)
            factor = _bisect(lambda k: median({**current, name: (base * k).tolist()}, regime), 1e-3, 1e3, steps,
                             log=True)
            if factor is not None:
                current[name] = (base * factor).tolist()
                _note_bound(on_bound, regime, np.log(factor), np.log(1e-3), np.log(1e3))
        ratio = _bisect(lambda k: median({**current, "impact_noise": k}, "impact"), 0.0, 3.0, steps, log=False)
        if ratio is not None:
            current["impact_noise"] = ratio
            _note_bound(on_bound, "impact", ratio, 0.0, 3.0)
    final = regime_nis(current, trajectories)
    passes[0] += 1
    return RegimeCalibration({n: current[n] for n in ("process_noise", "process_noise_rest", "impact_noise")},
                             {r: float(np.median(v)) if v.size else None for r, v in final.items()},
                             {r: int(v.size) for r, v in final.items()}, passes[0],
                             [r for r in REGIMES if r in on_bound])


def _note_bound(on_bound: set, regime: str, value: float, low: float, high: float) -> None:
    """Remember ``regime`` when ``value`` ended within 1 % of its range from an end (dropped when a later
    round moves it off)."""
    if min(value - low, high - value) <= 0.01 * (high - low):
        on_bound.add(regime)
    else:
        on_bound.discard(regime)


def _bisect(median_at, low: float, high: float, steps: int, log: bool) -> float | None:
    """The value in [low, high] where the decreasing ``median_at`` meets CONSISTENT_NIS_MEDIAN (an end
    when it does not cross), or None when the regime has too few frames."""
    lo, hi = (np.log(low) if log and low > 0 else low), (np.log(high) if log else high)
    to_value = (lambda u: float(np.exp(u))) if log else float
    for _ in range(steps):
        mid = 0.5 * (lo + hi)
        value = median_at(to_value(mid))
        if value is None:
            return None
        if value > CONSISTENT_NIS_MEDIAN:
            lo = mid  # overconfident: more noise
        else:
            hi = mid
    return to_value(0.5 * (lo + hi))
