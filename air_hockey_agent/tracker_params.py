"""Parameters of the puck tracker, shared by the node and the offline tools (ROS-free).

Declarations only (name, type, meaning with unit, valid range); the defaults and their sources are
in ``config/table.yaml`` and ``config/tracker.yaml``.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any, Iterable

from air_hockey_agent.params import ParamSpec, load_node_params

NODE_NAME = "/puck_tracker"
PARAM_FILES = ("table.yaml", "tracker.yaml")
# The puck physics of the simulated table (config/sim.yaml) for the tracker and the tactics on it; the
# defaults in tracker.yaml are a real table's (issue #13).
SIM_TABLE_FILE = "tracker_sim_table.yaml"
FILTER_KINDS = ("ekf", "ukf", "mee_ukf", "imm")  # core/estimation/ekf.py, ukf.py, imm.py

TABLE_PARAMS = (
    ParamSpec("table.length", float, "[m] playing surface length", 0.5, 5.0),
    ParamSpec("table.width", float, "[m] playing surface width", 0.3, 3.0),
    ParamSpec("table.goal_width", float, "[m] goal opening", 0.0, 1.0),
    ParamSpec("puck.radius", float, "[m] puck radius", 0.005, 0.2),
)
MOCAP_POSE_PARAM = ParamSpec("mocap_table_pose", list, "table pose in the mocap frame: x, y, z [m], yaw [rad]",
                             -100.0, 100.0, 4)  # config/table.yaml
# config/table.yaml, for the nodes that need them besides TABLE_PARAMS
MALLET_RADIUS_PARAM = ParamSpec("mallet.radius", float, "[m] mallet radius", 0.005, 0.2)
PUCK_HEIGHT_PARAM = ParamSpec("puck.height", float, "[m] puck thickness", 0.001, 0.1)
ROBOTS = ("iiwa_front", "iiwa_back")  # the two robots, each with /<robot>/joint_states
ROBOT_BASE_PARAMS = tuple(
    ParamSpec(f"robot_base.{name}", list, f"{name} base in the table frame: x, y, z [m], yaw [rad]", -10.0, 10.0, 4)
    for name in ROBOTS)
TRACKER_PARAMS = (
    ParamSpec("frequency", float, "[Hz] model step rate (mocap frame rate)", 1.0, 2000.0),
    ParamSpec("friction_surface", float, "[m/s^2] surface friction deceleration mu_s", 0.0, 10.0),
    ParamSpec("damping", float, "[1/s] viscous damping d", 0.0, 10.0),
    ParamSpec("restitution", float, "[-] rim restitution e", 0.0, 1.0),
    ParamSpec("friction_rim", float, "[-] rim friction mu_rim", 0.0, 2.0),
    ParamSpec("restitution_slope", float, "[s/m] fall of the rim restitution per m/s of normal speed", 0.0, 10.0),
    ParamSpec("restitution_min", float, "[-] the rim restitution does not fall below this", 0.0, 1.0),
    ParamSpec("restitution_knee", float, "[m/s] the rim restitution falls only beyond this normal speed",
              0.0, 10.0),
    ParamSpec("tangential_restitution", float, "[-] tangential restitution beta of a sticking rim impact "
              "(0: Routh's, -1: no tangential impulse)", -1.0, 1.0),
    ParamSpec("table_acceleration", list, "[m/s^2] constant acceleration of a free puck (x, y), table frame: "
              "a tilted surface", -10.0, 10.0, 2),
    ParamSpec("spin_damping", float, "[1/s] decay rate k of the spin in flight (0: constant spin)", 0.0, 10.0),
    ParamSpec("impact_delay", float, "[s] a rim impact comes this long after the puck's centre reaches the rim "
              "(half a compliant contact; 0: a rigid rim)", 0.0, 0.05),
    ParamSpec("filter", str, "estimator: ekf (thesis), ukf (unscented prediction), mee_ukf (and a minimum-"
              "error-entropy update, seed 001), imm (free / rim / contact modes, seed 004)", choices=FILTER_KINDS),
    ParamSpec("ukf.alpha", float, "[-] sigma-point spread of the ukf and mee_ukf filters", 1e-3, 10.0),
    ParamSpec("ukf.beta", float, "[-] prior-distribution term of the sigma points (2: Gaussian)", 0.0, 10.0),
    ParamSpec("mee.kernel", float, "[std] kernel bandwidth of the mee_ukf update", 0.1, 1000.0),
    ParamSpec("mee.fiducial", float, "[-] weight of the zero-error fiducial point in the MEE cost", 1e-3, 1.0),
    ParamSpec("mee.max_iterations", int, "fixed-point iterations of the MEE update at most", 1, 100),
    ParamSpec("imm.switch_probability", float, "[-] per frame, of leaving a motion mode (filter: imm)", 1e-6, 0.5),
    ParamSpec("imm.rim_impact_noise", float, "[-] the rim mode's impact noise (filter: imm)", 0.0, 10.0),
    ParamSpec("imm.contact_speed", float, "[m/s] std of the contact mode's velocity change per frame", 0.0, 100.0),
    ParamSpec("imm.contact_spin", float, "[rad/s] std of the contact mode's spin change per frame", 0.0, 1000.0),
    ParamSpec("hand.acceleration", float, "[m/s^2] a hand's acceleration as white noise (0: no hand regime)",
              0.0, 1000.0),
    ParamSpec("hand.spin_acceleration", float, "[rad/s^2] a hand's angular acceleration as white noise", 0.0, 1e4),
    ParamSpec("hand.window", float, "[s] a restart this soon after one or the regime's end starts it", 0.0, 60.0),
    ParamSpec("hand.calm_time", float, "[s] span over which the hand regime's end is judged", 1e-3, 10.0),
    ParamSpec("hand.calm_acceleration", float, "[m/s^2] unpredicted acceleration below which it ends", 0.0, 1000.0),
    ParamSpec("hand.stop_fraction", float, "a restart keeping less of the predicted speed starts it", 0.0, 1.0),
    ParamSpec("hand.hit_speed", float, "[m/s] a restart gaining more was a hit: it ends the regime", 0.0, 100.0),
    ParamSpec("measurement_noise", list, "R diagonal (x, y, theta) [m^2, m^2, rad^2]", 1e-15, 1.0, 3),
    ParamSpec("process_noise", list, "Q diagonal per step (x, y, vx, vy, theta, omega)", 1e-18, 1e3, 6),
    ParamSpec("process_noise_rest", list, "Q diagonal per step of a puck slower than regime_rest_speed",
              1e-18, 1e3, 6),
    ParamSpec("initial_covariance", list, "P0 diagonal after (re)initialisation", 1e-15, 1e4, 6),
    ParamSpec("gate_threshold", float, "squared Mahalanobis gate on the position innovation (2 dof)", 0.1, 1e6),
    ParamSpec("angle_gate_threshold", float, "squared angle innovation over its variance beyond which the "
              "angle is not fused (1 dof)", 0.1, 1e6),
    ParamSpec("measurement_noise_per_speed", float, "[s] position noise std added per m/s of speed", 0.0, 1.0),
    ParamSpec("marker_offset", list, "[m] the mocap rigid body's pivot off the disc's centre (x, y), puck frame",
              -0.05, 0.05, 2),
    ParamSpec("impact_noise", float, "[-] velocity/spin std after a rim impact, fraction of their size", 0.0, 10.0),
    ParamSpec("impact_contact_time", float, "[s] position std after a rim impact, as the puck's travel in this "
              "time", 0.0, 0.1),
    ParamSpec("rim_adaptation.enabled", bool, "learn this table's rim law online from the impacts seen"),
    ParamSpec("rim_adaptation.prior_impacts", float, "[-] weight of the configured rim law, in impacts", 0.0, 1e6),
    ParamSpec("rim_adaptation.window", float, "[s] fused frames after an impact fitted for its outcome", 0.01, 2.0),
    ParamSpec("rim_adaptation.min_frames", int, "fused frames the window needs (a line and a spin: 3 at least)",
              3, 1000),
    ParamSpec("rim_adaptation.min_normal_speed", float, "[m/s] slower impacts are not learned from", 0.0, 10.0),
    ParamSpec("rim_adaptation.max_impulse_disagreement", float, "[m/s] an impact whose tangential impulse from "
              "the velocity and from the spin differ by more is not learned from", 0.0, 100.0),
    ParamSpec("rim_adaptation.max_scale", float, "[-] an impact whose ratio to the law falls beyond "
              "[1/max_scale, max_scale] is not learned from", 1.0, 100.0),
    ParamSpec("rim_adaptation.max_incoming_uncertainty", float, "[-] velocity std before an impact, fraction "
              "of the speed, at most", 0.0, 10.0),
    ParamSpec("rim_adaptation.knee_count", int, "restitution knees tried, evenly from 0 to knee_max (0: the "
              "configured one only)", 0, 1000),
    ParamSpec("rim_adaptation.knee_max", float, "[m/s] the fastest restitution knee tried", 0.0, 20.0),
    ParamSpec("rim_adaptation.fall_width_count", int, "widths of the restitution's fall tried, evenly up to "
              "fall_width_max (0: the configured one only)", 0, 1000),
    ParamSpec("rim_adaptation.fall_width_max", float, "[m/s] the widest fall of the restitution tried", 0.0, 20.0),
    ParamSpec("rim_adaptation.friction_count", int, "rim frictions tried for Coulomb's bound alone, evenly in the "
              "logarithm from friction_min to friction_max (0: that form is not tried)", 0, 1000),
    ParamSpec("rim_adaptation.friction_min", float, "[-] the smallest rim friction tried", 1e-6, 100.0),
    ParamSpec("rim_adaptation.friction_max", float, "[-] the largest rim friction tried", 1e-6, 100.0),
    ParamSpec("rim_adaptation.stick_friction_rim", float, "[-] mu_rim of a learned rim law whose tangential impulse "
              "is a fraction of Routh's sticking one", 0.0, 100.0),
    ParamSpec("rim_adaptation.max_delay", float, "[s] an impact whose paths meet farther from the rim line than "
              "this times its normal speed is not learned from (impact_delay)", 0.0, 0.1),
    ParamSpec("rim_adaptation.offset_warning", float, "[m] a rim whose impacts meet farther from its line is said "
              "to be off (table pose or size)", 0.0, 0.1),
    ParamSpec("rim_adaptation.offset_significance", float, "[-] ... and beyond this many standard errors", 0.0, 100.0),
    ParamSpec("rim_adaptation.rederive_impacts", int, "the first impacts whose outgoing fits are derived again when "
              "the learned flight law moves (0: never)", 0, 10000),
    ParamSpec("rim_adaptation.rederive_tolerance", float, "[m/s^2] how far the flight law's acceleration at those "
              "impacts' speeds moves before they are derived again", 0.0, 10.0),
    ParamSpec("rim_adaptation.rederive_incoming", float, "[m/s^2] an impact derived again whose flight law when "
              "watched was off by more than this at its speed takes its incoming velocity from a line fit "
              "before it instead of the filter's state", 0.0, 10.0),
    ParamSpec("noise_adaptation.enabled", bool, "learn the mocap's position noise (R at rest and its growth with "
              "the speed) from the poses"),
    ParamSpec("noise_adaptation.window", int, "consecutive poses per quadratic fit", 4, 1000),
    ParamSpec("noise_adaptation.max_gap_frames", float, "[frame periods] a longer interval ends a window", 1.0, 100.0),
    ParamSpec("noise_adaptation.prior_windows", float, "weight of the configured noise, in windows", 0.0, 1e9),
    ParamSpec("noise_adaptation.min_windows", int, "windows before the first refit", 1, 1000000),
    ParamSpec("noise_adaptation.update_every", int, "new windows between refits", 1, 100000),
    ParamSpec("noise_adaptation.max_windows", int, "the last windows a refit uses", 10, 10000000),
    ParamSpec("noise_adaptation.outlier_ratio", float, "a window beyond this many times its expected variance "
              "is left out", 1.0, 1000.0),
    ParamSpec("noise_adaptation.angle_outlier_ratio", float, "a window beyond this many times the angle noise "
              "variance is left out of it", 1.0, 1000.0),
    ParamSpec("process_noise_adaptation.enabled", bool, "learn the scales of the process noise by regime (flight, "
              "rest, rim impacts) from the gated frames' position NIS"),
    ParamSpec("process_noise_adaptation.block", int, "free-flight (and resting) frames per update", 10, 1000000),
    ParamSpec("process_noise_adaptation.impact_block", int, "impact-regime frames per update", 10, 1000000),
    ParamSpec("process_noise_adaptation.impact_frames", int, "gated frames after a model impact that belong to "
              "the impact regime", 1, 100),
    ParamSpec("process_noise_adaptation.gain", float, "[-] exponent of a block's correction", 0.01, 1.0),
    ParamSpec("process_noise_adaptation.min_scale", float, "[-] smallest scale of a regime's configured noise "
              "(variance)", 1e-6, 1.0),
    ParamSpec("process_noise_adaptation.max_scale", float, "[-] largest scale of a regime's configured noise "
              "(variance)", 1.0, 1e6),
    ParamSpec("process_noise_adaptation.clear_of_rims", float, "[s] of travel from the rims a free-flight frame "
              "keeps, either way", 0.0, 10.0),
    ParamSpec("acceleration_adaptation.enabled", bool, "learn this table's acceleration (tilt, air film's mean) "
              "online from free flight"),
    ParamSpec("acceleration_adaptation.prior_std", float, "[m/s^2] std of the configured table_acceleration",
              1e-6, 10.0),
    ParamSpec("acceleration_adaptation.damping_prior_std", float, "[1/s] std of the configured damping",
              1e-6, 10.0),
    ParamSpec("acceleration_adaptation.friction_prior_std", float, "[m/s^2] std of the configured "
              "friction_surface (0: it is not learned)", 0.0, 10.0),
    ParamSpec("acceleration_adaptation.field_std", float, "[m/s^2] added to each window's std: what a constant "
              "acceleration cannot follow", 0.0, 10.0),
    ParamSpec("acceleration_adaptation.window", float, "[s] fused free-flight frames per fit", 0.05, 5.0),
    ParamSpec("acceleration_adaptation.marker_offset_prior_std", float, "[m] std of the configured marker_offset "
              "per axis (0: it is not learned)", 0.0, 0.05),
    ParamSpec("acceleration_adaptation.min_frames", int, "fused frames a window needs", 4, 10000),
    ParamSpec("acceleration_adaptation.min_speed", float, "[m/s] frames of a slower puck are not used", 0.0, 10.0),
    ParamSpec("acceleration_adaptation.gate", float, "squared Mahalanobis distance (2 dof) beyond which a window "
              "is not learned from", 0.1, 1e6),
    ParamSpec("acceleration_adaptation.spin_prior_std", float, "[1/s] std of the configured spin_damping (0: not "
              "learned)", 0.0, 100.0),
    ParamSpec("acceleration_adaptation.spin_gate", float, "squared distance (1 dof) beyond which a window's spin "
              "is left out", 0.1, 1e6),
    ParamSpec("mallet_contact.enabled", bool, "the robots' mallets (from their joint states) hit the estimate"),
    ParamSpec("mallet_contact.restitution", float, "[-] normal restitution of a mallet contact", 0.0, 1.0),
    ParamSpec("mallet_contact.friction", float, "[-] Coulomb friction of a mallet contact", 0.0, 2.0),
    ParamSpec("mallet_contact.velocity_noise", float, "[-] std of the velocity and spin after a mallet contact, "
              "as a fraction of their change", 0.0, 10.0),
    ParamSpec("mallet_contact.max_age", float, "[s] a mallet position older than this is not used", 0.001, 1.0),
    ParamSpec("mallet_contact.coast_after", float, "[s] with no frame for this long the estimate is predicted "
              "on the mallets' clock (a dropout)", 0.001, 10.0),
    ParamSpec("max_consecutive_rejections", int, "rejected frames in a row before re-initialising", 1, 1000),
    ParamSpec("outside_table_margin", float, "[m] drop measurements this far beyond the rims", 0.0, 10.0),
    ParamSpec("max_prediction_gap", float, "[s] gap after which the filter re-initialises", 0.01, 60.0),
    ParamSpec("glitch_speed", float, "[m/s] evaluation: a pose that jumps faster than this from both "
              "neighbours is a marker glitch, not ground truth", 0.1, 1000.0),
    ParamSpec("regime_rest_speed", float, "[m/s] below this speed the puck is at rest: process_noise_rest, and "
              "the evaluation's NIS by regime", 0.0, 10.0),
    ParamSpec("prediction_horizon", float, "[s] horizon of puck/prediction", 0.0, 10.0),
    ParamSpec("prediction_sample_period", float, "[s] spacing of predicted states", 0.001, 1.0),
    ParamSpec("defend_line_offset", float, "[m] defend line distance from each short rim", 0.0, 1.0),
    MOCAP_POSE_PARAM,
)
TRACKER_NODE_PARAMS = TABLE_PARAMS + (MALLET_RADIUS_PARAM,) + TRACKER_PARAMS + ROBOT_BASE_PARAMS


def without_learning(params: dict[str, Any]) -> dict[str, Any]:
    """``params`` with the configured physics kept as it is (nothing learned online of the table): what
    sysid identifies and the thesis's trajectory-level columns report (fixed parameters, thesis tables
    5.2-5.4)."""
    return {**params, "rim_adaptation.enabled": False, "acceleration_adaptation.enabled": False,
            "noise_adaptation.enabled": False, "process_noise_adaptation.enabled": False}


def trajectory_loss_params(params: dict[str, Any]) -> dict[str, Any]:
    """``params`` for the trajectory-level prediction losses (``sysid``, ``eval-prediction``'s thesis-style
    columns, ``plot``'s error curves): nothing learned online (:func:`without_learning`) and no hand regime.
    Preprocessing ends each trajectory where a hand took the puck (``cut_pushes``), so there the regime
    could only answer the model's own misfit: on the harsh test bed (40 shots seed 5) it started 206 times
    in the 36 trajectories and the 1.0 s loss was 86.70 mm with it, 84.70 without; the test bed's 40 shots
    unchanged."""
    return {**without_learning(params), "hand.acceleration": 0.0}


def load_tracker_params(extra_files: Iterable[Path] = ()) -> dict[str, Any]:
    """Tracker parameters: the defaults, overridden by ``extra_files`` (ROS 2 parameter YAML, in order).

    Raises :class:`air_hockey_agent.params.ParameterFileError` / ``ParameterValueError`` with a
    one-line message naming the file or parameter.
    """
    return load_node_params(PARAM_FILES, NODE_NAME, TRACKER_NODE_PARAMS, extra_files)
