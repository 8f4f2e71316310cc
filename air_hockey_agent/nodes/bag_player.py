"""``bag_player`` node: replay a rosbag2 bag (sqlite3 or MCAP) or a ROS 1 bag onto its original topics (a ROS 1 message
as the ROS 2 type of the same name).

Messages go out with their original spacing (divided by ``rate``), unchanged (header stamps included),
optionally looping; with ``publish_clock`` the bag's time is published on ``/clock`` so that nodes with
``use_sim_time`` run on it. The puck tracker and the whole agent run against a replay exactly as
against the simulation. Parameters: ``bag`` (path), ``rate``, ``loop``, ``publish_clock``, ``topics``
(comma-separated; empty = all). The bag is only read.
"""
from __future__ import annotations

import sys

import rclpy
from rclpy._rclpy_pybind11 import RCLError
from rclpy.executors import ExternalShutdownException
from rosgraph_msgs.msg import Clock

from air_hockey_agent.bags.playback import paced
from air_hockey_agent.bags.reader import BagError, bag_topics, iter_raw
from air_hockey_agent.nodes.messages import message_class, to_stamp
from air_hockey_agent.nodes.runtime import AirHockeyNode, NodeStartupError, run
from air_hockey_agent.tool_node_params import PLAYER_PARAMS


class BagPlayerNode(AirHockeyNode):
    NAME = "bag_player"
    DESCRIPTION = __doc__
    PARAM_FILES = ("bag_player.yaml",)
    PARAMS = PLAYER_PARAMS

    def __init__(self) -> None:
        super().__init__()
        p = self.params
        if not p["bag"]:
            raise NodeStartupError("no bag given: set the parameter bag (-p bag:=PATH)")
        wanted = [t.strip() for t in p["topics"].split(",") if t.strip()]
        try:
            available = bag_topics(p["bag"])
        except BagError as exc:
            raise NodeStartupError(str(exc)) from None
        missing = [t for t in wanted if t not in available]
        if missing:
            raise NodeStartupError(f"{p['bag']}: no topic {', '.join(missing)} "
                                   f"(topics: {', '.join(sorted(available))})")
        self.publishers_by_topic = {}
        for topic, msgtype in available.items():
            if wanted and topic not in wanted:
                continue
            try:
                self.publishers_by_topic[topic] = self.create_publisher(message_class(msgtype), topic, 10)
            except (ImportError, AttributeError, ValueError):
                self.get_logger().warn(f"{topic}: type {msgtype} is not installed; not replayed")
        self.clock_pub = self.create_publisher(Clock, "/clock", 10) if p["publish_clock"] else None
        self.get_logger().info(f"replaying {p['bag']}: {', '.join(self.publishers_by_topic)} at rate {p['rate']:g}"
                               + (", looping" if p["loop"] else ""))

    def spin(self) -> None:
        p = self.params
        count = 0
        try:
            for topic, bag_ns, raw in paced(lambda: iter_raw(p["bag"], self.publishers_by_topic), p["rate"],
                                            p["loop"]):
                if not rclpy.ok(context=self.context):
                    break
                if self.clock_pub is not None:
                    self.clock_pub.publish(Clock(clock=to_stamp(bag_ns * 1e-9)))
                self.publishers_by_topic[topic].publish(raw)
                count += 1
        except (RCLError, ExternalShutdownException):
            if rclpy.ok(context=self.context):
                raise
        except BagError as exc:
            self.get_logger().error(f"replay stopped: {exc}")
        if rclpy.ok(context=self.context):
            self.get_logger().info(f"replay finished: {count} messages")


def main(argv: list[str] | None = None) -> int:
    return run(BagPlayerNode, argv)


if __name__ == "__main__":
    sys.exit(main())
