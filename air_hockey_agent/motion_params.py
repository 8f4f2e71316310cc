"""Parameters of the motion layer (ROS-free declarations; defaults in ``config/table.yaml`` and
``config/motion.yaml``) and the planner they build, shared by the ``trajectory_generator`` node and
``air-hockey bench planner``."""
from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any, Iterable

from air_hockey_agent.params import ParamSpec, load_node_params
from air_hockey_agent.sim.params import ROBOT_BASE_PARAMS, ROBOTS
from air_hockey_agent.tracker_params import MALLET_RADIUS_PARAM, TABLE_PARAMS

if TYPE_CHECKING:
    from air_hockey_agent.core.motion.planner import MotionPlanner

NODE_NAME = "/trajectory_generator"
PARAM_FILES = ("table.yaml", "motion.yaml")

MOTION_PARAMS = TABLE_PARAMS + (
    MALLET_RADIUS_PARAM,
    ParamSpec("robot", str, "which robot this node drives (iiwa_front or iiwa_back)"),
    ParamSpec("playing_height", float, "[m] mallet bottom above the surface while playing", 0.0, 0.1),
    ParamSpec("joint_velocity_limits", list, "[rad/s] joint velocity limits", 0.01, 10.0, 7),
    ParamSpec("joint_acceleration_limits", list, "[rad/s^2] joint acceleration limits", 0.1, 1000.0, 7),
    ParamSpec("position_limit_scale", float, "fraction of each joint range planned with", 0.1, 1.0),
    ParamSpec("velocity_limit_scale", float, "fraction of the velocity limits planned with", 0.1, 1.0),
    ParamSpec("acceleration_limit_scale", float, "fraction of the acceleration limits planned with", 0.1, 1.0),
    ParamSpec("reference_posture", list, "[rad] null-space reference posture", -3.1, 3.1, 7),
    ParamSpec("region_margin", float, "[m] mallet distance kept from rims and the centre line", 0.0, 0.3),
    ParamSpec("max_reach", float, "[m] largest mallet distance from the base axis", 0.3, 2.0),
    ParamSpec("sample_period", float, "[s] time between planned knots", 0.002, 0.1),
    ParamSpec("run_up_length", list, "[m] shortest and longest run-up before a hit", 0.01, 1.0, 2),
    ParamSpec("run_up_time", float, "[s] longest duration of a run-up", 0.05, 5.0),
    ParamSpec("follow_through_length", list, "[m] shortest and longest stop after a hit", 0.001, 1.0, 2),
    ParamSpec("follow_through_time", float, "[s] longest duration of the stop after a hit", 0.05, 100.0),
    ParamSpec("follow_through_deceleration", float, "[m/s^2] peak deceleration of the stop after a hit (0: none)",
              0.0, 100.0),
    ParamSpec("posture_gain", float, "[1/s] rate of null-space convergence to a posture", 0.1, 100.0),
    ParamSpec("posture_tolerance", float, "[rad] a posture counts as reached within this", 1e-5, 0.1),
    ParamSpec("reach_acceleration", float, "[m/s^2] task acceleration of reach-and-stop motions", 0.1, 50.0),
    ParamSpec("ik_iterations", int, "IK iterations", 1, 10000),
    ParamSpec("ik_tolerance", float, "[m] accepted IK position error", 1e-7, 0.01),
    ParamSpec("planning_delay", float, "[s] a hit closer than this to now is too late", 0.0, 1.0),
    ParamSpec("max_tracking_error", float, "[rad] measured-to-plan distance that drops the running plan", 0.001, 10.0),
    ParamSpec("height_transition", float, "[s] time to reach the playing height from elsewhere", 0.02, 5.0),
    ParamSpec("hit_posture_range", float, "fraction of the planning range a hit posture stays in", 0.1, 1.0),
) + ROBOT_BASE_PARAMS


def load_motion_params(extra_files: Iterable[Path] = ()) -> dict[str, Any]:
    """Motion parameters: the defaults, overridden by ``extra_files`` (ROS 2 parameter YAML)."""
    return load_node_params(PARAM_FILES, NODE_NAME, MOTION_PARAMS, extra_files)


def build_planner(params: dict[str, Any], robot: str) -> MotionPlanner:
    """The motion planner of ``robot``, in its own table frame (both robots share one code path). The motion
    stack (pinocchio, numba) is imported here, not with the declarations: every command's parameter checks
    read those (:mod:`air_hockey_agent.param_registry`)."""
    from air_hockey_agent.core.frames import table_to_robot
    from air_hockey_agent.core.motion.kinematics import MalletKinematics
    from air_hockey_agent.core.motion.limits import JointLimits
    from air_hockey_agent.core.motion.planner import MotionPlanner, MotionSettings
    from air_hockey_agent.core.motion.region import Region
    from air_hockey_agent.paths import model_path
    if robot not in ROBOTS:
        raise ValueError(f"robot must be one of {', '.join(ROBOTS)}, got '{robot}'")
    x, y, z, yaw = params[f"robot_base.{robot}"]
    bx, by, byaw = table_to_robot(x, y, yaw, robot)
    kin = MalletKinematics(model_path("iiwa14_striker.urdf"), (bx, by, z, byaw))
    limits = JointLimits.build(kin.q_lower, kin.q_upper, params)
    region = Region.for_table(params["table.length"], params["table.width"], params["mallet.radius"],
                              params["region_margin"], kin.base_xy, params["max_reach"])
    return MotionPlanner(kin, limits, region, MotionSettings.from_params(params))
