"""air_hockey_msgs types round-trip between two processes over a real topic and a service."""
import sys

import pytest

from helpers.ros_wait import call_service, spin_until
from conftest import HELPERS
from air_hockey_agent.tools.launch import ProcessSpec

pytestmark = pytest.mark.integration


def test_puck_state_and_service_round_trip_between_processes(launcher, rclpy_node):
    from air_hockey_msgs.msg import PuckState
    from air_hockey_msgs.srv import ResetFilter

    echo = launcher.start(ProcessSpec("echo_node", [sys.executable, str(HELPERS / "echo_node.py")]))
    received = []
    pub = rclpy_node.create_publisher(PuckState, "puck_in", 10)
    rclpy_node.create_subscription(PuckState, "puck_out", received.append, 10)

    assert spin_until(rclpy_node, lambda: pub.get_subscription_count() > 0, timeout=20.0), "echo node not discovered"
    sent = PuckState(x=0.25, y=-0.1, vx=1.5, vy=-0.5, theta=0.3, omega=2.0)
    sent.covariance[7] = 4e-6
    sent.header.frame_id = "table"

    def echoed() -> bool:
        if not received:
            pub.publish(sent)  # re-send until the subscription is matched on both ends
        return bool(received)

    assert spin_until(rclpy_node, echoed, timeout=20.0), "no PuckState came back"
    back = received[0]
    assert back.x == pytest.approx(1.25) and back.vx == 1.5 and back.omega == 2.0
    assert back.covariance[7] == 4e-6 and back.header.frame_id == "table"
    assert back.flags & PuckState.FLAG_PREDICTED

    client = rclpy_node.create_client(ResetFilter, "reset")
    response = call_service(rclpy_node, client,
                            ResetFilter.Request(has_initial_state=True, initial_state=PuckState(x=-0.5)), 20.0)
    assert response is not None and response.success and response.message == "reset at x=-0.500"

    assert launcher.stop("echo_node") == 0, "echo node did not shut down cleanly on SIGINT"
    assert echo.returncode is not None
