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


def test_a_mallet_hits_the_unseen_puck_in_the_node(tracker, rclpy_node):
    """With the mallets (``mallet_contact.enabled``, the default): 0.5 s of poses of a resting puck, then none
    (a dropout) while ``/iiwa_front/joint_states`` (100 Hz; one message lacking joints first) turn the arm's
    first joint at 2 rad/s so its mallet sweeps through the puck: the node publishes the coasted estimate
    (FLAG_PREDICTED) with the hit's velocity, across the arc, and survives the bad message."""
    from air_hockey_msgs.msg import PuckState
    from geometry_msgs.msg import PoseStamped
    from sensor_msgs.msg import JointState
    from air_hockey_agent.core.motion.kinematics import ArmKinematics
    from air_hockey_agent.paths import model_path
    kin = ArmKinematics(model_path("iiwa14_striker.urdf"))
    base = np.array([-1.504, 0.0])  # config/table.yaml robot_base.iiwa_front (yaw 0)
    home = np.zeros(len(kin.joint_names))
    home[:7] = [0.0, 0.1943, 0.0, -1.3341, 0.0, 1.2999, 0.0]  # config/sim.yaml home_joint_positions
    puck = np.array(kin.tip_in_table(home, [*base, -0.07, 0.0]))
    radius, w = float(np.hypot(*(puck - base))), 2.0
    start = -(0.03165 + 0.04815 + 0.05) / radius  # [rad] the mallet 5 cm clear of the puck on its arc
    states = []
    poses = rclpy_node.create_publisher(PoseStamped, "/optitrack/puck", 10)
    joints = rclpy_node.create_publisher(JointState, "/iiwa_front/joint_states", 10)
    rclpy_node.create_subscription(PuckState, "/puck/state", states.append, 200)
    assert spin_until(rclpy_node, lambda: poses.get_subscription_count() > 0 and joints.get_subscription_count() > 0,
                      30.0), "tracker not discovered"
    step = [0]

    def joint_state(t, names, q, dq=()):
        msg = JointState(name=list(names), position=[float(v) for v in q], velocity=[float(v) for v in dq])
        msg.header.stamp.sec, msg.header.stamp.nanosec = int(t), int(round((t - int(t)) * 1e9))
        return msg

    def feed() -> bool:
        k = step[0]
        step[0] += 1
        if k < 60:
            poses.publish(pose(1.0 + k * DT, *puck))
        elif k == 60:
            joints.publish(joint_state(1.5, kin.joint_names[:3], home[:3]))
        else:
            t = 1.5 + (k - 61) * 0.01
            q, dq = home.copy(), np.zeros(len(home))
            q[0], dq[0] = start + w * (t - 1.5), w  # with the joint velocities (the mallet's velocity from them)
            joints.publish(joint_state(t, kin.joint_names, q, dq))
        return any(s.flags & PuckState.FLAG_PREDICTED and math.hypot(s.vx, s.vy) > 1.0 for s in states) or k > 120

    assert spin_until(rclpy_node, feed, 60.0)
    hit = [s for s in states if s.flags & PuckState.FLAG_PREDICTED and math.hypot(s.vx, s.vy) > 1.0]
    assert hit, f"no coasted estimate with the hit in {len(states)} states"
    tangent = np.array([-(puck - base)[1], (puck - base)[0]]) / radius  # the mallet's direction of travel
    assert np.array([hit[0].vx, hit[0].vy]) @ tangent > 0.9 * w * radius  # at least the mallet's speed
    assert tracker.returncode is None, "tracker died on a joint state without its joints"


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
