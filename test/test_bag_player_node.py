"""bag_player (separate process) replays a bag to a puck_tracker on the bag's clock; bad bags exit 2."""
import hashlib
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from air_hockey_agent.tools.launch import ProcessSpec
from helpers.ros_wait import spin_until

pytestmark = pytest.mark.integration
BIN = Path(sys.executable).parent


@pytest.fixture(scope="module")
def bag(tmp_path_factory):
    path = tmp_path_factory.mktemp("replay") / "shots"
    made = subprocess.run([str(BIN / "air-hockey"), "synth-bag", str(path), "--shots", "2"], capture_output=True,
                          text=True, timeout=120)
    assert made.returncode == 0, made.stderr
    return path


def digest(path: Path) -> str:
    return hashlib.sha256(b"".join(p.read_bytes() for p in sorted(path.iterdir()))).hexdigest()


def test_replay_drives_the_tracker_on_bag_time(bag, launcher, rclpy_node):
    from air_hockey_msgs.msg import PuckState
    from rosgraph_msgs.msg import Clock

    before = digest(bag)
    got = {"truth": [], "estimate": [], "clock": []}
    rclpy_node.create_subscription(PuckState, "/puck/true_state", got["truth"].append, 500)
    rclpy_node.create_subscription(PuckState, "/puck/state", got["estimate"].append, 500)
    rclpy_node.create_subscription(Clock, "/clock", got["clock"].append, 500)
    launcher.start(ProcessSpec("puck_tracker", [str(BIN / "puck_tracker"), "--ros-args", "-p", "use_sim_time:=true"]))
    assert spin_until(rclpy_node, lambda: rclpy_node.count_subscribers("/optitrack/puck") > 0, 30.0)
    launcher.start(ProcessSpec("bag_player", [str(BIN / "air-hockey"), "play", str(bag), "--rate", "4", "--clock"]))
    assert spin_until(rclpy_node, lambda: len(got["estimate"]) > 300, 60.0), len(got["estimate"])

    def t(m):
        return m.header.stamp.sec + m.header.stamp.nanosec * 1e-9

    # the truth is the state at each frame's capture, stamped with it; the pose's stamp scatters about it
    # (0.2 ms): an estimate is compared with the nearest truth carried on to the estimate's stamp
    truth_t = np.array([t(m) for m in got["truth"]])

    def error(e):
        k = int(np.argmin(np.abs(truth_t - t(e))))
        m, lag = got["truth"][k], t(e) - truth_t[k]
        return np.hypot(e.x - m.x - m.vx * lag, e.y - m.y - m.vy * lag) if abs(lag) < 2e-3 else None

    errors = [err for err in map(error, got["estimate"][50:]) if err is not None]
    assert len(errors) > 100 and np.median(errors) < 1e-3
    clock = [c.clock.sec + c.clock.nanosec * 1e-9 for c in got["clock"]]
    assert np.all(np.diff(clock) >= 0.0)
    assert digest(bag) == before  # the input bag is only read


def test_a_ros1_bag_is_replayed_as_ros2_messages(bag, tmp_path, launcher, rclpy_node):
    """The lab's recordings are ROS 1 bags: the same poses converted by rosbags' converter replay as the
    Jazzy PoseStamped, and the tracker follows them."""
    from air_hockey_msgs.msg import PuckState
    from geometry_msgs.msg import PoseStamped

    ros1 = tmp_path / "lab.bag"
    converted = subprocess.run([str(BIN / "rosbags-convert"), "--src", str(bag), "--dst", str(ros1),
                                "--dst-typestore", "ros1_noetic", "--include-topic", "/optitrack/puck"],
                               capture_output=True, text=True, timeout=120)
    assert converted.returncode == 0, converted.stderr
    poses, estimates = [], []
    rclpy_node.create_subscription(PoseStamped, "/optitrack/puck", poses.append, 500)
    rclpy_node.create_subscription(PuckState, "/puck/state", estimates.append, 500)
    launcher.start(ProcessSpec("puck_tracker", [str(BIN / "puck_tracker"), "--ros-args", "-p", "use_sim_time:=true"]))
    assert spin_until(rclpy_node, lambda: rclpy_node.count_subscribers("/optitrack/puck") > 1, 30.0)
    launcher.start(ProcessSpec("bag_player", [str(BIN / "air-hockey"), "play", str(ros1), "--rate", "4", "--clock"]))
    assert spin_until(rclpy_node, lambda: len(estimates) > 300, 60.0), len(estimates)
    assert poses[0].header.frame_id == "optitrack" and poses[1].header.stamp.sec > 0
    assert sum(abs(p.pose.orientation.w) > 0.0 for p in poses) == len(poses)  # real quaternions, not zeros


def test_bad_bag_is_one_line_and_exit_2(tmp_path, ros_env):
    out = subprocess.run([str(BIN / "bag_player"), "--ros-args", "-p", f"bag:={tmp_path}"], capture_output=True,
                         text=True, timeout=60, env=ros_env)
    assert out.returncode == 2
    assert f"{tmp_path}: not a bag (neither a rosbag2 bag" in out.stderr and len(out.stderr.strip().splitlines()) == 1
    out = subprocess.run([str(BIN / "air-hockey"), "play", str(tmp_path / "missing")], capture_output=True,
                         text=True, timeout=60, env=ros_env)
    assert out.returncode == 2 and "does not exist" in out.stderr
