"""Console scripts of nodes that are not implemented yet.

Each is a real rclpy node (it parses ``--ros-args``) that logs what it will be and exits with code 3,
so ``air-hockey game`` and users see honestly what is missing. A node moves out of this table when
it is built (and its entry point in setup.py moves to its own module).
"""
from __future__ import annotations

from typing import Callable

from air_hockey_agent.nodes.runtime import run_not_implemented

PENDING = {
    "strategy_test": "strategy test: forces one tactic, sets puck states through the sim, scores each trial",
}


def _entry(name: str) -> Callable[[list[str] | None], int]:
    def main(argv: list[str] | None = None) -> int:
        return run_not_implemented(name, PENDING[name], argv)
    main.__name__ = name
    return main


strategy_test = _entry("strategy_test")
