"""Parameters of the table simulation (ROS-free declarations; defaults in ``config/sim.yaml``)."""
from __future__ import annotations

from pathlib import Path
from typing import Any, Iterable

from air_hockey_agent.core.estimation.synthetic import MOCAP_BOUNDS, MOCAP_FIELDS
from air_hockey_agent.params import ParamSpec, load_node_params
from air_hockey_agent.tracker_params import (MOCAP_POSE_PARAM, PUCK_HEIGHT_PARAM, ROBOT_BASE_PARAMS, ROBOTS,
                                             TABLE_PARAMS)

__all__ = ["NODE_NAME", "PARAM_FILES", "ROBOTS", "ROBOT_BASE_PARAMS", "SIM_PARAMS", "load_sim_params"]

NODE_NAME = "/table_sim"
PARAM_FILES = ("table.yaml", "sim.yaml")
# ROBOTS and ROBOT_BASE_PARAMS (config/table.yaml) are the tracker's too: imported from tracker_params

SIM_PARAMS = TABLE_PARAMS + (
    PUCK_HEIGHT_PARAM,
    ParamSpec("physics_rate", float, "[Hz] physics step rate", 100.0, 10000.0),
    ParamSpec("real_time_factor", float, "sim seconds per wall second; 0 = as fast as possible", 0.0, 1000.0),
    ParamSpec("gui", bool, "open the pybullet window (top view)"),
    ParamSpec("clock_rate", float, "[Hz] /clock messages per simulated second", 1.0, 10000.0),
    ParamSpec("joint_state_rate", float, "[Hz] joint_states messages per simulated second", 1.0, 10000.0),
    ParamSpec("home_joint_positions", list, "[rad] home configuration of the 7 arm joints", -3.1, 3.1, 7),
    ParamSpec("surface_friction", float, "[m/s^2] air-cushion friction deceleration (eq. 3.1)", 0.0, 10.0),
    ParamSpec("surface_damping", float, "[1/s] air-cushion viscous damping (eq. 3.1)", 0.0, 10.0),
    ParamSpec("surface_tilt", float, "[rad] slope of the surface (core/puck/surface_field.py; 0: level)", 0.0, 0.1),
    ParamSpec("surface_tilt_heading", float, "[rad] direction (table frame) the surface falls toward", -7.0, 7.0),
    ParamSpec("air_film_amplitude", float, "[m/s^2] peak acceleration of an uneven air film's field (0: even)",
              0.0, 10.0),
    ParamSpec("air_film_wavelength", float, "[m] wavelength of the air film's field", 0.01, 100.0),
    ParamSpec("air_film_phase", list, "[rad] phases p1 p2 of the air film's field along y and x", -7.0, 7.0, 2),
    ParamSpec("random_acceleration", float, "[m/s^2] std per axis of the surface's random accelerations "
              "(core/puck/surface_field.py RandomPush; 0: none)", 0.0, 10.0),
    ParamSpec("random_acceleration_time", float, "[s] how long one random acceleration holds", 0.001, 100.0),
    ParamSpec("rim_restitution", float, "[-] puck-rim restitution e (Poisson, sim/rim_contact.py)", 0.0, 1.0),
    ParamSpec("rim_restitution_slope", float, "[s/m] the rim restitution falls by this per m/s of normal "
              "impact speed beyond rim_restitution_knee (0: constant)", 0.0, 10.0),
    ParamSpec("rim_restitution_knee", float, "[m/s] normal impact speed from which the rim restitution falls",
              0.0, 10.0),
    ParamSpec("rim_restitution_min", float, "[-] the falling rim restitution's floor", 0.0, 1.0),
    ParamSpec("rim_friction", float, "[-] puck-rim Coulomb friction (sim/rim_contact.py)", 0.0, 2.0),
    ParamSpec("rim_tangential_scale", float, "[-] the rim's tangential impulse as a share of the rigid-body "
              "(Coulomb) one (1: the thesis's Routh impact; below 1: softer)", 0.0, 1.0),
    ParamSpec("mallet_restitution", float, "[-] puck-mallet restitution", 0.0, 1.0),
    ParamSpec("mallet_friction", float, "[-] puck-mallet lateral friction", 0.0, 2.0),
    ParamSpec("contact_erp", float, "[-] contact error reduction parameter", 0.0, 1.0),
    ParamSpec("striker_control_rate", float, "[Hz] rate of the universal-joint (vertical mallet) control",
              1.0, 10000.0),
    ParamSpec("mocap_rate", float, "[Hz] OptiTrack stand-in frame rate", 1.0, 1000.0),
    MOCAP_POSE_PARAM,
    ParamSpec("callback_period", float, "[s] simulated time between two rounds of ROS callbacks", 1e-4, 1.0),
    ParamSpec("status_period", float, "[s] wall time between two progress lines in the log", 0.1, 3600.0),
    ParamSpec("max_lag", float, "[s] lag behind real_time_factor after which pacing re-anchors", 0.01, 60.0),
    ParamSpec("seed", int, "random seed of the mocap imperfections and the random accelerations", 0, 2**31 - 1),
    ParamSpec("lockstep_lead", float, "[s] as fast as possible: stay at most this far ahead of the agents' "
              "<robot>/sim_sync clocks (0: off)", 0.0, 10.0),
    ParamSpec("lockstep_timeout", float, "[s] wall time after which a silent agent is no longer waited for",
              0.01, 600.0),
) + ROBOT_BASE_PARAMS + tuple(
    ParamSpec(f"mocap.{name}", float, "OptiTrack stand-in imperfection (config/sim.yaml)", *MOCAP_BOUNDS[name])
    for name in MOCAP_FIELDS if name != "capture_jitter_std") + (
    ParamSpec("mocap.capture_jitter_std", float, "[s] must be 0: the stand-in captures at the simulation's ticks "
              "(its stamps scatter by mocap.jitter_std)", 0.0, 0.0),)


def load_sim_params(extra_files: Iterable[Path] = ()) -> dict[str, Any]:
    """Simulation parameters: the defaults, overridden by ``extra_files`` (ROS 2 parameter YAML)."""
    return load_node_params(PARAM_FILES, NODE_NAME, SIM_PARAMS, extra_files)
