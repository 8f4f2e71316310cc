"""Parameters of the visualizer (ROS-free declarations; defaults in ``config/table.yaml`` and
``config/visualizer.yaml``)."""
from __future__ import annotations

from typing import Any, Mapping

from air_hockey_agent.core.scene import SceneStyle
from air_hockey_agent.params import ParamSpec
from air_hockey_agent.sim.params import ROBOT_BASE_PARAMS, ROBOTS
from air_hockey_agent.tracker_params import MALLET_RADIUS_PARAM, MOCAP_POSE_PARAM, PUCK_HEIGHT_PARAM, TABLE_PARAMS

PARAM_FILES = ("table.yaml", "visualizer.yaml")
COLOR_NAMES = ("table", "rim", "puck", "measurement", "prediction", "impact", "text") + ROBOTS

VISUALIZER_PARAMS = TABLE_PARAMS + (
    MALLET_RADIUS_PARAM,
    PUCK_HEIGHT_PARAM,
    MOCAP_POSE_PARAM,
    ParamSpec("rate", float, "[Hz] scenes per simulated second", 0.1, 1000.0),
    ParamSpec("tracker", str, "robot whose puck_tracker's estimate and prediction are drawn", choices=ROBOTS),
    ParamSpec("line_width", float, "[m] width of rims and paths", 0.0001, 0.1),
    ParamSpec("text_size", float, "[m] height of labels", 0.001, 1.0),
    ParamSpec("rim_height", float, "[m] drawn rim height", 0.0, 0.5),
    ParamSpec("mallet_height", float, "[m] drawn mallet height", 0.001, 0.5),
    ParamSpec("arrow_time", float, "[s] velocity arrows cover this much motion", 0.0, 10.0),
) + tuple(ParamSpec(f"color.{name}", list, f"RGBA colour of {name}", 0.0, 1.0, 4) for name in COLOR_NAMES) \
    + ROBOT_BASE_PARAMS


def scene_style(params: Mapping[str, Any]) -> SceneStyle:
    """The scene's sizes and colours from the visualizer's parameters."""
    return SceneStyle(params["line_width"], params["text_size"], params["rim_height"], params["puck.height"],
                      params["mallet.radius"], params["mallet_height"], params["arrow_time"],
                      {name: tuple(params[f"color.{name}"]) for name in COLOR_NAMES})
