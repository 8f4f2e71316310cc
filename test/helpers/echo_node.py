"""Test helper node (separate process): echoes PuckState with x + 1 and answers ResetFilter.

Subscribes ``puck_in`` (air_hockey_msgs/PuckState), publishes ``puck_out``; service ``reset``
(air_hockey_msgs/ResetFilter) answers success with the initial x in its message.
"""
import sys

import rclpy
from air_hockey_msgs.msg import PuckState
from air_hockey_msgs.srv import ResetFilter
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node


class EchoNode(Node):
    def __init__(self):
        super().__init__("echo_node")
        self.pub = self.create_publisher(PuckState, "puck_out", 10)
        self.create_subscription(PuckState, "puck_in", self.on_puck, 10)
        self.create_service(ResetFilter, "reset", self.on_reset)
        self.get_logger().info("node ready: echo_node")

    def on_puck(self, msg: PuckState) -> None:
        msg.x += 1.0
        msg.flags |= PuckState.FLAG_PREDICTED
        self.pub.publish(msg)

    def on_reset(self, request, response):
        response.success = request.has_initial_state
        response.message = f"reset at x={request.initial_state.x:.3f}"
        return response


def main() -> int:
    rclpy.init(args=sys.argv)
    node = EchoNode()
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
