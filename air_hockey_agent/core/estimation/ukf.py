"""Unscented and minimum-error-entropy unscented filters for the puck (issue #13 item 2, seed 001).

Both share everything with :class:`~.ekf.PuckEKF` but the two steps they replace (Stone Soup's
predictor/updater split, ``../shared/design/STYLE.md``): the same model (:class:`~air_hockey_agent.
core.puck.model.PuckModel`), the same gates, re-acquisition, impact noise and speed-dependent
measurement noise, so a comparison on the same bags isolates the estimator.

* :class:`PuckUKF` (``filter: ukf``) predicts with scaled sigma points (van der Merwe: ``alpha``,
  ``beta``, kappa 0) pushed through the model's step, so a state near a rim whose spread straddles the
  impact gets a covariance from both outcomes instead of one linearisation. A frame gap longer than
  1.5 model steps uses the EKF's linearised fast prediction. The measurement (x, y, theta) is linear in
  the state, so the unscented update is the Kalman update: inherited.
* :class:`PuckMEEUKF` (``filter: mee_ukf``) keeps that prediction and replaces the update by the
  minimum-error-entropy fixed point of seed 001 (Chen et al.'s MEE-KF, refs. [11, 12] there): the prior
  and the measurement are stacked as a regression ``D = W x + e`` whitened by the Cholesky factors of
  ``P`` and ``R``, and ``x`` maximises ``lam sum_i G(e_i) + (1 - lam) sum_ij G(e_i - e_j)`` with the
  Gaussian kernel ``G`` of bandwidth ``mee.kernel`` (in standard deviations). The first sum is a fiducial
  point at zero error (MEE with fiducial points, weight ``mee.fiducial``): the entropy term alone does not
  care where the errors are centred. Each iteration solves ``x = (W^T Phi W)^-1 W^T Phi D`` with the
  weights of the current errors; impulsive errors get small weights instead of pulling the estimate.
  The covariance is the Joseph form with the final equivalent gain (seed 001 eq. 30).
"""
from __future__ import annotations

import math

import numpy as np

from air_hockey_agent.core.estimation.ekf import MEASURED, SINGLE_STEP_LIMIT, PuckEKF
from air_hockey_agent.core.puck.model import wrap_angle

ANGLE = 4  # state index of theta (its differences are wrapped)


class PuckUKF(PuckEKF):
    """EKF with an unscented prediction (module docstring)."""

    def predict_to(self, t: float) -> None:
        dt = t - self.stamp
        if dt <= 0.0:
            return
        if dt > SINGLE_STEP_LIMIT * self.settings.dt:
            super().predict_to(t)  # a long gap: the linearised fast prediction
            return
        try:
            points, wm, wc = self._sigma_points()
        except np.linalg.LinAlgError:  # P lost definiteness to rounding: this step linearised
            super().predict_to(t)
            return
        stepped = [self.model.step(p, dt, with_jacobian=False) for p in points]
        centre = stepped[0].state
        deviations = np.array([s.state - centre for s in stepped])
        deviations[:, ANGLE] = [wrap_angle(a) for a in deviations[:, ANGLE]]
        mean_offset = wm @ deviations
        x = centre + mean_offset
        x[ANGLE] = wrap_angle(x[ANGLE])
        spread = deviations - mean_offset
        p = (spread.T * wc) @ spread + self._step_noise(points[0], dt)
        self.x = x
        self.P = self._with_impact_noise(0.5 * (p + p.T), x, stepped[0].impacts)
        self.stamp = t

    def _sigma_points(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """2n + 1 scaled sigma points of (x, P) and their mean and covariance weights."""
        n = len(self.x)
        alpha, beta = self.settings.ukf_alpha, self.settings.ukf_beta
        lam = alpha * alpha * n - n
        root = np.linalg.cholesky((n + lam) * self.P)
        points = np.vstack([self.x, self.x + root.T, self.x - root.T])
        wm = np.full(2 * n + 1, 0.5 / (n + lam))
        wc = wm.copy()
        wm[0] = lam / (n + lam)
        wc[0] = wm[0] + 1.0 - alpha * alpha + beta
        return points, wm, wc


class PuckMEEUKF(PuckUKF):
    """UKF with the minimum-error-entropy measurement update (module docstring)."""

    def _apply_update(self, y: np.ndarray, s_inv: np.ndarray, rows=MEASURED) -> None:
        rows = list(rows)
        m = len(rows)
        r = self.settings.measurement_noise(math.hypot(self.x[2], self.x[3]))[np.ix_(range(m), range(m))]
        prior = self.x
        z = prior[rows] + y  # the measurement, its angle unwrapped next to the prior's
        h = np.zeros((m, len(prior)))
        h[np.arange(m), rows] = 1.0
        try:
            bp_inv = np.linalg.inv(np.linalg.cholesky(self.P))
            br_inv = np.linalg.inv(np.linalg.cholesky(r))
        except np.linalg.LinAlgError:  # P lost definiteness to rounding: this update the Kalman one
            super()._apply_update(y, s_inv, rows)
            return
        w = np.vstack([bp_inv, br_inv @ h])
        d = np.concatenate([bp_inv @ prior, br_inv @ z])
        x = prior + self.P[:, rows] @ s_inv @ y  # start from the Kalman update
        for _ in range(self.settings.mee_max_iterations):
            phi = self._entropy_weights(d - w @ x)
            normal = w.T @ phi @ w
            new = np.linalg.solve(normal, w.T @ phi @ d)
            done = np.linalg.norm(new - x) <= 1e-9 * (1.0 + np.linalg.norm(x))
            x = new
            if done:
                break
        gain = np.linalg.solve(normal, w.T @ phi)[:, len(prior):] @ br_inv
        joseph = np.eye(len(prior)) - gain @ h
        p = joseph @ self.P @ joseph.T + gain @ r @ gain.T
        self.x = x
        self.x[ANGLE] = wrap_angle(self.x[ANGLE])
        self.P = 0.5 * (p + p.T)

    def _entropy_weights(self, errors: np.ndarray) -> np.ndarray:
        """Phi of the fixed point: lam diag(G(e_i)) + (1 - lam) 2 (Lambda - Psi) with Psi_ij = G(e_i - e_j)
        and Lambda its row sums (the graph Laplacian of the pairwise kernel)."""
        sigma2 = 2.0 * self.settings.mee_kernel ** 2
        lam = self.settings.mee_fiducial
        psi = np.exp(-np.subtract.outer(errors, errors) ** 2 / sigma2)
        laplacian = np.diag(psi.sum(axis=1)) - psi
        return lam * np.diag(np.exp(-errors ** 2 / sigma2)) + (1.0 - lam) * 2.0 * laplacian
