"""The process noise of free flight learned online from the filter's own consistency (issue #13 item 2:
noise by regime identified from data, checked by the NIS).

Q's velocity terms (``process_noise``) stand for the accelerations the model lacks on a real table. The
configured ones come from the lab's 0.03 m/s^2 across the track (issue #13), but a table's air film and
its random accelerations are its own: on the test bed with three times its air film or random
accelerations the configured Q left the filter overconfident (NIS medians 2.66 and 2.61, 1.5 % of the
poses rejected), on harsher ones more so (2.85-3.06, 4.6-5.7 %; README "Puck model"); on the model's own
data, where nothing is missing, it is more than needed. With R learned from the poses themselves (:mod:`.noise_adaptation`), what
is left of a filter's inconsistency in free flight is Q's: the position innovation's squared Mahalanobis
distance (2 dof, the gate's) of a consistent filter has the median ``2 ln 2``.

Every ``block`` free-flight frames (gated frames, fused or rejected, of a puck at ``regime_rest_speed`` or
faster, clear of the rims by ``clear_of_rims`` seconds of its travel either way: an impact has its own
noise, ``impact_noise``) the block's median ``m`` scales Q's velocity terms by ``(m / 2 ln 2)^gain``, the
scale kept within [``min_scale``, ``max_scale``] of the configured ones. A median, so that glitches and
heavy-tailed frames (rejected or not) move it little; a partial step, as a block's median of 120 frames
scatters by about 13 %. Where the marker noise dominates the innovation the NIS hardly depends on Q, so
on a calm table the scale wanders (with the NIS and the errors unchanged); where the table adds
acceleration the NIS does depend on it and the scale rises. The velocity terms alone: the position,
angle and spin terms are the thesis's (sec. 4.4), and the rest regime keeps ``process_noise_rest``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

CONSISTENT_MEDIAN = 2.0 * math.log(2.0)  # median of a chi-square with 2 degrees of freedom
VELOCITY = (2, 3)                         # Q's terms the scale acts on (vx, vy)


@dataclass(frozen=True)
class ProcessNoiseAdaptationSettings:
    """``process_noise_adaptation.*`` in config/tracker.yaml (sources there; the defaults here are its values)."""

    block: int = 120             # free-flight frames per update
    gain: float = 0.5            # [-] exponent of a block's correction
    min_scale: float = 0.1       # [-] of the configured velocity terms
    max_scale: float = 100.0     # [-]
    clear_of_rims: float = 0.1   # [s] of travel from the rims a free-flight frame keeps, either way

    @classmethod
    def from_params(cls, params: Mapping[str, Any],
                    prefix: str = "process_noise_adaptation.") -> "ProcessNoiseAdaptationSettings":
        return cls(**{name: params[prefix + name] for name in cls.__dataclass_fields__})


class ProcessNoiseAdaptation:
    """The scale of Q's velocity terms (module docstring) learned from free-flight frames' position NIS."""

    def __init__(self, settings: ProcessNoiseAdaptationSettings, configured: np.ndarray, frame_period: float) -> None:
        self.settings, self.configured = settings, np.array(configured, float)
        self.frame_period = float(frame_period)
        self.scale, self.blocks = 1.0, 0
        self._block: list[float] = []

    @classmethod
    def from_params(cls, params: Mapping[str, Any]) -> "ProcessNoiseAdaptation | None":
        """None unless ``process_noise_adaptation.enabled``; the configured Q is ``process_noise``."""
        if not params["process_noise_adaptation.enabled"]:
            return None
        return cls(ProcessNoiseAdaptationSettings.from_params(params), np.diag(params["process_noise"]),
                   1.0 / float(params["frequency"]))

    def observe(self, distance: float) -> np.ndarray | None:
        """Take a free-flight frame's position innovation distance (squared Mahalanobis, 2 dof). Returns
        the new Q (6x6, per model step) when a block completes, else None."""
        self._block.append(float(distance))
        if len(self._block) < self.settings.block:
            return None
        median = float(np.median(self._block))
        self._block.clear()
        self.blocks += 1
        step = (max(median, 1e-9) / CONSISTENT_MEDIAN) ** self.settings.gain
        self.scale = min(self.settings.max_scale, max(self.settings.min_scale, self.scale * step))
        return self.q()

    def q(self) -> np.ndarray:
        """Q per model step with the learned scale on its velocity terms."""
        q = self.configured.copy()
        for i in VELOCITY:
            q[i, i] *= self.scale
        return q

    def report(self) -> dict:
        """JSON-ready: blocks learned from, the scale, and the velocity terms as an acceleration std [m/s^2]
        per axis (the random walk's std per step over the step, as config/tracker.yaml states Q)."""
        q = self.q()
        return {"blocks": self.blocks, "scale": self.scale,
                "acceleration_std_m_s2": math.sqrt(q[VELOCITY[0], VELOCITY[0]]) / self.frame_period}


def describe_process_noise(report: dict) -> str:
    """A :meth:`ProcessNoiseAdaptation.report` in words."""
    return (f"flight process noise {report['acceleration_std_m_s2']:.4f} m/s^2 ({report['scale']:.2f} x the "
            f"configured) from {report['blocks']} block{'' if report['blocks'] == 1 else 's'}")
