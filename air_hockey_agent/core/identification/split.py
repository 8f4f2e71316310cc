"""Split identification: flight parameters from free flight, then impact parameters from the impacts
(issue #13 item 5; ``air-hockey sysid --method split``).

The thesis identifies all four parameters at once by the filter's prediction loss (HEBO, :mod:`.sysid`).
Here each part of the model is fitted where it alone acts, by least squares on local fits of the
recorded positions (:mod:`.flight_fit`, :mod:`.impact_fit`): no filter runs, so the result does not
depend on the filter's tuning, and it takes a second instead of minutes. Parameters not identified keep
the tracker's values and enter the fits as known.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any, Collection, Mapping, Sequence

import numpy as np

from air_hockey_agent.core.estimation.marker_offset import centres_of, offset_normal_equations
from air_hockey_agent.core.identification.flight_fit import (FieldCheck, FlightFit, FlightSettings, NoiseModel,
                                                           field_check, flight_law, free_flight_windows,
                                                           identify_flight)
from air_hockey_agent.core.identification.impact_fit import (IMPACT_NAMES, DelayFit, ImpactFit, ImpactSettings,
                                                            find_impacts, fit_delay, fit_impacts)
from air_hockey_agent.core.identification.preprocess import GridTrajectory
from air_hockey_agent.core.identification.rim_lines import RimLines, corrected_geometry, recentred, rim_lines
from air_hockey_agent.core.identification.spin_fit import SpinDecay, fit_spin_decay, spin_windows
from air_hockey_agent.core.table import TableGeometry

FLIGHT = ("damping", "friction_surface", "table_acceleration")
SPIN = ("spin_damping",)  # from the angles of the flight fit's windows (:mod:`.spin_fit`)
IMPACT = ("restitution", "restitution_slope", "restitution_min", "restitution_knee", "friction_rim",
          "tangential_restitution", "impact_delay")  # the last from where the paths before and after meet
# where the rims are (:mod:`.rim_lines`: mocap_table_pose's x, y and yaw, table.length, table.width), from the
# same meeting points as impact_delay
GEOMETRY = ("table_geometry",)
OFFSET = ("marker_offset",)  # the mocap pivot off the disc's centre, from the flight windows' positions
SPLIT_IDENTIFIABLE = FLIGHT + SPIN + IMPACT + GEOMETRY + OFFSET
AXES = ("table_acceleration_x", "table_acceleration_y")


@dataclass
class SplitResult:
    identified: dict      # tracker parameter name -> value (table_acceleration as [x, y])
    std: dict             # tracker parameter name -> standard error (table_acceleration as [x, y])
    flight: FlightFit | None
    impacts: ImpactFit | None
    field: FieldCheck | None = None  # whether the free flight's acceleration varies over the table
    spin: SpinDecay | None = None    # the spin's decay in free flight (spin_damping's fit)
    delay: DelayFit | None = None    # where the impacts' paths meet (impact_delay's fit; after a move of the rims,
    #                                  where they meet the moved rims)
    rim_lines: RimLines | None = None  # where the rims were found (table_geometry), from the first pass's delay fit
    geometry: dict | None = None     # tracker parameters that move the model's rims there (only what changed)
    first_delay: DelayFit | None = None  # the first pass's delay fit, against the configured rims


def flight_settings(settings: Mapping[str, Any]) -> FlightSettings:
    return FlightSettings(settings["split.window"], settings["split.min_coverage"], settings["split.min_speed"],
                          settings["split.rim_margin"], settings["split.outlier_factor"])


def impact_settings(settings: Mapping[str, Any]) -> ImpactSettings:
    return ImpactSettings(settings["split.impact_window"], settings["split.impact_min_frames"],
                          settings["split.approach_distance"], settings["split.contact_tolerance"],
                          settings["split.min_normal_speed"], settings["split.rim_margin"],
                          settings["split.outlier_factor"])


def noise_model(tracker: Mapping[str, Any]) -> NoiseModel:
    """The tracker's position noise (x axis's R and its growth with speed) as the fits' weights."""
    return NoiseModel(tracker["measurement_noise"][0], tracker["measurement_noise_per_speed"])


def identify_split(trajectories: Sequence[GridTrajectory], tracker: Mapping[str, Any], settings: Mapping[str, Any],
                   names: Sequence[str], bounds: Mapping[str, Sequence[float]],
                   move_centre: bool = True) -> SplitResult:
    """Identify ``names`` (of SPLIT_IDENTIFIABLE) within ``bounds`` (per name; the table acceleration's
    per axis); raises ValueError when the recordings hold too little free flight or too few impacts. With
    ``table_geometry``, rims found elsewhere than the model has them (:func:`.rim_lines.rim_lines`) are moved
    there and everything is identified again on the trajectories measured from the moved table frame
    (:func:`.rim_lines.recentred`): the flight and impact fits then see the rims where they are. Without
    ``move_centre`` (poses not read through ``mocap_table_pose``) only the table's size moves, not its centre
    or yaw. The fits see the disc's centre: measured positions are taken back from the mocap pivot by the
    ``marker_offset`` (identified first from the free-flight windows, :func:`identify_offset`, or the
    configured one), as the filter takes them."""
    offset = None
    if "marker_offset" in names:
        offset = identify_offset(trajectories, TableGeometry.from_params(tracker), flight_settings(settings),
                                 tracker["marker_offset"], bounds["marker_offset"])
    pivot = tracker["marker_offset"] if offset is None else offset[0]
    if any(pivot):
        trajectories = [at_centre(t, pivot) for t in trajectories]
    first = _with_offset(_identify_once(trajectories, tracker, settings, names, bounds), offset)
    if "table_geometry" not in names:
        return first
    lines = rim_lines(first.delay, settings["split.significance"], bounds["table_geometry"],
                      settings["bounds.table_yaw"], move_centre)
    if not lines.any_taken:
        return replace(first, rim_lines=lines, geometry={}, first_delay=first.delay)
    geometry = corrected_geometry(tracker, lines)
    moved = [recentred(t, lines.centre(), lines.yaw()) for t in trajectories]
    again = _with_offset(_identify_once(moved, {**tracker, **geometry}, settings, names, bounds), offset)
    return replace(again, rim_lines=lines, geometry=geometry, first_delay=first.delay)


def identify_offset(trajectories: Sequence[GridTrajectory], table: TableGeometry, settings: FlightSettings,
                    configured: Sequence[float], box: Sequence[float]) -> tuple[list, list]:
    """The mocap pivot's offset from the disc's centre [m] (puck frame) and its standard errors, from the
    free-flight windows (``settings``; those that do not overlap) of the measured positions: each a
    parabola per axis plus ``R(theta) o`` (:func:`.marker_offset.offset_normal_equations`), weighted by
    its residual variance; each axis within ``box``. Pucks that do not turn cannot tell it: the
    configured offset then stays, with errors 0."""
    normal, rhs = np.zeros((2, 2)), np.zeros(2)
    for traj in trajectories:
        last = -1
        for rows, _ in free_flight_windows(traj, table, settings):
            if rows[0] <= last:
                continue
            last = int(rows[-1])
            n, r, variance = offset_normal_equations(rows * traj.dt, traj.z[rows])
            if variance > 0.0:
                normal, rhs = normal + n / variance, rhs + r / variance
    if np.linalg.eigvalsh(normal)[0] * (box[1] - box[0]) ** 2 < 1.0:  # not even the box's width pinned down
        return [float(v) for v in configured], [0.0, 0.0]
    value = np.clip(np.linalg.solve(normal, rhs), box[0], box[1])
    return [float(v) for v in value], [float(s) for s in np.sqrt(np.diag(np.linalg.inv(normal)))]


def _with_offset(result: SplitResult, offset: tuple[list, list] | None) -> SplitResult:
    """``result`` with the identified marker offset and its errors among its values (when identified)."""
    if offset is not None:
        result.identified["marker_offset"], result.std["marker_offset"] = offset
    return result


def at_centre(trajectory: GridTrajectory, offset) -> GridTrajectory:
    """A copy of ``trajectory`` with its positions taken back from the mocap pivot to the disc's centre by
    ``offset`` [m] (puck frame; :func:`~air_hockey_agent.core.estimation.marker_offset.centres_of`)."""
    return GridTrajectory(trajectory.t0, trajectory.dt, centres_of(trajectory.z, offset))


def _identify_once(trajectories: Sequence[GridTrajectory], tracker: Mapping[str, Any], settings: Mapping[str, Any],
                   names: Sequence[str], bounds: Mapping[str, Sequence[float]]) -> SplitResult:
    """One pass of the fits on the model's table as ``tracker`` has it."""
    table = TableGeometry.from_params(tracker)
    noise = noise_model(tracker)
    flight_values = {"damping": tracker["damping"], "friction_surface": tracker["friction_surface"],
                     AXES[0]: tracker["table_acceleration"][0], AXES[1]: tracker["table_acceleration"][1]}
    identified, std = {}, {}
    flight = field = spin = None
    windows = flight_settings(settings)
    if any(n in FLIGHT for n in names):
        fixed = {k: v for k, v in flight_values.items()
                 if (k in AXES and "table_acceleration" not in names) or (k not in AXES and k not in names)}
        axis_bounds = {axis: bounds.get("table_acceleration", (-np.inf, np.inf)) for axis in AXES}
        flight = identify_flight(trajectories, table, noise, windows, fixed,
                                 {**bounds, **axis_bounds})
        flight_values = flight.values
        _collect(flight.values, flight.std, names, identified, std)
        field = field_check(flight, table, settings["split.field_grid"], settings["split.field_min_windows"])
    if any(n in FLIGHT + SPIN for n in names):
        spin = fit_spin_decay(spin_windows(trajectories, table, windows),
                              tracker["measurement_noise"][2], settings["split.outlier_factor"])
    if "spin_damping" in names and spin is not None:  # without spinning windows it stays as configured
        low, high = bounds["spin_damping"]
        identified["spin_damping"], std["spin_damping"] = float(min(max(spin.rate, low), high)), spin.std
    impacts = delay = None
    if any(n in IMPACT + GEOMETRY for n in names):
        fixed = {n: tracker[n] for n in IMPACT_NAMES if n not in names}
        chosen = impact_settings(settings)
        law = flight_law(flight_values)
        spin_damping = identified.get("spin_damping", tracker["spin_damping"])
        found = [o for traj in trajectories for o in find_impacts(traj, table, law, noise, chosen, spin_damping)]
        impacts = fit_impacts(found, table.puck_radius, fixed, bounds, chosen, {n: tracker[n] for n in IMPACT_NAMES})
        _collect(impacts.values, {}, names, identified, std)
    if "impact_delay" in names or "table_geometry" in names:
        known = None if "impact_delay" in names else tracker["impact_delay"]
        delay = fit_delay(impacts.used, bounds.get("impact_delay", (0.0, 0.0)), settings["split.outlier_factor"], known)
        if known is None:
            identified["impact_delay"], std["impact_delay"] = delay.value, delay.std
    return SplitResult(identified, std, flight, impacts, field, spin, delay)


def _collect(values: Mapping[str, float], errors: Mapping[str, float], names: Sequence[str], identified: dict,
             std: dict) -> None:
    """Copy the identified ``names`` into tracker-parameter form (the two axes as one list)."""
    for name in names:
        if name == "table_acceleration" and AXES[0] in values:
            identified[name] = [float(values[a]) for a in AXES]
            std[name] = [float(errors.get(a, 0.0)) for a in AXES]
        elif name in values and name != "table_acceleration":
            identified[name] = float(values[name])
            if name in errors:
                std[name] = float(errors[name])


def learning_priors(result: SplitResult, kept: Collection[str], std: Mapping[str, Any],
                    ranges: Mapping[str, tuple[float, float]]) -> dict[str, float]:
    """What the online learning (``rim_adaptation``, ``acceleration_adaptation`` in config/tracker.yaml) should
    take as its priors' weights when it starts from this identification, by tracker parameter name: the rim
    law is worth the impacts it was fitted to (``prior_impacts``), the table acceleration, damping, surface
    friction and spin damping their standard errors (``std``). Only for parameters in ``kept`` (identified
    and left as fitted: a polished value has neither), each within its parameter's (low, high) in
    ``ranges``; an error of 0 (the fit could not tell) leaves the configured prior. The configured priors
    are a stranger's table's, weak by design; kept after an identification they let a session's windows
    replace a better estimate."""
    priors = {}
    if result.impacts is not None and result.impacts.impacts and any(n in kept for n in IMPACT_NAMES):
        priors["rim_adaptation.prior_impacts"] = float(result.impacts.impacts)
    errors = {"table_acceleration": "acceleration_adaptation.prior_std",
              "damping": "acceleration_adaptation.damping_prior_std",
              "friction_surface": "acceleration_adaptation.friction_prior_std",
              "spin_damping": "acceleration_adaptation.spin_prior_std",
              "marker_offset": "acceleration_adaptation.marker_offset_prior_std"}
    for name, prior in errors.items():
        value = float(np.max(std[name])) if name in kept and name in std else 0.0
        if value > 0.0:
            priors[prior] = value
    return {name: min(max(value, ranges[name][0]), ranges[name][1]) for name, value in priors.items()}
