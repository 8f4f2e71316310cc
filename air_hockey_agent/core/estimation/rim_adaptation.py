"""The rim law learned online from the impacts the tracker sees (issue #13 item 3: a table's own rims).

The configured rim law (restitution falling with the normal speed, Routh's tangential impulse capped by
Coulomb's, thesis eq. 3.2-3.3) is a prior: no constant law fits every table (another engine's rims
return 0.96-0.67 of the normal speed and push far less along themselves than Coulomb's bound, issue #13),
and a rim law that is off dominates the prediction error of every path through a rim. So the tracker
scales the configured law by numbers it estimates from each rim impact it observes:

* ``restitution_scale`` k and ``fall_scale`` f: the configured restitution is its slow impacts' value e
  less a fall with the normal speed, ``e(|vn|) = e - fall(|vn|)`` (``fall = min(slope max(|vn| - knee, 0),
  e - e_min)``); the learned one is ``k e - f fall(|vn|)`` (e scaled by k and kept <= 1, slope by f, the
  floor where the fall ends). The outgoing normal speed ``(k e - f fall) |vn|`` is linear in (k, f); with
  k = f the whole law is scaled, and a table whose rims lose no more at speed (the pybullet table's
  constant 0.947) has f = 0. Impacts slower than the knee say nothing of f, which then stays at 1. The
  knee itself (where the fall starts) is chosen among ``rim_adaptation.knee_count`` knees from 0 to
  ``knee_max`` and the configured one: (k, f) are fitted for each, and the knee whose fit leaves the
  least sum of squares (the prior's pseudo-impacts included) wins, another knee than the configured one
  only by more than the Bayesian information criterion's price of one more parameter (``ln n`` times the
  best fit's residual variance, n impacts): noise alone does not move it. So is the fall's width w, the
  normal speeds over which it runs from the knee to its floor (``fall = slope min(max(|vn| - knee, 0),
  w)``; configured: ``(e - e_min) / slope``), among ``fall_width_count`` widths up to ``fall_width_max``:
  a table whose restitution keeps falling past the configured floor's speed, or stops sooner, gets its
  own floor ``k e - f slope w``; a width other than the configured one pays BIC's price too;
* the tangential impulse, in one of three forms, whichever fits the impacts better (the configured
  form unless another beats it by BIC's price of a parameter, as the knee):

  - ``tangential_scale`` s: s times the configured law's (Routh's sticking impulse with ``(1 + beta)``
    scaled by s, Coulomb's bound with ``mu_rim`` scaled by s: the same impacts stick and slide);
  - ``stick_fraction`` q: q times Routh's sticking impulse ``-m c / 3`` on every impact (tangential
    restitution ``beta = q - 1``) with ``mu_rim`` raised to ``stick_friction_rim``, so Coulomb's bound
    no longer decides: soft rims whose impulse follows the contact point's slip, not the normal impulse
    (a MuJoCo table's rims return 0.45 of Routh's sticking impulse on every impact and stay far below
    Coulomb's bound: ``sim/mujoco_table.py``; issue #13's other engine pushed far less than Coulomb's);
  - ``friction_rim`` alone: Coulomb's bound with its own ``mu_rim``, chosen among ``friction_count``
    values from ``friction_min`` to ``friction_max`` (evenly in the logarithm) and the configured one,
    the sticking impulse as configured: rims that grip harder (or slip more) than the configured mu_rim
    (thesis table 5.3's 0.098) while sticking as Routh's impact does, which the first form cannot hold
    (it scales the sticking impulse with the bound).

Each is a least-squares estimate with the configured law (scales 1) as a prior worth ``prior_impacts``
impacts of the mean size seen that the law predicts exactly. An impact is observed in its rim's frame
(:mod:`~air_hockey_agent.core.puck.impact`: ``b`` along the rim, ``n`` into the table): the filter's
incoming state just before it, and the outgoing velocity and spin from line fits over the measured poses
of the ``window`` after it (the flight law's acceleration removed; seed 003's model-based batch
estimate), not the filter's post-impact state, which the law being learned has biased.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping, NamedTuple, Sequence

import numpy as np

from air_hockey_agent.core.identification.local_fit import fit_angle_rate, line_fit
from air_hockey_agent.core.puck.impact import rim_impact
from air_hockey_agent.core.puck.model import PuckParams
from air_hockey_agent.core.table import WALL_NORMALS, TableGeometry

RimState = tuple[float, float, float]  # (vb, vn, omega) [m/s, m/s, rad/s] in a rim's frame
TIE = 1e-9  # [-] of the sum of squares: knees (or tangential forms) whose fits differ by less are tied (rounding)
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
    knee_count: int = 0       # knees tried, evenly from 0 to knee_max (0: the configured knee only)
    knee_max: float = 0.0     # [m/s] the fastest knee tried
    stick_friction_rim: float = 1.0  # [-] mu_rim of a learned law in the stick-fraction form
    max_delay: float = 0.01   # [s] paths meeting farther from the rim than this times the speed: no rim's
    offset_warning: float = 0.001  # [m] a rim whose impacts meet farther from its line (and beyond ...
    offset_significance: float = 3.0  # [-] ... this many standard errors) is said to be off
    friction_count: int = 0    # rim friction values tried, evenly in the logarithm (0: not learned alone)
    friction_min: float = 0.01  # [-] the smallest mu_rim tried
    friction_max: float = 1.0  # [-] the largest
    fall_width_count: int = 0  # fall widths tried, evenly up to fall_width_max (0: the configured one only)
    fall_width_max: float = 0.0  # [m/s] the widest fall tried
    # [m/s] an impact whose two measures of the tangential impulse (from the tangential velocity and from
    # the spin) differ by more than this is left out: one of its fits is off
    max_impulse_disagreement: float = math.inf
    rederive_impacts: int = 0        # the first impacts derived again when the flight law moves (0: never)
    rederive_tolerance: float = 0.0  # [m/s^2] how far that law's acceleration moves first
    rederive_incoming: float = math.inf  # [m/s^2] ... and beyond which a line fit gives the incoming velocity

    @classmethod
    def from_params(cls, params: Mapping[str, Any]) -> "AdaptationSettings":
        p = "rim_adaptation."
        return cls(**{name: params[p + name] for name in cls.__dataclass_fields__})

    def knees(self, configured: float) -> np.ndarray:
        """The knees tried [m/s]: the configured one first, then ``knee_count`` from 0 to ``knee_max``."""
        grid = np.linspace(0.0, self.knee_max, self.knee_count) if self.knee_count > 1 else \
            np.zeros(self.knee_count)
        return _configured_first(configured, grid, 1e-9)

    def frictions(self, configured: float) -> np.ndarray:
        """The rim frictions mu_rim tried [-]: the configured one first, then ``friction_count`` evenly in
        the logarithm between ``friction_min`` and ``friction_max``, ascending."""
        grid = np.sort(np.geomspace(self.friction_min, self.friction_max, self.friction_count)) \
            if self.friction_count else np.zeros(0)
        return _configured_first(configured, grid, 1e-12)

    def widths(self, configured: float) -> np.ndarray:
        """The fall widths tried [m/s]: the configured one first, then ``fall_width_count`` evenly from
        ``fall_width_max / fall_width_count`` to ``fall_width_max``."""
        count = self.fall_width_count
        grid = np.linspace(self.fall_width_max / count, self.fall_width_max, count) if count else np.zeros(0)
        return _configured_first(configured, grid, 1e-9)


def _configured_first(configured: float, grid: np.ndarray, tolerance: float) -> np.ndarray:
    """The values a learning tries: ``configured`` first, then ``grid`` without the values within
    ``tolerance`` of it (tried once, as the configured one)."""
    return np.concatenate(([configured], grid[np.abs(grid - configured) > tolerance]))


def rim_frame(wall: int, vx: float, vy: float) -> tuple[float, float]:
    """Velocity (vx, vy) [m/s] in rim ``wall``'s frame: (vb along the rim, vn into the table)."""
    nx, ny = WALL_NORMALS[wall]
    return ny * vx - nx * vy, nx * vx + ny * vy


def _falls(law: PuckParams) -> bool:
    """Whether ``law``'s restitution falls with the normal speed (a slope, and a floor below e; a floor at
    or above e holds e at the floor)."""
    return law.restitution_slope > 0.0 and law.restitution_min < law.restitution


def fall_width(law: PuckParams) -> float:
    """[m/s] The normal speeds over which ``law``'s restitution falls from its knee to its floor (0
    without a fall)."""
    return (law.restitution - law.restitution_min) / law.restitution_slope if _falls(law) else 0.0


def fall_regressors(base: PuckParams, incoming_normal_speed: float, knee=None, width=None):
    """``(e |vn|, fall(|vn|) |vn|)`` [m/s] of ``base``'s restitution law (module docstring), its fall
    starting at ``knee`` [m/s] and running over ``width`` [m/s] of normal speed (None: the law's own;
    arrays of knees and widths give an array of falls): the outgoing normal speed is ``k`` times the first
    less ``f`` times the second. A law without a fall has the whole outgoing speed in the first."""
    speed = abs(incoming_normal_speed)
    e, floor = base.restitution, base.restitution_min
    knee = base.restitution_knee if knee is None else knee
    width = fall_width(base) if width is None else width
    if not _falls(base):
        return max(e, floor) * speed, np.zeros_like(np.asarray(knee) + np.asarray(width), dtype=float)
    fall = base.restitution_slope * np.minimum(np.maximum(speed - knee, 0.0), width)
    return e * speed, fall * speed


def scaled_params(base: PuckParams, restitution_scale: float, tangential_scale: float,
                  fall_scale: float | None = None, knee: float | None = None, width: float | None = None) -> PuckParams:
    """``base`` with its rim law scaled (module docstring; ``fall_scale`` None: the restitution's fall
    scaled with it, the whole law by ``restitution_scale``), its fall from ``knee`` [m/s] over ``width``
    [m/s] of normal speed (None: the law's own); restitutions kept in [0, 1], beta in [-1, 1], the
    tangential scale at 0 or above (a rim pushing the contact point's slip on is no rim: a few noisy
    impacts can fit a negative scale, which would make mu_rim negative)."""
    k, s = restitution_scale, max(0.0, tangential_scale)
    f = k if fall_scale is None else max(0.0, fall_scale)  # a restitution rising with speed is no rim's
    e = base.restitution
    if not _falls(base):  # the level alone
        floor, slope = base.restitution_min * k, base.restitution_slope
    else:
        width = fall_width(base) if width is None else width
        floor, slope = k * e - f * base.restitution_slope * width, base.restitution_slope * f
    if knee is not None and slope > 0.0:
        base = base.with_values(restitution_knee=knee)
    return base.with_values(restitution=min(1.0, e * k), restitution_min=min(1.0, max(0.0, floor)),
                            restitution_slope=slope, friction_rim=base.friction_rim * s,
                            tangential_restitution=min(1.0, max(-1.0, s * (1.0 + base.tangential_restitution) - 1.0)))


class RimAdaptation:
    """Running estimate of the scales of ``base``'s rim law from observed impacts."""

    def __init__(self, base: PuckParams, table: TableGeometry, settings: AdaptationSettings) -> None:
        self.base, self.settings = base, settings
        self.radius = table.puck_radius
        self.impacts = 0
        # normal, per (knee, width) tried: sums over impacts of x x^T, x o and x c, x = (e |vn|, -fall |vn|)
        # with that fall, o the observed outgoing normal speed, c the configured law's [m^2/s^2]; and of
        # o^2, c^2. Tangential: of the law's impulse per mass times the observed, and squared. The
        # configured (knee, width) first.
        knees, widths = settings.knees(base.restitution_knee), settings.widths(fall_width(base))
        self.knees, self.widths = np.repeat(knees, len(widths)), np.tile(widths, len(knees))
        self._freedom = (self.knees != knees[0]).astype(float) + (self.widths != widths[0])  # BIC parameters
        self._fitted = 2 + int(len(knees) > 1) + int(len(widths) > 1)  # k, f and the grids' dimensions
        self._xx, self._xo, self._xc = np.zeros((len(self.knees), 2, 2)), np.zeros((len(self.knees), 2)), \
            np.zeros((len(self.knees), 2))
        self._oo = self._cc = 0.0
        self._fit = (1.0, 1.0, base.restitution_knee, widths[0])  # (k, f, knee, width) (:meth:`_restitution`)
        # tangential, over impacts: the law's impulse per mass a [m/s] (configured form) and Routh's sticking
        # one x = -c / 3 (stick-fraction form), seen = (from vb, from the spin): sums of a (seen0 + seen1),
        # 2 a^2; of x (seen0 + seen1), 2 x^2, 2 x a (the prior: the configured law's impulses); seen0^2 + seen1^2
        self._tangential = [0.0, 0.0]
        self._stick = [0.0, 0.0, 0.0]
        self._seen_square = 0.0
        # friction form, per mu_rim tried: sums of the impulse y (seen0 + seen1), 2 y^2, 2 y a; and of 2 a^2
        self.frictions = settings.frictions(base.friction_rim)
        self._friction = np.zeros((3, len(self.frictions)))
        self._law_square = 0.0
        self._chosen_friction = 0  # index into frictions of the friction form's fit
        self._refined_friction = float(base.friction_rim)
        self._form = "scaled"      # the tangential form taken: "scaled", "stick fraction" or "friction"

    @property
    def restitution_scale(self) -> float:
        """k: least squares of the observed outgoing normal speeds on the law's two parts (the faster
        impacts, whose errors move a prediction most, weigh most; split sysid's objective), with the prior."""
        return self._fit[0]

    @property
    def fall_scale(self) -> float:
        """f: the restitution's fall with the normal speed, scaled (1 until faster impacts than the knee)."""
        return self._fit[1]

    @property
    def knee(self) -> float:
        """[m/s] the normal speed from which the restitution falls: of the knees tried, the one whose
        (k, f) fits best (the configured one until another fits better)."""
        return self._fit[2]

    @property
    def width(self) -> float:
        """[m/s] the normal speeds over which the restitution falls to its floor: of the widths tried, the
        one whose (k, f) fits best (the configured one until another fits better)."""
        return self._fit[3]

    def _restitution(self) -> tuple[float, float, float, float]:
        """(k, f, knee, width): for each (knee, width) tried, least squares of the observed outgoing normal
        speeds and of ``prior_impacts`` pseudo-impacts of the mean impact seen that the configured law
        predicts exactly (the estimate moves from the configured law toward the impacts' own fit as they
        outnumber it); the pair with the least sum of squares wins, a knee and a width other than the
        configured ones each paying BIC's ``ln n`` residual variances for being chosen. A fall no impact
        has shown (none faster than the knee) stays at 1. k and f kept in [1 / max_scale, max_scale] and
        [0, max_scale]."""
        if self.impacts == 0:
            return self._fit
        w = self.settings.prior_impacts / self.impacts
        b0, b1 = (self._xo + w * self._xc).T                      # (pairs,) each
        s00, s01, s11 = ((1.0 + w) * self._xx[:, i, j] for i, j in ((0, 0), (0, 1), (1, 1)))
        ridge = PRIOR_FLOOR * s00                                 # f = 1 until the fall is seen: solvable
        b1 = b1 + ridge
        a11 = s11 + ridge
        det = s00 * a11 - s01 * s01                               # the 2x2 normal equations in closed form
        k_all, f_all = (a11 * b0 - s01 * b1) / det, (s00 * b1 - s01 * b0) / det
        quad = s00 * k_all * k_all + 2.0 * s01 * k_all * f_all + s11 * f_all * f_all
        cost = self._oo + w * self._cc - 2.0 * (k_all * b0 + f_all * b1) + quad
        variance = max(cost.min(), 0.0) / max(self.impacts - self._fitted, 1)  # per impact, of the best fit
        cost += np.log(self.impacts) * variance * self._freedom   # BIC: a knee, a width, each one more parameter
        # ties (fits no impact tells apart: all knees above the fastest, say) go to the one nearest the configured
        tied = np.flatnonzero(cost <= cost.min() + TIE * (self._oo + w * self._cc))
        distance = np.abs(self.knees[tied] - self.knees[0]) + np.abs(self.widths[tied] - self.widths[0])
        best = int(tied[np.argmin(distance)])
        bound = self.settings.max_scale
        k, f = k_all[best], f_all[best]
        return (float(min(max(k, 1.0 / bound), bound)), float(min(max(f, 0.0), bound)), float(self.knees[best]),
                float(self.widths[best]))

    @property
    def tangential_scale(self) -> float:
        """Least squares of the observed tangential impulses on the law's, with the prior."""
        return self._scale(self._tangential)

    @property
    def stick_fraction(self) -> float:
        """q: least squares of the observed tangential impulses on Routh's sticking impulse, with
        ``prior_impacts`` pseudo-impacts of the configured law's impulses at the impacts seen; in [0, 2]."""
        cross, square, prior = self._stick
        if square <= 0.0:
            return 1.0 + self.base.tangential_restitution
        w = self.settings.prior_impacts / self.impacts
        return min(max((cross + w * prior) / ((1.0 + w) * square), 0.0), 2.0)

    @property
    def stick_form(self) -> bool:
        """True when the stick-fraction form fits the impacts better than the configured law scaled, by
        more than BIC's ``ln n`` residual variances (n impacts)."""
        return self._form == "stick fraction"

    @property
    def tangential_form(self) -> str:
        """The tangential form taken: "scaled" (the configured), "stick fraction" or "friction"."""
        return self._form

    @property
    def friction_rim(self) -> float:
        """[-] mu_rim of the friction form's fit: of the values tried, the one whose impulses with the
        configured sticking impulse fit best, with ``prior_impacts`` pseudo-impacts of the configured
        law's impulses (the configured one until another fits better), refined between its neighbours
        on the grid by the parabola through the three sums of squares (in the logarithm of mu_rim)."""
        return self._refined_friction

    def _friction_fit(self) -> tuple[int, float]:
        """Index of the mu_rim tried whose impulses leave the least sum of squares against the impacts and
        the prior's pseudo-impacts (ties, values no impact tells apart as when none slid, go to the one
        nearest the configured in the logarithm), and the refined mu_rim (:attr:`friction_rim`)."""
        cross, square, prior = self._friction
        w = self.settings.prior_impacts / self.impacts
        cost = -2.0 * cross + square + w * (square - 2.0 * prior)  # + seen^2 + w a^2, alike for all
        tied = np.flatnonzero(cost <= cost.min() + TIE * (self._seen_square + w * self._law_square))
        best = int(tied[np.argmin(np.abs(np.log(self.frictions[tied] / self.frictions[0])))])
        return best, self._refine(cost, best)

    def _refine(self, cost: np.ndarray, best: int) -> float:
        """mu_rim at the vertex of the parabola through the sums of squares of ``best`` and its neighbours
        on the grid (the values after the configured one, ascending), in the logarithm of mu_rim and within
        half-way to either neighbour; the value tried itself for the configured one, at the grid's ends,
        or where the sums do not curve upward."""
        if not 2 <= best <= len(self.frictions) - 2:
            return float(self.frictions[best])
        x, y = np.log(self.frictions[best - 1:best + 2]), cost[best - 1:best + 2]
        slopes = np.diff(y) / np.diff(x)
        curvature = (slopes[1] - slopes[0]) / (x[2] - x[0])  # half the parabola's second derivative
        if curvature <= 0.0:
            return float(self.frictions[best])
        vertex = 0.5 * (x[0] + x[1]) - slopes[0] / (2.0 * curvature)
        return float(np.exp(min(max(vertex, 0.5 * (x[0] + x[1])), 0.5 * (x[1] + x[2]))))

    def _choose_form(self) -> str:
        """The tangential form whose fit leaves the least sum of squares of the observed impulses; another
        than the configured ("scaled") only by more than BIC's ``ln n`` residual variances (n impacts)."""
        s, q, j = self.tangential_scale, self.stick_fraction, self._chosen_friction
        (cross_a, square_a), (cross_x, square_x, _) = self._tangential, self._stick
        sums = {"scaled": self._seen_square - 2.0 * s * cross_a + s * s * square_a,
                "stick fraction": self._seen_square - 2.0 * q * cross_x + q * q * square_x,
                "friction": self._seen_square - 2.0 * self._friction[0, j] + self._friction[1, j]}
        variance = max(min(sums.values()), 0.0) / max(2 * self.impacts - 1, 1)
        price = np.log(self.impacts) * variance
        other = min(("stick fraction", "friction"), key=lambda form: sums[form])
        # ties (all fit, as one impact does) keep the configured form
        return other if sums[other] + price < sums["scaled"] - TIE * self._seen_square else "scaled"

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
        k, f, knee, width = self._fit
        if self._form == "scaled":
            return scaled_params(self.base, k, self.tangential_scale, f, knee, width)
        law = scaled_params(self.base, k, 1.0, f, knee, width)
        if self._form == "friction":
            return law.with_values(friction_rim=self.friction_rim)
        return law.with_values(friction_rim=max(law.friction_rim, self.settings.stick_friction_rim),
                               tangential_restitution=self.stick_fraction - 1.0)

    def report(self) -> dict:
        """The law learned so far, for reports: impacts learned from, both scales and the scaled rim
        parameters (names as in ``config/tracker.yaml``)."""
        p = self.params()
        k, f, knee, width = self._fit
        return {"impacts": self.impacts, "restitution_scale": k, "fall_scale": f, "knee": knee, "fall_width": width,
                "tangential_scale": self.tangential_scale, "stick_fraction": self.stick_fraction,
                "tangential_form": self._form, "friction_rim": self.friction_rim,
                "params": {n: getattr(p, n) for n in ("restitution", "restitution_knee", "restitution_slope",
                                                      "restitution_min", "friction_rim", "tangential_restitution")}}

    def observe(self, before: RimState, after: RimState) -> bool:
        """Learn from one impact (incoming ``before``, vn < 0; outgoing ``after``); False when it is left
        out (too slow, not leaving the rim, a normal speed beyond ``max_scale`` times the law's or a
        tangential impulse, from vb or from the spin, beyond ``max_scale`` times the larger of either
        form's at scale 1: a hit, not the rim; or the two measures of its tangential impulse, from vb and
        from the spin, apart by more than ``max_impulse_disagreement``: one contact's impulse moves both
        alike, so one of the fits is off)."""
        vb, vn, omega = before
        if -vn < self.settings.min_normal_speed or after[1] <= 0.0:
            return False
        configured = self._impact(self.base, before).vn  # the configured law's outgoing normal speed [m/s]
        ratio = after[1] / configured
        k, f, knee, width = self._fit
        law = scaled_params(self.base, k, 1.0, f, knee, width)
        outgoing = self._impact(law, before)  # the law's impact, e learned so far, tangential law configured
        model = outgoing.vb - vb  # its tangential impulse per mass [m/s]
        seen = (after[0] - vb, 0.5 * self.radius * (after[2] - omega))  # from vb, and from the spin
        stick = -(vb + self.radius * omega) / 3.0  # Routh's sticking impulse per mass [m/s]
        bound = self.settings.max_scale
        if not 1.0 / bound <= ratio <= bound:
            return False
        largest = max(abs(model), abs(stick))  # of either form's impulse at scale 1
        if largest > 1e-9 and max(abs(seen[0]), abs(seen[1])) > bound * largest:
            return False
        if abs(seen[0] - seen[1]) > self.settings.max_impulse_disagreement:
            return False
        self.impacts += 1
        x = self._regressors(vn)
        self._xx += x[:, :, None] * x[:, None, :]
        self._xo += x * after[1]
        self._xc += x * configured
        self._oo += after[1] * after[1]
        self._cc += configured * configured
        self._fit = self._restitution()
        self._tangential[0] += model * (seen[0] + seen[1])
        self._tangential[1] += 2.0 * model * model
        self._stick[0] += stick * (seen[0] + seen[1])
        self._stick[1] += 2.0 * stick * stick
        self._stick[2] += 2.0 * stick * model
        self._seen_square += seen[0] * seen[0] + seen[1] * seen[1]
        impulses = self._friction_impulses(law, before, outgoing.vn / -vn)
        self._friction += (impulses * (seen[0] + seen[1]), 2.0 * impulses * impulses, 2.0 * impulses * model)
        self._law_square += 2.0 * model * model
        self._chosen_friction, self._refined_friction = self._friction_fit()
        self._form = self._choose_form()
        return True

    def _friction_impulses(self, law: PuckParams, before: RimState, e: float) -> np.ndarray:
        """(frictions,): the tangential impulse per mass [m/s] of ``law`` with each mu_rim tried, at this
        impact's restitution ``e``: Routh's sticking impulse, capped by Coulomb's bound mu (1 + e) |vn|
        (:func:`~air_hockey_agent.core.puck.impact.rim_impact`'s two branches)."""
        vb, vn, omega = before
        slip = vb + self.radius * omega
        sticking = (1.0 + law.tangential_restitution) * abs(slip) / 3.0
        return -math.copysign(1.0, slip) * np.minimum(sticking, self.frictions * (1.0 + e) * abs(vn))

    def _regressors(self, vn: float) -> np.ndarray:
        """(pairs, 2): x = (e |vn|, -fall |vn|) with the fall of each (knee, width) tried."""
        level, fall = fall_regressors(self.base, vn, self.knees, self.widths)
        return np.column_stack((np.full(len(self.knees), level), -fall))

    def _impact(self, law: PuckParams, before: RimState):
        return rim_impact(*before, self.radius, law.restitution, law.friction_rim, law.restitution_slope,
                          law.restitution_min, law.tangential_restitution, law.restitution_knee)


def describe(report: dict) -> str:
    """A learned law's :meth:`RimAdaptation.report` in words, for logs and tables."""
    impacts = report["impacts"]
    tangential = {"stick fraction": f"{report['stick_fraction']:.3f} of Routh's sticking one, uncapped",
                  "friction": f"Routh's capped by Coulomb's bound with mu_rim {report['friction_rim']:.3f}",
                  "scaled": f"x{report['tangential_scale']:.3f}"}[report["tangential_form"]]
    return (f"from {impacts} impact{'' if impacts == 1 else 's'}: restitution x{report['restitution_scale']:.3f} "
            f"(its fall with speed x{report['fall_scale']:.3f} from {report['knee']:.2f} m/s over "
            f"{report['fall_width']:.2f} m/s), tangential impulse "
            f"{tangential}")


class Outgoing(NamedTuple):
    """The outgoing path of an impact, at the impact's time."""

    vx: float             # [m/s]
    vy: float
    omega: float          # [rad/s]
    position: np.ndarray  # (x, y) [m] of the fitted line (beyond the rim line for a compliant rim)


def outgoing_fit(times: Sequence[float], poses: Sequence[Sequence[float]], t_impact: float,
                 acceleration, spin_damping: float = 0.0) -> Outgoing | None:
    """Velocity (vx, vy) [m/s], spin [rad/s] and the path's position just after an impact at ``t_impact``
    [s] from the measured poses (x, y, theta) at ``times`` after it: line fits (:mod:`~air_hockey_agent.core.
    identification.local_fit`, as split sysid's impact fits), the flight law's acceleration
    ``acceleration(v) -> a`` [m/s^2] removed from the positions, the spin's decay ``spin_damping`` [1/s]
    from the angles'; None with fewer than three poses."""
    times, z = np.asarray(times, float), np.asarray(poses, float)
    fit = line_fit(times, z[:, :2], t_impact, acceleration)
    omega = fit_angle_rate(times, z[:, 2], t_impact, spin_damping)
    if fit is None or omega is None:
        return None
    return Outgoing(float(fit.v[0]), float(fit.v[1]), omega, np.asarray(fit.p, float))
