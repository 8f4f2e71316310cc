"""Parameters of the referee (ROS-free declarations; defaults in ``config/table.yaml`` and ``config/referee.yaml``)."""
from __future__ import annotations

from air_hockey_agent.params import ParamSpec
from air_hockey_agent.sim.params import ROBOT_BASE_PARAMS
from air_hockey_agent.tracker_params import MALLET_RADIUS_PARAM, MOCAP_POSE_PARAM, TABLE_PARAMS

NODE_NAME = "/referee"
PARAM_FILES = ("table.yaml", "referee.yaml")

REFEREE_PARAMS = TABLE_PARAMS + (
    MALLET_RADIUS_PARAM,
    MOCAP_POSE_PARAM,
    ParamSpec("rate", float, "[Hz] rule checks per simulated second", 1.0, 10000.0),
    ParamSpec("status_period", float, "[s] GameStatus re-publication period", 0.01, 3600.0),
    ParamSpec("goal_margin", float, "[m] puck centre behind a goal line for a goal", 0.0, 1.0),
    ParamSpec("out_margin", float, "[m] puck centre beyond a rim for puck out", 0.0, 1.0),
    ParamSpec("lost_timeout", float, "[s] no puck pose for this long is puck out", 0.01, 3600.0),
    ParamSpec("confirm_frames", int, "poses in a row beyond a line for a goal or a puck out", 1, 1000),
    ParamSpec("vanish_time", float, "[s] a puck last seen beyond a line and unseen this long has gone there", 0.0, 60.0),
    ParamSpec("stuck_radius", float, "[m] movement below which the puck is at rest", 0.0, 1.0),
    ParamSpec("stuck_time", float, "[s] at rest in the neutral zone for this long is stuck", 0.0, 3600.0),
    ParamSpec("neutral_zone_length", float, "[m] zone around the centre line no robot reaches", 0.0, 5.0),
    ParamSpec("possession_limit", float, "[s] puck on one side for this long is a foul", 0.1, 3600.0),
    ParamSpec("centre_line_margin", float, "[m] mallet this far into the opponent's half is a fault", 0.0, 1.0),
    ParamSpec("rim_margin", float, "[m] mallet overlap with a rim tolerated", -1.0, 1.0),
    ParamSpec("pause_duration", float, "[s] pause after an event before play resumes", 0.0, 3600.0),
    ParamSpec("restart_after_fault", bool, "a robot fault pauses and resets instead of stopping"),
    ParamSpec("reset_x_range", list, "[m] |x| range of a reset puck", 0.0, 5.0, 2),
    ParamSpec("reset_y_margin", float, "[m] reset puck distance from the long rims beyond its radius", 0.0, 1.0),
    ParamSpec("sim", bool, "reset puck and robots through table_sim's services"),
    ParamSpec("seed", int, "random seed of reset positions", 0, 2**31 - 1),
) + ROBOT_BASE_PARAMS
