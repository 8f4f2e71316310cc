"""The topics a recorded game holds (``air-hockey game --record``, node graph or in process), with their
message types. Light on purpose: the CLI imports it at start."""
from __future__ import annotations

from air_hockey_agent.sim.params import ROBOTS

MARKER_TOPICS = {"/visualization/markers": "visualization_msgs/msg/MarkerArray"}  # the visualizer's
RECORDED_TOPICS = {
    "/optitrack/puck": "geometry_msgs/msg/PoseStamped",
    "/sim/puck_true_state": "air_hockey_msgs/msg/PuckState",
    "/sim/contacts": "air_hockey_msgs/msg/MalletContact",
    "/game_status": "air_hockey_msgs/msg/GameStatus",
    **{f"/{r}/{t}": m for r in ROBOTS for t, m in (
        ("joint_states", "sensor_msgs/msg/JointState"), ("puck/state", "air_hockey_msgs/msg/PuckState"),
        ("puck/physics", "air_hockey_msgs/msg/PuckPhysics"),
        ("tactic", "air_hockey_msgs/msg/TacticState"), ("hit_command", "air_hockey_msgs/msg/HitCommand"),
        ("trajectory_status", "air_hockey_msgs/msg/TrajectoryStatus"),
        ("joint_trajectory", "trajectory_msgs/msg/JointTrajectory"))},
}
# published latched (transient local): a recorder subscribes to them so, or misses what came before it
LATCHED_TOPICS = frozenset({"/game_status", *(f"/{r}/{t}" for r in ROBOTS for t in ("tactic", "puck/physics"))})
