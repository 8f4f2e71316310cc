"""Parameters of the reference filter of ``air-hockey eval-prediction --reference`` (ROS-free declarations;
the values and where they come from in ``config/reference_filter.yaml``)."""
from __future__ import annotations

from pathlib import Path
from typing import Any, Iterable

from air_hockey_agent.params import ParamSpec, load_node_params

NODE_NAME = "/reference_filter"
PARAM_FILES = ("reference_filter.yaml",)
REFERENCE_PARAMS = (
    ParamSpec("damping", list, "[1/s] linear damping along x and y", 0.0, 10.0, 2),
    ParamSpec("step", float, "[s] the step the process noise is given for", 1e-4, 1.0),
    ParamSpec("process_noise", list, "process noise variances per step (x, y, vx, vy, theta, omega; SI)",
              0.0, 1e3, 6),
    ParamSpec("measurement_noise", list, "measurement noise variances (x, y [m^2], theta [rad^2])", 1e-12, 1e3, 3),
    ParamSpec("initial_covariance", float, "[-] a track's first covariance: this times the identity", 1e-9, 1e6),
    ParamSpec("rim.tangential", list, "rim map vt' = a vt + b omega: a [-], b [m/rad]", -10.0, 10.0, 2),
    ParamSpec("rim.restitution", float, "[-] rim map vn' = -e vn", 0.0, 1.0),
    ParamSpec("rim.spin", list, "rim map omega' = a vt + b s vn + c omega: a, b [rad/m], c [-]", -1e3, 1e3, 3),
    ParamSpec("rim.noise", list, "process noise of an impact step in the rim's frame: var vt, var vn, cov vt vn, "
              "cov vt omega, cov vn omega, var omega (SI)", -1e4, 1e4, 6),
)


def load_reference_params(extra_files: Iterable[Path] = ()) -> dict[str, Any]:
    """The reference filter's parameters: ``config/reference_filter.yaml`` overridden by ``extra_files``."""
    return load_node_params(PARAM_FILES, NODE_NAME, REFERENCE_PARAMS, extra_files)
