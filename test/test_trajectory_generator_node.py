"""The trajectory_generator node (separate process) driving table_sim's arm on sim time.

A HitCommand is planned, executed by the simulation, and the mallet passes the hit point at the hit
time (measured from the simulated joint states by pybullet-checked forward kinematics); a command
faster than the arm allows is refused on trajectory_status and nothing moves; a malformed command is
refused and the node keeps running.
"""
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from air_hockey_agent.tools.launch import ProcessSpec
from helpers.ros_wait import spin_until

pytestmark = pytest.mark.integration
BIN = Path(sys.executable).parent
ROBOT = "iiwa_front"


@pytest.fixture
def arm(launcher):
    launcher.start(ProcessSpec("table_sim", [str(BIN / "table_sim"), "--ros-args", "-p", "real_time_factor:=1.0"]))
    launcher.start(ProcessSpec("trajectory_generator", [
        str(BIN / "trajectory_generator"), "--ros-args", "-r", f"__ns:=/{ROBOT}", "-p", "use_sim_time:=true",
        "-p", f"robot:={ROBOT}"]))
    return launcher


def _command(stamp_seconds, point, velocity, hit_time):
    from air_hockey_msgs.msg import HitCommand
    from air_hockey_agent.nodes.messages import to_stamp
    msg = HitCommand(tactic=HitCommand.TACTIC_SMASH)
    msg.header.stamp = to_stamp(stamp_seconds)
    msg.hit_point.x, msg.hit_point.y = point
    msg.hit_velocity.x, msg.hit_velocity.y = velocity
    msg.hit_time = to_stamp(hit_time)
    return msg


def test_a_hit_is_planned_executed_and_passes_the_hit_point(arm, rclpy_node):
    from air_hockey_msgs.msg import HitCommand, TrajectoryStatus
    from sensor_msgs.msg import JointState
    from trajectory_msgs.msg import JointTrajectory
    from air_hockey_agent.motion_params import build_planner, load_motion_params
    from air_hockey_agent.nodes.messages import to_seconds

    kin = build_planner(load_motion_params(), ROBOT).kin
    states, statuses, trajectories = [], [], []
    rclpy_node.create_subscription(JointState, f"/{ROBOT}/joint_states", states.append, 500)
    rclpy_node.create_subscription(TrajectoryStatus, f"/{ROBOT}/trajectory_status", statuses.append, 10)
    rclpy_node.create_subscription(JointTrajectory, f"/{ROBOT}/joint_trajectory", trajectories.append, 10)
    commands = rclpy_node.create_publisher(HitCommand, f"/{ROBOT}/hit_command", 10)
    assert spin_until(rclpy_node, lambda: states and commands.get_subscription_count() > 0, 60.0)

    # too fast: refused with the reason, nothing published to the arm (repeated while the node has not
    # yet received joint states, which it says)
    def answered_too_fast():
        now = to_seconds(states[-1].header.stamp)
        commands.publish(_command(now, (-0.5, 0.1), (9.0, 0.0), now + 1.5))
        count = len(statuses)
        spin_until(rclpy_node, lambda: len(statuses) > count, 10.0)
        return statuses and "no joint_states" not in statuses[-1].reason
    assert spin_until(rclpy_node, answered_too_fast, 60.0)
    statuses[:] = statuses[-1:]
    assert statuses[-1].outcome == TrajectoryStatus.OUTCOME_TOO_FAST and "at most" in statuses[-1].reason
    assert math.isfinite(statuses[-1].max_hit_speed) and statuses[-1].max_hit_speed < 9.0
    # malformed: NaN hit point
    now = to_seconds(states[-1].header.stamp)
    commands.publish(_command(now, (math.nan, 0.1), (1.0, 0.0), now + 1.5))
    assert spin_until(rclpy_node, lambda: len(statuses) >= 2, 30.0)
    assert statuses[-1].outcome == TrajectoryStatus.OUTCOME_INVALID
    assert trajectories == []

    # a feasible hit
    now = to_seconds(states[-1].header.stamp)
    hit_time, point, velocity = now + 2.0, np.array([-0.5, 0.1]), np.array([1.0, 0.2])
    commands.publish(_command(now, point, velocity, hit_time))
    assert spin_until(rclpy_node, lambda: len(statuses) >= 3, 30.0)
    status = statuses[-1]
    assert status.outcome == TrajectoryStatus.OUTCOME_ACCEPTED, status.reason
    assert to_seconds(status.hit_time) == pytest.approx(hit_time, abs=1e-6)
    assert status.hit_speed == pytest.approx(float(np.linalg.norm(velocity)))
    assert spin_until(rclpy_node, lambda: trajectories, 10.0)
    assert spin_until(rclpy_node, lambda: to_seconds(states[-1].header.stamp) > hit_time + 0.2, 60.0)

    names = list(states[0].name)
    order = [names.index(f"iiwa_joint_{i}") for i in range(1, 8)]
    t = np.array([to_seconds(s.header.stamp) for s in states])
    mallet = np.array([kin.position(np.asarray(s.position)[order]) for s in states])
    k = int(np.searchsorted(t, hit_time))
    w = (hit_time - t[k - 1]) / (t[k] - t[k - 1])
    at_hit = (1 - w) * mallet[k - 1] + w * mallet[k]
    assert np.linalg.norm(at_hit[:2] - point) < 0.005
    measured = (mallet[k + 1, :2] - mallet[k - 2, :2]) / (t[k + 1] - t[k - 2])
    assert np.linalg.norm(measured - velocity) < 0.1 * np.linalg.norm(velocity)
    assert arm.processes["trajectory_generator"].returncode is None
