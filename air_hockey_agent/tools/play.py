"""``air-hockey play BAG``: replay a bag onto its original topics (runs the ``bag_player`` node).

The same as ``ros2 run air_hockey_agent bag_player --ros-args -p bag:=BAG ...``: original timing divided
by ``--rate``, ``--loop`` to start again at the end, ``--clock`` to publish the bag's time on ``/clock``
for nodes with ``use_sim_time``, ``--topics`` to replay only some topics. Ctrl-C stops it.
"""
from __future__ import annotations

import argparse
import os
from pathlib import Path

from air_hockey_agent.tools.argtypes import count, number


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("play", help="replay a bag onto its topics (bag_player node)",
                                   description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("bag", type=Path, help="rosbag2 bag (directory, or its .mcap/.db3 file) or ROS 1 .bag file")
    parser.add_argument("--rate", type=number(0.0, low_open=True), default=1.0, help="speed factor (default 1.0)")
    parser.add_argument("--loop", action="store_true", help="start again at the end")
    parser.add_argument("--clock", action="store_true", help="publish the bag's time on /clock")
    parser.add_argument("--topics", nargs="+", default=[], metavar="TOPIC", help="only these topics")
    parser.add_argument("--domain-id", type=count(1, 101), default=None,
                        help="ROS_DOMAIN_ID (1..101; default: the environment's), as for game and record")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    from air_hockey_agent.nodes.bag_player import main
    if args.domain_id is not None:
        os.environ["ROS_DOMAIN_ID"] = str(args.domain_id)  # read by rclpy.init in the node
    ros_args = ["-p", f"bag:={args.bag}", "-p", f"rate:={args.rate}", "-p", f"loop:={str(args.loop).lower()}",
                "-p", f"publish_clock:={str(args.clock).lower()}"]
    if args.topics:
        ros_args += ["-p", f"topics:={','.join(args.topics)}"]
    return main(["bag_player", "--ros-args", *ros_args])
