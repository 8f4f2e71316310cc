"""The flight law learned online (``acceleration_adaptation.*``): the table acceleration, the damping,
the surface friction and the mocap pivot's offset from free-flight windows, one Gaussian
(:class:`AccelerationAdaptation`); the windows are cut and handed over by :mod:`.table_learning`."""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from air_hockey_agent.core.identification.local_fit import fit_positions
from air_hockey_agent.core.estimation.marker_offset import offset_normal_equations
from air_hockey_agent.core.puck.model import PuckParams


@dataclass(frozen=True)
class AccelerationSettings:
    """``acceleration_adaptation.*`` in ``config/tracker.yaml``."""

    enabled: bool
    prior_std: float     # [m/s^2] per axis, of the configured table_acceleration
    damping_prior_std: float  # [1/s] of the configured damping
    field_std: float     # [m/s^2] per axis, added to each window's std: what a constant cannot follow
    window: float        # [s] fused frames per fit
    min_frames: int      # fused frames a window needs
    min_speed: float     # [m/s] frames of a slower puck are not used (at rest the surface may hold it)
    gate: float          # squared Mahalanobis distance (2 dof) beyond which a window is no free flight
    spin_prior_std: float  # [1/s] of the configured spin_damping (0: it is not learned)
    spin_gate: float     # squared distance (1 dof) beyond which a window's spin is not the table's
    friction_prior_std: float = 0.0  # [m/s^2] of the configured friction_surface (0: it is not learned)
    marker_offset_prior_std: float = 0.0  # [m] per axis, of the configured marker_offset (0: it is not learned)

    @classmethod
    def from_params(cls, params: Mapping[str, Any]) -> "AccelerationSettings":
        p = "acceleration_adaptation."
        return cls(*(params[p + name] for name in ("enabled", "prior_std", "damping_prior_std", "field_std", "window",
                                                    "min_frames", "min_speed", "gate", "spin_prior_std",
                                                    "spin_gate", "friction_prior_std", "marker_offset_prior_std")))


class AccelerationAdaptation:
    """Gaussian estimate of the table acceleration g = (gx, gy) [m/s^2], the damping d [1/s], the
    surface friction mu_s [m/s^2] and the marker offset o [m] (puck frame) from free-flight windows: each
    window's acceleration a at velocity v, fitted to its positions taken back to the centre by the offset
    known so far o', is ``g - d v - mu_s v/|v| + M (o - o')`` (eq. 3.1 with the table acceleration; ``M``
    the fit's sensitivity to the offset, :func:`~.marker_offset.offset_sensitivity`), linear in (gx, gy,
    d, mu_s, ox, oy); what a window's positions leave once its parabola is projected out adds the offset's
    own equations (:func:`~.marker_offset.offset_normal_equations`). Fitting d too keeps a wrong configured
    damping out of g when the shots share a direction (a human's); fitting mu_s keeps a constant
    deceleration out of d, which would otherwise take it as d + mu_s / |v| at the session's typical speed
    and mispredict faster and slower pucks. With ``friction_prior_std`` 0, mu_s stays as configured; with
    ``marker_offset_prior_std`` 0, so does the offset (``offset``, the configured one)."""

    def __init__(self, base: PuckParams, settings: AccelerationSettings,
                 offset: tuple[float, float] = (0.0, 0.0)) -> None:
        self.settings, self.friction = settings, base.friction_surface
        self.learns_friction = settings.friction_prior_std > 0.0
        self.learns_offset = settings.marker_offset_prior_std > 0.0
        self.windows = 0  # windows learned from
        self.fits = 0     # fits learned from (a window's provisional one, then its whole one)
        self.offset_windows = 0  # windows whose own offset equations were learned from
        self._provisional: tuple[np.ndarray, np.ndarray] | None = None  # the window in progress's first fit
        stds = [settings.prior_std] * 2 + [settings.damping_prior_std]
        prior = [*base.table_acceleration, base.damping]
        if self.learns_friction:
            stds.append(settings.friction_prior_std)
            prior.append(base.friction_surface)
        self._offset_at = len(stds)  # where (ox, oy) sit in the parameters, when learned
        if self.learns_offset:
            stds += [settings.marker_offset_prior_std] * 2
            prior += [float(offset[0]), float(offset[1])]
        self._configured_offset = (float(offset[0]), float(offset[1]))
        self._information = np.diag(np.array(stds) ** -2.0)
        self._weighted = self._information @ np.array(prior)
        self._set_mean(np.array(prior))

    def _set_mean(self, mean: np.ndarray) -> None:
        """Keep the posterior mean and the offset it gives (read every frame) from the last change."""
        self._mean_now = mean
        o = mean[self._offset_at:] if self.learns_offset else self._configured_offset
        self._offset_now = (float(o[0]), float(o[1]))

    def _solve(self) -> np.ndarray:
        """The posterior mean; where its mu_s is below 0 (a friction cannot push), the mean of the rest
        given mu_s = 0, so that the others do not keep what they took on to balance a negative mu_s."""
        mean = np.linalg.solve(self._information, self._weighted)
        if self.learns_friction and mean[3] < 0.0:
            rest = [i for i in range(len(mean)) if i != 3]
            mean[rest] = np.linalg.solve(self._information[np.ix_(rest, rest)], self._weighted[rest])
            mean[3] = 0.0
        return mean

    @property
    def offset(self) -> tuple[float, float]:
        """[m] The marker offset (puck frame): learned, or the configured one."""
        return self._offset_now

    @property
    def offset_covariance(self) -> np.ndarray:
        """[m^2] The learned offset's covariance (2, 2)."""
        at = self._offset_at
        return np.linalg.inv(self._information)[at:at + 2, at:at + 2]

    def observe_offset(self, times, pivots: np.ndarray) -> bool:
        """Learn the offset's own equations from one whole window's pivot positions (n, 3: x, y, theta)
        [m, m, rad] at ``times`` [s], what its parabolas leave (a puck that hardly turns adds next to
        nothing); False without a fit. The caller passes only windows :meth:`observe` accepted."""
        if not self.learns_offset or len(times) < 5:
            return False
        normal, rhs, variance = offset_normal_equations(times, pivots)
        if variance <= 0.0:
            return False
        at = self._offset_at
        self._information[at:at + 2, at:at + 2] += normal / variance
        self._weighted[at:at + 2] += rhs / variance
        self._set_mean(self._solve())
        self.offset_windows += 1
        return True

    def offset_report(self) -> dict:
        """Windows, value and std [m] of the offset (puck frame)."""
        std = np.sqrt(np.diag(self.offset_covariance))
        return {"windows": self.offset_windows, "value": list(self.offset), "std": [float(std[0]), float(std[1])]}

    def flight_law(self) -> dict[str, Any]:
        """The learned ``table_acceleration`` (gx, gy) [m/s^2], ``damping`` [1/s] (never below 0) and
        ``friction_surface`` [m/s^2] (learned, never below 0, or the configured one), from one solve."""
        m = self._mean_now
        return {"table_acceleration": (float(m[0]), float(m[1])), "damping": max(0.0, float(m[2])),
                "friction_surface": float(m[3]) if self.learns_friction else self.friction}

    @property
    def value(self) -> tuple[float, float]:
        """[m/s^2] The learned table acceleration (gx, gy) (:meth:`flight_law`)."""
        return self.flight_law()["table_acceleration"]

    @property
    def damping(self) -> float:
        """[1/s] The learned damping (:meth:`flight_law`)."""
        return self.flight_law()["damping"]

    @property
    def friction_surface(self) -> float:
        """[m/s^2] mu_s: learned, or the configured one (:meth:`flight_law`)."""
        return self.flight_law()["friction_surface"]

    @property
    def std(self) -> tuple[float, ...]:
        """Standard errors of (gx, gy, d[, mu_s])."""
        return tuple(float(s) for s in np.sqrt(np.diag(np.linalg.inv(self._information)))[:self._offset_at])

    def observe(self, acceleration: np.ndarray, variance: np.ndarray, velocity: np.ndarray,
                provisional: bool = False, sensitivity: np.ndarray | None = None) -> bool:
        """Learn from one window's acceleration [m/s^2] (x, y), its fit's variance per axis and the
        velocity [m/s], the fit made with the offset known now (``sensitivity``: the fit's acceleration
        per metre of offset, 2 x 2, when the offset is learned); False when it is left out: farther than
        ``gate`` from what is known (a hand or a mallet moved the puck, not the table). A ``provisional``
        fit (the window's first part, for an early estimate) is replaced by the window's next fit; one
        that is left out leaves the provisional fit learned."""
        earlier, self._provisional = self._provisional, None
        if earlier is not None:
            self._add(earlier, -1.0)
        vx, vy = velocity.tolist()
        speed = math.hypot(vx, vy)
        if self.learns_friction:
            known = np.zeros(2)
            design = np.array([[1.0, 0.0, -vx, -vx / speed], [0.0, 1.0, -vy, -vy / speed]])
        else:
            known = -self.friction * np.array([vx, vy]) / speed  # the configured surface friction's part
            design = np.array([[1.0, 0.0, -vx], [0.0, 1.0, -vy]])
        noise = np.asarray(variance, float) + self.settings.field_std ** 2
        unexplained = np.asarray(acceleration, float) - known
        if self.learns_offset:  # a = ... + M (o - o'): M o' back on the measured side
            m = np.zeros((2, 2)) if sensitivity is None else np.asarray(sensitivity, float)
            design = np.hstack([design, m])
            unexplained = unexplained + m @ np.array(self.offset)
        innovation = unexplained - design @ self._mean_now
        spread = np.diag(noise) + design @ np.linalg.inv(self._information) @ design.T
        if float(innovation @ np.linalg.solve(spread, innovation)) > self.settings.gate:
            if earlier is not None:
                self._add(earlier, 1.0)
            return False
        weight = np.diag(1.0 / noise)
        contribution = (design.T @ weight @ design, design.T @ weight @ unexplained)
        self._add(contribution, 1.0)
        self.windows += int(earlier is None)
        self.fits += 1
        self._provisional = contribution if provisional else None
        return True

    def commit(self) -> None:
        """The window in progress ended without a further fit: its provisional fit stays learned."""
        self._provisional = None

    def _add(self, contribution: tuple[np.ndarray, np.ndarray], sign: float) -> None:
        self._information = self._information + sign * contribution[0]
        self._weighted = self._weighted + sign * contribution[1]
        self._set_mean(self._solve())

    def report(self) -> dict:
        """Windows, value and std [m/s^2] of g, the damping and its std [1/s], the surface friction and its
        std [m/s^2] (std None when it is not learned)."""
        sx, sy, sd, *sf = self.std
        law = self.flight_law()
        return {"windows": self.windows, "value": list(law["table_acceleration"]), "std": [sx, sy],
                "damping": law["damping"], "damping_std": sd,
                "friction_surface": law["friction_surface"], "friction_surface_std": sf[0] if sf else None}


def quadratic_fit(times: list[float], poses: list) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Acceleration (x, y) [m/s^2], its variance per axis (from the residuals) and the velocity at the
    window's middle [m/s] of a quadratic fit of the poses' positions over ``times`` [s]
    (:func:`~air_hockey_agent.core.identification.local_fit.fit_positions`); None with fewer than four
    poses."""
    times = np.asarray(times, float)
    fit = fit_positions(times, np.asarray(poses, float)[:, :2], 0.5 * (times[0] + times[-1]), 2)
    return None if fit is None else (fit.a, fit.a_gain * fit.variance, fit.v)
