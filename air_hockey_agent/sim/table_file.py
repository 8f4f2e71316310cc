"""Another simulated table (``air-hockey game --table FILE``, ``strategy-test --table FILE``; ROS-free).

By default the game and the strategy test play on the thesis's table (``config/sim.yaml``) and tell each
robot's tracker and tactics its true physics (``config/tracker_sim_table.yaml``, nothing learned). A table
file is a ROS 2 parameter YAML with sections for any namespace of up to three nodes:

- ``table_sim`` (required): the simulated table, read after ``config/sim.yaml`` (its air film, rims, mallet
  contact, OptiTrack stand-in);
- ``puck_tracker`` (optional): what the agent is told. With a table file the tracker and the tactics read
  ``config/tracker.yaml`` (a real table's defaults, its online learning on) and then this section, as they
  would on a real table, instead of ``config/tracker_sim_table.yaml``;
- ``strategy_test`` (optional): the strategy test's settings for this table (e.g. a longer ``timeout`` where
  a slide lasts longer).

``config/lab_table.yaml`` is the lab's table as its recordings show it (issue #13).
"""
from __future__ import annotations

import argparse
from pathlib import Path

TABLE_NODES = ("table_sim", "puck_tracker", "strategy_test")


def check_table_file(path: Path, flag: str = "--table") -> None:
    """Raise ``ParameterFileError`` / ``ParameterValueError`` naming ``path`` and the section or parameter when
    ``path`` is not a table file: a section for another node or for one namespace only, no ``table_sim``
    section, or a parameter a node does not declare or a value out of its bounds."""
    from air_hockey_agent.params import ParameterFileError, check_only_nodes, file_nodes
    from air_hockey_agent.sim.params import load_sim_params
    from air_hockey_agent.strategy_params import load_strategy_params
    from air_hockey_agent.tracker_params import load_tracker_params
    check_only_nodes(path, TABLE_NODES, flag, "both robots' trackers read it")
    if "table_sim" not in file_nodes(path):
        raise ParameterFileError(f"{path}: no '/**/table_sim' section: a table file sets the simulated table's "
                                 "parameters")
    load_sim_params([path])
    load_tracker_params([path])
    load_strategy_params([path])


def add_table_option(parser: argparse.ArgumentParser, agents: str, also: str = "") -> None:
    """The ``--table FILE`` option of a tool that plays on the simulated table: ``agents`` names whose trackers
    and tactics it deploys as on a real table, ``also`` what else reads the file."""
    parser.add_argument("--table", type=Path, default=None, metavar="FILE",
                        help=f"play on another simulated table: FILE's table_sim parameters over config/sim.yaml; "
                             f"{agents} read config/tracker.yaml (a real table's defaults, learning on) and FILE's "
                             f"puck_tracker section instead of config/tracker_sim_table.yaml{also} (e.g. "
                             "config/lab_table.yaml, the lab's table)")


def table_problem(path: Path, flag: str = "--table") -> str:
    """What is wrong with the table file ``path`` as one line naming the file; '' when it loads."""
    from air_hockey_agent.params import file_problem
    return file_problem(path, flag, check_table_file)
