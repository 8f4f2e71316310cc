"""``air-hockey record OUT``: record the game's topics to a rosbag2 bag (MCAP by default) for Foxglove,
``eval-prediction`` and system identification.

Default topics: the OptiTrack stream ``/optitrack/puck``, the simulation's true puck state
``/sim/puck_true_state``, both robots' ``joint_states`` and ``/game_status``; ``--topics`` names others
(their types are taken from the running graph) and ``--all`` records every topic of the graph, ours
(``air_hockey_msgs``) and the standard ones (``/clock`` included). Messages are stored as
received (CDR), with the receive time as log time; their header stamps are untouched. Latched topics
(every publisher transient local; rosbag2 adapts the same way) are recorded from what they last said
before the recorder joined. Recording stops
after ``--duration`` seconds or on Ctrl-C; the bag appears under OUT only once it is complete (a
``.mcap`` suffix names the data file inside the bag directory OUT without the suffix).
"""
from __future__ import annotations

import argparse
import sys
import time
from collections import Counter
from pathlib import Path

from air_hockey_agent.bags.writer import STORAGES, BagExistsError, BagWriter
from air_hockey_agent.sim.game_topics import LATCHED_TOPICS
from air_hockey_agent.tools import interrupt
from air_hockey_agent.tools.argtypes import count, number
from air_hockey_agent.tools.files import output_bag_directory

DEFAULT_TOPICS = {
    "/optitrack/puck": "geometry_msgs/msg/PoseStamped",
    "/sim/puck_true_state": "air_hockey_msgs/msg/PuckState",
    "/iiwa_front/joint_states": "sensor_msgs/msg/JointState",
    "/iiwa_back/joint_states": "sensor_msgs/msg/JointState",
    "/game_status": "air_hockey_msgs/msg/GameStatus",
}
STATUS_PERIOD = 5.0  # [s] between progress lines
HISTORY = 100  # messages a subscription queues (and takes of a latched topic's history)


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("record", help="record the game's topics to a bag (MCAP)", description=__doc__,
                                   formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("out", type=Path, help="bag to create (directory; must not exist)")
    parser.add_argument("--topics", nargs="+", metavar="TOPIC",
                        help=f"topics to record (default: {' '.join(DEFAULT_TOPICS)})")
    parser.add_argument("-a", "--all", action="store_true", help="record every topic in the graph")
    parser.add_argument("--wait", type=number(0.0), default=2.0,
                        help="seconds of discovery before --all or unlisted --topics are looked up (default 2)")
    parser.add_argument("--domain-id", type=count(1, 101), default=None,
                        help="ROS_DOMAIN_ID (1..101; default: the environment's)")
    parser.add_argument("--duration", type=number(0.0), default=0.0, help="seconds to record (default: until Ctrl-C)")
    parser.add_argument("--storage", choices=sorted(STORAGES), default="mcap", help="bag storage (default mcap)")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    if args.all and args.topics:
        print("air-hockey record: error: give --topics or --all, not both", file=sys.stderr)
        return 2
    out = output_bag_directory(args.out)
    if out.exists():
        print(f"air-hockey record: error: {out}: exists already, not overwriting", file=sys.stderr)
        return 2
    from air_hockey_agent.tools.ros_cli import CliError, Probe
    try:
        probe = Probe(args.domain_id)
    except CliError as exc:
        print(f"air-hockey record: error: {exc}", file=sys.stderr)
        return 2
    counts: Counter = Counter()
    try:
        try:
            topics = _topics(probe, args)
            writer = BagWriter(out, topics, args.storage)
        except (CliError, BagExistsError) as exc:
            print(f"air-hockey record: error: {exc}", file=sys.stderr)
            return 2
        from rclpy.executors import ExternalShutdownException

        from air_hockey_agent.nodes.messages import message_class
        with writer:
            for topic, msgtype in topics.items():
                probe.node.create_subscription(message_class(msgtype), topic,
                                               lambda data, t=topic: _store(writer, counts, t, data),
                                               recording_qos(probe.node, topic), raw=True)
            print(f"recording {', '.join(topics)} to {out} ({args.storage}); Ctrl-C to stop", flush=True)
            _spin(probe.executor, args.duration, counts, ExternalShutdownException)
    finally:
        probe.close()
    print(f"wrote {out}: {writer.count} messages ({', '.join(f'{t} {n}' for t, n in counts.items()) or 'none'})")
    return 0


def _topics(probe, args) -> dict[str, str]:
    """Topic -> type: the defaults' known types, the rest from the graph (after ``--wait`` of discovery)."""
    from air_hockey_agent.bags.types import typestore
    from air_hockey_agent.tools.ros_cli import CliError
    wanted = None if args.all else list(args.topics or DEFAULT_TOPICS)
    if wanted is not None and all(t in DEFAULT_TOPICS for t in wanted):
        return {t: DEFAULT_TOPICS[t] for t in wanted}
    probe.spin_for(args.wait)
    graph = {name: types[0] for name, types in probe.node.get_topic_names_and_types()}
    if wanted is None:
        wanted = sorted(graph)
        if not wanted:
            raise CliError(f"no topics in the graph after {args.wait:g} s (is the game running on this ROS_DOMAIN_ID?)")
    missing = [t for t in wanted if t not in graph and t not in DEFAULT_TOPICS]
    if missing:
        raise CliError(f"not in the graph after {args.wait:g} s: {', '.join(missing)} (air-hockey topic list shows "
                       f"what is)")
    topics = {t: graph.get(t) or DEFAULT_TOPICS[t] for t in wanted}
    store = typestore()
    unknown = {t: m for t, m in topics.items() if m not in store.fielddefs}
    if unknown and not args.all:
        raise CliError("types without a definition here: " + ", ".join(f"{t} ({m})" for t, m in unknown.items()))
    for topic, msgtype in unknown.items():
        print(f"air-hockey record: warning: {topic} ({msgtype}): no definition of this type here; not recorded",
              file=sys.stderr)
    return {t: m for t, m in topics.items() if t not in unknown}


def recording_qos(node, topic: str):
    """The subscription's QoS, as rosbag2 adapts it: latched (transient local, so what was published
    before the recorder joined is recorded too) when every publisher seen is latched, or, none seen yet,
    when the topic is one of ours that is (game status, tactics, the trackers' physics); else volatile."""
    from rclpy.qos import DurabilityPolicy, QoSProfile
    publishers = node.get_publishers_info_by_topic(topic)
    latched = (all(p.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL for p in publishers) if publishers
               else topic in LATCHED_TOPICS)
    return QoSProfile(depth=HISTORY, durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE)


def _store(writer: BagWriter, counts: Counter, topic: str, data: bytes) -> None:
    writer.write(topic, time.time_ns(), data)
    counts[topic] += 1


def _spin(executor, duration: float, counts: Counter, shutdown_error: type) -> None:
    start = last = time.monotonic()
    try:
        while duration <= 0.0 or time.monotonic() - start < duration:
            executor.spin_once(timeout_sec=0.1)
            interrupt.check()
            if time.monotonic() - last > STATUS_PERIOD:
                last = time.monotonic()
                print(f"  {last - start:.0f} s: {sum(counts.values())} messages", flush=True)
    except (KeyboardInterrupt, shutdown_error):
        print("\nstopping", flush=True)
