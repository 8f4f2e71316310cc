"""The spin's decay learned online from free-flight windows (``spin_damping``; issue #13 item 3).

Thesis eq. 3.1 keeps the spin constant in flight; a real table's air film or felt damps it (a uniform
viscous film at the velocity's own rate d, :mod:`~air_hockey_agent.core.identification.spin_fit`), and a
spin the model keeps while the puck's slows shows in the angle's innovations. The free-flight windows of
:mod:`.table_learning` give each a quadratic through the unwrapped angles: the spin w and its rate of change
wdot at the window's middle. A decay ``wdot = -k w`` is a line through the origin; k is estimated as a
Gaussian mean, the configured ``spin_damping`` with std ``spin_prior_std`` as its prior and each window's
wdot with the variance its angles' noise gives (the configured angle noise, or the fit's residuals' when
larger: a few dozen residuals estimate a variance too loosely to be trusted below it). A window farther
than ``spin_gate`` (squared, 1 dof) from what is known was turned by a hand or a mallet, or its angles
glitched: left out.
"""
from __future__ import annotations

from air_hockey_agent.core.identification.local_fit import spin_quadratic


class SpinAdaptation:
    """Gaussian estimate of the spin damping k [1/s] from free-flight windows."""

    def __init__(self, configured: float, prior_std: float, gate: float, angle_variance: float) -> None:
        self.gate, self.angle_variance = gate, angle_variance  # [-], [rad^2]
        self.windows = 0
        self._information = prior_std ** -2  # [s^2]
        self._weighted = self._information * configured

    @property
    def value(self) -> float:
        """The estimate [1/s], never below zero (a spin that grows in flight is no table's)."""
        return max(0.0, self._weighted / self._information)

    @property
    def std(self) -> float:
        return self._information ** -0.5

    def observe(self, times, angles) -> bool:
        """Learn from one window's measured ``angles`` [rad] at ``times`` [s]; False when it is left out
        (too few angles, no spin, or beyond the gate)."""
        fit = spin_quadratic(times, angles)
        if fit is None or fit.spin == 0.0:
            return False
        noise = fit.gain * max(fit.variance, self.angle_variance)  # [rad^2/s^4] of wdot
        mean = self._weighted / self._information
        innovation = -fit.rate - mean * fit.spin
        if innovation * innovation > self.gate * (noise + fit.spin * fit.spin / self._information):
            return False
        self._information += fit.spin * fit.spin / noise
        self._weighted += fit.spin * -fit.rate / noise
        self.windows += 1
        return True

    def report(self) -> dict:
        return {"windows": self.windows, "value": self.value, "std": self.std}


def describe_spin(report: dict) -> str:
    """A :meth:`SpinAdaptation.report` in words."""
    n = report["windows"]
    return (f"spin damping {report['value']:.4f} +- {report['std']:.4f} 1/s from {n} free-flight "
            f"window{'' if n == 1 else 's'}")

