"""``air-hockey record OUT``: record the game's topics to a rosbag2 bag (MCAP by default) for Foxglove,
``eval-prediction`` and system identification.

Default topics: the OptiTrack stream ``/optitrack/puck``, the simulation's true puck state
``/sim/puck_true_state``, both robots' ``joint_states`` and ``/game_status``. Messages are stored as
received (CDR), with the receive time as log time; their header stamps are untouched. Recording stops
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
from air_hockey_agent.tools.argtypes import number

DEFAULT_TOPICS = {
    "/optitrack/puck": "geometry_msgs/msg/PoseStamped",
    "/sim/puck_true_state": "air_hockey_msgs/msg/PuckState",
    "/iiwa_front/joint_states": "sensor_msgs/msg/JointState",
    "/iiwa_back/joint_states": "sensor_msgs/msg/JointState",
    "/game_status": "air_hockey_msgs/msg/GameStatus",
}
STATUS_PERIOD = 5.0  # [s] between progress lines


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("record", help="record the game's topics to a bag (MCAP)", description=__doc__,
                                   formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("out", type=Path, help="bag to create (directory; must not exist)")
    parser.add_argument("--topics", nargs="+", metavar="TOPIC",
                        help=f"topics with known types to record (default: {' '.join(DEFAULT_TOPICS)})")
    parser.add_argument("--duration", type=number(0.0), default=0.0, help="seconds to record (default: until Ctrl-C)")
    parser.add_argument("--storage", choices=sorted(STORAGES), default="mcap", help="bag storage (default mcap)")
    parser.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    topics = {t: DEFAULT_TOPICS.get(t) for t in (args.topics or DEFAULT_TOPICS)}
    unknown = [t for t, msgtype in topics.items() if msgtype is None]
    if unknown:
        print(f"air-hockey record: error: no known type for {', '.join(unknown)} "
              f"(known: {', '.join(DEFAULT_TOPICS)})", file=sys.stderr)
        return 2
    out = args.out.with_suffix("") if args.out.suffix == ".mcap" else args.out
    try:
        writer = BagWriter(out, topics, args.storage)
    except BagExistsError as exc:
        print(f"air-hockey record: error: {exc}", file=sys.stderr)
        return 2
    import rclpy
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor

    from air_hockey_agent.nodes.messages import message_class
    rclpy.init()
    node = rclpy.create_node("air_hockey_recorder")
    counts: Counter = Counter()
    try:
        with writer:
            for topic, msgtype in topics.items():
                node.create_subscription(message_class(msgtype), topic,
                                         lambda data, t=topic: _store(writer, counts, t, data), 100, raw=True)
            print(f"recording {', '.join(topics)} to {out} ({args.storage}); Ctrl-C to stop", flush=True)
            _spin(node, SingleThreadedExecutor(), args.duration, counts, ExternalShutdownException)
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    print(f"wrote {out}: {writer.count} messages ({', '.join(f'{t} {n}' for t, n in counts.items()) or 'none'})")
    return 0


def _store(writer: BagWriter, counts: Counter, topic: str, data: bytes) -> None:
    writer.write(topic, time.time_ns(), data)
    counts[topic] += 1


def _spin(node, executor, duration: float, counts: Counter, shutdown_error: type) -> None:
    executor.add_node(node)
    start = last = time.monotonic()
    try:
        while duration <= 0.0 or time.monotonic() - start < duration:
            executor.spin_once(timeout_sec=0.1)
            if time.monotonic() - last > STATUS_PERIOD:
                last = time.monotonic()
                print(f"  {last - start:.0f} s: {sum(counts.values())} messages", flush=True)
    except (KeyboardInterrupt, shutdown_error):
        print("\nstopping", flush=True)
