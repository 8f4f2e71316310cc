"""The mocap's noise (position and angle) learned online from the poses themselves (issue #13 item 2: noise
identified from data, the filter kept calibrated).

The marker noise is modelled as the filter's R models it: a variance ``a`` [m^2] per axis at rest that
grows with the speed v [m/s] as ``a + b v^2`` (``b`` = ``measurement_noise_per_speed`` squared, [s^2]:
marker blur and timestamp jitter). A filter whose R is too small rejects good frames and restarts (the
lab's symptoms with the old filter; on the test bed with twice its marker noise the defaults rejected 17 %
of the poses and read a NIS median of 6.2); one whose R is too large smooths too much and reads a NIS far
below the chi-square. What the noise is follows from the poses alone, whatever the filter makes of them:
over ``window`` consecutive poses (intervals up to ``max_gap_frames`` frame periods) the positions are fitted by a quadratic in
time per axis, a motion no puck departs from measurably in a few frames (0.1 m/s^2 of unmodelled
acceleration moves it 3 um in 75 ms) unless a rim, a hit or a glitch acts, and the residuals' sum of
squares over both axes, divided by its 2 (window - 3) degrees of freedom, is an unbiased sample of the
noise variance at the window's speed; the angle's, unwrapped, over its window - 3, one of the angle noise
(R's third term: a constant, as configured). The windows do not overlap.

``a`` and ``b`` are refitted every ``update_every`` new windows, once there are ``min_windows``, by
iteratively reweighted least squares over the last ``max_windows`` windows (each weighted by its expected
variance's inverse square; windows beyond ``outlier_ratio`` times their expected variance, those with a
rim impact, a hit or a glitch, left out), with the configured values as a prior worth ``prior_windows``
windows, half at rest and half at ``PRIOR_SPEED``; the angle noise as the mean of its samples within
``angle_outlier_ratio`` times it (a rim impact's or a hand's turn of the spin left out), the configured
value worth ``prior_windows`` windows.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np

from air_hockey_agent.core.puck.model import wrap_angle

PRIOR_SPEED = 2.0      # [m/s] where the prior's second half of pseudo-windows sits (the lab's shots: 2-5 m/s)
IRLS_ITERATIONS = 4    # reweightings of the fit (the weights settle in two or three)
MIN_VARIANCE = 1e-12   # [m^2] a floor for the expected variance in the weights (0.001 mm)


@dataclass(frozen=True)
class NoiseAdaptationSettings:
    """``noise_adaptation.*`` in config/tracker.yaml (sources there; the defaults here are its values)."""

    window: int = 9                 # consecutive poses per quadratic fit
    max_gap_frames: float = 2.5     # [frame periods] a longer interval between two poses ends the window
    prior_windows: float = 4.0      # weight of the configured noise, in windows (half at rest, half moving)
    min_windows: int = 10           # windows before the first refit (until then the configured noise stands)
    update_every: int = 10          # new windows between refits
    max_windows: int = 3000         # the last windows the fit uses
    outlier_ratio: float = 3.0      # a window beyond this many times its expected variance is left out
    angle_outlier_ratio: float = 4.0  # ... of its angle variance (6 degrees of freedom)

    @classmethod
    def from_params(cls, params: Mapping[str, Any], prefix: str = "noise_adaptation.") -> "NoiseAdaptationSettings":
        return cls(**{name: params[prefix + name] for name in cls.__dataclass_fields__})


def window_sample(stamps: Sequence[float], poses: Sequence[Sequence[float]]) -> tuple[float, float, float]:
    """(position noise variance sample [m^2], speed [m/s], angle noise variance sample [rad^2]) of one
    window: the quadratic fits' residual sums of squares, over x and y divided by their 2 (n - 3) degrees
    of freedom and of the (unwrapped) angle by its n - 3, and the position fit's speed at the window's
    middle. ``stamps`` (n,) [s], ``poses`` (n, 3) x, y [m], theta [rad], n >= 4. Normal equations in
    plain floats (a few microseconds for a handful of points, where a general least-squares call takes
    tens)."""
    n = len(stamps)
    mid = sum(stamps) / n
    s1 = s2 = s3 = s4 = 0.0
    x0 = x1 = x2 = y0 = y1 = y2 = a0 = a1 = a2 = sxx = syy = saa = 0.0
    angle, previous = 0.0, poses[0][2]
    for t, (x, y, theta) in zip(stamps, poses):
        angle += wrap_angle(theta - previous)  # unwrapped from the window's first angle
        previous = theta
        u = t - mid
        u2 = u * u
        s1 += u
        s2 += u2
        s3 += u2 * u
        s4 += u2 * u2
        x0 += x
        x1 += u * x
        x2 += u2 * x
        y0 += y
        y1 += u * y
        y2 += u2 * y
        a0 += angle
        a1 += u * angle
        a2 += u2 * angle
        sxx += x * x
        syy += y * y
        saa += angle * angle
    gram = ((float(n), s1, s2), (s1, s2, s3), (s2, s3, s4))
    cx, cy, ca = _solve3(gram, (x0, x1, x2)), _solve3(gram, (y0, y1, y2)), _solve3(gram, (a0, a1, a2))
    rss_x = sxx - (cx[0] * x0 + cx[1] * x1 + cx[2] * x2)  # residual sums of squares of the least squares fits
    rss_y = syy - (cy[0] * y0 + cy[1] * y1 + cy[2] * y2)
    rss_a = saa - (ca[0] * a0 + ca[1] * a1 + ca[2] * a2)
    return max(rss_x + rss_y, 0.0) / (2 * (n - 3)), math.hypot(cx[1], cy[1]), max(rss_a, 0.0) / (n - 3)


def _solve3(m: tuple, rhs: Sequence[float]) -> tuple[float, float, float]:
    """The symmetric 3x3 system ``m`` x = ``rhs`` by Cramer's rule (``m`` well conditioned: a window's
    centred times)."""
    (a, b, c), (_, e, f), (_, _, i) = m
    co_a, co_b, co_c = e * i - f * f, c * f - b * i, b * f - c * e
    det = a * co_a + b * co_b + c * co_c
    co_e, co_f, co_i = a * i - c * c, b * c - a * f, a * e - b * b
    r0, r1, r2 = rhs
    return ((co_a * r0 + co_b * r1 + co_c * r2) / det, (co_b * r0 + co_e * r1 + co_f * r2) / det,
            (co_c * r0 + co_f * r1 + co_i * r2) / det)


def fit_noise(variances: np.ndarray, speeds: np.ndarray, prior: tuple[float, float], prior_windows: float,
              outlier_ratio: float) -> tuple[float, float, int]:
    """``a`` [m^2], ``b`` [s^2] of the variance model ``a + b v^2`` from window samples, with ``prior``
    (a0, b0) as ``prior_windows`` pseudo-windows (half at rest, half at ``PRIOR_SPEED``), and the number of
    windows used (the rest: outliers). Weighted least squares on the relative error, reweighted."""
    a0, b0 = prior
    half = 0.5 * prior_windows
    v2 = speeds * speeds
    p2 = PRIOR_SPEED ** 2
    a, b, used = a0, b0, np.ones(len(variances), bool)
    for _ in range(IRLS_ITERATIONS):
        expected = np.maximum(a + b * v2, MIN_VARIANCE)
        used = variances <= outlier_ratio * expected
        w = np.where(used, 1.0 / expected ** 2, 0.0)
        w0, w1 = half / max(a, MIN_VARIANCE) ** 2, half / max(a + b * p2, MIN_VARIANCE) ** 2  # the prior's
        s0, s1, s2 = w.sum() + w0 + w1, w @ v2 + w1 * p2, w @ (v2 * v2) + w1 * p2 * p2
        t0, t1 = w @ variances + w0 * a0 + w1 * (a0 + b0 * p2), w @ (variances * v2) + w1 * (a0 + b0 * p2) * p2
        det = s0 * s2 - s1 * s1
        if det <= 0.0:
            return a0, b0, 0
        a, b = (s2 * t0 - s1 * t1) / det, (s0 * t1 - s1 * t0) / det
        if b < 0.0:  # the noise does not fall with the speed: the weighted mean at all speeds, b = 0
            a, b = t0 / s0, 0.0
        a = max(float(a), MIN_VARIANCE)
    return float(a), float(b), int(used.sum())


def fit_angle_noise(variances: np.ndarray, prior: float, prior_windows: float, outlier_ratio: float) -> float:
    """The angle noise variance [rad^2]: the mean of the window samples within ``outlier_ratio`` times the
    estimate (a rim impact's or a hand's turn left out), with ``prior`` worth ``prior_windows`` windows."""
    value = prior
    for _ in range(IRLS_ITERATIONS):
        used = variances[variances <= outlier_ratio * max(value, MIN_VARIANCE)]
        value = (float(used.sum()) + prior_windows * prior) / (len(used) + prior_windows) if len(used) else prior
    return max(value, MIN_VARIANCE)


class MarkerNoiseAdaptation:
    """Learns ``a`` and ``b`` (module docstring) from every plausible pose the filter is given."""

    def __init__(self, settings: NoiseAdaptationSettings, a0: float, b0: float, frame_period: float,
                 angle0: float = 0.0) -> None:
        self.settings, self.prior, self.angle_prior = settings, (float(a0), float(b0)), float(angle0)
        self.a, self.b, self.angle = float(a0), float(b0), float(angle0)
        self.frame_period = float(frame_period)
        self.windows_used = 0
        self._stamps: list[float] = []
        self._poses: list[tuple[float, float, float]] = []
        self._variances = np.zeros(settings.max_windows)  # ring buffers of the windows' samples
        self._speeds = np.zeros(settings.max_windows)
        self._angle_variances = np.zeros(settings.max_windows)
        self._count = 0                                     # windows collected (the buffers hold the last)
        self._new = 0

    @classmethod
    def from_params(cls, params: Mapping[str, Any]) -> "MarkerNoiseAdaptation | None":
        """None unless ``noise_adaptation.enabled``; the prior is ``measurement_noise`` (its position part at
        rest and its angle part) and ``measurement_noise_per_speed``."""
        if not params["noise_adaptation.enabled"]:
            return None
        return cls(NoiseAdaptationSettings.from_params(params), float(params["measurement_noise"][0]),
                   float(params["measurement_noise_per_speed"]) ** 2, 1.0 / float(params["frequency"]),
                   float(params["measurement_noise"][2]))

    @property
    def windows(self) -> int:
        """Windows collected so far (the last ``max_windows`` are kept)."""
        return self._count

    def observe(self, t: float, pose: Sequence[float] | None) -> bool:
        """Take a pose at ``t`` [s] (table frame x, y [m], theta [rad]; None: a lost or implausible frame,
        which ends the window). Returns True when the noise was refitted."""
        if pose is None:
            self._clear()
            return False
        if self._stamps and not (0.0 < t - self._stamps[-1] <= self.settings.max_gap_frames * self.frame_period):
            self._clear()  # a lost frame, a repeated or earlier stamp, a new track
        elif self._poses and pose[0] == self._poses[-1][0] and pose[1] == self._poses[-1][1]:
            self._clear()  # a frozen frame repeats the pose: no sample of the noise
            return False
        self._stamps.append(float(t))
        self._poses.append((float(pose[0]), float(pose[1]), float(pose[2])))
        if len(self._stamps) < self.settings.window:
            return False
        slot = self._count % self.settings.max_windows
        self._variances[slot], self._speeds[slot], self._angle_variances[slot] = window_sample(self._stamps,
                                                                                               self._poses)
        self._count += 1
        self._clear()
        self._new += 1
        if self._new < self.settings.update_every or self._count < self.settings.min_windows:
            return False
        self._new = 0
        kept = min(self._count, self.settings.max_windows)
        self.a, self.b, self.windows_used = fit_noise(self._variances[:kept], self._speeds[:kept], self.prior,
                                                      self.settings.prior_windows, self.settings.outlier_ratio)
        self.angle = fit_angle_noise(self._angle_variances[:kept], self.angle_prior, self.settings.prior_windows,
                                     self.settings.angle_outlier_ratio)
        return True

    def _clear(self) -> None:
        self._stamps.clear()
        self._poses.clear()

    def report(self) -> dict:
        """JSON-ready: windows collected and used, and the learned noise (std at rest [m], per m/s [s])."""
        return {"windows": self.windows, "used": self.windows_used, "at_rest_m": math.sqrt(self.a),
                "per_speed_s": math.sqrt(self.b), "angle_rad": math.sqrt(self.angle)}


def describe_noise(report: dict) -> str:
    """A :meth:`MarkerNoiseAdaptation.report` in words."""
    return (f"marker noise {report['at_rest_m'] * 1e3:.3f} mm at rest, {report['per_speed_s'] * 1e3:.3f} mm per m/s "
            f"in quadrature, angle {report['angle_rad'] * 1e3:.2f} mrad, from {report['used']} of "
            f"{report['windows']} windows")
