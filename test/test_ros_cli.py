"""`air-hockey topic|service|param|shoot` against running nodes, exactly as README "ROS command-line
habits without ros2" shows them (the block is read from the README, so the two cannot drift apart)."""
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from air_hockey_agent.tools.launch import ProcessSpec
from helpers.ros_wait import spin_until

pytestmark = pytest.mark.integration
BIN = Path(sys.executable).parent
README = Path(__file__).resolve().parents[1] / "README.md"

# what each README command must print (besides exiting 0)
EXPECTED = {
    "topic list -t": ["/iiwa_front/puck/state [air_hockey_msgs/msg/PuckState]", "/clock [rosgraph_msgs/msg/Clock]"],
    "topic echo": ["header:", "frame_id: table", "covariance:"],
    "topic hz": ["average rate:"],
    "service list": ["/set_puck_state", "/iiwa_front/puck_tracker/list_parameters"],
    "service call": ["requester: making request", "response:", "success: true"],
    "param list": ["/iiwa_front/puck_tracker:", "  damping"],
    "param get": ["Double value is: 0.125"],
    "param set": ["Set parameter successful"],
    "shoot": ["shot at 3 m/s, 150 deg"],
}


def readme_block(title: str) -> list[str]:
    """The commands of the first ```bash block after the heading ``title`` (comments dropped)."""
    text = README.read_text()
    section = text[text.index(f"## {title}"):]
    block = re.search(r"```bash\n(.*?)```", section, re.S).group(1)
    return [line.split("  #")[0].strip() for line in block.splitlines() if line.strip()]


@pytest.fixture
def sim_and_agent(launcher):
    launcher.start(ProcessSpec("table_sim", [str(BIN / "table_sim"), "--ros-args", "-p", "real_time_factor:=1.0"]))
    for node in ("puck_tracker", "tactics"):
        args = ["-p", "robot:=iiwa_front"] if node == "tactics" else []
        launcher.start(ProcessSpec(node, [str(BIN / node), "--ros-args", "-r", "__ns:=/iiwa_front",
                                          "-p", "use_sim_time:=true", *args]))
    return launcher


def test_the_readme_ros_commands_work_against_running_nodes(sim_and_agent, rclpy_node, ros_env):
    from air_hockey_msgs.msg import PuckState
    states, truth = [], []
    rclpy_node.create_subscription(PuckState, "/iiwa_front/puck/state", states.append, 10)
    rclpy_node.create_subscription(PuckState, "/sim/puck_true_state", truth.append, 2000)  # kept while we call
    assert spin_until(rclpy_node, lambda: states, 60.0), "the tracker published no state"
    commands = readme_block("ROS command-line habits without `ros2`")
    assert len(commands) == len(EXPECTED)
    for command in commands:
        args = shlex.split(command)
        assert args[0] == ".venv/bin/air-hockey"
        key = next(k for k in EXPECTED if " ".join(args[1:]).startswith(k))
        result = subprocess.run([str(BIN / "air-hockey"), *args[1:]], capture_output=True, text=True,
                                timeout=60, env=ros_env)
        assert result.returncode == 0, (command, result.stderr[-2000:])
        for words in EXPECTED[key]:
            assert words in result.stdout, (command, result.stdout[-2000:])
    # the parameter really changed in the running node, and the puck really moves
    get = subprocess.run([str(BIN / "air-hockey"), "param", "get", "/iiwa_front/tactics", "smash_lead_time"],
                         capture_output=True, text=True, timeout=60, env=ros_env)
    assert "Double value is: 1.0" in get.stdout, get.stdout + get.stderr
    spin_until(rclpy_node, lambda: any(t.vx < -2.0 for t in truth), 20.0)  # a loaded machine runs the sim slowly
    assert any(abs(t.x + 0.5) < 1e-3 and abs(t.y - 0.1) < 1e-3 for t in truth), "service call did not set the puck"
    assert any(t.vx < -2.0 for t in truth), "the shot puck never moved toward iiwa_front at 3 m/s"


def test_param_set_outside_the_range_is_refused_in_one_line(sim_and_agent, rclpy_node, ros_env):
    result = subprocess.run([str(BIN / "air-hockey"), "param", "set", "/iiwa_front/puck_tracker", "damping", "-3"],
                            capture_output=True, text=True, timeout=60, env=ros_env)
    assert result.returncode == 1 and len(result.stderr.strip().splitlines()) == 1, result.stderr
    assert "setting parameter failed" in result.stderr


def test_record_all_takes_every_topic_of_the_graph_with_our_types(launcher, ros_env, tmp_path):
    from rosbags.rosbag2 import Reader
    launcher.start(ProcessSpec("table_sim", [str(BIN / "table_sim"), "--ros-args", "-p", "real_time_factor:=1.0"]))
    launcher.start(ProcessSpec("puck_tracker", [str(BIN / "puck_tracker"), "--ros-args", "-r", "__ns:=/iiwa_front",
                                                "-p", "use_sim_time:=true"]))
    result = subprocess.run([str(BIN / "air-hockey"), "record", str(tmp_path / "all.mcap"), "--all", "--wait", "3",
                             "--duration", "3"], capture_output=True, text=True, timeout=120, env=ros_env)
    assert result.returncode == 0, result.stderr[-2000:]
    with Reader(tmp_path / "all") as bag:
        topics = {c.topic: c.msgtype for c in bag.connections}
        counts = {c.topic: c.msgcount for c in bag.connections}
    for topic, msgtype in (("/clock", "rosgraph_msgs/msg/Clock"), ("/sim/puck_true_state", "air_hockey_msgs/msg/PuckState"),
                           ("/iiwa_front/puck/state", "air_hockey_msgs/msg/PuckState"),
                           ("/iiwa_front/puck/prediction", "air_hockey_msgs/msg/PuckPrediction")):
        assert topics.get(topic) == msgtype and counts[topic] > 0, (topic, topics, counts)
    # latched, published once when the tracker started, seconds before the recorder joined
    assert counts.get("/iiwa_front/puck/physics") == 1, counts
