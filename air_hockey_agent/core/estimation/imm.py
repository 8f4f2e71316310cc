"""Multiple-model filter for the puck (issue #13 item 2, seed 004's ball motion modes).

Seed 004 tracks a ball with discrete motion modes (free, bounced, kicked/grabbed), a Kalman filter per
mode. Here the modes are the puck's: **free** flight, a **rim** impact whose rebound is less certain than
the model's (``imm.rim_impact_noise`` instead of ``impact_noise``), and a **contact** with a mallet or a
hand, a velocity change of about ``imm.contact_speed`` within the frame (white-noise acceleration over
the step: velocity variance ``c^2``, position ``c^2 dt^2 / 3``). All modes share the model
(:class:`~air_hockey_agent.core.puck.model.PuckModel`), so their predicted means are one and they differ
in covariance only.

The estimator is the interacting multiple model filter (IMM, Blom and Bar-Shalom 1988; Bar-Shalom
et al., "Estimation with Applications to Tracking and Navigation", sec. 11.6.6): each mode carries its
own mean and covariance; before each frame they are mixed with the probabilities of a Markov chain
(leaving a mode with ``imm.switch_probability`` per frame), each mode predicts with its own noise and
fuses the measurement with its own gain, and the modes' probabilities are weighted by their measurement
likelihoods. The filter's ``x`` and ``P`` are the moment-matched mixture, so every other part of
:class:`~.ekf.PuckEKF` (gates, re-acquisition, services, predictions) works on it unchanged; where that
code sets ``x`` and ``P`` itself (a restart) the modes restart from them. The gate asks whether *any*
mode explains the frame: the innovation is gated with the mode it fits best, so a hit the contact mode
expects is fused, not rejected; the NIS reported is that of the mode the prior makes most likely. (Carrying one merged Gaussian instead,
GPB1, was tried first: the contact mode's covariance then leaks into every frame's velocity, and the
1.0 s error on a pybullet bag tripled.)
"""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from air_hockey_agent.core.estimation.ekf import _MEASURED_BLOCK, MEASURED, SINGLE_STEP_LIMIT, PuckEKF
from air_hockey_agent.core.estimation.hand_regime import white_noise_acceleration
from air_hockey_agent.core.puck.model import wrap_angle
from air_hockey_agent.core.puck.prediction import with_impact_noise

MODES = ("free", "rim", "contact")
_FREE, _RIM, _CONTACT = range(3)


class PuckIMM(PuckEKF):
    """IMM filter over MODES (module docstring); ``mode_probabilities`` after each frame."""

    def __post_init__(self) -> None:
        super().__post_init__()
        self._restart_modes()

    def _restart_modes(self) -> None:
        """Every mode at the filter's (x, P), the probabilities at the free mode's row of the chain."""
        n = len(MODES)
        self.mode_probabilities = self._transition()[_FREE].copy()
        self._xs = [self.x.copy() for _ in range(n)]
        self._ps = [self.P.copy() for _ in range(n)]
        self._innovations: list = []  # per mode (y, S) of the frame being fused (_innovation_and_covariance)

    def reset(self, state: Sequence[float] | None = None, stamp: float | None = None) -> None:
        super().reset(state, stamp)
        self._restart_modes()

    def _initialise_from_pending(self) -> None:
        super()._initialise_from_pending()
        self._restart_modes()

    def _restart_angle(self, angle: float) -> None:
        super()._restart_angle(angle)
        self._state_replaced()

    def _state_replaced(self) -> None:
        probabilities = self.mode_probabilities  # the modes restart from the mixture, their weights stay
        self._restart_modes()
        self.mode_probabilities = probabilities

    def _transition(self) -> np.ndarray:
        """Markov matrix: row i holds the probabilities of the next frame's modes after mode i."""
        p = self.settings.imm_switch_probability
        n = len(MODES)
        return np.full((n, n), p / (n - 1)) + np.eye(n) * (1.0 - p - p / (n - 1))

    def _contact_noise(self, dt: float) -> np.ndarray:
        """Process noise [6x6] of a contact within a step of ``dt`` [s]: white-noise acceleration with a
        velocity variance c^2 (position c^2 dt^2/3, cross term c^2 dt/2), spin and angle likewise: density
        c^2 / dt."""
        speed, spin = self.settings.imm_contact_speed, self.settings.imm_contact_spin
        return white_noise_acceleration((speed * speed / dt, speed * speed / dt, spin * spin / dt), dt)

    def _mode_noise(self, mode: int, res, dt: float) -> np.ndarray | float:
        """What mode ``mode`` adds to the common process noise in a step ``res`` of ``dt`` [s]: an impact's
        noise (the rim mode's larger), and for the contact mode its velocity change."""
        ratio = self.settings.imm_rim_impact_noise if mode == _RIM else self.settings.impact_noise
        self._impacts_met(res.impacts)
        extra = with_impact_noise(0.0, res.state, res.impacts, ratio, self.settings.impact_contact_time)
        return extra + self._contact_noise(dt) if mode == _CONTACT else extra

    def _mixed(self) -> tuple[np.ndarray, list, list]:
        """Prior mode probabilities and each mode's mixed starting mean and covariance."""
        chain = self._transition()
        prior = chain.T @ self.mode_probabilities
        xs, ps = [], []
        for j in range(len(MODES)):
            weights = chain[:, j] * self.mode_probabilities / prior[j]
            xs_j, ps_j = _mixture(weights, self._xs, self._ps, self._xs[j])
            xs.append(xs_j)
            ps.append(ps_j)
        return prior, xs, ps

    def predict_to(self, t: float) -> None:
        dt = t - self.stamp
        if dt <= 0.0:
            return
        if dt > SINGLE_STEP_LIMIT * self.settings.dt:
            super().predict_to(t)  # a long gap: the mixture's fast prediction, the modes restart from it
            probabilities = self._transition().T @ self.mode_probabilities
            self._restart_modes()
            self.mode_probabilities = probabilities
            return
        prior, xs, ps = self._mixed()
        for j in range(len(MODES)):
            q = self._step_noise(xs[j], dt)
            res = self.model.step(xs[j], dt)
            self._xs[j] = res.state
            self._ps[j] = res.jacobian @ ps[j] @ res.jacobian.T + q + self._mode_noise(j, res, dt)
        self.mode_probabilities = prior
        self.x, self.P = _mixture(prior, self._xs, self._ps, self._xs[_FREE])
        self.stamp = t

    def _gate_and_update(self, t: float, z: np.ndarray) -> int:
        nis = self._likely_mode_nis(z)
        flags = super()._gate_and_update(t, z)
        self.last_nis = nis
        return flags

    def _likely_mode_nis(self, z: np.ndarray) -> float:
        """NIS of the frame under the mode the prior makes most likely (free flight but for a frame or two
        after an impact or a hit). A mixture's moment-matched covariance is no test of consistency: the
        rare contact mode widens it (its velocity std is metres per second), and a consistent filter's
        NIS against it falls far below the chi-square's (1.4-1.5 on the test bed where the EKF read 2.3)."""
        j = int(np.argmax(self.mode_probabilities))
        y = self.residual(z, self._xs[j])
        s = self._ps[j][_MEASURED_BLOCK] + self.settings.measurement_noise(math.hypot(self.x[2], self.x[3]))
        return float(y @ np.linalg.solve(s, y))

    def _innovation_and_covariance(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The innovation and covariance of the mode the measurement fits best (the gate's question); every
        mode's are kept for the update that follows."""
        r = self.settings.measurement_noise(math.hypot(self.x[2], self.x[3]))
        self._innovations = [(self.residual(z, x), p[_MEASURED_BLOCK] + r) for x, p in zip(self._xs, self._ps)]
        return min(self._innovations, key=lambda ys: float(ys[0] @ np.linalg.solve(ys[1], ys[0])))

    def _apply_update(self, y: np.ndarray, s_inv: np.ndarray, rows: Sequence[int] = MEASURED) -> None:
        """Each mode's Kalman update with its own innovation (the first ``len(rows)`` measured components:
        all three, or the position alone), the likelihoods, the mixture."""
        rows = list(rows)
        m = len(rows)
        weights = []
        for j, (y_full, s_full) in enumerate(self._innovations):
            y_j, s_j = y_full[:m], s_full[:m, :m]
            p_ht = self._ps[j][:, rows]
            gain = np.linalg.solve(s_j, p_ht.T).T
            self._xs[j] = self._xs[j] + gain @ y_j
            self._xs[j][4] = wrap_angle(self._xs[j][4])
            self._ps[j] = self._ps[j] - gain @ p_ht.T
            d2 = float(y_j @ np.linalg.solve(s_j, y_j))
            weights.append(self.mode_probabilities[j] * math.exp(-0.5 * d2)
                           / math.sqrt(np.linalg.det(2.0 * math.pi * s_j)))
        total = sum(weights)
        if total > 0.0 and math.isfinite(total):
            self.mode_probabilities = np.array(weights) / total
        self.x, self.P = _mixture(self.mode_probabilities, self._xs, self._ps, self._xs[_FREE])


def _mixture(weights, means: list, covariances: list, reference: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Moment-matched Gaussian of a weighted mixture (angles averaged as offsets from ``reference``)."""
    offsets = []
    for m in means:
        d = m - reference
        d[4] = wrap_angle(d[4])
        offsets.append(d)
    mean_offset = sum(w * d for w, d in zip(weights, offsets))
    mean = reference + mean_offset
    mean[4] = wrap_angle(mean[4])
    cov = sum(w * (c + np.outer(d - mean_offset, d - mean_offset)) for w, d, c in zip(weights, offsets, covariances))
    return mean, 0.5 * (cov + cov.T)
