"""One robot's agent (puck_tracker, tactics, trajectory_generator in the robot's namespace), for a real
table or the simulation:

    ros2 launch air_hockey_agent agent.launch.py robot:=iiwa_front [use_sim_time:=false] [sim_table:=false]

The nodes and their parameters are ``air_hockey_agent.node_graph.agent_nodes``'s, as `air-hockey game`
starts them. ``sim_table:=true`` gives the tracker and the tactics the simulated table's puck physics
(``config/tracker_sim_table.yaml``); by default they take the tracker's defaults, a real table's. Add a
node's own parameters with ``ros2 param set`` or by editing ``config/`` (README "Parameters").
"""
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction

from air_hockey_agent.node_graph import ROBOTS, agent_nodes, launch_flag, ros_launch_nodes


def _nodes(context):
    config = context.launch_configurations
    return ros_launch_nodes(agent_nodes(config["robot"], launch_flag("use_sim_time", config["use_sim_time"]),
                                        launch_flag("sim_table", config["sim_table"])))


def generate_launch_description() -> LaunchDescription:
    return LaunchDescription([
        DeclareLaunchArgument("robot", choices=list(ROBOTS), description="which arm this agent plays"),
        DeclareLaunchArgument("use_sim_time", default_value="false", choices=["true", "false"],
                              description="run on /clock (the simulation's) instead of the wall clock"),
        DeclareLaunchArgument("sim_table", default_value="false", choices=["true", "false"],
                              description="the simulated table's puck physics instead of a real table's"),
        OpaqueFunction(function=_nodes),
    ])
