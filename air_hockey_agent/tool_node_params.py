"""Parameters of the two tool nodes, ``bag_player`` and ``prediction_optimizer`` (ROS-free declarations;
defaults in ``config/bag_player.yaml`` and ``config/prediction_optimizer.yaml``), apart from the nodes'
rclpy code so that every command's parameter checks (:mod:`air_hockey_agent.param_registry`) read them
without loading rclpy."""
from __future__ import annotations

from air_hockey_agent.params import ParamSpec
from air_hockey_agent.sysid_params import SYSID_PARAMS

PLAYER_PARAMS = (
    ParamSpec("bag", str, "rosbag2 bag directory (or its .mcap/.db3 file) or ROS 1 .bag file to replay"),
    ParamSpec("rate", float, "replay speed factor (1.0 = as recorded)", 1e-3, 1000.0),
    ParamSpec("loop", bool, "start again at the end"),
    ParamSpec("publish_clock", bool, "publish the bag's time on /clock"),
    ParamSpec("topics", str, "comma-separated topics to replay (empty: all)"),
)

OPTIMIZER_PARAMS = (
    ParamSpec("bags", str, "comma-separated bags or directories of bags"),
    ParamSpec("topic", str, "PoseStamped (or tf2_msgs/TFMessage) topic in the bags"),
    ParamSpec("frame", str, "the puck's child frame when topic is a TFMessage topic such as /tf"),
    ParamSpec("table_frame", str, "take the table pose from the bags' transform to this frame (empty: "
                                  "mocap_table_pose)"),
    ParamSpec("tracker", str, "namespace of the puck_tracker's services (e.g. /iiwa_front; empty: /)"),
    ParamSpec("horizon", float, "[s] prediction horizon of the loss", 0.05, 3.0),
    ParamSpec("iterations", int, "HEBO iterations", 1, 1000),
    ParamSpec("batch", int, "suggestions per iteration", 1, 100),
    ParamSpec("split", float, "training fraction of the trajectories", 0.0, 1.0),
    ParamSpec("seed", int, "seed of the split and of HEBO", 0, 2**31 - 1),
    ParamSpec("out", str, "parameter YAML to write (empty: do not write)"),
    ParamSpec("service_timeout", float, "[s] wait for each service answer", 0.1, 600.0),
) + SYSID_PARAMS
