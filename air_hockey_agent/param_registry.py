"""Which parameters each node (and tool section) of the package declares (for the misspelling checks of
:mod:`air_hockey_agent.params`: a parameter file section may be meant for any of them)."""
from __future__ import annotations

from functools import lru_cache


@lru_cache(maxsize=1)
def node_parameters() -> dict[str, frozenset[str]]:
    """Node name -> the names of its declared parameters."""
    from air_hockey_agent.agent_params import AGENT_PARAMS
    from air_hockey_agent.motion_params import MOTION_PARAMS
    from air_hockey_agent.referee_params import REFEREE_PARAMS
    from air_hockey_agent.reference_params import REFERENCE_PARAMS
    from air_hockey_agent.sim.params import SIM_PARAMS
    from air_hockey_agent.strategy_params import STRATEGY_PARAMS
    from air_hockey_agent.sysid_params import SYSID_PARAMS
    from air_hockey_agent.tool_node_params import OPTIMIZER_PARAMS, PLAYER_PARAMS
    from air_hockey_agent.tools.game import GAME_PARAMS
    from air_hockey_agent.tools.synth_bag import SESSION_PARAMS
    from air_hockey_agent.tracker_params import TRACKER_NODE_PARAMS
    from air_hockey_agent.visualizer_params import VISUALIZER_PARAMS
    specs = {"puck_tracker": TRACKER_NODE_PARAMS, "tactics": AGENT_PARAMS, "trajectory_generator": MOTION_PARAMS,
             "referee": REFEREE_PARAMS, "table_sim": SIM_PARAMS, "strategy_test": STRATEGY_PARAMS,
             "visualizer": VISUALIZER_PARAMS,
             # the tools' own sections (config/sysid.yaml, synthetic.yaml, game.yaml, reference_filter.yaml)
             "sysid": SYSID_PARAMS, "synth_bag": SESSION_PARAMS, "game": GAME_PARAMS,
             "reference_filter": REFERENCE_PARAMS, "bag_player": PLAYER_PARAMS,
             "prediction_optimizer": OPTIMIZER_PARAMS}
    return {name: frozenset(s.name for s in group) for name, group in specs.items()}
