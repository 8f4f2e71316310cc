"""Parameters of the tactics layer (ROS-free declarations; defaults in ``config/table.yaml`` and
``config/agent.yaml``), and the puck model and arm planner the tactics read from the tracker's and the
trajectory generator's own files, so each number has one home."""
from __future__ import annotations

from pathlib import Path
from typing import Any, Iterable

from air_hockey_agent.core.game.tactics.settings import BLOCK_CHOICES
from air_hockey_agent.params import ParamSpec, ParameterValueError, load_node_params
from air_hockey_agent.sim.params import ROBOT_BASE_PARAMS
from air_hockey_agent.tracker_params import MALLET_RADIUS_PARAM, TABLE_PARAMS

NODE_NAME = "/tactics"
PARAM_FILES = ("table.yaml", "agent.yaml")

AGENT_PARAMS = TABLE_PARAMS + (
    MALLET_RADIUS_PARAM,
    ParamSpec("robot", str, "which robot this node plays (iiwa_front or iiwa_back)"),
    ParamSpec("puck_params_file", str, "tracker parameter YAML whose puck physics the shots are predicted with "
                                       "('': config/tracker.yaml's; give the tracker's own --params-file)"),
    ParamSpec("physics_from_tracker", bool, "aim the shots with the physics the robot's tracker publishes on "
                                            "puck/physics (what it learned online of the table) once it does"),
    ParamSpec("rate", float, "[Hz] decisions per simulated second", 1.0, 1000.0),
    ParamSpec("status_period", float, "[s] re-publication period of the current tactic", 0.01, 3600.0),
    ParamSpec("defend_line", float, "[m] depth of the defend line from the own goal line", 0.0, 1.0),
    ParamSpec("ready_point", list, "[m] depth, y of the waiting point", -1.0, 1.0, 2),
    ParamSpec("ready_guard_depth", float, "[m] a puck closer to the own goal line than this is guarded: the mallet "
                                          "waits between it and the goal (0: never)", 0.0, 1.0),
    ParamSpec("ready_guard_speed", float, "[m/s] ... when it is slower than this (else the mallet keeps off "
                                          "its path)", 0.0, 10.0),
    ParamSpec("ready_checks_way", bool, "the waiting mallet moves off a way to its point that would meet the "
              "puck so as to turn it into the own goal"),
    ParamSpec("ready_dodge_steps", int, "steps of a contact distance plus approach_clearance the waiting point "
              "may move to get off such a way (in y either way and away from the goal)", 0, 10),
    ParamSpec("ready_blocks", bool, "a puck whose prediction goes into the own goal, which no other tactic "
              "takes, is blocked: the mallet waits on its path where it meets it head-on"),
    ParamSpec("ready_block_step", float, "[m] the block's candidate points lie where the puck's path crosses "
                                         "lines x = const this far apart (0: the prediction's samples)", 0.0, 0.5),
    ParamSpec("ready_block_in_way", bool, "with no block found, a puck going into the own goal is awaited where "
              "its path crosses the ready point's line"),
    ParamSpec("ready_block_keep", bool, "the block the arm is running is kept while it still keeps the puck out "
              "(not chosen anew at every decision)"),
    ParamSpec("ready_block_choice", str, "which block is tried first: 'first' the puck meets on its path, or "
              "'margin' the one the mallet reaches longest before the puck", choices=BLOCK_CHOICES),
    ParamSpec("ready_switch_time", float, "[s] a new waiting point must stay for this long before the mallet leaves "
                                          "the one it is reaching, while that one's way is harmless (0: at once)",
              0.0, 1.0),
    ParamSpec("ready_unseen_time", float, "[s] with no puck frame for this long the mallet waits at "
                                          "ready_unseen_point instead of the ready point (0: off)", 0.0, 60.0),
    ParamSpec("ready_unseen_point", list, "[m] depth, y of the waiting point while the puck is unseen", -1.0, 1.0, 2),
    ParamSpec("home_point", list, "[m] depth, y of the home point (pause)", -1.0, 1.0, 2),
    ParamSpec("smash_depth", list, "[m] depth range of the smash area", 0.0, 1.0, 2),
    ParamSpec("smash_rim_margin", float, "[m] smash area distance from the long rims beyond the puck radius", 0.0, 0.5),
    ParamSpec("static_speed", float, "[m/s] puck at rest below this speed", 0.0, 1.0),
    ParamSpec("drift_speed", float, "[m/s] puck hit where it lies below this speed", 0.0, 1.0),
    ParamSpec("drift_significance", float, "a puck whose estimated speed is within this many of its standard "
              "deviations is hit where it lies (0: drift_speed alone)", 0.0, 10.0),
    ParamSpec("smash_puck_speed", float, "[m/s] smash a puck slower than this", 0.0, 5.0),
    ParamSpec("beyond_smash_speed", float,
              "[m/s] smash a puck beyond the smash area's far edge when it is this slow at the hit time", 0.0, 5.0),
    ParamSpec("smash_chase_speed", float, "[m/s] smash a puck moving away from the own goal up to this speed "
              "at the hit time (in the smash area or beyond it)", 0.0, 5.0),
    ParamSpec("smash_chase_lead", float, "[s] shortest lead a chased puck's smash is planned with (tried after "
              "smash_lead_time, lead_time_step shorter each time)", 0.05, 5.0),
    ParamSpec("smash_checks_way", bool, "a smash at a moving puck is played only when the mallet's way to the "
              "strike keeps clear of the puck's predicted path until the strike"),
    ParamSpec("approach_speed", float, "[m/s] puck approaches when vx < -this", 0.0, 1.0),
    ParamSpec("min_plan_time", float,
              "[s] shortest time before a crossing a defence is planned for (or a running smash or push re-aimed for)", 0.0, 2.0),
    ParamSpec("repel_time", list, "[s] crossing time range in which Repel is chosen", 0.0, 5.0, 2),
    ParamSpec("repel_line", float, "[m] depth at which a Repel meets the puck", 0.0, 1.0),
    ParamSpec("repel_width", float, "[m] Repel a puck crossing the defend line within |y| < this", 0.0, 1.0),
    ParamSpec("repel_speed", float, "[m/s] mallet speed of a Repel", 0.05, 5.0),
    ParamSpec("smash_lead_time", float, "[s] a smash is planned at least this far ahead", 0.05, 5.0),
    ParamSpec("lead_time_step", float, "[s] lead time added after 'too late'", 0.01, 2.0),
    ParamSpec("hit_speed_fraction", float, "fraction of the fastest hit the arm allows", 0.1, 1.0),
    ParamSpec("max_hit_speed", float, "[m/s] fastest hit ever asked for", 0.1, 10.0),
    ParamSpec("speed_cap_fraction", float, "fraction of the reported maximum after 'too fast'", 0.1, 1.0),
    ParamSpec("prepare_speed", list, "[m/s] mallet speed range of a Prepare", 0.01, 5.0, 2),
    ParamSpec("prepare_speed_steps", int, "mallet speeds a Prepare tries over prepare_speed", 1, 50),
    ParamSpec("prepare_directions", int, "push directions a Prepare tries around the puck", 4, 360),
    ParamSpec("prepare_end_speed", float, "[m/s] a pushed puck is predicted until it is this slow", 1e-4, 1.0),
    ParamSpec("prepare_horizon", float, "[s] longest prediction of a pushed puck", 0.1, 30.0),
    ParamSpec("clear_depth", float, "[m] a cleared puck should stop this far past the centre line", 0.0, 2.0),
    ParamSpec("clear_after", float, "[s] on the own half this long, a puck Prepare cannot smash is cleared",
              0.0, 600.0),
    ParamSpec("recontact_watch", float, "[s] a pushed or cut puck may not meet the mallet again this long", 0.0, 10.0),
    ParamSpec("mallet_restitution", float, "[-] puck-mallet restitution of the shot model", 0.0, 1.0),
    ParamSpec("mallet_friction", float, "[-] puck-mallet Coulomb friction of the shot model", 0.0, 2.0),
    ParamSpec("aim_noise", float, "[rad] shot direction spread used to rank shots", 1e-4, 1.0),
    ParamSpec("approach_clearance", float, "[m] gap between the approaching mallet and the puck", 0.0, 0.5),
    ParamSpec("guard_margin", float, "[m] clearance of the opponent's ready point a shot needs", 0.0, 0.5),
    ParamSpec("guarded_factor", float, "[-] goal likelihood factor of a shot at the opponent's mallet", 0.0, 1.0),
    ParamSpec("shot_horizon", float, "[s] a shot that needs longer to reach the goal line misses", 0.1, 10.0),
    ParamSpec("goal_aim_margin", float, "[m] aim at least this far inside the goal mouth's edge", 0.0, 0.2),
    ParamSpec("aim_search_steps", int, "steps of 0.02 rad to either side of the reflection law's angle searched "
              "for a first shot that reaches the goal line (0: that angle only)", 0, 50),
    ParamSpec("resend_distance", float, "[m] command change that is sent again", 0.0, 1.0),
    ParamSpec("resend_time", float, "[s] hit time change that is sent again", 0.0, 1.0),
    ParamSpec("hit_replan_distance", float, "[m] puck displacement that re-plans an accepted hit", 0.0, 1.0),
    ParamSpec("hit_correction_distance", float, "[m] puck displacement that moves an accepted hit with the puck "
              "(0: off)", 0.0, 1.0),
    ParamSpec("hit_correction_time", float, "[s] an accepted hit is moved with the puck until this long before "
              "its time", 0.0, 1.0),
    ParamSpec("resend_speed", float, "[m/s] hit velocity change that is sent again", 0.0, 5.0),
    ParamSpec("retry_delay", float, "[s] wait after a refused command", 0.0, 5.0),
    ParamSpec("max_lead_extra", float, "[s] largest lead time added after 'too late'", 0.0, 10.0),
    ParamSpec("limits_slowdown", float, "[-] speed factor after a joint-limit refusal", 0.1, 1.0),
    ParamSpec("cut_arrive_early", float, "[s] a Cut's mallet stops this long before the puck arrives", 0.0, 1.0),
    ParamSpec("cut_contact_steps", int, "contact times a Cut tries on the puck's predicted path", 1, 50),
    ParamSpec("cut_normal_steps", int, "contact normals a Cut tries around head-on", 1, 90),
    ParamSpec("cut_normal_range", float, "[rad] largest angle of a Cut's contact normal from head-on", 0.0, 1.5),
    ParamSpec("cut_offset_noise", float, "[m] sideways error of where a Cut's puck meets the mallet", 0.0, 0.07),
    ParamSpec("cut_catch", list, "[-] fractions of the speed that stops the puck's normal motion a Cut tries",
              0.0, 1.5),
    ParamSpec("reach_time_margin", float, "[-] multiple of the shortest reach time given to a reach", 1.0, 10.0),
    ParamSpec("stale_estimate", float, "[s] no estimate for this long: puck unseen", 0.01, 60.0),
    ParamSpec("unseen_after_own_contact", bool, "an estimate with no frame fused since the robot's last played "
              "contact counts as unseen (it describes the puck before the contact)"),
    ParamSpec("settle_time", float, "[s] time after a hit before re-deciding", 0.0, 5.0),
    ParamSpec("keep_checks_outcome", bool, "a hit or cut under way is kept (its re-plan refused) only while its "
              "contact, on the current prediction, does not send the puck into the own goal"),
    ParamSpec("speed_map_grid", list, "points along depth, along y, hit directions of the fastest-hit table",
              2, 100, 3),
    ParamSpec("contact_learning", bool, "the mallet's restitution and friction learned from the robot's own contacts"),
    ParamSpec("contact_learning_min", int, "contacts measured before the mallet's law is first fitted", 2, 1000),
    ParamSpec("contact_learning_max", int, "the newest this many contacts are fitted", 2, 10000),
    ParamSpec("contact_restitution_bounds", list, "[-] lowest and highest mallet restitution learned", 0.0, 1.0, 2),
    ParamSpec("contact_friction_bounds", list, "[-] lowest and highest mallet friction learned", 0.0, 2.0, 2),
) + ROBOT_BASE_PARAMS


def load_agent_params(extra_files: Iterable[Path] = ()) -> dict[str, Any]:
    """Tactics parameters: the defaults, overridden by ``extra_files`` (ROS 2 parameter YAML)."""
    return load_node_params(PARAM_FILES, NODE_NAME, AGENT_PARAMS, extra_files)


# the nodes an agent variant may set (--versus, --params-file): the robot's agent with its own tracker
VARIANT_NODES = ("tactics", "trajectory_generator", "puck_tracker")


def load_agent_variant(path: Path, flag: str = "--versus") -> tuple[dict[str, Any], dict[str, Any]]:
    """One robot's agent variant (``air-hockey game --versus``, ``strategy-test --params-file``: ``flag``): the
    tactics' and the trajectory generator's parameters with the ROS 2 parameter YAML ``path`` over their
    defaults (its puck_tracker parameters, also allowed, are the game's: each robot's tracker reads them).
    Raises :class:`~air_hockey_agent.params.ParameterFileError` (a parameter of another node, a misspelled
    one) or ``ParameterValueError`` naming the file and the parameter."""
    from air_hockey_agent.motion_params import load_motion_params
    from air_hockey_agent.params import check_only_nodes
    check_only_nodes(path, VARIANT_NODES, flag)
    return load_agent_params([path]), load_motion_params([path])


def agent_variant_problem(path: Path, flag: str) -> str:
    """What is wrong with the agent variant file ``path`` given as ``flag`` (``--versus``, ``--params-file``), as
    one line naming the file and the parameter; '' when it loads (:func:`load_agent_variant`)."""
    from air_hockey_agent.params import file_problem
    return file_problem(path, flag, load_agent_variant)


def puck_model_for_tactics(puck_params_file: str = ""):
    """The tracker's puck model (``config/table.yaml``, ``config/tracker.yaml``, then ``puck_params_file``
    when given): shots are predicted with the physics the filter uses."""
    return _puck_model(_tracker_params(puck_params_file))


def _puck_model(p: dict[str, Any]):
    from air_hockey_agent.core.puck.model import PuckModel, PuckParams
    from air_hockey_agent.core.table import TableGeometry
    return PuckModel(TableGeometry.from_params(p), PuckParams.from_params(p))


def _tracker_params(puck_params_file: str) -> dict[str, Any]:
    from air_hockey_agent.params import ParameterFileError
    from air_hockey_agent.tracker_params import load_tracker_params
    try:
        return load_tracker_params([Path(puck_params_file)] if puck_params_file else [])
    except ParameterFileError as exc:
        raise ParameterFileError(f"parameter 'puck_params_file': {exc}") from None


def build_selector(params: dict[str, Any], robot: str, log=None, motion: dict[str, Any] | None = None):
    """The tactics state machine of ``robot`` with its puck model (the tracker's), arm (the trajectory
    generator's region and the cached fastest-hit table, from the motion parameters ``motion``, default
    ``config/motion.yaml``'s) and settings. Returns (selector, kinematics)."""
    from air_hockey_agent.core.game.arm_reach import ArmReach
    from air_hockey_agent.core.game.shots import ShotPredictor
    from air_hockey_agent.core.game.situation import own_frame_physics
    from air_hockey_agent.core.game.speed_map import load_or_build
    from air_hockey_agent.core.game.tactics.selector import TacticsSelector
    from air_hockey_agent.core.game.tactics.settings import TacticsSettings
    from air_hockey_agent.motion_params import build_planner, load_motion_params
    if params["drift_speed"] > params["static_speed"]:
        raise ParameterValueError(f"parameter 'drift_speed' = {params['drift_speed']!r} must not exceed "
                                  f"'static_speed' = {params['static_speed']!r}")
    motion = load_motion_params() if motion is None else motion
    planner = build_planner(motion, robot)
    speeds = load_or_build(planner, motion, params["speed_map_grid"], log=log)
    reach = ArmReach.of_planner(planner, params["reach_time_margin"], speeds)
    settings = TacticsSettings.from_params(params)
    tracker = _tracker_params(params["puck_params_file"])
    model = _puck_model(tracker)  # table frame; the shots are aimed in the robot's own
    model = model.with_params(own_frame_physics(model.params, robot))
    shots = ShotPredictor(model, settings, 1.0 / tracker["frequency"], reach.max_speed)
    selector = TacticsSelector(settings, reach, shots)
    selector.log = log
    return selector, planner.kin
