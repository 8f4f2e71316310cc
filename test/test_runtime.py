"""AirHockeyNode's endpoints: no per-endpoint QoS event handlers except on latched topics (nodes/runtime.py)."""
from __future__ import annotations

import os

import pytest


@pytest.fixture
def probe(ros_env):
    import rclpy
    from air_hockey_agent.nodes.runtime import AirHockeyNode

    class Probe(AirHockeyNode):
        NAME = "runtime_probe"

    os.environ["FASTRTPS_DEFAULT_PROFILES_FILE"] = ros_env["FASTRTPS_DEFAULT_PROFILES_FILE"]
    context = rclpy.Context()
    rclpy.init(context=context, domain_id=int(ros_env["ROS_DOMAIN_ID"]))
    node = Probe(context=context)
    try:
        yield node
    finally:
        node.executor_.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=context)


def test_plain_endpoints_have_no_event_handlers_and_latched_ones_keep_the_qos_warnings(probe):
    from rclpy.event_handler import PublisherEventCallbacks
    from rclpy.qos import DurabilityPolicy, QoSProfile
    from std_msgs.msg import String

    latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    assert probe.create_publisher(String, "plain", 10).event_handlers == []
    assert probe.create_subscription(String, "plain", lambda _: None, 10).event_handlers == []
    assert len(probe.create_publisher(String, "latched", latched).event_handlers) >= 1
    assert len(probe.create_subscription(String, "latched", lambda _: None, latched).event_handlers) >= 1
    # a caller's own callbacks are kept
    own = PublisherEventCallbacks(incompatible_qos=lambda _: None, use_default_callbacks=False)
    assert len(probe.create_publisher(String, "own", 10, event_callbacks=own).event_handlers) == 1
