"""The rim law learned online from the impacts the tracker sees (issue #13 item 3: a table's own rims).

The configured rim law (restitution falling with the normal speed, Routh's tangential impulse capped by
Coulomb's, thesis eq. 3.2-3.3) is a prior: no constant law fits every table (another engine's rims
return 0.96-0.67 of the normal speed and push far less along themselves than Coulomb's bound, issue #13),
and a rim law that is off dominates the prediction error of every path through a rim. So the tracker
scales the configured law by three numbers it estimates from each rim impact it observes:

* ``restitution_scale`` k and ``fall_scale`` f: the configured restitution is its slow impacts' value e
  less a fall with the normal speed, ``e(|vn|) = e - fall(|vn|)`` (``fall = min(slope max(|vn| - knee, 0),
  e - e_min)``); the learned one is ``k e - f fall(|vn|)`` (e scaled by k and kept <= 1, slope by f, the
  floor where the fall ends). The outgoing normal speed ``(k e - f fall) |vn|`` is linear in (k, f); with
  k = f the whole law is scaled, and a table whose rims lose no more at speed (the pybullet table's
  constant 0.947) has f = 0. Impacts slower than the knee say nothing of f, which then stays at 1;
* ``tangential_scale`` s: the tangential impulse is s times the configured law's (Routh's sticking
  impulse with ``(1 + beta)`` scaled by s, Coulomb's bound with ``mu_rim`` scaled by s: the same impacts
  stick and slide).

Each is a least-squares estimate with the configured law (scales 1) as a prior worth ``prior_impacts``
impacts of the mean size seen that the law predicts exactly. An impact is observed in its rim's frame (:mod:`~air_hockey_agent.core.puck.impact`: ``b``
along the rim, ``n`` into the table): the filter's incoming state just before it, and the outgoing
velocity and spin from line fits over the measured poses of the ``window`` after it (the flight law's
acceleration removed; seed 003's model-based batch estimate), not the filter's post-impact state, which
the law being learned has biased.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np

from air_hockey_agent.core.identification.local_fit import fit_angle_rate, line_fit
from air_hockey_agent.core.puck.impact import rim_impact
from air_hockey_agent.core.puck.model import PuckParams
from air_hockey_agent.core.table import WALL_NORMALS, TableGeometry

RimState = tuple[float, float, float]  # (vb, vn, omega) [m/s, m/s, rad/s] in a rim's frame
PRIOR_FLOOR = 1e-9  # [-] of the level's information added to the fall's: solvable before a fall is seen


@dataclass(frozen=True)
class AdaptationSettings:
    """``rim_adaptation.*`` in ``config/tracker.yaml``."""

    enabled: bool
    prior_impacts: float      # [-] weight of the configured law, in impacts
    window: float             # [s] measured poses after an impact that its outgoing fit uses
    min_frames: int           # fused poses the window needs
    min_normal_speed: float   # [m/s] slower impacts are not observed (their ratios are noise)
    max_scale: float          # [-] an impact whose ratios fall beyond [1 / max_scale, max_scale] is no rim's
    max_incoming_uncertainty: float  # [-] velocity std before the impact, as a fraction of the speed, at most

    @classmethod
    def from_params(cls, params: Mapping[str, Any]) -> "AdaptationSettings":
        p = "rim_adaptation."
        return cls(*(params[p + name] for name in ("enabled", "prior_impacts", "window", "min_frames",
                                                    "min_normal_speed", "max_scale", "max_incoming_uncertainty")))


def rim_frame(wall: int, vx: float, vy: float) -> tuple[float, float]:
    """Velocity (vx, vy) [m/s] in rim ``wall``'s frame: (vb along the rim, vn into the table)."""
    nx, ny = WALL_NORMALS[wall]
    return ny * vx - nx * vy, nx * vx + ny * vy


def fall_regressors(base: PuckParams, incoming_normal_speed: float) -> tuple[float, float]:
    """``(e |vn|, fall(|vn|) |vn|)`` [m/s] of ``base``'s restitution law (module docstring): the outgoing
    normal speed is ``k`` times the first less ``f`` times the second. A law without a fall (no slope, or a
    floor at or above e, which holds e at the floor) has the whole outgoing speed in the first."""
    speed = abs(incoming_normal_speed)
    e, floor = base.restitution, base.restitution_min
    if base.restitution_slope <= 0.0 or floor >= e:
        return max(e, floor) * speed, 0.0
    fall = min(base.restitution_slope * max(speed - base.restitution_knee, 0.0), e - floor)
    return e * speed, fall * speed


def scaled_params(base: PuckParams, restitution_scale: float, tangential_scale: float,
                  fall_scale: float | None = None) -> PuckParams:
    """``base`` with its rim law scaled (module docstring; ``fall_scale`` None: the restitution's fall
    scaled with it, the whole law by ``restitution_scale``); restitutions kept in [0, 1], beta in [-1, 1]."""
    k, s = restitution_scale, tangential_scale
    f = k if fall_scale is None else max(0.0, fall_scale)  # a restitution rising with speed is no rim's
    e = base.restitution
    if base.restitution_slope <= 0.0 or base.restitution_min >= e:  # no fall: the level alone
        floor, slope = base.restitution_min * k, base.restitution_slope
    else:
        floor, slope = k * e - f * (e - base.restitution_min), base.restitution_slope * f
    return base.with_values(restitution=min(1.0, e * k), restitution_min=min(1.0, max(0.0, floor)),
                            restitution_slope=slope, friction_rim=base.friction_rim * s,
                            tangential_restitution=min(1.0, max(-1.0, s * (1.0 + base.tangential_restitution) - 1.0)))


class RimAdaptation:
    """Running estimate of the scales of ``base``'s rim law from observed impacts."""

    def __init__(self, base: PuckParams, table: TableGeometry, settings: AdaptationSettings) -> None:
        self.base, self.settings = base, settings
        self.radius = table.puck_radius
        self.impacts = 0
        # normal: sums of x x^T and x o over impacts, x = (e |vn|, -fall |vn|), o the observed outgoing
        # normal speed [m^2/s^2]; tangential: of the law's impulse per mass times the observed, and squared
        self._normal_xx, self._normal_xo = np.zeros((2, 2)), np.zeros(2)
        self._kf = (1.0, 1.0)  # (k, f) of the impacts so far (:meth:`_restitution`)
        self._tangential = [0.0, 0.0]

    @property
    def restitution_scale(self) -> float:
        """k: least squares of the observed outgoing normal speeds on the law's two parts (the faster
        impacts, whose errors move a prediction most, weigh most; split sysid's objective), with the prior."""
        return self._kf[0]

    @property
    def fall_scale(self) -> float:
        """f: the restitution's fall with the normal speed, scaled (1 until faster impacts than the knee)."""
        return self._kf[1]

    def _restitution(self) -> tuple[float, float]:
        """(k, f): least squares with the prior of :meth:`_scale`, ``prior_impacts`` impacts of the mean
        ``x x^T`` seen that the law predicts exactly (the estimate moves from (1, 1) toward the impacts'
        own fit as they outnumber it); a fall no impact has shown (none faster than the knee) stays at 1.
        Kept in [1 / max_scale, max_scale] and [0, max_scale]."""
        if self.impacts == 0:
            return 1.0, 1.0
        xx, xo = self._normal_xx, self._normal_xo
        prior = self.settings.prior_impacts / self.impacts * xx
        prior[1, 1] += PRIOR_FLOOR * xx[0, 0]  # solvable before the fall is seen
        k, f = np.linalg.solve(prior + xx, prior.sum(axis=1) + xo)
        bound = self.settings.max_scale
        return float(min(max(k, 1.0 / bound), bound)), float(min(max(f, 0.0), bound))

    @property
    def tangential_scale(self) -> float:
        """Least squares of the observed tangential impulses on the law's, with the prior."""
        return self._scale(self._tangential)

    def _scale(self, sums: list) -> float:
        """``(prior + sum a b) / (prior + sum a^2)``: the prior is ``prior_impacts`` impacts of the mean size
        seen that the law predicts exactly (1 before any)."""
        cross, square = sums
        if square <= 0.0:
            return 1.0
        prior = self.settings.prior_impacts * square / self.impacts
        return (prior + cross) / (prior + square)

    def params(self) -> PuckParams:
        """The rim law learned so far (``base`` itself before any impact)."""
        if self.impacts == 0:
            return self.base
        k, f = self._kf
        return scaled_params(self.base, k, self.tangential_scale, f)

    def report(self) -> dict:
        """The law learned so far, for reports: impacts learned from, both scales and the scaled rim
        parameters (names as in ``config/tracker.yaml``)."""
        p = self.params()
        k, f = self._kf
        return {"impacts": self.impacts, "restitution_scale": k, "fall_scale": f,
                "tangential_scale": self.tangential_scale,
                "params": {n: getattr(p, n) for n in ("restitution", "restitution_slope", "restitution_min",
                                                      "friction_rim", "tangential_restitution")}}

    def observe(self, before: RimState, after: RimState) -> bool:
        """Learn from one impact (incoming ``before``, vn < 0; outgoing ``after``); False when it is left
        out (too slow, not leaving the rim, or a ratio beyond ``max_scale``: a hit, not the rim)."""
        vb, vn, omega = before
        if -vn < self.settings.min_normal_speed or after[1] <= 0.0:
            return False
        configured = self._impact(self.base, before).vn  # the configured law's outgoing normal speed [m/s]
        ratio = after[1] / configured
        k, f = self._kf
        law = scaled_params(self.base, k, 1.0, f)
        model = self._impact(law, before).vb - vb  # the law's tangential impulse per mass [m/s], e learned so far
        seen = (after[0] - vb, 0.5 * self.radius * (after[2] - omega))  # from vb, and from the spin
        bound = self.settings.max_scale
        if not 1.0 / bound <= ratio <= bound:
            return False
        if abs(model) > 1e-9 and not -bound <= (seen[0] + seen[1]) / (2.0 * model) <= bound:
            return False
        self.impacts += 1
        level, fall = fall_regressors(self.base, vn)
        x = np.array([level, -fall])
        self._normal_xx += np.outer(x, x)
        self._normal_xo += x * after[1]
        self._kf = self._restitution()
        self._tangential[0] += model * (seen[0] + seen[1])
        self._tangential[1] += 2.0 * model * model
        return True

    def _impact(self, law: PuckParams, before: RimState):
        return rim_impact(*before, self.radius, law.restitution, law.friction_rim, law.restitution_slope,
                          law.restitution_min, law.tangential_restitution, law.restitution_knee)


def describe(report: dict) -> str:
    """A learned law's :meth:`RimAdaptation.report` in words, for logs and tables."""
    impacts = report["impacts"]
    return (f"from {impacts} impact{'' if impacts == 1 else 's'}: restitution x{report['restitution_scale']:.3f} "
            f"(its fall with speed x{report['fall_scale']:.3f}), tangential impulse x{report['tangential_scale']:.3f}")


def outgoing_fit(times: Sequence[float], poses: Sequence[Sequence[float]], t_impact: float,
                 acceleration) -> tuple[float, float, float] | None:
    """Velocity (vx, vy) [m/s] and spin [rad/s] just after an impact at ``t_impact`` [s] from the measured
    poses (x, y, theta) at ``times`` after it: line fits (:mod:`~air_hockey_agent.core.identification.
    local_fit`, as split sysid's impact fits), the flight law's acceleration ``acceleration(v) -> a``
    [m/s^2] removed from the positions; None with fewer than three poses."""
    times, z = np.asarray(times, float), np.asarray(poses, float)
    fit = line_fit(times, z[:, :2], t_impact, acceleration)
    omega = fit_angle_rate(times, z[:, 2])
    if fit is None or omega is None:
        return None
    return float(fit.v[0]), float(fit.v[1]), omega


def flight_acceleration(params: PuckParams):
    """The flight law's acceleration ``v -> a`` [m/s, m/s^2] (eq. 3.1 and the table acceleration)."""
    d, mu = params.damping, params.friction_surface
    g = np.asarray(params.table_acceleration, float)

    def acceleration(v: np.ndarray) -> np.ndarray:
        speed = float(np.hypot(v[0], v[1]))
        return g - d * v - (mu * v / speed if speed > 0.0 else 0.0)
    return acceleration
