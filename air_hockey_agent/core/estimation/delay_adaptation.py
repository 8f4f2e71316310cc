"""A compliant rim's impact delay learned online (``impact_delay``; issue #13 item 3).

A rigid rim's paths before and after an impact meet on its line (the thesis's instantaneous impact); a
compliant rim holds the puck for a contact of some milliseconds, and they meet beyond it by about the
normal speed times half the contact (:mod:`~air_hockey_agent.core.puck.model`, ``impact_delay``). Each
impact the rim learning watches (:mod:`.table_learning`) gives the filter's incoming state at the frame
before it and a line fit of the fused poses after it; where the two paths meet, ``depth`` [m] from the
model's rim line (< 0 beyond it), at the incoming normal speed ``|vn|`` [m/s], is one observation of
``depth = -s |vn|``. The estimate of s is their least-squares slope with the configured ``impact_delay`` as
a prior worth ``prior_impacts`` impacts of the mean size seen (as the rim law's, :mod:`.rim_adaptation`),
never below 0. An impact whose paths meet farther from the line than ``max_delay`` times its normal speed,
either way, met a hand or a mallet, not the rim: left out. ``split`` sysid fits the same relation over a
recording (:func:`~air_hockey_agent.core.identification.impact_fit.fit_delay`).
"""
from __future__ import annotations


class DelayAdaptation:
    """Least-squares estimate of the impact delay s [s] from watched rim impacts, with a prior."""

    def __init__(self, configured: float, prior_impacts: float, max_delay: float) -> None:
        self.configured, self.prior_impacts, self.max_delay = configured, prior_impacts, max_delay
        self.impacts = 0
        self._depth_speed = 0.0  # sum of -depth |vn| [m^2/s]
        self._speed2 = 0.0       # sum of vn^2 [m^2/s^2]

    @property
    def value(self) -> float:
        """The estimate [s]: the configured delay until an impact is seen, never below zero."""
        if self.impacts == 0:
            return self.configured
        prior = self.prior_impacts * self._speed2 / self.impacts  # prior_impacts impacts of the mean vn^2
        return max(0.0, (prior * self.configured + self._depth_speed) / (prior + self._speed2))

    def observe(self, depth: float, speed: float) -> bool:
        """Learn from one impact whose paths met ``depth`` [m] from the rim line at normal speed ``speed``
        [m/s]; False when it is left out (no speed, or beyond ``max_delay``)."""
        if speed <= 0.0 or abs(depth) > self.max_delay * speed:
            return False
        self._depth_speed -= depth * speed
        self._speed2 += speed * speed
        self.impacts += 1
        return True

    def report(self) -> dict:
        return {"impacts": self.impacts, "value": self.value}
