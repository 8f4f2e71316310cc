"""The node graph (README "Architecture") as data: which node runs in which namespace with which
parameters. One description, two launchers: `air-hockey game` and `air-hockey strategy-test` start it as
processes (``tools/launch.py``), and ``launch/*.launch.py`` hand the same nodes to ``ros2 launch`` on a
ROS 2 install. ROS-free.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from air_hockey_agent.paths import PACKAGE, config_file
from air_hockey_agent.sim.params import ROBOTS

VIEW_NODE = "visualizer"
PER_ROBOT_NODES = ("puck_tracker", "tactics", "trajectory_generator")


@dataclass(frozen=True)
class NodeRun:
    """One node process: its executable (= node name), namespace ('' or '/<robot>'), parameter files
    (read first) and parameters (applied over them), in order."""

    executable: str
    namespace: str = ""
    params_files: tuple[str, ...] = ()
    parameters: tuple[tuple[str, Any], ...] = ()

    @property
    def label(self) -> str:
        """How logs name it: ``iiwa_front/tactics``, ``referee``."""
        return f"{self.namespace.strip('/')}/{self.executable}" if self.namespace else self.executable

    def ros_arguments(self) -> list[str]:
        """The command line after the executable, as ``ros2 run`` takes it."""
        args = ["--ros-args"] + (["-r", f"__ns:={self.namespace}"] if self.namespace else [])
        for path in self.params_files:
            args += ["--params-file", path]
        for name, value in self.parameters:
            args += ["-p", f"{name}:={parameter_text(value)}"]
        return args


def parameter_text(value: Any) -> str:
    """A parameter value as ``-p name:=VALUE`` reads it (YAML): ``true``, ``0.0``, ``3``, ``iiwa_front``."""
    return str(value).lower() if isinstance(value, bool) else str(value)


def agent_nodes(robot: str, use_sim_time: bool, sim_table: bool, variant_file: str = "",
                table_file: str = "") -> list[NodeRun]:
    """``robot``'s agent: tracker, tactics and trajectory generator in its namespace. ``sim_table``: the
    tracker and the tactics take the simulated table's puck physics (``config/tracker_sim_table.yaml``;
    the tracker's defaults are a real table's), or with ``table_file`` (another simulated table,
    :mod:`air_hockey_agent.sim.table_file`) the tracker's defaults and that file's ``puck_tracker`` section.
    ``use_sim_time``: on the simulation's /clock. ``variant_file``: a parameter YAML the tactics, the
    trajectory generator and the tracker read after their defaults (``air-hockey game --versus``)."""
    from air_hockey_agent.param_registry import node_parameters
    from air_hockey_agent.tracker_params import SIM_TABLE_FILE
    if robot not in ROBOTS:
        raise ValueError(f"robot must be one of {', '.join(ROBOTS)}, got {robot!r}")
    physics = table_file or str(config_file(SIM_TABLE_FILE))
    declared = node_parameters()
    nodes = []
    for node in PER_ROBOT_NODES:
        parameters: list[tuple[str, Any]] = [("use_sim_time", True)] if use_sim_time else []
        parameters += [("robot", robot)] if "robot" in declared[node] else []
        files = (physics,) if sim_table and node == "puck_tracker" else ()
        files += (variant_file,) if variant_file else ()
        parameters += [("puck_params_file", physics)] if sim_table and node == "tactics" else []
        nodes.append(NodeRun(node, f"/{robot}", files, tuple(parameters)))
    return nodes


def game_nodes(gui: bool, real_time_factor: float, seed: int, markers: bool = False,
               versus: tuple[str, str] | None = None, table_file: str = "") -> list[NodeRun]:
    """The simulated two-robot game: the table, the referee (which restarts play itself after a robot's
    fault: nobody watches), both agents on the simulated table's physics, all on sim time; ``markers``:
    with the visualizer; ``versus`` (robot, parameter YAML): that robot's agent reads the file too;
    ``table_file``: on another simulated table (:func:`agent_nodes`)."""
    nodes = [NodeRun("table_sim", params_files=(table_file,) if table_file else (),
                     parameters=(("gui", gui), ("real_time_factor", real_time_factor), ("seed", seed))),
             NodeRun("referee", parameters=(("use_sim_time", True), ("seed", seed), ("restart_after_fault", True)))]
    if markers:
        nodes.append(NodeRun(VIEW_NODE, parameters=(("use_sim_time", True),)))
    variant = {versus[0]: versus[1]} if versus is not None else {}
    return nodes + [n for robot in ROBOTS for n in agent_nodes(robot, use_sim_time=True, sim_table=True,
                                                                variant_file=variant.get(robot, ""),
                                                                table_file=table_file)]


# --- ros2 launch (launch/*.launch.py) -----------------------------------------------------------------
def launch_node_arguments(node: NodeRun) -> dict:
    """``launch_ros.actions.Node``'s arguments for ``node``: named as its executable (launch_ros then keys
    the parameters' file by the full node name, ``/iiwa_front/tactics``), the files before the values."""
    arguments = {"package": PACKAGE, "executable": node.executable, "name": node.executable, "output": "screen",
                 "parameters": [*node.params_files, dict(node.parameters)]}
    return {**arguments, "namespace": node.namespace} if node.namespace else arguments


def ros_launch_nodes(nodes: list[NodeRun]) -> list:
    """``launch_ros.actions.Node`` actions for ``nodes`` (imports launch_ros: only on a ROS 2 install)."""
    from launch_ros.actions import Node
    return [Node(**launch_node_arguments(node)) for node in nodes]


def launch_flag(name: str, text: str) -> bool:
    """A launch argument ``true`` / ``false`` as a bool; ValueError naming the argument otherwise."""
    if text.strip().lower() not in ("true", "false"):
        raise ValueError(f"launch argument {name}: true or false, got {text!r}")
    return text.strip().lower() == "true"


def launch_table(text: str) -> str:
    """The launch argument ``table`` (a table file, or '' for none); ValueError naming what is wrong with it."""
    from pathlib import Path
    from air_hockey_agent.sim.table_file import table_problem
    problem = table_problem(Path(text), "launch argument table") if text else ""
    if problem:
        raise ValueError(problem)
    return text


def launch_number(name: str, text: str, kind: type) -> Any:
    """A numeric launch argument (``kind``: int or float, not negative); ValueError naming it otherwise."""
    try:
        value = kind(text)
    except ValueError:
        raise ValueError(f"launch argument {name}: a number, got {text!r}") from None
    if not value >= 0:
        raise ValueError(f"launch argument {name}: must be >= 0, got {text!r}")
    return value
