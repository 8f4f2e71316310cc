"""The referee node (separate process) refereeing the table_sim node on sim time: goal, reset, resume, stop."""
import math
import sys
from pathlib import Path

import pytest

from air_hockey_agent.tools.launch import ProcessSpec
from helpers.ros_wait import call_service, spin_until

pytestmark = pytest.mark.integration
BIN = Path(sys.executable).parent


@pytest.fixture
def game(launcher):
    launcher.start(ProcessSpec("table_sim", [str(BIN / "table_sim"), "--ros-args", "-p", "real_time_factor:=2.0"]))
    launcher.start(ProcessSpec("referee", [str(BIN / "referee"), "--ros-args", "-p", "use_sim_time:=true",
                                           "-p", "pause_duration:=1.0"]))
    return launcher


def test_a_goal_scores_the_puck_is_put_back_and_play_resumes(game, rclpy_node):
    from air_hockey_msgs.msg import GameStatus, PuckState
    from air_hockey_msgs.srv import SetPuckState
    from rclpy.qos import DurabilityPolicy, QoSProfile
    from std_srvs.srv import Trigger

    statuses, truth = [], []
    latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    rclpy_node.create_subscription(GameStatus, "/game_status", statuses.append, latched)
    rclpy_node.create_subscription(PuckState, "/sim/puck_true_state", truth.append, 50)
    assert spin_until(rclpy_node, lambda: statuses and truth, 60.0), (len(statuses), len(truth))
    assert statuses[-1].status == GameStatus.STATUS_STOPPED

    # malformed input is logged and ignored: a NaN pose, joint states with too few positions
    from geometry_msgs.msg import PoseStamped
    from sensor_msgs.msg import JointState
    bad_pose = PoseStamped()
    bad_pose.pose.position.x = float("nan")
    rclpy_node.create_publisher(PoseStamped, "/optitrack/puck", 10).publish(bad_pose)
    rclpy_node.create_publisher(JointState, "/iiwa_front/joint_states", 10).publish(
        JointState(name=["iiwa_joint_1", "iiwa_joint_2"], position=[0.0]))

    start = rclpy_node.create_client(Trigger, "/referee/start_game")
    answers = []

    def started():  # refused until the referee has seen the puck on the table
        answers.append(call_service(rclpy_node, start, Trigger.Request(), 30.0))
        return answers[-1] is not None and answers[-1].success
    assert spin_until(rclpy_node, started, 60.0), answers[-1]
    assert answers[0] is None or answers[0].success or "no puck" in answers[0].message
    shoot = rclpy_node.create_client(SetPuckState, "/set_puck_state")
    assert call_service(rclpy_node, shoot, SetPuckState.Request(x=0.5, y=0.02, vx=2.0), 30.0).success

    def goal():
        return any(s.last_event == GameStatus.EVENT_GOAL_FRONT for s in statuses)
    assert spin_until(rclpy_node, goal, 60.0), [(s.status, s.last_event, s.reason) for s in statuses]
    scored = next(s for s in statuses if s.last_event == GameStatus.EVENT_GOAL_FRONT)
    assert (scored.score_front, scored.score_back) == (1, 0) and scored.status == GameStatus.STATUS_PAUSED
    assert "goal for iiwa_front" in scored.reason

    # the puck is put back at rest on iiwa_back's half (it conceded), and play resumes
    assert spin_until(rclpy_node, lambda: statuses[-1].status == GameStatus.STATUS_RUNNING, 60.0)
    puck = truth[-1]
    assert 0.25 < puck.x < 0.9 and math.hypot(puck.vx, puck.vy) < 1e-6

    stop = rclpy_node.create_client(Trigger, "/referee/stop_game")
    assert call_service(rclpy_node, stop, Trigger.Request(), 30.0).success
    assert spin_until(rclpy_node, lambda: statuses[-1].status == GameStatus.STATUS_STOPPED
                      and statuses[-1].score_front == 0, 30.0)
    assert game.processes["referee"].returncode is None  # still running


def test_the_game_does_not_start_before_table_sim_has_reset_the_robots(launcher, rclpy_node):
    """table_sim drops the trajectories of the robots it resets: a game started before its answer let a
    planner go on from a motion that never ran (a joint at 157 % of its velocity limit). Here no table_sim
    answers the referee's reset, so start_game is refused and says why."""
    from geometry_msgs.msg import PoseStamped
    from std_srvs.srv import Trigger
    launcher.start(ProcessSpec("referee", [str(BIN / "referee")]))
    pose = PoseStamped()
    pose.header.frame_id = "table"
    pose.pose.orientation.w = 1.0
    pose.pose.position.x = 0.3
    poses = rclpy_node.create_publisher(PoseStamped, "/optitrack/puck", 10)
    reset = rclpy_node.create_client(Trigger, "/referee/reset_robots")
    start = rclpy_node.create_client(Trigger, "/referee/start_game")
    answers = []

    def seen_then_started():  # the referee sees the puck (else it refuses for that), resets, is asked to start
        pose.header.stamp = rclpy_node.get_clock().now().to_msg()
        poses.publish(pose)
        answers.append(call_service(rclpy_node, start, Trigger.Request(), 10.0))
        return answers[-1] is not None and answers[-1].success
    assert spin_until(rclpy_node, seen_then_started, 30.0)  # no reset asked yet: it starts
    assert call_service(rclpy_node, reset, Trigger.Request(), 10.0).success
    pose.header.stamp = rclpy_node.get_clock().now().to_msg()
    poses.publish(pose)
    refused = call_service(rclpy_node, start, Trigger.Request(), 10.0)
    assert refused is not None and not refused.success and refused.message.startswith("cannot start yet")
