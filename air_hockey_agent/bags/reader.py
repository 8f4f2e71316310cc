"""Reading bags with one-line errors that name the bag and the problem: rosbag2 (sqlite3 or MCAP) and ROS 1
``.bag`` files (the thesis's lab recorded with ROS 1). A ROS 1 bag's messages are read with the types its
own connection records define; :func:`iter_raw` hands them on as ROS 2 CDR (a ROS 1 header's ``seq`` is
dropped, as rosbags' converter does)."""
from __future__ import annotations

import sqlite3
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable, Iterator

from rosbags.convert.converter import is_same_wireformat, migrate_bytes
from rosbags.highlevel import AnyReader, AnyReaderError
from rosbags.rosbag2 import ReaderError
from rosbags.serde import SerdeError
from rosbags.typesys.base import TypesysError

from air_hockey_agent.bags.types import typestore

POSE_TYPE = "geometry_msgs/msg/PoseStamped"
TF_TYPE = "tf2_msgs/msg/TFMessage"
PUCK_FRAME = "Puck"  # the puck's child frame on /tf: the ROS 1 lab's tracker looked up "Puck" (REFERENCE_FACTS 1.9)
TF_TOPICS = ("/tf_static", "/tf")  # where a fixed frame's transform (the lab's world -> Table) is looked up
ROS1_SUFFIX = ".bag"  # a ROS 1 bag is one file; a rosbag2 bag is a directory with metadata.yaml
_READ_ERRORS = (AnyReaderError, ReaderError, SerdeError, TypesysError, sqlite3.Error, OSError, ValueError,
                KeyError, IndexError, EOFError, AssertionError)


class BagError(Exception):
    """A bag cannot be used; the message is one line: '<bag>: <problem>'."""

    def __init__(self, bag: Path | str, problem: str) -> None:
        super().__init__(f"{bag}: {problem}")
        self.bag, self.problem = str(bag), problem


@dataclass(frozen=True)
class PoseRecord:
    """One pose message: stamp [s] (header stamp, or the log time if no message of the topic has one)."""

    stamp: float
    position: tuple[float, float, float]
    orientation: tuple[float, float, float, float]  # quaternion x, y, z, w
    log_time: float  # [s] when the recorder received it
    frame_id: str = ""  # the header's frame ("table": already in the table frame)


def bag_directory(path: Path | str) -> Path:
    """What the reader opens for ``path``: a rosbag2 directory (the directory itself, or the one holding a
    .db3/.mcap file) or a ROS 1 ``.bag`` file. Raises :class:`BagError` for anything else."""
    path = Path(path)
    if not path.exists():
        raise BagError(path, "does not exist")
    if is_ros1(path):
        return path
    directory = path if path.is_dir() else path.parent
    if not (directory / "metadata.yaml").is_file():
        raise BagError(path, "not a bag (neither a rosbag2 bag with metadata.yaml next to the data nor a ROS 1 "
                             ".bag file)")
    return directory


def is_ros1(source: Path) -> bool:
    """Whether ``source`` (a path, or a :func:`bag_directory` result) is a ROS 1 bag file."""
    return source.suffix == ROS1_SUFFIX and source.is_file()


def read_poses(path: Path | str, topic: str, frame: str = PUCK_FRAME) -> list[PoseRecord]:
    """The puck's poses on ``topic`` in bag order: every ``geometry_msgs/PoseStamped`` message, or from a
    ``tf2_msgs/TFMessage`` topic (``/tf``, as the ROS 1 lab's tracker read the puck) every transform whose
    child frame is ``frame`` (a leading "/" ignored), in its parent frame. Raises :class:`BagError`."""
    directory = bag_directory(path)
    frame, children = frame.lstrip("/"), set()
    try:
        with AnyReader([directory], default_typestore=typestore()) as reader:
            records = []
            for c, log_ns, raw in reader.messages(connections=_topic_connections(reader, directory, topic)):
                msg = reader.deserialize(raw, c.msgtype)
                if c.msgtype == POSE_TYPE:
                    records.append(_pose_record(msg.header, msg.pose.position, msg.pose.orientation, log_ns))
                    continue
                records.extend(_transform_record(t, log_ns) for t in _transforms_to(msg, frame, children))
    except BagError:
        raise
    except _READ_ERRORS as exc:
        raise BagError(directory, f"cannot read ({_one_line(exc)})") from None
    if not records and children:
        raise BagError(directory, f"no transform to frame {frame} on {topic} (child frames: "
                                  f"{', '.join(sorted(children))}; choose one with --frame)")
    if not records:
        raise BagError(directory, f"no messages on {topic}")
    if all(r.stamp == 0.0 for r in records):  # a publisher that leaves the header empty: use log times
        records = [PoseRecord(r.log_time, r.position, r.orientation, r.log_time, r.frame_id) for r in records]
    return records


def read_frame_transform(path: Path | str, frame: str) -> PoseRecord:
    """The first transform to child ``frame`` on ``/tf_static``, else on ``/tf`` (a fixed frame such as the
    ROS 1 lab's ``world -> Table``), as a pose in its parent frame. Raises :class:`BagError`."""
    directory = bag_directory(path)
    frame, children = frame.lstrip("/"), set()
    try:
        with AnyReader([directory], default_typestore=typestore()) as reader:
            for topic in TF_TOPICS:
                connections = [c for c in reader.connections if c.topic == topic and c.msgtype == TF_TYPE]
                for c, log_ns, raw in reader.messages(connections=connections) if connections else ():
                    for t in _transforms_to(reader.deserialize(raw, c.msgtype), frame, children):
                        return _transform_record(t, log_ns)
    except _READ_ERRORS as exc:
        raise BagError(directory, f"cannot read ({_one_line(exc)})") from None
    raise BagError(directory, f"no transform to frame {frame} on {' or '.join(TF_TOPICS)} (child frames: "
                              f"{', '.join(sorted(children)) or 'none'})")


def _topic_connections(reader: AnyReader, directory: Path, topic: str) -> list:
    connections = [c for c in reader.connections if c.topic == topic]
    if not connections:
        available = ", ".join(sorted({c.topic for c in reader.connections})) or "none"
        raise BagError(directory, f"no topic {topic} (topics: {available})")
    wrong = sorted({c.msgtype for c in connections if c.msgtype not in (POSE_TYPE, TF_TYPE)})
    if wrong:
        raise BagError(directory, f"{topic} has type {', '.join(wrong)}, expected {POSE_TYPE} or {TF_TYPE}")
    return connections


def _pose_record(header, position, orientation, log_ns: int) -> PoseRecord:
    p, q, stamp = position, orientation, header.stamp
    return PoseRecord(stamp.sec + stamp.nanosec * 1e-9, (p.x, p.y, p.z), (q.x, q.y, q.z, q.w), log_ns * 1e-9,
                      header.frame_id.lstrip("/"))


def _transforms_to(msg, frame: str, children: set[str]) -> Iterator:
    """The transforms of a TFMessage to child ``frame`` (a leading "/" ignored, as ROS 1's tf allowed it);
    every child frame seen is added to ``children`` (for the error that names them)."""
    for t in msg.transforms:
        child = t.child_frame_id.lstrip("/")
        children.add(child)
        if child == frame:
            yield t


def _transform_record(t, log_ns: int) -> PoseRecord:
    """A TransformStamped as the pose of its child frame in its parent frame."""
    return _pose_record(t.header, t.transform.translation, t.transform.rotation, log_ns)


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text if len(text) <= 200 else text[:197] + "..."


def _cdr_converters(source: Path, reader: AnyReader, connections: list) -> dict:
    """Connection id -> function turning a ROS 1 message into ROS 2 CDR of the Jazzy type of that name."""
    ros2, cache, converters = typestore(), {}, {}
    for c in connections:
        if c.msgtype not in ros2.types:
            raise BagError(source, f"{c.topic}: type {c.msgtype} has no ROS 2 counterpart")
        if is_same_wireformat(reader.typestore, ros2, c.msgtype, c.msgtype):
            converters[c.id] = lambda raw, t=c.msgtype: ros2.ros1_to_cdr(raw, t)
        else:
            converters[c.id] = lambda raw, t=c.msgtype: migrate_bytes(reader.typestore, ros2, t, t, cache, raw,
                                                                      src_is2=False, dst_is2=True)
    return converters


def bag_topics(path: Path | str) -> dict[str, str]:
    """Topic -> message type of every connection in a bag. Raises :class:`BagError`."""
    directory = bag_directory(path)
    try:
        with AnyReader([directory], default_typestore=typestore()) as reader:
            return {c.topic: c.msgtype for c in reader.connections}
    except _READ_ERRORS as exc:
        raise BagError(directory, f"cannot read ({_one_line(exc)})") from None


def iter_raw(path: Path | str, topics: Iterable[str] = ()) -> Iterator[tuple[str, int, bytes]]:
    """(topic, log time [ns], serialised CDR message) in log-time order, optionally for some topics only."""
    directory = bag_directory(path)
    wanted = set(topics)
    try:
        with AnyReader([directory], default_typestore=typestore()) as reader:
            connections = [c for c in reader.connections if not wanted or c.topic in wanted]
            if not connections:
                return
            to_cdr = _cdr_converters(directory, reader, connections) if is_ros1(directory) else {}
            for c, log_ns, raw in reader.messages(connections=connections):
                yield c.topic, log_ns, bytes(to_cdr[c.id](raw) if to_cdr else raw)
    except _READ_ERRORS as exc:
        raise BagError(directory, f"cannot read ({_one_line(exc)})") from None
