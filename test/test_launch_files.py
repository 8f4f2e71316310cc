"""launch/*.launch.py for `ros2 launch` on a ROS 2 install, and the node graph they share with `air-hockey game`.

launch and launch_ros are not on the package registry (TOOLCHAIN.md), so the launch files run here against a
stand-in of the part of their API they use (DeclareLaunchArgument, OpaqueFunction, LaunchDescription,
launch_ros.actions.Node), and the nodes are then started as launch_ros starts them: named and namespaced by
remapping, the dict parameters in a parameter file keyed by the full node name.
"""
import importlib.util
import signal
import subprocess
import sys
import time
import types
from pathlib import Path

import pytest
import yaml

from air_hockey_agent import node_graph
from air_hockey_agent.param_registry import node_parameters
from air_hockey_agent.paths import config_file
from air_hockey_agent.sim.params import ROBOTS

REPO = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent
ROS_PARAMETERS = {"use_sim_time"}  # rclpy declares it on every node


class _Recorded:
    def __init__(self, *args, **kwargs):
        self.args, self.kwargs = args, kwargs


@pytest.fixture
def launch_api(monkeypatch):
    """Stand-in modules for launch and launch_ros.actions: each action records its arguments."""
    kinds = {}
    for name in ("LaunchDescription", "DeclareLaunchArgument", "OpaqueFunction", "Node"):
        kinds[name] = type(name, (_Recorded,), {})
    launch = types.ModuleType("launch")
    launch.LaunchDescription = kinds["LaunchDescription"]
    actions = types.ModuleType("launch.actions")
    actions.DeclareLaunchArgument, actions.OpaqueFunction = kinds["DeclareLaunchArgument"], kinds["OpaqueFunction"]
    launch.actions = actions
    launch_ros = types.ModuleType("launch_ros")
    ros_actions = types.ModuleType("launch_ros.actions")
    ros_actions.Node = kinds["Node"]
    launch_ros.actions = ros_actions
    for name, module in (("launch", launch), ("launch.actions", actions), ("launch_ros", launch_ros),
                         ("launch_ros.actions", ros_actions)):
        monkeypatch.setitem(sys.modules, name, module)
    return kinds


def run_launch_file(name, overrides):
    """Evaluate ``launch/<name>`` as ros2 launch would with ``overrides`` (name -> text): the declared
    arguments (name -> their arguments) and the Node actions' arguments."""
    spec = importlib.util.spec_from_file_location(name.replace(".", "_"), REPO / "launch" / name)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    description = module.generate_launch_description()
    entities = description.args[0]
    declared = {e.args[0]: e.kwargs for e in entities if type(e).__name__ == "DeclareLaunchArgument"}
    unknown = set(overrides) - set(declared)
    assert not unknown, f"{name} declares no argument {unknown}"
    configurations = {k: v.get("default_value") for k, v in declared.items()} | overrides
    for key, value in configurations.items():
        assert value is not None, f"{name}: argument {key} has no default and was not given"
        assert value in declared[key].get("choices", [value]), (key, value)
    context = types.SimpleNamespace(launch_configurations=configurations)
    functions = [e.kwargs["function"] for e in entities if type(e).__name__ == "OpaqueFunction"]
    return declared, [node.kwargs for f in functions for node in f(context)]


@pytest.mark.parametrize("robot", ROBOTS)
def test_the_agent_launch_file_starts_what_the_game_starts_for_one_robot(launch_api, robot):
    declared, nodes = run_launch_file("agent.launch.py", {"robot": robot, "use_sim_time": "true",
                                                          "sim_table": "true"})
    assert declared["robot"]["choices"] == list(ROBOTS) and "default_value" not in declared["robot"]
    game = [n for n in node_graph.game_nodes(False, 0.0, 0) if n.namespace == f"/{robot}"]
    assert nodes == [node_graph.launch_node_arguments(n) for n in game]
    assert [n["executable"] for n in nodes] == list(node_graph.PER_ROBOT_NODES)
    for node in nodes:
        assert node["package"] == "air_hockey_agent" and node["namespace"] == f"/{robot}"
        *files, values = node["parameters"]
        assert all(Path(f).is_file() for f in files)
        assert set(values) <= set(node_parameters()[node["executable"]]) | ROS_PARAMETERS, values
    real = run_launch_file("agent.launch.py", {"robot": robot})[1]  # a real table: its own clock and physics
    assert all(n["parameters"][-1].get("use_sim_time") is None for n in real)
    assert all(len(n["parameters"]) == 1 and "puck_params_file" not in n["parameters"][0] for n in real)


def test_the_game_launch_file_starts_the_games_nodes(launch_api):
    _, nodes = run_launch_file("game.launch.py", {"seed": "7", "real_time_factor": "0", "markers": "true"})
    expected = node_graph.game_nodes(False, 0.0, 7, markers=True)
    assert nodes == [node_graph.launch_node_arguments(n) for n in expected]
    assert {n["executable"] for n in nodes} == {"table_sim", "referee", "visualizer", *node_graph.PER_ROBOT_NODES}
    table = next(n for n in nodes if n["executable"] == "table_sim")
    assert table["parameters"] == [{"gui": False, "real_time_factor": 0.0, "seed": 7}]


def test_the_game_launch_file_plays_on_a_table_file(launch_api):
    """``table:=FILE`` (another simulated table): table_sim reads the file, each robot's tracker reads it
    instead of config/tracker_sim_table.yaml and its tactics take it as their puck physics."""
    lab = str(config_file("lab_table.yaml"))
    _, nodes = run_launch_file("game.launch.py", {"table": lab})
    assert nodes == [node_graph.launch_node_arguments(n) for n in node_graph.game_nodes(False, 1.0, 0, table_file=lab)]
    table = next(n for n in nodes if n["executable"] == "table_sim")
    assert table["parameters"][0] == lab
    for robot in ROBOTS:
        tracker, tactics, generator = (n for n in nodes if n.get("namespace") == f"/{robot}")
        assert tracker["parameters"][:-1] == [lab] and tactics["parameters"][-1]["puck_params_file"] == lab
        assert lab not in generator["parameters"]


@pytest.mark.parametrize("name, overrides, message", [
    ("game.launch.py", {"seed": "-1"}, "launch argument seed: must be >= 0"),
    ("game.launch.py", {"table": "/no/such.yaml"}, "launch argument table /no/such.yaml: no such file"),
    ("game.launch.py", {"real_time_factor": "fast"}, "launch argument real_time_factor: a number"),
    ("agent.launch.py", {"robot": "iiwa_left"}, "iiwa_left"),
])
def test_a_bad_launch_argument_is_named(launch_api, name, overrides, message):
    with pytest.raises((ValueError, AssertionError), match=message):
        run_launch_file(name, overrides)


def test_the_game_command_lines_are_the_graphs():
    """`air-hockey game` starts each node of node_graph.game_nodes with its ros_arguments."""
    from air_hockey_agent.tools.game import game_processes
    specs = game_processes(gui=False, real_time_factor=0.0, seed=4, markers=False)
    nodes = node_graph.game_nodes(False, 0.0, 4)
    assert [s.label for s in specs] == [n.label for n in nodes]
    assert [s.command[1:] for s in specs] == [n.ros_arguments() for n in nodes]
    tactics = next(n for n in nodes if n.label == "iiwa_back/tactics")
    assert tactics.ros_arguments()[:3] == ["--ros-args", "-r", "__ns:=/iiwa_back"]
    assert "robot:=iiwa_back" in tactics.ros_arguments() and "use_sim_time:=true" in tactics.ros_arguments()


@pytest.mark.integration
def test_the_agents_nodes_start_as_ros2_launch_starts_them(ros_env, launch_api, tmp_path):
    """Each node of agent.launch.py (real table) started with the command line launch_ros builds: it
    comes up (its parameters are all accepted) and stops on SIGINT."""
    _, nodes = run_launch_file("agent.launch.py", {"robot": "iiwa_back"})
    procs = []
    try:
        for node in nodes:
            name, namespace = node["name"], node["namespace"]
            args = ["--ros-args", "-r", f"__node:={name}", "-r", f"__ns:={namespace}"]
            for k, entry in enumerate(node["parameters"]):
                if isinstance(entry, dict):  # launch_ros writes a dict to a file keyed by the full node name
                    path = tmp_path / f"launch_params_{name}_{k}.yaml"
                    path.write_text(yaml.safe_dump({f"{namespace}/{name}": {"ros__parameters": entry}}))
                    entry = str(path)
                args += ["--params-file", entry]
            procs.append(subprocess.Popen([str(BIN / node["executable"]), *args], env=ros_env,
                                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True))
        deadline = time.monotonic() + 90
        for proc, node in zip(procs, nodes):
            seen = []
            for line in proc.stdout:
                seen.append(line)
                if "node ready" in line or time.monotonic() > deadline:
                    break
            assert "node ready: /iiwa_back/" + node["name"] in "".join(seen), "".join(seen)[-2000:]
    finally:
        for proc in procs:
            if proc.poll() is None:
                proc.send_signal(signal.SIGINT)
        for proc in procs:
            try:
                proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
