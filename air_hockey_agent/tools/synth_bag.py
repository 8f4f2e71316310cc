"""``air-hockey synth-bag OUT``: a rosbag2 bag of synthetic puck shots recorded like OptiTrack.

Random shots (``config/synthetic.yaml``) are integrated with the tracker's puck model at 1 kHz and
sampled as a 120 Hz mocap stream with noise, jitter, lost and frozen frames, glitches and dropouts.
Topics: ``/optitrack/puck`` (geometry_msgs/PoseStamped, mocap frame; lost frames are absent) and
``/puck/true_state`` (air_hockey_msgs/PuckState, table frame, the true state when each frame was
captured, stamped with that time; the pose's stamp scatters about it by ``mocap.jitter_std``).
The model's parameters come from ``config/tracker.yaml`` unless ``--params-file`` overrides them, so a
bag with known parameters can test system identification.

``--source testbed`` takes it from the test bed's real-table physics (``core/puck/real_table.py``,
``testbed.*`` in config/synthetic.yaml): a resting puck hit by a human after a random delay, a tilted
surface, an uneven air film, random accelerations, rim restitution falling with the normal speed and
a tangential impulse softer than Coulomb's, effects the tracker's model lacks (issue #13 item 1).

``--source mujoco`` takes it from a MuJoCo table (``air_hockey_agent/sim/mujoco_table.py``, ``mujoco.*`` in
config/synthetic.yaml): another physics engine, whose soft rim contacts and damping no code of ours
wrote; the shots are human hits from rest as on the test bed (``testbed.hit_delay``).

``--source sim`` takes the truth from the pybullet table instead (``config/sim.yaml``, the puck alone
at the simulation's physics rate): the same shots and imperfections, with the simulation's physics
(its own air film, rim impact coefficients and goals: a puck in a goal stops there, as the
tracker's model holds it a radius past the face); use it to measure model error and to identify the tracker's
parameters for the simulation.
"""
from __future__ import annotations

import argparse
import contextlib
import sys
from pathlib import Path

import numpy as np

from air_hockey_agent.bags.build import build, pose_fields, puck_state_fields
from air_hockey_agent.bags.writer import STORAGES, BagExistsError, BagWriter
from air_hockey_agent.core.estimation.ekf import PuckEKF
from air_hockey_agent.core.frames import table_to_mocap
from air_hockey_agent.core.puck.real_table import HandCarry, TableEffects, testbed_shots, with_hand_carries
from air_hockey_agent.core.estimation.synthetic import (MOCAP_BOUNDS, MOCAP_FIELDS, MocapImperfections, ShotRanges,
                                                        synthetic_session)
from air_hockey_agent.params import (ParameterFileError, ParameterValueError, ParamSpec, check_files_read,
                                     load_node_params)
from air_hockey_agent.tracker_params import load_tracker_params
from air_hockey_agent.tools.argtypes import count, seed
from air_hockey_agent.core.estimation.evaluation import count_lost_frames

POSE_TOPIC, TRUTH_TOPIC = "/optitrack/puck", "/puck/true_state"
SESSION_PARAMS = (
    ParamSpec("shots", int, "trajectories per bag", 1, 100000),
    ParamSpec("shot_duration", float, "[s] recorded time per shot", 0.1, 600.0),
    ParamSpec("pause", float, "[s] time without frames between shots", 0.0, 600.0),
    ParamSpec("speed", list, "[m/s] initial speed range", 0.0, 20.0, 2),
    ParamSpec("spin", list, "[rad/s] initial spin range", -200.0, 200.0, 2),
    ParamSpec("rate", float, "[Hz] mocap frame rate", 1.0, 2000.0),
    ParamSpec("fine_dt", float, "[s] integration step of the truth", 1e-5, 0.1),
    ParamSpec("start_time", float, "[s] stamp of the first frame", 0.0, 1e10),
) + tuple(ParamSpec(f"mocap.{name}", float, "measurement imperfection (config/synthetic.yaml)", *MOCAP_BOUNDS[name])
          for name in MOCAP_FIELDS) + (
    ParamSpec("testbed.damping", float, "[1/s] test bed's viscous damping", 0.0, 10.0),
    ParamSpec("testbed.friction_surface", float, "[m/s^2] test bed's constant deceleration", 0.0, 10.0),
    ParamSpec("testbed.tilt", float, "[rad] slope of the test bed's surface", 0.0, 0.1),
    ParamSpec("testbed.tilt_heading", float, "[rad] direction the surface falls toward", -7.0, 7.0),
    ParamSpec("testbed.air_film_amplitude", float, "[m/s^2] peak acceleration of the air film's field", 0.0, 10.0),
    ParamSpec("testbed.air_film_wavelength", float, "[m] wavelength of the air film's field", 0.01, 100.0),
    ParamSpec("testbed.random_acceleration", float, "[m/s^2] std of the random acceleration", 0.0, 10.0),
    ParamSpec("testbed.random_acceleration_time", float, "[s] how long one random acceleration holds", 0.001, 10.0),
    ParamSpec("testbed.restitution_slow", float, "[-] rim restitution at low normal speed", 0.0, 1.0),
    ParamSpec("testbed.restitution_fast", float, "[-] rim restitution at high normal speed", 0.0, 1.0),
    ParamSpec("testbed.restitution_speed_low", float, "[m/s] normal speed up to which restitution_slow holds",
              0.0, 20.0),
    ParamSpec("testbed.restitution_speed_high", float, "[m/s] normal speed from which restitution_fast holds",
              0.0, 20.0),
    ParamSpec("testbed.friction_rim", float, "[-] rim friction of the Coulomb bound", 0.0, 2.0),
    ParamSpec("testbed.tangential_scale", float, "[-] tangential impulse as a fraction of Coulomb's", 0.0, 1.0),
    ParamSpec("testbed.hit_delay", list, "[s] range of the rest before the human hit", 0.0, 600.0, 2),
    ParamSpec("testbed.hit_duration", float, "[s] how long the human hit pushes the puck (0: an impulse)", 0.0, 1.0),
    ParamSpec("testbed.carry_time", list, "[s] range of a hand's carry of the puck at a shot's end (0 0: none)",
              0.0, 600.0, 2),
    ParamSpec("testbed.carry_hold", float, "[s] how long the hand holds the carried puck still before the shot "
              "ends", 0.0, 600.0),
    ParamSpec("mujoco.timestep", float, "[s] MuJoCo table's integration step", 1e-5, 0.01),
    ParamSpec("mujoco.puck_mass", float, "[kg] MuJoCo table's puck mass", 1e-4, 10.0),
    ParamSpec("mujoco.damping", float, "[1/s] MuJoCo table's viscous damping", 0.0, 10.0),
    ParamSpec("mujoco.angular_damping", float, "[1/s] MuJoCo table's spin damping", 0.0, 100.0),
    ParamSpec("mujoco.tilt", float, "[rad] slope of the MuJoCo table's surface", 0.0, 0.1),
    ParamSpec("mujoco.tilt_heading", float, "[rad] direction the MuJoCo table's surface falls toward", -7.0, 7.0),
    ParamSpec("mujoco.rim_timeconst", float, "[s] MuJoCo solref time constant of the rim contact", 1e-4, 1.0),
    ParamSpec("mujoco.rim_dampratio", float, "[-] MuJoCo solref damping ratio of the rim contact", 0.0, 10.0),
    ParamSpec("mujoco.rim_solimp", list, "MuJoCo solimp of the rim contact (dmin, dmax, width [m], midpoint, "
              "power)", 0.0, 10.0, 5),
    ParamSpec("mujoco.rim_friction", float, "[-] MuJoCo table's rim sliding friction", 0.0, 1e5),
)


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("synth-bag", help="write a bag of synthetic puck shots (mocap stream + truth)",
                                   description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("out", type=Path, help="bag directory to create (must not exist)")
    parser.add_argument("--shots", type=count(1), help="number of shots (default: config/synthetic.yaml)")
    parser.add_argument("--seed", type=seed, default=0, help="random seed (default 0)")
    parser.add_argument("--storage", choices=sorted(STORAGES), default="mcap", help="bag storage (default mcap)")
    parser.add_argument("--source", choices=("model", "sim", "testbed", "mujoco"), default="model",
                        help="truth from the puck model (default), the pybullet table simulation, the test "
                             "bed's real-table physics (testbed.* in config/synthetic.yaml) or the MuJoCo "
                             "table (mujoco.*)")
    parser.add_argument("--params-file", type=Path, action="append", default=[],
                        help="parameter YAML overriding the tracker's model parameters and/or the session "
                             "(synth_bag node); may be repeated")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    try:
        tracker = load_tracker_params(args.params_file)
        session = load_node_params(["synthetic.yaml"], "/synth_bag", SESSION_PARAMS, args.params_file)
        sim = ("table_sim",) if args.source == "sim" else ()  # only the pybullet table reads table_sim
        check_files_read(args.params_file, ("puck_tracker", "synth_bag", *sim))
    except (ParameterFileError, ParameterValueError) as exc:
        print(f"air-hockey synth-bag: error: {exc}", file=sys.stderr)
        return 2
    if args.shots is not None:
        session["shots"] = SESSION_PARAMS[0].check(args.shots)
    mujoco_physics = None
    if args.source == "mujoco":  # checked before the (possibly long) session; imported here: only it needs MuJoCo
        from air_hockey_agent.sim.mujoco_table import MujocoTable
        try:
            mujoco_physics = MujocoTable.from_params(session)
        except ValueError as exc:
            print(f"air-hockey synth-bag: error: {exc}", file=sys.stderr)
            return 2
    model = PuckEKF.from_params(tracker).model
    shots = ShotRanges(tuple(session["speed"]), tuple(session["spin"]), session["shot_duration"], session["pause"])
    try:  # before the (possibly long) session: an existing OUT is refused at once
        writer = BagWriter(args.out, {POSE_TOPIC: "geometry_msgs/msg/PoseStamped",
                                      TRUTH_TOPIC: "air_hockey_msgs/msg/PuckState"}, args.storage)
    except BagExistsError as exc:
        print(f"air-hockey synth-bag: error: {exc}", file=sys.stderr)
        return 2
    with _truth_source(args.source, args.params_file, session, model.table, args.seed, mujoco_physics) as simulate:
        frames = synthetic_session(model, shots, session["shots"], session["rate"],
                                   MocapImperfections.from_params(session), np.random.default_rng(args.seed),
                                   session["fine_dt"], simulate)
    with writer:
        for topic, log_ns, msg in _messages(frames, session["start_time"], tracker["mocap_table_pose"]):
            writer.write(topic, log_ns, msg)
    count = writer.count
    stamps = [f.stamp for f in frames if f.measurement is not None]
    # counted as eval-prediction counts them (nominal frames missing between two received ones), so both
    # tools give the same figure for the same bag (dropouts included, the pauses between shots not)
    lost = count_lost_frames(stamps, 1.0 / session["rate"], tracker["max_prediction_gap"])
    print(f"wrote {args.out} ({args.storage}, truth from the {args.source}): {session['shots']} shots, "
          f"{len(stamps)} poses on {POSE_TOPIC} "
          f"({lost} frames lost), {len(frames)} true states on {TRUTH_TOPIC}, {count} messages")
    return 0


@contextlib.contextmanager
def _truth_source(source: str, params_files, session, table, seed: int, mujoco_physics=None):
    """None for the puck model (synthetic_session's default), the test bed's shot simulator, the MuJoCo
    table's (``mujoco_physics``, checked by the caller; human hits after ``testbed.hit_delay`` as on the
    test bed), or one on the pybullet table without robots (imported here: pybullet prints a banner when
    loaded); the test bed's, MuJoCo's and pybullet's shots end in a hand's carry where ``testbed.carry_time``
    asks for one."""
    if source == "model":
        yield None
        return
    if source == "testbed":
        yield testbed_shots(TableEffects.from_params(session), table, session["testbed.hit_delay"],
                            session["fine_dt"], np.random.default_rng([seed, 1]), HandCarry.from_params(session),
                            np.random.default_rng([seed, 2]))
        return
    carries = HandCarry.from_params(session), np.random.default_rng([seed, 2])  # another engine's shots end so too
    if source == "mujoco":  # imported here: only this source needs the engine
        from air_hockey_agent.sim.mujoco_table import mujoco_shots
        yield with_hand_carries(mujoco_shots(mujoco_physics, table, session["testbed.hit_delay"],
                                             np.random.default_rng([seed, 1])), table, *carries)
        return
    from air_hockey_agent.sim.params import load_sim_params
    from air_hockey_agent.sim.world import SimSettings, TableWorld, simulate_shot
    world = TableWorld(SimSettings.from_params(load_sim_params(params_files)).puck_only())
    try:
        yield with_hand_carries(lambda state, duration: simulate_shot(world, state, duration), table, *carries)
    finally:
        world.close()


def _messages(frames, start_time: float, table_pose):
    """(topic, log time [ns], message) in stamp order: the pose in the mocap frame and the truth."""
    for f in frames:
        stamp = start_time + f.stamp
        stamp_ns = int(round(stamp * 1e9))
        captured = stamp if f.captured is None else start_time + f.captured  # the pose's stamp has the jitter
        yield TRUTH_TOPIC, stamp_ns, build("air_hockey_msgs/msg/PuckState", puck_state_fields(captured, f.truth))
        if f.measurement is None:
            continue
        mx, my, myaw = table_to_mocap(*(float(v) for v in f.measurement), table_pose)
        yield POSE_TOPIC, stamp_ns, build("geometry_msgs/msg/PoseStamped",
                                          pose_fields(stamp, "optitrack", mx, my, float(table_pose[2]), myaw))
