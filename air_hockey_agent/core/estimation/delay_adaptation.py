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

Each rim's own mean of ``depth + s |vn|`` is where its impacts meet at no speed, from the model's line
(:meth:`DelayAdaptation.rim_offsets`): a table pose or size millimetres off shows there (opposite rims
apart, or alike), which the tracker cannot correct online but says (``sysid --method split`` moves them:
``table_geometry``).
"""
from __future__ import annotations

import math
from collections import defaultdict

from air_hockey_agent.core.identification.local_fit import beyond_noise
from air_hockey_agent.core.table import WALL_NAMES


class DelayAdaptation:
    """Least-squares estimate of the impact delay s [s] from watched rim impacts, with a prior."""

    def __init__(self, configured: float, prior_impacts: float, max_delay: float, offset_warning: float = math.inf,
                 offset_significance: float = 3.0) -> None:
        self.configured, self.prior_impacts, self.max_delay = configured, prior_impacts, max_delay
        self.offset_warning, self.offset_significance = offset_warning, offset_significance
        # per rim id: impacts, sums of depth, |vn|, depth^2, depth |vn|, vn^2 (the delay's fit is their total)
        self._rims: dict = defaultdict(lambda: [0, 0.0, 0.0, 0.0, 0.0, 0.0])

    @property
    def impacts(self) -> int:
        """Impacts learned from, on every rim."""
        return int(sum(sums[0] for sums in self._rims.values()))

    @property
    def value(self) -> float:
        """The estimate [s]: the configured delay until an impact is seen, never below zero."""
        impacts = self.impacts
        if impacts == 0:
            return self.configured
        depth_speed = sum(sums[4] for sums in self._rims.values())  # sum of depth |vn| [m^2/s]
        speed2 = sum(sums[5] for sums in self._rims.values())       # sum of vn^2 [m^2/s^2]
        prior = self.prior_impacts * speed2 / impacts  # prior_impacts impacts of the mean vn^2
        return max(0.0, (prior * self.configured - depth_speed) / (prior + speed2))

    def observe(self, depth: float, speed: float, rim: int) -> bool:
        """Learn from one impact on ``rim`` (its id) whose paths met ``depth`` [m] from the rim line at normal
        speed ``speed`` [m/s]; False when it is left out (no speed, or beyond ``max_delay``)."""
        if speed <= 0.0 or abs(depth) > self.max_delay * speed:
            return False
        sums = self._rims[rim]
        for k, term in enumerate((1.0, depth, speed, depth * depth, depth * speed, speed * speed)):
            sums[k] += term
        return True

    def rim_offsets(self) -> dict[int, tuple[float, float, int]]:
        """Per rim id: (offset [m], its standard error [m], impacts): the mean of ``depth + s |vn|`` at the
        current delay s, where the rim's impacts meet at no speed (> 0: inside the model's line); the error
        from their scatter (infinite below two impacts)."""
        s, out = self.value, {}
        for rim, (n, d, v, dd, dv, vv) in sorted(self._rims.items()):
            mean = (d + s * v) / n
            square = (dd + 2.0 * s * dv + s * s * vv) / n
            spread = math.sqrt(max(square - mean * mean, 0.0) * n / (n - 1)) if n > 1 else math.inf
            out[rim] = (mean, spread / math.sqrt(n), int(n))
        return out

    def report(self) -> dict:
        """Impacts, the delay [s], each rim's offset (:meth:`rim_offsets`) by rim name, and the names of the
        rims that are off (farther than ``offset_warning`` [m] and ``offset_significance`` errors)."""
        offsets = {WALL_NAMES[rim]: {"offset_m": o, "std_m": e, "impacts": n} for rim, (o, e, n) in
                   self.rim_offsets().items()}
        off = [name for name, o in offsets.items()
               if beyond_noise(o["offset_m"], o["std_m"], self.offset_significance, self.offset_warning)]
        return {"impacts": self.impacts, "value": self.value, "rim_offsets": offsets, "rims_off": off}
