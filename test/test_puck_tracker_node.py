"""The puck_tracker node (separate process): stream in, state and prediction out, the four services."""
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from air_hockey_agent.tools.launch import ProcessSpec
from helpers.ros_wait import call_service, spin_until

pytestmark = pytest.mark.integration
DT = 1.0 / 120.0
TABLE_X = 1.504  # mocap_table_pose x in config/table.yaml


@pytest.fixture
def tracker(launcher):
    exe = Path(sys.executable).parent / "puck_tracker"
    return launcher.start(ProcessSpec("puck_tracker", [str(exe), "--ros-args", "-p", "prediction_horizon:=0.5"]))


@pytest.mark.parametrize("kind", ["ukf", "mee_ukf", "imm"])
def test_each_filter_tracks_in_the_node(launcher, rclpy_node, kind):
    """`-p filter:=...` selects the estimator in the live node (issue #13: each selectable by parameter)."""
    from air_hockey_msgs.msg import PuckState
    from geometry_msgs.msg import PoseStamped
    exe = Path(sys.executable).parent / "puck_tracker"
    node = launcher.start(ProcessSpec(f"puck_tracker_{kind}", [str(exe), "--ros-args", "-p", f"filter:={kind}"]))
    states = []
    pub = rclpy_node.create_publisher(PoseStamped, "/optitrack/puck", 10)
    rclpy_node.create_subscription(PuckState, "/puck/state", states.append, 50)
    assert spin_until(rclpy_node, lambda: pub.get_subscription_count() > 0, 30.0), "tracker not discovered"
    frame = [0]

    def feed() -> bool:
        k = frame[0]
        frame[0] += 1
        pub.publish(pose(1.0 + k * DT, -0.5 + 1.0 * k * DT, 0.1))
        return len(states) > 30

    assert spin_until(rclpy_node, feed, 30.0), f"got {len(states)} states"
    assert states[-1].vx == pytest.approx(1.0, abs=0.1) and states[-1].y == pytest.approx(0.1, abs=1e-3)
    assert node.returncode is None


def pose(t, x, y, yaw=0.0):
    from geometry_msgs.msg import PoseStamped
    msg = PoseStamped()
    msg.header.stamp.sec, msg.header.stamp.nanosec = int(t), int(round((t - int(t)) * 1e9))
    msg.header.frame_id = "mocap"
    msg.pose.position.x, msg.pose.position.y = x + TABLE_X, y
    msg.pose.orientation.z, msg.pose.orientation.w = math.sin(yaw / 2), math.cos(yaw / 2)
    return msg


def test_stream_gives_state_and_prediction_and_survives_bad_frames(tracker, rclpy_node):
    from air_hockey_msgs.msg import PuckPrediction, PuckState
    from geometry_msgs.msg import PoseStamped

    states, predictions = [], []
    pub = rclpy_node.create_publisher(PoseStamped, "/optitrack/puck", 10)
    rclpy_node.create_subscription(PuckState, "/puck/state", states.append, 50)
    rclpy_node.create_subscription(PuckPrediction, "/puck/prediction", predictions.append, 50)
    assert spin_until(rclpy_node, lambda: pub.get_subscription_count() > 0, 30.0), "tracker not discovered"
    assert spin_until(rclpy_node, lambda: rclpy_node.count_publishers("/puck/state") > 0, 30.0)
    bad = pose(0.0, 0.0, 0.0)
    bad.pose.position.x = float("nan")
    frame = [0]

    def feed() -> bool:
        k = frame[0]
        frame[0] += 1
        pub.publish(bad if k == 5 else pose(1.0 + k * DT, -0.5 + 1.0 * k * DT, 0.1))
        return len(states) > 20 and len(predictions) > 5

    assert spin_until(rclpy_node, feed, 30.0), f"got {len(states)} states, {len(predictions)} predictions"
    last = states[-1]
    # constant 1 m/s input, while the model expects damping: the estimate sits a little below 1 m/s
    assert last.header.frame_id == "table" and last.vx == pytest.approx(1.0, abs=0.1)
    assert last.y == pytest.approx(0.1, abs=1e-3)
    pred = predictions[-1]
    assert pred.states and pred.states[-1].x > last.x
    assert tracker.returncode is None, "tracker died on a malformed frame"


def test_services_answer_and_refuse_bad_requests(tracker, rclpy_node):
    from air_hockey_msgs.msg import PuckPhysics
    from air_hockey_msgs.srv import KalmanStep, ResetFilter, SetNoiseCovariance, SetPhysicalParams
    from rclpy.qos import DurabilityPolicy, QoSProfile

    def call(kind, name, **fields):
        return call_service(rclpy_node, rclpy_node.create_client(kind, name), kind.Request(**fields), 30.0)

    physics = []  # latched: the configured physics at start, then every change
    rclpy_node.create_subscription(PuckPhysics, "/puck/physics", physics.append,
                                   QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL))
    assert spin_until(rclpy_node, lambda: physics, 30.0), "no puck/physics"
    assert physics[0].damping == 0.125 and physics[0].restitution_knee == 0.5  # config/tracker.yaml
    assert physics[0].impacts_learned == physics[0].windows_learned == 0

    bad = call(SetPhysicalParams, "/set_physical_params", friction_surface=-0.1, damping=0.5, restitution=0.9,
               friction_rim=0.1)
    assert bad is not None and not bad.success and "friction_surface" in bad.message
    assert not call(SetPhysicalParams, "/set_physical_params", friction_surface=0.0, damping=0.5,
                    restitution=1.5, friction_rim=0.1).success
    assert call(SetPhysicalParams, "/set_physical_params", friction_surface=0.0, damping=0.5, restitution=0.9,
                friction_rim=0.1).success
    assert spin_until(rclpy_node, lambda: physics[-1].damping == 0.5, 10.0), "new parameters not on puck/physics"
    assert (physics[-1].restitution, physics[-1].friction_rim, physics[-1].restitution_slope) == (0.9, 0.1, 0.193)
    not_pd = call(SetNoiseCovariance, "/set_noise_covariance", measurement_covariance=list(np.diag([1.0, -1.0, 1.0]).ravel()))
    assert not not_pd.success and "positive definite" in not_pd.message
    set_r = call(SetNoiseCovariance, "/set_noise_covariance", measurement_covariance=list(np.diag([1e-8, 1e-8, 1e-4]).ravel()))
    assert set_r.success and "(the marker noise is no longer learned online)" in set_r.message  # an R set by hand
    set_q = call(SetNoiseCovariance, "/set_noise_covariance", process_covariance=list(np.diag([1e-10, 1e-10, 1e-7, 1e-7,
                                                                                              1e-6, 1e-6]).ravel()))
    assert set_q.success and "(the process noise is no longer learned online)" in set_q.message  # a Q too
    assert call(ResetFilter, "/reset").success
    from builtin_interfaces.msg import Time
    responses = [call(KalmanStep, "/kalman_step", stamp=Time(sec=10, nanosec=int(k * DT * 1e9)), has_measurement=True,
                      x=0.01 * k, y=0.0, theta=0.0, prediction_horizon=0.5) for k in range(6)]
    # a track starts at its third frame (ACQUISITION_FRAMES: the first fit with a residual to check)
    assert not any(r.success for r in responses[:2]) and all(r.success for r in responses[2:])
    last = responses[-1]
    assert last.estimate.vx == pytest.approx(1.2, abs=0.1)
    a = 1.0 - DT * 0.5  # damping 0.5 1/s set above, no surface friction: 60 free steps in closed form
    travel = last.estimate.vx * DT * (1.0 - a ** 60) / (1.0 - a)
    assert last.prediction.x == pytest.approx(last.estimate.x + travel, abs=1e-6)
    # A state set by hand with a zero stamp holds at the next frame: that frame is fused, not a restart.
    from air_hockey_msgs.msg import PuckState
    reset = call(ResetFilter, "/reset", has_initial_state=True, initial_state=PuckState(x=0.3, y=-0.1))
    assert reset.success
    step = call(KalmanStep, "/kalman_step", stamp=Time(sec=20), has_measurement=True, x=0.3002, y=-0.1, theta=0.0)
    assert step.success and step.estimate.flags == PuckState.FLAG_MEASUREMENT_USED
    assert step.estimate.header.stamp.sec == 20


def test_physics_messages_carry_every_parameter_and_refuse_invalid_ones():
    """puck/physics (tracker -> tactics): what the message carries is the model's parameters exactly; a
    message with an invalid one (a restitution above 1, a NaN) is refused with its name."""
    from air_hockey_agent.core.estimation.ekf import PuckEKF
    from air_hockey_agent.nodes.messages import physics_from_msg, physics_msg
    from air_hockey_agent.tracker_params import load_tracker_params
    params = PuckEKF.from_params(load_tracker_params()).model.params
    learned = params.with_values(restitution=0.91, restitution_knee=0.3, tangential_restitution=-0.6,
                                 table_acceleration=(0.01, -0.02), damping=0.2, friction_surface=0.01)
    msg = physics_msg(learned, 12.5, impacts=7, windows=30)
    assert (msg.impacts_learned, msg.windows_learned, msg.stamp.sec, msg.stamp.nanosec) == (7, 30, 12, 500_000_000)
    assert physics_from_msg(msg) == learned
    for field, value in (("restitution", 1.2), ("damping", float("nan"))):
        setattr(msg, field, value)
        with pytest.raises(ValueError, match=field):
            physics_from_msg(msg)
        setattr(msg, field, getattr(learned, field))
