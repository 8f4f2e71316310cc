"""The simulated two-robot game (table_sim, referee, both agents; with ``markers:=true`` the visualizer):

    ros2 launch air_hockey_agent game.launch.py [gui:=true] [real_time_factor:=1.0] [seed:=0] [markers:=false]
        [table:=FILE]

then start play with ``ros2 service call /referee/start_game std_srvs/srv/Trigger``. The nodes and their
parameters are ``air_hockey_agent.node_graph.game_nodes``'s, the graph `air-hockey game` starts (which
also starts play, follows the score and stops everything at the end). ``table:=FILE``: on another
simulated table (``air_hockey_agent.sim.table_file``; e.g. the package's ``config/lab_table.yaml``).
"""
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction

from air_hockey_agent.node_graph import game_nodes, launch_flag, launch_number, launch_table, ros_launch_nodes


def _nodes(context):
    config = context.launch_configurations
    return ros_launch_nodes(game_nodes(launch_flag("gui", config["gui"]),
                                       launch_number("real_time_factor", config["real_time_factor"], float),
                                       launch_number("seed", config["seed"], int),
                                       launch_flag("markers", config["markers"]),
                                       table_file=launch_table(config["table"])))


def generate_launch_description() -> LaunchDescription:
    return LaunchDescription([
        DeclareLaunchArgument("gui", default_value="false", choices=["true", "false"],
                              description="open the pybullet window"),
        DeclareLaunchArgument("real_time_factor", default_value="1.0",
                              description="simulation speed: 1 watchable, >1 faster, 0 as fast as possible"),
        DeclareLaunchArgument("seed", default_value="0", description="seed of the simulation and the referee"),
        DeclareLaunchArgument("markers", default_value="false", choices=["true", "false"],
                              description="also the visualizer (/visualization/markers for RViz and Foxglove)"),
        DeclareLaunchArgument("table", default_value="",
                              description="a table file: play on another simulated table (default: config/sim.yaml's)"),
        OpaqueFunction(function=_nodes),
    ])
