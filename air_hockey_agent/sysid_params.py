"""Parameters of system identification (ROS-free declarations; defaults in ``config/sysid.yaml``)."""
from __future__ import annotations

from pathlib import Path
from typing import Any, Iterable

from air_hockey_agent.params import ParamSpec, load_node_params

NODE_NAME = "/sysid"
PARAM_FILES = ("sysid.yaml",)
SYSID_PARAMS = (
    ParamSpec("bounds.friction_surface", list, "[m/s^2] search bounds (thesis table 4.1)", 0.0, 10.0, 2),
    ParamSpec("bounds.friction_rim", list, "[-] search bounds (thesis table 4.1)", 0.0, 2.0, 2),
    ParamSpec("bounds.restitution", list, "[-] search bounds (thesis table 4.1)", 0.0, 1.0, 2),
    ParamSpec("bounds.damping", list, "[1/s] search bounds (thesis table 4.1)", 0.0, 10.0, 2),
    ParamSpec("bounds.restitution_slope", list, "[s/m] search bounds (--identify restitution_slope)", 0.0, 10.0, 2),
    ParamSpec("bounds.restitution_min", list, "[-] search bounds (--identify restitution_min)", 0.0, 1.0, 2),
    ParamSpec("bounds.restitution_knee", list, "[m/s] search bounds (--identify restitution_knee)", 0.0, 10.0, 2),
    ParamSpec("bounds.tangential_restitution", list, "[-] search bounds (--method split)", -1.0, 1.0, 2),
    ParamSpec("bounds.table_acceleration", list, "[m/s^2] bounds per axis (--method split)", -10.0, 10.0, 2),
    ParamSpec("bounds.spin_damping", list, "[1/s] bounds of the spin's decay rate (--method split)", 0.0, 100.0, 2),
    ParamSpec("bounds.impact_delay", list, "[s] bounds of a compliant rim's impact delay (--method split)", 0.0, 0.05,
              2),
    ParamSpec("bounds.table_geometry", list, "[m] how far the rims' centre and distances may move (--identify "
              "table_geometry)", -0.5, 0.5, 2),
    ParamSpec("bounds.marker_offset", list, "[m] bounds per axis of the mocap pivot's offset from the disc's "
              "centre (--method split)", -0.05, 0.05, 2),
    ParamSpec("bounds.table_yaw", list, "[rad] how far the rims may turn (--identify table_geometry)", -0.5, 0.5, 2),
    ParamSpec("split.window", float, "[s] free-flight window of the split identification", 0.05, 5.0),
    ParamSpec("split.min_coverage", float, "[-] share of a window's frames that must be measured", 0.1, 1.0),
    ParamSpec("split.min_speed", float, "[m/s] slower windows are left out", 0.0, 10.0),
    ParamSpec("split.rim_margin", float, "[m] free-flight frames this far inside the rim lines", 0.0, 0.5),
    ParamSpec("split.outlier_factor", float, "[-] robust z beyond which a window or impact is dropped", 1.0, 100.0),
    ParamSpec("split.impact_window", float, "[s] fitted before and after a rim impact", 0.02, 1.0),
    ParamSpec("split.impact_min_frames", int, "measured frames each impact window needs", 3, 1000),
    ParamSpec("split.approach_distance", float, "[m] closest approach to a rim line that may be an impact",
              0.0, 0.5),
    ParamSpec("split.contact_tolerance", float, "[m] the lines before and after must meet this close to the rim",
              0.0, 0.5),
    ParamSpec("split.min_normal_speed", float, "[m/s] slower impacts are left out", 0.0, 10.0),
    ParamSpec("split.field_grid", list, "cells along x and y of the table acceleration field check", 1.0, 100.0, 2),
    ParamSpec("split.field_min_windows", int, "free-flight windows a cell of the field check needs", 2, 100000),
    ParamSpec("split.field_significance", float, "p-value below which the free flight shows a field", 0.0, 1.0),
    ParamSpec("split.rim_offset_warning", float, "[m] a rim line farther than this from the model's (and 3 "
              "standard errors) is warned about", 0.0, 0.1),
    ParamSpec("split.significance", float, "[-] standard errors beyond which an effect counts (rim offsets, "
              "table geometry, rates at 0)", 0.0, 100.0),
    ParamSpec("random_samples", int, "HEBO's initial random suggestions", 1, 1000),
    ParamSpec("polish_evaluations", int, "Nelder-Mead evaluations after HEBO (0 = off)", 0, 100000),
    ParamSpec("stride", int, "predict from every stride-th frame with a state while optimising", 1, 1000),
    ParamSpec("calibrated_nis", list, "NIS median band of a calibrated filter (--loss loglik)", 0.0, 1000.0, 2),
    ParamSpec("bound_margin", float, "[-] share of a search range within which a result is on its bound", 0.0, 0.5),
    ParamSpec("workers", int, "processes evaluating a batch in parallel", 1, 64),
    ParamSpec("frozen_threshold", float, "[m] frozen-frame threshold", 0.0, 1.0),
    ParamSpec("max_gap", float, "[s] time without frames that ends a trajectory", 0.01, 60.0),
    ParamSpec("rest_speed", float, "[m/s] speed below which the puck is at rest", 0.0, 10.0),
    ParamSpec("rest_window", float, "[s] window of the rest test", 0.001, 10.0),
    ParamSpec("push_window", float, "[s] chord of the speed a hand's push or grab is told by", 0.001, 10.0),
    ParamSpec("push_speed_gain", float, "[m/s] speed gained between two chords that no table gives", 0.0, 100.0),
    ParamSpec("push_rim_margin", float, "[m] chords this near a rim line are not judged", 0.0, 1.0),
    ParamSpec("push_memory", float, "[s] span over which a slow hand's speed gain adds up", 0.0, 10.0),
    ParamSpec("min_duration", float, "[s] shortest trajectory kept", 0.0, 600.0),
)


def load_sysid_params(extra_files: Iterable[Path] = ()) -> dict[str, Any]:
    return load_node_params(PARAM_FILES, NODE_NAME, SYSID_PARAMS, extra_files)


def bounds(params: dict[str, Any], names: Iterable[str] | None = None) -> dict[str, tuple[float, float]]:
    """Search box per identified parameter (default: ``core.identification.sysid.PHYSICAL``, in its order)."""
    from air_hockey_agent.core.identification.sysid import PHYSICAL
    return {name: tuple(params[f"bounds.{name}"]) for name in (PHYSICAL if names is None else names)}
