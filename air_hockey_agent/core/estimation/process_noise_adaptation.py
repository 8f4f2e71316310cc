"""The process noise by regime (flight, rest, rim impacts) learned online from the filter's own
consistency (issue #13 item 2: noise by regime identified from data, checked by the NIS).

Q's velocity terms (``process_noise``) stand for the accelerations the model lacks on a real table. The
configured ones come from the lab's 0.03 m/s^2 across the track (issue #13), but a table's air film and
its random accelerations are its own: on the test bed with three times its air film or random
accelerations the configured Q left the filter overconfident (NIS medians 2.66 and 2.61, 1.5 % of the
poses rejected), on harsher ones more so (2.85-3.06, 4.6-5.7 %; README "Puck model"); on the model's own
data, where nothing is missing, it is more than needed. At rest (``process_noise_rest``) a puck on a
tilted table creeps; after a rim impact (``impact_noise``, ``impact_contact_time``: a guess for real
rims) the learned rim law leaves less than the configured noise allows (impact NIS 0.8 on the test bed
and MuJoCo). With R learned from the poses themselves (:mod:`.noise_adaptation`), what is left of a
filter's inconsistency in a regime is that regime's process noise: the position innovation's squared
Mahalanobis distance (2 dof, the gate's) of a consistent filter has the median ``2 ln 2``.

The filter gives each gated frame's distance (fused or rejected) to its regime: *impact* for the
``impact_frames`` gated frames after a step the model put a rim impact in, *rest* for a puck slower than
``regime_rest_speed``, *flight* for one clear of the rims by ``clear_of_rims`` seconds of its travel
either way (the rest of a rim's neighbourhood to none). Every ``block`` frames of a regime
(``impact_block`` for impacts) the block's median ``m`` scales that regime's configured noise by
``(m / 2 ln 2)^gain``, the scale kept within [``min_scale``, ``max_scale``]: in flight and at rest Q's
velocity terms, after an impact both impact terms' standard deviations by its square root. A median, so
that glitches and heavy-tailed frames (rejected or not) move it little; a partial step, as a block's
median of 120 frames scatters by about 13 %. Where the marker noise dominates the innovation the NIS
hardly depends on Q, so on a calm table the flight scale wanders (with the NIS and the errors
unchanged); where the table adds acceleration it does depend on it and the scale rises. The position,
angle and spin terms of Q are the thesis's (sec. 4.4) and stay. Every frame's NIS is computed with the
noise learned from the frames before it, so ``eval-prediction``'s NIS by regime checks the learning on
data it had not yet seen.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

CONSISTENT_MEDIAN = 2.0 * math.log(2.0)  # median of a chi-square with 2 degrees of freedom
VELOCITY = (2, 3)                         # Q's terms the flight and rest scales act on (vx, vy)
REGIMES = ("flight", "rest", "impact")


@dataclass(frozen=True)
class ProcessNoiseAdaptationSettings:
    """``process_noise_adaptation.*`` in config/tracker.yaml (sources there; the defaults here are its values)."""

    block: int = 120             # free-flight (and resting) frames per update
    impact_block: int = 40       # impact-regime frames per update
    impact_frames: int = 2       # gated frames after a model impact that belong to the impact regime
    gain: float = 0.5            # [-] exponent of a block's correction
    min_scale: float = 0.01      # [-] of the configured noise (variance)
    max_scale: float = 100.0     # [-]
    clear_of_rims: float = 0.1   # [s] of travel from the rims a free-flight frame keeps, either way

    @classmethod
    def from_params(cls, params: Mapping[str, Any],
                    prefix: str = "process_noise_adaptation.") -> "ProcessNoiseAdaptationSettings":
        return cls(**{name: params[prefix + name] for name in cls.__dataclass_fields__})


class _Scale:
    """One regime's scale of its configured noise, moved by each full block's median distance."""

    def __init__(self, block: int) -> None:
        self.block, self.scale, self.blocks = block, 1.0, 0
        self._distances: list[float] = []

    def observe(self, distance: float, settings: ProcessNoiseAdaptationSettings) -> bool:
        self._distances.append(float(distance))
        if len(self._distances) < self.block:
            return False
        median = float(np.median(self._distances))
        self._distances.clear()
        self.blocks += 1
        step = (max(median, 1e-9) / CONSISTENT_MEDIAN) ** settings.gain
        self.scale = min(settings.max_scale, max(settings.min_scale, self.scale * step))
        return True


class ProcessNoiseAdaptation:
    """The scales of the configured process noise by regime (module docstring), learned from the gated
    frames' position NIS: Q's velocity terms in flight (``process_noise``) and at rest
    (``process_noise_rest``), and a rim impact's covariance (``impact_noise``, ``impact_contact_time``:
    both standard deviations by the scale's square root)."""

    def __init__(self, settings: ProcessNoiseAdaptationSettings, q: np.ndarray, q_rest: np.ndarray,
                 impact_noise: float, impact_contact_time: float, frame_period: float) -> None:
        self.settings = settings
        self.configured = {"flight": np.array(q, float), "rest": np.array(q_rest, float)}
        self.configured_impact = (float(impact_noise), float(impact_contact_time))
        self.frame_period = float(frame_period)
        self.scales = {regime: _Scale(settings.impact_block if regime == "impact" else settings.block)
                       for regime in REGIMES}

    @classmethod
    def from_params(cls, params: Mapping[str, Any]) -> "ProcessNoiseAdaptation | None":
        """None unless ``process_noise_adaptation.enabled``; the configured noise is ``process_noise``,
        ``process_noise_rest``, ``impact_noise`` and ``impact_contact_time``."""
        if not params["process_noise_adaptation.enabled"]:
            return None
        return cls(ProcessNoiseAdaptationSettings.from_params(params), np.diag(params["process_noise"]),
                   np.diag(params["process_noise_rest"]), params["impact_noise"], params["impact_contact_time"],
                   1.0 / float(params["frequency"]))

    def observe(self, regime: str, distance: float) -> bool:
        """Take a gated frame's position innovation distance (squared Mahalanobis, 2 dof) in ``regime``
        (one of ``REGIMES``). True when that regime's noise changed (read :meth:`q` and :meth:`impact`)."""
        return self.scales[regime].observe(distance, self.settings)

    def q(self, regime: str = "flight") -> np.ndarray:
        """Q per model step of ``regime`` (flight or rest) with its learned scale on the velocity terms."""
        q = self.configured[regime].copy()
        for i in VELOCITY:
            q[i, i] *= self.scales[regime].scale
        return q

    def impact(self) -> tuple[float, float]:
        """(``impact_noise`` [-], ``impact_contact_time`` [s]) with the impact regime's learned scale."""
        factor = math.sqrt(self.scales["impact"].scale)
        return self.configured_impact[0] * factor, self.configured_impact[1] * factor

    def report(self) -> dict:
        """JSON-ready, by regime: blocks learned from and the scale; for flight and rest the velocity terms
        as an acceleration std [m/s^2] per axis (the random walk's std per step over the step, as
        config/tracker.yaml states Q), for impacts the resulting ``impact_noise`` and
        ``impact_contact_time`` [s]."""
        out = {}
        for regime in ("flight", "rest"):
            q = self.q(regime)
            out[regime] = {"blocks": self.scales[regime].blocks, "scale": self.scales[regime].scale,
                           "acceleration_std_m_s2": math.sqrt(q[VELOCITY[0], VELOCITY[0]]) / self.frame_period}
        noise, contact = self.impact()
        out["impact"] = {"blocks": self.scales["impact"].blocks, "scale": self.scales["impact"].scale,
                         "impact_noise": noise, "impact_contact_time_s": contact}
        return out


def _blocks(n: int) -> str:
    return f"{n} block{'' if n == 1 else 's'}"


def describe_process_noise(report: dict) -> str:
    """A :meth:`ProcessNoiseAdaptation.report` in words (the regimes learned from; empty when none is)."""
    parts = [f"{regime} {report[regime]['acceleration_std_m_s2']:.4f} m/s^2 (x{report[regime]['scale']:.2f}, "
             f"{_blocks(report[regime]['blocks'])})" for regime in ("flight", "rest") if report[regime]["blocks"]]
    impact = report["impact"]
    if impact["blocks"]:
        parts.append(f"rim impacts {impact['impact_noise']:.3f} of the velocity and "
                     f"{impact['impact_contact_time_s'] * 1e3:.2f} ms of travel (x{impact['scale']:.2f}, "
                     f"{_blocks(impact['blocks'])})")
    return "process noise " + ", ".join(parts) if parts else ""
