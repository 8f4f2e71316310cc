"""Flight parameters from free-flight stretches (split identification, issue #13 item 5).

Every recorded trajectory is cut into short overlapping windows; a window away from the rims, with
enough frames and a moving puck, gets a local quadratic fit (:mod:`.local_fit`): velocity ``v`` and
acceleration ``a`` at its centre. The flight law (thesis eq. 3.1 in the README's reading, plus a
constant table acceleration ``g``: a tilt, issue #13 item 3)

    a = -d v - mu_s v/|v| + g

is linear in ``(d, mu_s, g_x, g_y)``, so one weighted linear least-squares problem over all windows
gives them, each window weighted by the inverse variance of its fitted acceleration (the marker noise
grows with the speed: the tracker's ``measurement_noise`` and ``measurement_noise_per_speed``).
Windows whose positions a quadratic does not fit (an impact, a hit or a glitch inside) and windows
whose acceleration is an outlier of the fit are dropped. Bounds keep d and mu_s in the sysid box.

The objective minimised is ``sum_i w_i |a_i - a_model(v_i)|^2`` (reported per window as ``objective``);
the parameters' standard errors come from the weighted normal equations scaled by the fit's residual.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Mapping, Sequence

import numpy as np

from air_hockey_agent.core.identification.local_fit import LocalFit, fit_positions, rows_in, smooth_fits
from air_hockey_agent.core.identification.preprocess import GridTrajectory
from air_hockey_agent.core.puck.model import flight_acceleration
from air_hockey_agent.core.table import TableGeometry

FLIGHT_NAMES = ("damping", "friction_surface", "table_acceleration_x", "table_acceleration_y")


@dataclass(frozen=True)
class NoiseModel:
    """Position noise of a marker [m^2] at a speed [m/s]: the tracker's R growing with speed."""

    at_rest: float        # [m^2] per axis
    per_speed: float      # [s] std added in quadrature per m/s

    def variance(self, speed: float) -> float:
        return self.at_rest + (self.per_speed * speed) ** 2

    def fit_quality(self, fit: LocalFit) -> float:
        """A local fit's residual RMS over the noise expected at its speed [-] (about 1 for a good fit)."""
        return fit.rms / math.sqrt(self.variance(float(np.linalg.norm(fit.v))))


@dataclass(frozen=True)
class FlightSettings:
    """``split.*`` in ``config/sysid.yaml``."""

    window: float          # [s] length of one window
    min_coverage: float    # [-] share of a window's rows that must hold a measurement
    min_speed: float       # [m/s] slower windows are left out (rest, a hand)
    rim_margin: float      # [m] every frame of a window this far inside the rim lines
    outlier_factor: float  # [-] robust z beyond which a window is dropped


@dataclass
class FlightFit:
    values: dict           # FLIGHT_NAMES -> value (fixed ones as given)
    std: dict              # identified name -> standard error
    windows: int           # windows in the final fit
    dropped: int           # windows dropped as outliers (poor quadratic fit or outlying acceleration)
    objective: float       # weighted squared residual per window (dimensionless)
    rms_acceleration: float  # [m/s^2] unweighted residual RMS per axis
    used: list = field(default_factory=list)  # the windows (LocalFit) of the final fit, for plots
    used_weights: list = field(default_factory=list)  # [s^4/m^2] their weights in the fit


@dataclass(frozen=True)
class FieldCheck:
    """Does the free flight's acceleration vary over the table beyond the flight law's constant ``g``
    (an uneven air film, a warped surface: issue #13 item 3, "where the data support it")? The fit's
    residual accelerations, averaged per cell of a grid over the table."""

    cells: list            # per cell with enough windows: {"x", "y" [m] centre, "windows", "ax", "ay" [m/s^2]
    #                        mean residual, "std_error" [m/s^2] per axis}
    largest: float         # [m/s^2] the largest cell mean's magnitude
    f_statistic: float     # between-cell over within-cell variance of the residuals, both axes
    p_value: float         # of "one acceleration all over the table" (one-way analysis of variance)


def flight_windows(traj: GridTrajectory, table: TableGeometry, settings: FlightSettings) -> list[LocalFit]:
    """Quadratic fits of the trajectory's windows that lie inside the rim margin and move fast enough."""
    return [fit for _, fit in free_flight_windows(traj, table, settings)]


def free_flight_windows(traj: GridTrajectory, table: TableGeometry, settings: FlightSettings):
    """(rows, quadratic fit of their positions) of each window of the trajectory inside the rim margin,
    covered enough and moving at least ``min_speed``."""
    rows_per_window = max(5, int(round(settings.window / traj.dt)) + 1)
    hop = max(1, rows_per_window // 2)
    for start in range(0, len(traj) - rows_per_window + 1, hop):
        rows = rows_in(traj.z, start, start + rows_per_window)
        if len(rows) < settings.min_coverage * rows_per_window:
            continue
        xy = traj.z[rows, :2]
        if _closest_to_rims(table, xy) < settings.rim_margin:
            continue
        times = rows * traj.dt
        fit = fit_positions(times, xy, float(np.mean(times)), 2)
        if fit is not None and math.hypot(*fit.v) >= settings.min_speed:
            yield rows, fit


def _closest_to_rims(table: TableGeometry, xy: np.ndarray) -> float:
    """Smallest distance [m] of any of the centres ``xy`` (n, 2) from a rim line (negative beyond it)."""
    return float(min(np.min(table.x_limit - np.abs(xy[:, 0])), np.min(table.y_limit - np.abs(xy[:, 1]))))


def fit_flight(windows: Sequence[LocalFit], noise: NoiseModel, settings: FlightSettings,
               fixed: Mapping[str, float], bounds: Mapping[str, Sequence[float]]) -> FlightFit:
    """Weighted least squares of the flight law over ``windows``; names in ``fixed`` keep their value,
    the others are identified within ``bounds`` (the table acceleration is unbounded if not given)."""
    smooth = smooth_fits([noise.fit_quality(w) for w in windows], settings.outlier_factor)
    kept = [w for w, ok in zip(windows, smooth) if ok]
    weights = np.array([1.0 / (w.a_gain * noise.variance(math.hypot(*w.v))) for w in kept])
    free = [n for n in FLIGHT_NAMES if n not in fixed]
    if len(kept) < len(free) + 1:
        raise ValueError(f"{len(kept)} free-flight windows: too few to identify {', '.join(free)}")
    mask = np.ones(len(kept), bool)
    for _ in range(3):  # refit without outlying windows until none is left out anew
        solution = _solve(kept, weights, mask, fixed, free, bounds)
        z = _normalised_residuals(kept, weights, solution)
        scale = 1.4826 * float(np.median(z[mask])) or 1e-12
        new_mask = z <= settings.outlier_factor * scale
        if np.array_equal(new_mask, mask) or new_mask.sum() < len(free) + 1:
            break
        mask = new_mask
    solution = _solve(kept, weights, mask, fixed, free, bounds)
    return _report(kept, weights, mask, solution, free, len(windows) - len(kept) + int((~mask).sum()))


def _rows(window: LocalFit) -> tuple[np.ndarray, np.ndarray]:
    """Design rows (2, 4) over FLIGHT_NAMES and the measured acceleration (2,) of one window."""
    v = window.v
    speed = math.hypot(*v)
    u = v / speed
    return np.array([[-v[0], -u[0], 1.0, 0.0], [-v[1], -u[1], 0.0, 1.0]]), window.a


def _solve(windows, weights, mask, fixed, free, bounds) -> dict:
    from scipy.optimize import lsq_linear

    design, target = [], []
    for w, weight, use in zip(windows, weights, mask):
        if not use:
            continue
        rows, a = _rows(w)
        rhs = a - sum(rows[:, FLIGHT_NAMES.index(n)] * fixed[n] for n in fixed)
        keep = [FLIGHT_NAMES.index(n) for n in free]
        design.append(math.sqrt(weight) * rows[:, keep])
        target.append(math.sqrt(weight) * rhs)
    a_mat, b_vec = np.vstack(design), np.concatenate(target)
    low = [bounds.get(n, (-np.inf, np.inf))[0] for n in free]
    high = [bounds.get(n, (-np.inf, np.inf))[1] for n in free]
    result = lsq_linear(a_mat, b_vec, bounds=(low, high), method="bvls")
    values = dict(fixed)
    values.update(zip(free, (float(v) for v in result.x)))
    return values


def flight_law(values: Mapping[str, float]):
    """``a(v)`` [m/s^2] of the flight law ``-d v - mu_s v/|v| + g`` with ``values`` (FLIGHT_NAMES)."""
    return flight_acceleration(values["damping"], values["friction_surface"],
                               (values[FLIGHT_NAMES[2]], values[FLIGHT_NAMES[3]]))


def _model_acceleration(window: LocalFit, values: Mapping[str, float]) -> np.ndarray:
    return flight_law(values)(window.v)


def _normalised_residuals(windows, weights, values) -> np.ndarray:
    """Per window: |a - a_model| in units of its standard deviation (per axis)."""
    return np.array([math.sqrt(weight / 2.0) * float(np.linalg.norm(w.a - _model_acceleration(w, values)))
                     for w, weight in zip(windows, weights)])


def _report(windows, weights, mask, values, free, dropped) -> FlightFit:
    used = [(w, weight) for w, weight, m in zip(windows, weights, mask) if m]
    residuals = [w.a - _model_acceleration(w, values) for w, _ in used]
    weighted = sum(weight * float(r @ r) for (_, weight), r in zip(used, residuals))
    design = np.vstack([math.sqrt(weight) * _rows(w)[0][:, [FLIGHT_NAMES.index(n) for n in free]]
                        for w, weight in used])
    dof = max(1, 2 * len(used) - len(free))
    covariance = np.linalg.pinv(design.T @ design) * weighted / dof
    std = {n: float(math.sqrt(max(covariance[i, i], 0.0))) for i, n in enumerate(free)}
    rms = math.sqrt(sum(float(r @ r) for r in residuals) / (2 * len(used)))
    return FlightFit(values, std, len(used), dropped, weighted / len(used), rms, [w for w, _ in used],
                     [weight for _, weight in used])


def field_check(fit: FlightFit, table: TableGeometry, grid: Sequence[int], min_windows: int) -> FieldCheck | None:
    """One-way analysis of variance of the flight fit's residual accelerations over a ``grid`` (cells along
    x, along y) of the table; cells with fewer than ``min_windows`` windows are left out. Every other
    window is used (neighbours share half their frames, and correlated residuals would look like a
    field). None when fewer than two cells have enough windows. The p-value is the F distribution's
    survival function (scipy.special.fdtrc, the same as scipy.stats.f.sf without importing scipy.stats,
    0.3 s of each sysid's start)."""
    from scipy.special import fdtrc

    groups = {key: items for key, items in _cell_residuals(fit, table, grid).items() if len(items) >= min_windows}
    n, k = sum(len(g) for g in groups.values()), len(groups)
    if k < 2 or n <= k:
        return None
    means = {key: _weighted_mean(items) for key, items in groups.items()}
    within = sum(weight * float(np.sum((residual - means[key][0]) ** 2))
                 for key, items in groups.items() for residual, weight in items)
    total_weight = sum(weight for _, weight in means.values())
    grand = sum(weight * mean for mean, weight in means.values()) / total_weight
    between = sum(weight * float(np.sum((mean - grand) ** 2)) for mean, weight in means.values())
    df_between, df_within = 2 * (k - 1), 2 * (n - k)
    scale = within / df_within
    statistic = (between / df_between) / scale if scale > 0.0 else math.inf
    nx, ny = int(grid[0]), int(grid[1])
    cells = [{"x": float((i + 0.5) * table.length / nx - table.length / 2),
              "y": float((j + 0.5) * table.width / ny - table.width / 2), "windows": len(groups[(i, j)]),
              "ax": float(mean[0]), "ay": float(mean[1]), "std_error": float(math.sqrt(scale / weight))}
             for (i, j), (mean, weight) in sorted(means.items())]
    largest = max(math.hypot(c["ax"], c["ay"]) for c in cells)
    return FieldCheck(cells, largest, float(statistic), float(fdtrc(df_between, df_within, statistic)))


def _cell_residuals(fit: FlightFit, table: TableGeometry, grid: Sequence[int]) -> dict:
    """(cell along x, cell along y) -> [(residual acceleration (2,) [m/s^2], weight)] of every other window."""
    law = flight_law(fit.values)
    nx, ny = int(grid[0]), int(grid[1])
    cells: dict[tuple[int, int], list] = {}
    for w, weight in list(zip(fit.used, fit.used_weights))[::2]:
        i = min(nx - 1, max(0, int((w.p[0] + table.length / 2) / table.length * nx)))
        j = min(ny - 1, max(0, int((w.p[1] + table.width / 2) / table.width * ny)))
        cells.setdefault((i, j), []).append((w.a - law(w.v), weight))
    return cells


def _weighted_mean(items: list) -> tuple[np.ndarray, float]:
    """Weighted mean of (residual, weight) pairs and the sum of the weights."""
    weights = np.array([weight for _, weight in items])
    residuals = np.array([residual for residual, _ in items])
    return (weights @ residuals) / weights.sum(), float(weights.sum())


def identify_flight(trajectories: Sequence[GridTrajectory], table: TableGeometry, noise: NoiseModel,
                    settings: FlightSettings, fixed: Mapping[str, float],
                    bounds: Mapping[str, Sequence[float]]) -> FlightFit:
    """:func:`fit_flight` over the windows of every trajectory."""
    windows = [w for traj in trajectories for w in flight_windows(traj, table, settings)]
    return fit_flight(windows, noise, settings, fixed, bounds)
