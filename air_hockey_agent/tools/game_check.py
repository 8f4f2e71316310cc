"""``air-hockey game-check BAG...``: how the arms executed their motions and met the puck in a recorded game.

Reads a recording of `air-hockey game --record` (or any bag with ``/<robot>/joint_states`` and, for the
plans, ``/<robot>/joint_trajectory``; rosbags, no ROS needed) and reports per robot: how far the mallet
went beyond the motion layer's allowed region (the referee stops play 2 cm into a rim), the largest joint
velocity against the real limits, and how many received trajectories had a planned knot outside the
region (:mod:`air_hockey_agent.core.motion.execution_check`), and how well the tactics' contact law
predicted the puck's exit at its mallet contacts (:mod:`air_hockey_agent.core.game.contact_check`; the puck
and its yaw from ``/sim/puck_true_state`` if recorded, else from ``/optitrack/puck``; the table's flight law from
the tracker's ``/<robot>/puck/physics`` where recorded). ``--plot DIR`` also draws each bag as
``DIR/<bag>_arms.png``: the table seen from above with both regions, the mallets' paths and the puck's
(``/sim/puck_true_state``, if recorded), the worst excursion marked; below, each arm's largest joint
velocity against its limit over time; and, where contacts were measured, ``DIR/<bag>_contacts.png``: the
puck's exit speed measured against the law's, and the law's error against the mallet's speed. A bag that
cannot be used gives a one-line error on stderr and exit code 2; the other bags are still checked.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from air_hockey_agent.bags.reader import BagError, bag_directory, bag_topics, iter_raw
from air_hockey_agent.sim.params import ROBOTS
from air_hockey_agent.tools.json_output import json_text

if TYPE_CHECKING:
    from air_hockey_agent.core.game.contact_check import ContactGeometry

PROG = "air-hockey game-check"
JOINT_STATE = "sensor_msgs/msg/JointState"
TRAJECTORY = "trajectory_msgs/msg/JointTrajectory"
PUCK_TRUTH, PUCK_STATE = "/sim/puck_true_state", "air_hockey_msgs/msg/PuckState"
MOCAP, POSE = "/optitrack/puck", "geometry_msgs/msg/PoseStamped"
PHYSICS = "air_hockey_msgs/msg/PuckPhysics"  # on /<robot>/puck/physics: the tracker's flight law as it went
# [m] a planned knot this far outside the region counts: the planner's own path check allows 1 mm between
# its samples (core/motion/planner.py PATH_TOLERANCE), so more is a plan that left the region
PLANNED_TOLERANCE = 0.002


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("game-check",
                                   help="mallet excursions, joint velocities and mallet contacts in a recorded game",
                                   description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("bags", nargs="+", type=Path, metavar="BAG",
                        help="rosbag2 bags (directory, or its .mcap/.db3 file) or ROS 1 .bag files")
    parser.add_argument("--json", action="store_true", help="print exactly one JSON object")
    parser.add_argument("--plot", type=Path, default=None, metavar="DIR",
                        help="also write DIR/<bag>_arms.png (paths over the table, joint velocity over time) and "
                             "DIR/<bag>_contacts.png (the contact law against the measured exits)")
    parser.set_defaults(run=run)


def check_bag(bag: Path, planners: dict, checks_out: dict | None = None,
              geometry: ContactGeometry | None = None) -> dict:
    """Per robot :class:`ArmExecution` as a dict, with its mallet contacts under ``"contacts"`` when
    ``geometry`` is given and the bag holds the true puck states or else the mocap's poses
    (:func:`contact_check.summary`, and ``"puck"``: the topic used); raises
    :class:`BagError` when the bag has no joint states. With ``checks_out`` (a dict), the per-robot
    :class:`ExecutionCheck` with its trace is put there, and the recorded true puck positions (table frame)
    under ``"puck"``."""
    from air_hockey_agent.bags.types import typestore
    from air_hockey_agent.core.motion.execution_check import ExecutionCheck
    from air_hockey_agent.core.motion.kinematics import in_order
    from air_hockey_agent.core.puck.model import PuckParams
    topics = bag_topics(bag)
    robots = [r for r in ROBOTS if topics.get(f"/{r}/joint_states") == JOINT_STATE]
    if not robots:
        raise BagError(bag, "no /<robot>/joint_states (sensor_msgs/msg/JointState) of "
                            f"{' or '.join(ROBOTS)}: record a game with `air-hockey game --record`")
    keep = checks_out is not None
    checks = {r: ExecutionCheck(planners[r], PLANNED_TOLERANCE, keep_trace=keep) for r in robots}
    wanted = {f"/{r}/joint_states": r for r in robots}
    wanted.update({f"/{r}/joint_trajectory": r for r in robots if topics.get(f"/{r}/joint_trajectory") == TRAJECTORY})
    puck: list[tuple[float, float, float, float]] = []  # (stamp [s], x, y [m], yaw [rad]) table frame
    mallets: dict[str, list] = {r: [] for r in robots}  # (stamp [s], x, y [m], vx, vy [m/s]) own frame
    if (keep or geometry is not None) and topics.get(PUCK_TRUTH) == PUCK_STATE:
        wanted[PUCK_TRUTH] = ""
    physics: dict[str, list] = {r: [] for r in robots}  # (stamp [s], PuckParams) table frame
    if geometry is not None:
        wanted.update({f"/{r}/puck/physics": r for r in robots if topics.get(f"/{r}/puck/physics") == PHYSICS})
    store = typestore()
    for topic, _, raw in iter_raw(bag, wanted):
        robot, msg = wanted[topic], store.deserialize_cdr(raw, topics[topic])
        if topic == PUCK_TRUTH:
            puck.append((_stamp(msg), msg.x, msg.y, msg.theta))
            continue
        if topic.endswith("physics"):
            physics[robot].append((msg.stamp.sec + msg.stamp.nanosec * 1e-9, PuckParams.from_attributes(msg)))
            continue
        names = planners[robot].kin.joint_names
        if topic.endswith("joint_states"):
            q, dq = in_order(msg.name, msg.position, names), in_order(msg.name, msg.velocity, names)
            if q is not None and dq is not None:
                checks[robot].joint_state(_stamp(msg), q, dq)
                if geometry is not None and np.all(np.isfinite(q)) and np.all(np.isfinite(dq)):
                    mallets[robot].append((_stamp(msg), *np.concatenate(planners[robot].kin.planar_motion(q, dq))))
        else:
            knots = (in_order(msg.joint_names, point.positions, names) for point in msg.points)
            checks[robot].trajectory([q for q in knots if q is not None])
    if keep:
        checks_out.update(checks, puck=[(x, y) for _, x, y, _ in puck])
    result = {r: c.result.as_dict() for r, c in checks.items()}
    if geometry is None:
        return result
    source = PUCK_TRUTH
    if not puck and topics.get(MOCAP) == POSE:
        try:
            puck, source = mocap_positions(bag), MOCAP
        except BagError:
            puck = []  # unreadable poses: the arms' checks still stand, without the contacts
    for robot in robots:
        if puck:
            flight = FlightLaws.of(physics[robot], robot)
            result[robot]["contacts"] = {"puck": source, "flight": f"/{robot}/puck/physics" if flight else None,
                                         **robot_contacts(np.array(puck), np.array(mallets[robot]).reshape(-1, 5),
                                                          robot, geometry, flight)}
    return result


class FlightLaws:
    """The tracker's flight law (eq. 3.1 with the table's acceleration, :func:`~air_hockey_agent.core.puck.model.
    flight_acceleration`) in ``robot``'s frame as it was at a time: ``physics`` the (stamp [s], PuckParams) of its
    recorded ``puck/physics`` messages, in their order."""

    @classmethod
    def of(cls, physics: list, robot: str) -> "FlightLaws | None":
        """The laws of the physically valid ones (:meth:`PuckParams.validate`: a malformed message is left
        out); None when none is."""
        valid = []
        for stamp, params in physics:
            try:
                params.validate()
            except ValueError:
                continue
            valid.append((stamp, params))
        return cls(valid, robot) if valid else None

    def __init__(self, physics: list, robot: str) -> None:
        from air_hockey_agent.core.game.situation import own_frame_physics
        from air_hockey_agent.core.puck.model import flight_acceleration
        self.stamps = np.array([t for t, _ in physics])
        self.laws = [flight_acceleration(p.damping, p.friction_surface, p.table_acceleration)
                     for p in (own_frame_physics(q, robot) for _, q in physics)]

    def __call__(self, t: float):
        return self.laws[max(0, int(np.searchsorted(self.stamps, t, side="right")) - 1)]


def mocap_positions(bag: Path) -> list[tuple[float, float, float, float]]:
    """(stamp [s], x, y [m], yaw [rad]) of the puck's usable poses on ``/optitrack/puck``, in the table frame of
    the tracker's ``mocap_table_pose`` (as ``eval-prediction`` reads them)."""
    from air_hockey_agent.bags.reader import PUCK_FRAME
    from air_hockey_agent.bags.trajectories import bag_measurements
    from air_hockey_agent.tracker_params import load_tracker_params
    records, measurements, _, _ = bag_measurements(bag, MOCAP, PUCK_FRAME, "", load_tracker_params())
    return [(r.stamp, m[0], m[1], m[2]) for r, m in zip(records, measurements) if m is not None]


def robot_contacts(puck: np.ndarray, mallet: np.ndarray, robot: str, geometry: ContactGeometry,
                   flight: FlightLaws | None = None) -> dict:
    """:func:`contact_check.summary` of ``robot``'s contacts: ``puck`` (n, 4) stamps [s], table-frame
    positions [m] and yaws [rad], ``mallet`` (m, 5) stamps, own-frame positions [m] and velocities [m/s];
    ``flight``: the table's flight law as the tracker had it (None: the puck's lines not decelerated)."""
    from air_hockey_agent.core.game.contact_check import measure_contacts, summary
    from air_hockey_agent.core.game.situation import to_own_frame
    puck, mallet = puck[np.argsort(puck[:, 0], kind="stable")], mallet[np.argsort(mallet[:, 0], kind="stable")]
    states = np.zeros((len(puck), 6))
    states[:, :2], states[:, 4] = puck[:, 1:3], puck[:, 3]
    own = to_own_frame(states, robot)
    return summary(measure_contacts(puck[:, 0], own[:, :2], mallet[:, 0], mallet[:, 1:3], mallet[:, 3:5], geometry,
                                    own[:, 4], flight), geometry)


def _stamp(msg) -> float:
    return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9


def _print(bag: Path, result: dict) -> None:
    print(f"{bag}")
    for robot, r in result.items():
        when = f" at {r['worst_outside_time']:.2f} s" if r["worst_outside_time"] is not None else ""
        vel_when = f" at {r['worst_velocity_time']:.2f} s" if r["worst_velocity_time"] is not None else ""
        print(f"  {robot}: {r['joint_states']} joint states, mallet at most {r['worst_outside_m'] * 1000:.1f} mm "
              f"outside its region{when}; joint velocity at most {r['worst_velocity_use'] * 100:.0f} % of a "
              f"limit{vel_when}; {r['trajectories']} trajectories, {r['trajectories_outside']} with a planned "
              f"knot outside (at most {r['worst_planned_outside_m'] * 1000:.1f} mm)"
              + (f"; {r['non_finite_skipped']} joint states or knots with NaN or inf left out"
                 if r["non_finite_skipped"] else ""))
        if "contacts" in r:
            print(f"  {robot}: {_contact_line(r['contacts'])}")


def _contact_line(c: dict) -> str:
    """One line of :func:`contact_check.summary`'s report."""
    def part(name: str) -> str:
        g = c[name]
        return (f"{name} {g['n']}" if not g["n"] else
                f"{name} {g['n']}: {g['error_median']:.3f} (p90 {g['error_p90']:.3f}, along {g['along_median']:+.3f})")
    law = c["configured"]
    line = (f"{c['all']['n']} mallet contacts measured; the contact law's exit error [m/s] "
            f"(e {law['restitution']:g}, mu {law['friction']:g}): "
            + ", ".join(part(n) for n in ("all", "parked", "moving", "fast")))
    fitted = c.get("fitted")
    if fitted is not None:
        line += (f"; fitted e {fitted['restitution']:.3f}, mu {fitted['friction']:.3f} "
                 f"(error median {fitted['error_median']:.3f})")
    return line


def _contact_geometry() -> ContactGeometry:
    """The contact check's table, mallet and contact law: the tactics' (``config/agent.yaml``)."""
    from air_hockey_agent.agent_params import load_agent_params
    from air_hockey_agent.core.game.contact_check import ContactGeometry
    from air_hockey_agent.core.game.tactics.settings import TacticsSettings
    return ContactGeometry.from_settings(TacticsSettings.from_params(load_agent_params()))


def run(args: argparse.Namespace) -> int:
    from air_hockey_agent.motion_params import build_planner, load_motion_params
    motion = load_motion_params()
    planners = {r: build_planner(motion, r) for r in ROBOTS}
    geometry = _contact_geometry()
    if args.plot is not None:
        try:
            args.plot.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            print(f"{PROG}: error: --plot {args.plot}: cannot create the directory ({exc.strerror})", file=sys.stderr)
            return 2
    results, failed = {}, 0
    for bag in args.bags:
        checks = {} if args.plot is not None else None
        try:
            results[str(bag)] = check_bag(bag, planners, checks, geometry)
        except BagError as exc:
            print(f"{PROG}: error: {exc}", file=sys.stderr)
            failed += 1
            continue
        if not args.json:
            _print(bag, results[str(bag)])
        if checks is not None:
            from air_hockey_agent.tools.game_check_plot import plot_arms, plot_contacts
            written = [plot_arms(checks, args.plot / f"{bag_directory(bag).name}_arms.png")]
            contacts = {r: v["contacts"] for r, v in results[str(bag)].items() if v.get("contacts", {}).get("each")}
            if contacts:
                written.append(plot_contacts(contacts, args.plot / f"{bag_directory(bag).name}_contacts.png"))
            for path in written:
                print(f"wrote {path}", file=sys.stderr if args.json else sys.stdout)
    if args.json:
        print(json_text(results))
    return 2 if failed else 0
