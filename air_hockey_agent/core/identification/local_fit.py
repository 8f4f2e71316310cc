"""Local polynomial fits of a stretch of recorded positions (split identification, issue #13 item 5).

A stretch is a set of grid rows of a :class:`~.preprocess.GridTrajectory` (blank rows skipped). Its
table-frame positions ``p(t)`` [m] are fitted per axis by least squares with a polynomial in
``tau = t - t_ref`` [s]: degree 2 gives position, velocity and acceleration at ``t_ref``; degree 1
(velocity only) may first have a known acceleration removed. The angle is fitted the same way after
unwrapping. Nothing here knows the puck model: these are the independent references the split
identification regresses the model's parameters on.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np


@dataclass(frozen=True)
class LocalFit:
    """Polynomial fit of the positions of one stretch at ``t_ref``."""

    t_ref: float           # [s] time the coefficients hold at (trajectory time)
    p: np.ndarray          # (2,) [m] position at t_ref
    v: np.ndarray          # (2,) [m/s] velocity at t_ref
    a: np.ndarray          # (2,) [m/s^2] acceleration (zeros for degree 1, or the removed one)
    a_gain: float          # [1/s^4] variance of a per unit position noise variance ((X^T X)^-1, a's entry)
    v_gain: float          # [1/s^2] the same for v
    rms: float             # [m] residual RMS over both axes
    frames: int            # rows used
    variance: np.ndarray   # (2,) [m^2] residual variance per axis (sum of squares over the degrees of freedom)


def fit_positions(times: np.ndarray, xy: np.ndarray, t_ref: float, degree: int,
                  known_acceleration: np.ndarray | None = None) -> LocalFit | None:
    """Fit ``xy`` (n, 2) [m] at ``times`` (n,) [s] with a polynomial of ``degree`` (1 or 2) in ``t - t_ref``;
    for degree 1, ``known_acceleration`` [m/s^2] is removed first. None if too few rows for the fit."""
    tau = np.asarray(times, float) - t_ref
    n = len(tau)
    if n < degree + 2:
        return None
    columns = [np.ones(n), tau] + ([0.5 * tau ** 2] if degree == 2 else [])
    x = np.column_stack(columns)
    target = np.asarray(xy, float)
    accel = np.zeros(2)
    if degree == 1 and known_acceleration is not None:
        accel = np.asarray(known_acceleration, float)
        target = target - 0.5 * tau[:, None] ** 2 * accel[None, :]
    gram_inv = np.linalg.inv(x.T @ x)
    coef = gram_inv @ (x.T @ target)
    residual = target - x @ coef
    rms = math.sqrt(float(np.sum(residual ** 2)) / max(1, 2 * (n - len(columns))))
    a = coef[2] if degree == 2 else accel
    a_gain = float(gram_inv[2, 2]) if degree == 2 else 0.0
    variance = np.sum(residual ** 2, axis=0) / max(1, n - len(columns))
    return LocalFit(t_ref, coef[0], coef[1], a, a_gain, float(gram_inv[1, 1]), rms, n, variance)


def line_fit(times: np.ndarray, xy: np.ndarray, t_ref: float, acceleration) -> LocalFit | None:
    """Line fit of ``xy`` [m] at ``times`` [s] with a flight law's acceleration ``acceleration(v) -> a``
    [m/s^2] (at a first line fit's velocity) removed first; None if too few rows."""
    first = fit_positions(times, xy, t_ref, 1)
    if first is None:
        return None
    return fit_positions(times, xy, t_ref, 1, acceleration(first.v))


def fit_angle_rate(times: np.ndarray, theta: np.ndarray, t_ref: float | None = None,
                   spin_damping: float = 0.0) -> float | None:
    """Spin [rad/s]: slope of a line through the unwrapped angles ``theta`` [rad] at ``times`` [s], the spin
    at their mean time; at ``t_ref`` [s] instead when given, for a spin decaying at ``spin_damping`` [1/s]
    (the slope of an exponential decay's angles is its spin at the middle, to second order)."""
    if len(times) < 3:
        return None
    unwrapped = np.unwrap(np.asarray(theta, float))
    middle = float(np.mean(times))
    tau = np.asarray(times, float) - middle
    rate = float(np.sum(tau * (unwrapped - np.mean(unwrapped))) / np.sum(tau ** 2))
    return rate if t_ref is None else rate * math.exp(spin_damping * (middle - t_ref))


class SpinFit(NamedTuple):
    spin: float      # w [rad/s] at the window's mean time
    rate: float      # wdot [rad/s^2]
    gain: float      # variance of wdot per rad^2 of angle noise [1/s^4]
    variance: float  # [rad^2] the angles' residual variance about the quadratic


def spin_quadratic(times: np.ndarray, angles: np.ndarray) -> SpinFit | None:
    """A quadratic through the unwrapped ``angles`` [rad] at ``times`` [s]: spin and its rate of change at the
    mean time; None with fewer than four angles."""
    theta = np.unwrap(np.asarray(angles, float))
    fit = fit_positions(times, np.column_stack((theta, theta)), float(np.mean(times)), 2)  # one axis, twice
    return None if fit is None else SpinFit(float(fit.v[0]), float(fit.a[0]), fit.a_gain, float(fit.variance[0]))


def rows_in(z: np.ndarray, start: int, stop: int) -> np.ndarray:
    """Indices of the measured (non-blank) rows of ``z`` in [start, stop)."""
    start = max(0, start)
    stop = max(start, min(len(z), stop))
    rows = np.arange(start, stop)
    return rows[~np.isnan(z[start:stop, 0])]


def smooth_fits(quality, factor: float) -> np.ndarray:
    """Mask of the fits whose quality (residual RMS over the expected noise) is within ``factor`` times the
    median quality: the others had an impact, a hit or a glitch inside."""
    quality = np.asarray(quality, float)
    if not quality.size:
        return np.zeros(0, bool)
    return quality <= factor * max(float(np.median(quality)), 1e-12)


def beyond_noise(value: float, std: float, significance: float, limit: float = 0.0) -> bool:
    """Whether an estimate ``value`` lies farther from 0 than ``limit`` and ``significance`` times its standard
    error ``std`` (same units): the one rule for an offset, a rate or a part of the table's geometry that
    counts. False for a NaN value (nothing estimated)."""
    return abs(value) > max(limit, significance * std)


def paths_meet(normal: tuple[float, float], p_before: np.ndarray, v_before: np.ndarray, p_after: np.ndarray,
               v_after: np.ndarray) -> tuple[float, float] | None:
    """Where two straight paths, positions ``p_*`` [m] at a common time and velocities ``v_*`` [m/s], are
    equally far along ``normal``: (time [s] from that common time, ``normal . p`` [m] there); None when the
    second does not leave along the normal faster than the first arrives (no impact between them)."""
    n = np.asarray(normal, float)
    closing = float(n @ (np.asarray(v_before) - np.asarray(v_after)))
    if closing >= 0.0:
        return None
    tau = -float(n @ (np.asarray(p_before) - np.asarray(p_after))) / closing
    return tau, float(n @ (np.asarray(p_before) + tau * np.asarray(v_before)))
