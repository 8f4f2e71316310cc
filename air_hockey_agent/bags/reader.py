"""Reading rosbag2 bags (sqlite3 or MCAP) with one-line errors that name the bag and the problem."""
from __future__ import annotations

import sqlite3
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable, Iterator

from rosbags.highlevel import AnyReader, AnyReaderError
from rosbags.rosbag2 import ReaderError
from rosbags.serde import SerdeError
from rosbags.typesys.base import TypesysError

from air_hockey_agent.bags.types import typestore

POSE_TYPE = "geometry_msgs/msg/PoseStamped"
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
    """The rosbag2 directory for ``path``: the directory itself, or the one holding a .db3/.mcap file."""
    path = Path(path)
    if not path.exists():
        raise BagError(path, "does not exist")
    directory = path if path.is_dir() else path.parent
    if not (directory / "metadata.yaml").is_file():
        raise BagError(path, "not a rosbag2 bag (no metadata.yaml next to the data)")
    return directory


def read_poses(path: Path | str, topic: str) -> list[PoseRecord]:
    """All ``geometry_msgs/PoseStamped`` messages of ``topic`` in bag order. Raises :class:`BagError`."""
    directory = bag_directory(path)
    try:
        with AnyReader([directory], default_typestore=typestore()) as reader:
            connections = _topic_connections(reader, directory, topic, POSE_TYPE)
            records = [_pose_record(reader.deserialize(raw, c.msgtype), log_ns)
                       for c, log_ns, raw in reader.messages(connections=connections)]
    except BagError:
        raise
    except _READ_ERRORS as exc:
        raise BagError(directory, f"cannot read ({_one_line(exc)})") from None
    if not records:
        raise BagError(directory, f"no messages on {topic}")
    if all(r.stamp == 0.0 for r in records):  # a publisher that leaves the header empty: use log times
        records = [PoseRecord(r.log_time, r.position, r.orientation, r.log_time, r.frame_id) for r in records]
    return records


def _topic_connections(reader: AnyReader, directory: Path, topic: str, msgtype: str) -> list:
    connections = [c for c in reader.connections if c.topic == topic]
    if not connections:
        available = ", ".join(sorted({c.topic for c in reader.connections})) or "none"
        raise BagError(directory, f"no topic {topic} (topics: {available})")
    wrong = sorted({c.msgtype for c in connections if c.msgtype != msgtype})
    if wrong:
        raise BagError(directory, f"{topic} has type {', '.join(wrong)}, expected {msgtype}")
    return connections


def _pose_record(msg, log_ns: int) -> PoseRecord:
    p, q, s = msg.pose.position, msg.pose.orientation, msg.header.stamp
    return PoseRecord(s.sec + s.nanosec * 1e-9, (p.x, p.y, p.z), (q.x, q.y, q.z, q.w), log_ns * 1e-9,
                      msg.header.frame_id)


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text if len(text) <= 200 else text[:197] + "..."


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
            for c, log_ns, raw in reader.messages(connections=connections):
                yield c.topic, log_ns, bytes(raw)
    except _READ_ERRORS as exc:
        raise BagError(directory, f"cannot read ({_one_line(exc)})") from None
