"""Rim-impact parameters from pre/post-impact fits (split identification, issue #13 item 5).

An impact is looked for where a recorded trajectory comes closest to a rim line (a local minimum of
the centre's distance from it, outside the goal mouths and away from the other rims). The frames just
before and just after it (one row either side of the closest one skipped) get a line fit each, with
the flight law's acceleration (:mod:`.flight_fit`) removed first; the impact time is where the two
lines' distances from the rim meet, so it does not depend on where the table's geometry puts the rim.
Both velocities and spins (angle lines) are read there, in the rim's frame (:mod:`~air_hockey_agent.
core.puck.impact`: ``b`` along the rim, ``n`` into the table).

* Restitution (speed-dependent, eq. 3.2-3.3 with ``e(vn) = max(e0 - slope max(|vn| - knee, 0), e_min)``):
  least squares of the outgoing normal speed ``e(vn) |vn|``, which is linear in ``(e0, slope)`` once the
  knee and the speed where the line meets its floor are chosen (a grid of both, then a simplex).
* Rim friction and tangential restitution: the Routh impact
  (:func:`~air_hockey_agent.core.puck.impact.rim_impact`) with the fitted restitution predicts the
  outgoing ``vb`` and ``r omega`` from the incoming state; ``mu_rim`` (the sliding impacts' Coulomb
  bound) and ``beta`` (how much of the slip a sticking impact removes) minimise their squared error
  [m^2/s^2] over all impacts: a grid over both bounds, then a bounded simplex from the best grid point
  (one of them alone: a grid and a bounded scalar search). Where the cost does not depend on a parameter
  (no sticking impact says anything about beta) it keeps its starting value.

Impacts whose fits are poor (another impact or a hit inside a window) or whose residual is an outlier
are dropped.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Mapping, Sequence

import numpy as np

from air_hockey_agent.core.identification.flight_fit import NoiseModel
from air_hockey_agent.core.identification.local_fit import (fit_angle_rate, line_fit, paths_meet, rows_in,
                                                            smooth_fits)
from air_hockey_agent.core.identification.preprocess import GridTrajectory
from air_hockey_agent.core.puck.impact import rim_impact
from air_hockey_agent.core.table import SHORT_WALLS, WALL_NORMALS, TableGeometry

RESTITUTION_NAMES = ("restitution", "restitution_slope", "restitution_min", "restitution_knee")
TANGENTIAL_NAMES = ("friction_rim", "tangential_restitution")
IMPACT_NAMES = RESTITUTION_NAMES + TANGENTIAL_NAMES
FRICTION_GRID = 201  # scalar search: grid points over the bounds before the local refinement
PAIR_GRID = 41       # both tangential parameters: grid points per parameter before the simplex
FLAT = 1e-9          # [-] grid costs within this share of the best are ties (the parameter is not seen)
KINK_GRID = 41      # the restitution's knee and floor speeds: grid points each before the simplex


@dataclass(frozen=True)
class ImpactSettings:
    """``split.impact_*`` in ``config/sysid.yaml``."""

    window: float             # [s] fitted before and after an impact
    min_frames: int           # measured rows each window needs
    approach_distance: float  # [m] a closest approach farther than this from the rim line is no impact
    contact_tolerance: float  # [m] the two lines must meet this close to the rim line
    min_normal_speed: float   # [m/s] slower impacts are left out (their restitution is noise)
    rim_margin: float         # [m] the windows' frames stay this far from the other rims
    outlier_factor: float     # [-] robust z / fit-quality factor beyond which an impact is dropped


@dataclass(frozen=True)
class ImpactObservation:
    """One rim impact in its rim's frame: incoming and outgoing (vb, vn [m/s], omega [rad/s])."""

    wall: int
    time: float            # [s] trajectory time of the impact
    before: tuple          # (vb, vn, omega), vn < 0
    after: tuple           # (vb, vn, omega), vn > 0
    fit_quality: float     # [-] worse window's residual RMS over the expected noise
    depth: float = 0.0     # [m] where the lines before and after meet, from the model's rim line (< 0: beyond it)
    along: float = 0.0     # [m] where along the rim, b . p with b = (n_y, -n_x) (0: the rim's middle)


@dataclass
class ImpactFit:
    values: dict           # IMPACT_NAMES -> value (fixed ones as given)
    impacts: int           # impacts in the final fits
    dropped: int           # impacts dropped (poor fit or outlier)
    rms_normal: float      # [m/s] residual RMS of the outgoing normal speed (the restitution fit's objective)
    rms_tangential: float  # [m/s] residual RMS of vb and r omega (the tangential fit's objective)
    radius: float          # [m] the puck's, with which the impacts were fitted
    used: list = field(default_factory=list)  # the impacts (ImpactObservation) of the final fits, for plots


def find_impacts(traj: GridTrajectory, table: TableGeometry, acceleration, noise: NoiseModel,
                 settings: ImpactSettings, spin_damping: float = 0.0) -> list[ImpactObservation]:
    """Rim impacts of one trajectory. ``acceleration(v) -> a`` [m/s^2] is the identified flight law,
    ``spin_damping`` [1/s] the spin's decay (the spins before and after are taken at the impact)."""
    z = traj.z
    rows = np.flatnonzero(~np.isnan(z[:, 0]))
    n_rows = max(3, int(round(settings.window / traj.dt)))
    found = []
    for wall, (nx, ny) in enumerate(WALL_NORMALS):
        distance = nx * z[rows, 0] + ny * z[rows, 1] + table.wall_offset(wall)
        for i in _closest_approaches(distance, settings.approach_distance):
            k = int(rows[i])
            if wall in SHORT_WALLS and abs(z[k, 1]) < table.goal_mouth + table.puck_radius:
                continue  # at a goal mouth: the puck may have entered the goal
            obs = _observe(traj, table, wall, k, n_rows, acceleration, noise, settings, spin_damping)
            if obs is not None:
                found.append(obs)
    return found


def _closest_approaches(distance: np.ndarray, limit: float) -> list[int]:
    """Indices of local minima (over two neighbours each side) of ``distance`` below ``limit``."""
    out = []
    for i in np.flatnonzero(distance < limit):
        lo, hi = max(0, i - 2), min(len(distance), i + 3)
        if distance[i] == np.min(distance[lo:hi]):
            out.append(int(i))
    return out


def _observe(traj, table, wall, k, n_rows, acceleration, noise, settings, spin_damping) -> ImpactObservation | None:
    """Fits before and after row ``k`` (rows k-1..k+1 skipped) and the impact they meet at."""
    z, dt = traj.z, traj.dt
    pre, post = rows_in(z, k - 1 - n_rows, k - 1), rows_in(z, k + 2, k + 2 + n_rows)
    if min(len(pre), len(post)) < settings.min_frames:
        return None
    if any(_near_other_rims(table, wall, z[r, :2], settings.rim_margin) for r in (pre, post)):
        return None
    t_ref = k * dt
    fits = [line_fit(rows * dt, z[rows, :2], t_ref, acceleration) for rows in (pre, post)]
    if any(f is None for f in fits):
        return None
    (before, after) = fits
    n = np.array(WALL_NORMALS[wall])
    met = paths_meet(n, before.p, before.v, after.p, after.v)  # where the two lines' distances from the rim meet
    if met is None or abs(met[0]) > 1.5 * dt:
        return None
    tau, contact = met[0], met[1] + table.wall_offset(wall)
    if abs(contact) > settings.contact_tolerance:
        return None
    b = np.array([n[1], -n[0]])
    v_in, v_out = before.v + tau * before.a, after.v + tau * after.a
    if float(n @ v_in) > -settings.min_normal_speed or float(n @ v_out) <= 0.0:
        return None
    spins = [fit_angle_rate(rows * dt, z[rows, 2], t_ref + tau, spin_damping) for rows in (pre, post)]
    quality = max(noise.fit_quality(f) for f in fits)
    return ImpactObservation(wall, t_ref + tau, (float(b @ v_in), float(n @ v_in), spins[0]),
                             (float(b @ v_out), float(n @ v_out), spins[1]), quality, contact,
                             float(b @ (before.p + tau * before.v)))


def _near_other_rims(table: TableGeometry, wall: int, xy: np.ndarray, margin: float) -> bool:
    for other, (nx, ny) in enumerate(WALL_NORMALS):
        if other != wall and np.min(nx * xy[:, 0] + ny * xy[:, 1] + table.wall_offset(other)) < margin:
            return True
    return False


def _robust_keep(residuals: np.ndarray, factor: float) -> np.ndarray:
    """Residuals [m/s] within ``factor`` robust standard deviations (1.4826 MAD; at least 1e-9 m/s, far
    below any measurement, so exact data keep every point)."""
    scale = max(1.4826 * float(np.median(np.abs(residuals))), 1e-9)
    return np.abs(residuals) <= factor * scale


def restitution_law(vn: np.ndarray, values: Mapping[str, float]) -> np.ndarray:
    """e(|vn|) = max(e0 - slope max(|vn| - knee, 0), e_min) [-], never above e0
    (:func:`~air_hockey_agent.core.puck.impact.speed_restitution`)."""
    line = values["restitution"] - values["restitution_slope"] * np.maximum(vn - values["restitution_knee"], 0.0)
    return np.minimum(values["restitution"], np.maximum(line, values["restitution_min"]))


def _fit_all(vn: np.ndarray, out: np.ndarray, bounds: Mapping[str, Sequence[float]]) -> dict:
    """All four. For a knee speed k and a speed f >= k where the line meets its floor the law is continuous,
    so ``out = e0 vn - slope vn clip(vn - k, 0, f - k)`` is linear in (e0, slope), with
    ``e_min = e0 - slope (f - k)``: bounded linear least squares for (k, f) on a grid over the measured
    speeds (and f infinite: no floor), then a bounded simplex from the best grid point."""
    from scipy.optimize import lsq_linear, minimize

    names = ("restitution", "restitution_slope")
    low, high = [bounds[n][0] for n in names], [bounds[n][1] for n in names]
    knee_low, knee_high = bounds["restitution_knee"]

    def fit_at(knee: float, floor_speed: float) -> tuple[float, dict | None]:
        if not (knee_low <= knee <= knee_high and floor_speed >= knee):
            return math.inf, None
        design = np.column_stack([vn, -vn * np.clip(vn - knee, 0.0, floor_speed - knee)])
        e0, slope = map(float, lsq_linear(design, out, bounds=(low, high), method="bvls").x)
        floor = e0 - slope * (floor_speed - knee) if math.isfinite(floor_speed) else 0.0
        if not bounds["restitution_min"][0] <= floor <= min(e0, bounds["restitution_min"][1]):
            return math.inf, None
        values = {"restitution": e0, "restitution_slope": slope, "restitution_min": floor, "restitution_knee": knee}
        return float(np.sum((out - vn * restitution_law(vn, values)) ** 2)), values

    top = float(np.max(vn))
    knees = np.linspace(knee_low, max(knee_low, min(knee_high, top)), KINK_GRID)
    floors = [*np.linspace(0.0, top, KINK_GRID), math.inf]
    grid = [(k, f) for k in knees for f in floors if f >= k]
    costs = [fit_at(k, f)[0] for k, f in grid]
    knee, floor_speed = grid[int(np.argmin(costs))]  # ties: the lowest knee, the lowest floor speed
    candidates = [fit_at(knee, floor_speed)]
    if math.isfinite(floor_speed):
        step = top / (KINK_GRID - 1)
        refined = minimize(lambda x: fit_at(float(x[0]), float(x[1]))[0], [knee, floor_speed],
                           method="Nelder-Mead", options={"initial_simplex": [[knee, floor_speed],
                                                                              [knee + step, floor_speed],
                                                                              [knee, floor_speed + step]],
                                                          "xatol": 1e-10, "fatol": 1e-24})
        candidates.append(fit_at(float(refined.x[0]), float(refined.x[1])))
    cost, values = min(candidates, key=lambda c: c[0])
    if values is None:
        raise ValueError("no restitution law within the sysid bounds fits the impacts")
    return _unseen_knee_at_zero(values, float(np.min(vn)), bounds)


def _unseen_knee_at_zero(values: dict, slowest: float, bounds: Mapping[str, Sequence[float]]) -> dict:
    """A knee below the slowest impact's normal speed [m/s] is not seen: the same line from a knee at the
    lowest bound (if the line's start stays within its bounds)."""
    knee = bounds["restitution_knee"][0]
    start = values["restitution"] + values["restitution_slope"] * (values["restitution_knee"] - knee)
    if values["restitution_knee"] < slowest and start <= bounds["restitution"][1]:
        return {**values, "restitution": start, "restitution_knee": knee}
    return values


def _fit_some(vn: np.ndarray, out: np.ndarray, fixed: Mapping[str, float],
              bounds: Mapping[str, Sequence[float]], start: Mapping[str, float]) -> dict:
    """Some of the three fixed: bounded nonlinear least squares of the others from ``start``."""
    from scipy.optimize import least_squares

    free = [n for n in RESTITUTION_NAMES if n not in fixed]
    if not free:
        return {n: fixed[n] for n in RESTITUTION_NAMES}
    low = np.array([bounds[n][0] for n in free])
    high = np.array([bounds[n][1] for n in free])

    def values_of(x: np.ndarray) -> dict:
        return {**{n: fixed[n] for n in RESTITUTION_NAMES if n in fixed}, **dict(zip(free, map(float, x)))}

    def residual(x: np.ndarray) -> np.ndarray:
        return out - vn * restitution_law(vn, values_of(x))

    x0 = np.clip([start[n] for n in free], low, high)
    return values_of(least_squares(residual, x0, bounds=(low, high)).x)


def fit_restitution(impacts: Sequence[ImpactObservation], fixed: Mapping[str, float],
                    bounds: Mapping[str, Sequence[float]], factor: float,
                    start: Mapping[str, float]) -> tuple[dict, np.ndarray, float]:
    """The restitution law's free parameters by least squares of the outgoing normal speed [m/s], refitted
    without outlying impacts; returns values, the impacts kept and the residual RMS [m/s]."""
    vn = np.array([-o.before[1] for o in impacts])
    out = np.array([o.after[1] for o in impacts])
    keep = np.ones(len(impacts), bool)
    for _ in range(3):
        if any(n in fixed for n in RESTITUTION_NAMES):
            values = _fit_some(vn[keep], out[keep], fixed, bounds, start)
        else:
            values = _fit_all(vn[keep], out[keep], bounds)
        residual = out - vn * restitution_law(vn, values)
        new_keep = _robust_keep(residual, factor)
        if np.array_equal(new_keep, keep) or new_keep.sum() < 3:
            break
        keep = new_keep
    return values, keep, float(math.sqrt(np.mean(residual[keep] ** 2)))


def tangential_residuals(impacts: Sequence[ImpactObservation], radius: float, law: Mapping[str, float],
                         friction: float, tangential: float = 0.0) -> np.ndarray:
    """Per impact: the Routh impact's error in outgoing (vb, r omega) [m/s], as a norm, with the
    restitution law ``law`` (RESTITUTION_NAMES), rim friction ``friction`` and tangential restitution
    ``tangential``."""
    out = np.empty(len(impacts))
    for i, o in enumerate(impacts):
        vb, vn, omega = o.before
        res = rim_impact(vb, vn, omega, radius, law["restitution"], friction, law["restitution_slope"],
                         law["restitution_min"], tangential)
        out[i] = math.hypot(res.vb - o.after[0], radius * (res.omega - o.after[2]))
    return out


def _best_on_grid(costs: np.ndarray, points: np.ndarray, start: np.ndarray) -> int:
    """Index of the cheapest grid point; among ties (a parameter the cost does not see) the nearest to
    ``start``."""
    best = float(np.min(costs))
    ties = np.flatnonzero(costs <= best + FLAT * abs(best) + 1e-30)
    return int(ties[np.argmin(np.sum((points[ties] - start) ** 2, axis=-1))])


def _scalar_fit(cost, bounds: Sequence[float], start: float) -> float:
    """A grid over ``bounds``, then a bounded search between the best grid point's neighbours."""
    from scipy.optimize import minimize_scalar

    grid = np.linspace(bounds[0], bounds[1], FRICTION_GRID)
    costs = np.array([cost(x) for x in grid])
    best = _best_on_grid(costs, grid[:, None], np.array([start]))
    lo, hi = grid[max(0, best - 1)], grid[min(len(grid) - 1, best + 1)]
    refined = minimize_scalar(cost, bounds=(lo, hi), method="bounded", options={"xatol": 1e-6})
    return float(refined.x) if refined.fun < costs[best] else float(grid[best])


def _pair_fit(cost, bounds: Sequence[Sequence[float]], start: Sequence[float]) -> tuple[float, float]:
    """A PAIR_GRID x PAIR_GRID grid over both ``bounds``, then a bounded Nelder-Mead from the best point."""
    from scipy.optimize import minimize

    axes = [np.linspace(b[0], b[1], PAIR_GRID) for b in bounds]
    points = np.array([(a, b) for a in axes[0] for b in axes[1]])
    costs = np.array([cost(p) for p in points])
    best = _best_on_grid(costs, points, np.clip(start, [b[0] for b in bounds], [b[1] for b in bounds]))
    steps = [(b[1] - b[0]) / (PAIR_GRID - 1) for b in bounds]
    simplex = np.array([points[best], points[best] + [steps[0], 0.0], points[best] + [0.0, steps[1]]])
    refined = minimize(cost, points[best], method="Nelder-Mead", bounds=bounds,
                       options={"initial_simplex": np.clip(simplex, [b[0] for b in bounds], [b[1] for b in bounds]),
                                "xatol": 1e-6, "fatol": 1e-12})
    x = refined.x if refined.fun < costs[best] else points[best]
    return float(x[0]), float(x[1])


def fit_tangential(impacts: Sequence[ImpactObservation], radius: float, law: Mapping[str, float],
                   fixed: Mapping[str, float], bounds: Mapping[str, Sequence[float]],
                   start: Mapping[str, float]) -> dict:
    """mu_rim and the tangential restitution (those not in ``fixed``) minimising the squared tangential
    residuals; returns both (TANGENTIAL_NAMES)."""
    free = [n for n in TANGENTIAL_NAMES if n not in fixed]
    values = {n: fixed.get(n, start[n]) for n in TANGENTIAL_NAMES}

    def cost_of(x: Sequence[float]) -> float:
        trial = {**values, **dict(zip(free, map(float, np.atleast_1d(x))))}
        return float(np.sum(tangential_residuals(impacts, radius, law, trial["friction_rim"],
                                                 trial["tangential_restitution"]) ** 2))

    if len(free) == 1:
        values[free[0]] = _scalar_fit(cost_of, bounds[free[0]], start[free[0]])
    elif free:
        values.update(zip(free, _pair_fit(cost_of, [bounds[n] for n in free], [start[n] for n in free])))
    best = cost_of([values[n] for n in free])
    for i, name in enumerate(free):  # a parameter the impacts do not see keeps its starting value
        at_start = [start[n] if j == i else values[n] for j, n in enumerate(free)]
        if cost_of(at_start) <= best + FLAT * abs(best) + 1e-30:
            values[name] = start[name]
    return values


def fit_impacts(impacts: Sequence[ImpactObservation], radius: float, fixed: Mapping[str, float],
                bounds: Mapping[str, Sequence[float]], settings: ImpactSettings,
                start: Mapping[str, float]) -> ImpactFit:
    """Restitution law, then rim friction and tangential restitution, over the impacts whose fits are good; ``fixed`` names keep
    their values, ``start`` (all IMPACT_NAMES) seeds the nonlinear fits."""
    smooth = smooth_fits([o.fit_quality for o in impacts], settings.outlier_factor)
    good = [o for o, ok in zip(impacts, smooth) if ok]
    needed = sum(1 for n in IMPACT_NAMES if n not in fixed) + 1
    if len(good) < needed:
        raise ValueError(f"{len(good)} usable rim impacts: too few to identify "
                         + ", ".join(n for n in IMPACT_NAMES if n not in fixed))
    values, keep, rms_normal = fit_restitution(good, fixed, bounds, settings.outlier_factor, start)
    kept = [o for o, k in zip(good, keep) if k]
    values.update(fit_tangential(kept, radius, values, fixed, bounds, start))
    if any(n not in fixed for n in TANGENTIAL_NAMES):
        residuals = tangential_residuals(kept, radius, values, *(values[n] for n in TANGENTIAL_NAMES))
        keep_t = _robust_keep(residuals, settings.outlier_factor)
        if not keep_t.all() and keep_t.sum() >= 2:
            kept = [o for o, k in zip(kept, keep_t) if k]
            values.update(fit_tangential(kept, radius, values, fixed, bounds, start))
    residuals = tangential_residuals(kept, radius, values, *(values[n] for n in TANGENTIAL_NAMES))
    rms_t = float(math.sqrt(np.mean(residuals ** 2)))
    return ImpactFit(values, len(kept), len(impacts) - len(kept), rms_normal, rms_t, radius, kept)


@dataclass(frozen=True)
class DelayFit:
    """A compliant rim's delay from where the impacts' paths meet: ``depth = offset(rim) + yaw along - delay |vn|``."""

    value: float        # [s] the impact delay the model takes: the fit within its bounds, or the one known
    std: float          # [s] its standard error (0 when known)
    fitted: float       # [s] the least-squares value before the bounds
    offsets: dict       # rim id -> (offset, std) [m]: where an impact's paths at no speed meet, from the model's
    #                     line at the rim's middle, at the delay ``value`` (> 0: inside the table)
    impacts: int        # impacts in the fit (outliers dropped)
    covariance: dict = field(default_factory=dict)  # (rim id, rim id) -> covariance of the two offsets [m^2]
    yaw: tuple = (0.0, 0.0)  # [rad] (value, std): the rims turned by this from the model's (offsets growing along them)


def fit_delay(impacts: Sequence[ImpactObservation], bounds: Sequence[float], outlier_factor: float,
              known: float | None = None) -> DelayFit:
    """Least squares of each impact's meeting depth (:attr:`ImpactObservation.depth`) on its incoming normal
    speed: a rigid rim's paths meet on its line at every speed, a compliant one's beyond it by the delay
    times the speed (the model's ``impact_delay``: the impact comes that long after the centre reaches the
    line). Each rim has its own offset at no speed: how far the table's rim lines are from the model's (a
    table longer or wider than configured moves opposite rims' alike, a table pose shifted moves them
    apart); a table turned by a small yaw from the model's makes every rim's offset grow along it
    (:attr:`ImpactObservation.along`) at that rate. Outliers beyond ``outlier_factor`` robust standard
    deviations are dropped once. The offsets are where the rims are for the delay the model will take: the
    fit's, or at its bound when it falls outside ``bounds``, or ``known`` [s] (a delay not identified);
    their covariance is the joint fit's when the delay is its own, else without the delay's."""
    speed = np.array([-o.before[1] for o in impacts])
    depth = np.array([o.depth for o in impacts])
    walls = np.array([o.wall for o in impacts])
    along = np.array([o.along for o in impacts])
    if len(speed) < 4 or np.ptp(speed) == 0.0:
        raise ValueError(f"{len(speed)} rim impacts at {len(set(speed.tolist()))} normal speeds: too few to find where "
                         f"the paths before and after meet (impact_delay, table_geometry)")
    keep = np.ones(len(speed), bool)
    coef, rims = _delay_lstsq(speed, depth, walls, along)
    residual = depth - _delay_design(speed, walls, rims, along) @ coef
    dropped = ~_robust_keep(residual, outlier_factor)
    if dropped.any() and (~dropped).sum() >= 4 and np.ptp(speed[~dropped]) > 0.0:
        keep = ~dropped
        coef, rims = _delay_lstsq(speed[keep], depth[keep], walls[keep], along[keep])
    design = _delay_design(speed[keep], walls[keep], rims, along[keep])
    residual = depth[keep] - design @ coef
    n = int(keep.sum())
    variance = float(residual @ residual) / max(n - design.shape[1], 1)
    cov = variance * np.linalg.pinv(design.T @ design)
    fitted, std = float(coef[-1]), float(math.sqrt(cov[-1, -1]))
    value = float(min(max(fitted, bounds[0]), bounds[1])) if known is None else float(known)
    if value != fitted:  # the offsets where the model's delay puts the rims, that delay taken as exact
        rim_design, target = design[:, :-1], depth[keep] + value * speed[keep]
        coef, *_ = np.linalg.lstsq(rim_design, target, rcond=None)
        residual = target - rim_design @ coef
        cov = float(residual @ residual) / max(n - rim_design.shape[1], 1) * np.linalg.pinv(rim_design.T @ rim_design)
    m = len(rims)
    return DelayFit(value, std if known is None else 0.0, fitted,
                    {int(w): (float(coef[k]), float(math.sqrt(cov[k, k]))) for k, w in enumerate(rims)}, n,
                    {(int(a), int(b)): float(cov[i, j]) for i, a in enumerate(rims) for j, b in enumerate(rims)},
                    (float(coef[m]), float(math.sqrt(cov[m, m]))))


def _delay_design(speed: np.ndarray, walls: np.ndarray, rims: Sequence[int], along: np.ndarray) -> np.ndarray:
    """Columns: one offset per rim in ``rims`` (1 on its impacts), the position along the rim (a turn's
    rate), then minus the normal speed."""
    return np.column_stack([(walls == w).astype(float) for w in rims] + [along, -speed])


def _delay_lstsq(speed: np.ndarray, depth: np.ndarray, walls: np.ndarray,
                 along: np.ndarray) -> tuple[np.ndarray, list[int]]:
    rims = sorted(set(walls.tolist()))
    coef, *_ = np.linalg.lstsq(_delay_design(speed, walls, rims, along), depth, rcond=None)
    return coef, rims
