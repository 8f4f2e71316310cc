"""Parameters of the strategy test (ROS-free declarations; defaults in ``config/table.yaml`` and
``config/strategy_test.yaml``)."""
from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any, Iterable, Mapping

from air_hockey_agent.params import ParamSpec, load_node_params
from air_hockey_agent.tracker_params import TABLE_PARAMS

if TYPE_CHECKING:
    from air_hockey_agent.core.game.strategy.trials import TrialSettings

NODE_NAME = "/strategy_test"
PARAM_FILES = ("table.yaml", "strategy_test.yaml")

STRATEGY_PARAMS = TABLE_PARAMS + (
    ParamSpec("smash_depth", list, "[m] depth range of Smash start positions from the own goal line", 0.0, 2.0, 2),
    ParamSpec("smash_rim_margin", float, "[m] Smash starts this far off the long rims beyond the puck radius", 0.0, 0.5),
    ParamSpec("prepare_depth", list, "[m] depth range of Prepare start positions", 0.0, 2.0, 2),
    ParamSpec("prepare_rim_margin", float, "[m] Prepare starts this far off the long rims beyond the puck radius", 0.0, 0.5),
    ParamSpec("defend_line", float, "[m] the defend line's distance from a short rim", 0.0, 1.0),
    ParamSpec("start_y", float, "[m] |y| range of Cut and Repel starts", 0.0, 0.5),
    ParamSpec("shot_speed", float, "[m/s] speed of the opponent's simulated shot", 0.1, 10.0),
    ParamSpec("cut_impact_x", list, "[m] x range of a Cut shot's rim impact", -1.0, 1.0, 2),
    ParamSpec("guard_depth", list, "[m] depth range of Guard start positions from the own goal line", 0.0, 1.0, 2),
    ParamSpec("guard_rim_margin", float, "[m] Guard starts this far off the long rims beyond the puck radius",
              0.0, 0.5),
    ParamSpec("guard_speed", float, "[m/s] Guard starts at speeds up to this, in any direction", 0.0, 5.0),
    ParamSpec("guard_exit_depth", float, "[m] a Guard trial ends without a goal once the puck is this far from "
              "the own goal line", 0.1, 2.0),
    ParamSpec("guard_time", float, "[s] a Guard trial ends without a goal after this long", 0.5, 60.0),
    ParamSpec("rest_speed", float, "[m/s] the puck is at rest below this speed", 0.001, 1.0),
    ParamSpec("timeout", float, "[s] a trial ends as a failure after this long", 0.5, 120.0),
    ParamSpec("hit_timeout", float, "[s] a trial whose puck nobody touched ends as a failure after this long",
              0.5, 120.0),
    ParamSpec("after_hit", float, "[s] Smash and Repel end this long after the last hit", 0.1, 60.0),
    ParamSpec("settle", float, "[s] time between the reset and the puck being set", 0.0, 60.0),
    ParamSpec("start_gap", float, "[m] no Smash, Prepare or Guard puck starts closer than this to the waiting "
              "mallet", 0.0, 0.5),
    ParamSpec("seed", int, "random seed of the trials' initial states", 0, 2**31 - 1),
    ParamSpec("trials", str, "the trials to run: 'strategy:index' separated by commas"),
    ParamSpec("defended", bool, "the opponent's agent waits until the tested robot's hit, then defends"),
    ParamSpec("table_file", str, "the simulated table's parameter file (strategy-test --table; '' for "
              "config/sim.yaml's)"),
    ParamSpec("wall_timeout", float, "[s] wall time after which a stuck trial is given up", 1.0, 3600.0),
)


def load_strategy_params(extra_files: Iterable[Path] = ()) -> dict[str, Any]:
    return load_node_params(PARAM_FILES, NODE_NAME, STRATEGY_PARAMS, extra_files)


def trial_settings(params: Mapping[str, Any] | None = None, table_file: str = "") -> "TrialSettings":
    """The trials' :class:`~air_hockey_agent.core.game.strategy.trials.TrialSettings` from ``params`` (default:
    the configured ones, then ``table_file``'s ``strategy_test`` section), with the simulated table's damping
    (a slow slide's outcome is decided before it stops; ``config/sim.yaml``, then the table file: the one
    ``params`` name, else ``table_file``; 0, no such decision, where the surface's own push may beat its
    friction or pushes at random) and where the tested robot's mallet waits when a trial's puck is set: its ready point
    (``config/agent.yaml``; iiwa_front's own frame is the table frame)."""
    from air_hockey_agent.agent_params import load_agent_params
    from air_hockey_agent.core.game.strategy.trials import TrialSettings
    from air_hockey_agent.core.puck.surface_field import SurfaceField
    from air_hockey_agent.sim.params import load_sim_params
    agent = load_agent_params()
    depth, y = agent["ready_point"]
    waiting = (depth - agent["table.length"] / 2, y)
    if params is None:
        params = load_strategy_params([Path(table_file)] if table_file else [])
    table = params["table_file"] or table_file
    sim = load_sim_params([Path(table)] if table else [])
    # a surface that may push a puck harder than the friction holds it (its field, or random pushes, which
    # have no bound) bounds no slide by the damping
    held = SurfaceField.from_params(sim).max_push <= sim["surface_friction"] and sim["random_acceleration"] == 0.0
    return TrialSettings.from_params(params, damping=sim["surface_damping"] if held else 0.0, waiting=waiting,
                                     contact_distance=agent["puck.radius"] + agent["mallet.radius"])
