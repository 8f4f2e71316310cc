"""Writing rosbag2 bags (MCAP by default, or sqlite3) atomically: a finished bag or nothing.

The bag is written into a hidden staging directory next to the target and renamed into place when
complete, so an interrupted run never leaves a half-written bag under the requested name, and an
existing path is never overwritten.
"""
from __future__ import annotations

import os
import shutil
from pathlib import Path
from typing import Iterable

from rosbags.rosbag2 import StoragePlugin, Writer

from air_hockey_agent.bags.types import typestore

STORAGES = {"mcap": StoragePlugin.MCAP, "sqlite3": StoragePlugin.SQLITE3}
BAG_VERSION = 9  # rosbag2 metadata version written by Jazzy


class BagExistsError(FileExistsError):
    pass


class BagWriter:
    """Context manager writing one bag; messages are rosbags objects or already serialised CDR bytes.

    ``topics`` maps each topic to its type name (e.g. ``geometry_msgs/msg/PoseStamped``). The bag
    appears at ``path`` only when the ``with`` block ends without an exception.
    """

    def __init__(self, path: Path | str, topics: dict[str, str], storage: str = "mcap") -> None:
        self.path = Path(path)
        if self.path.exists():
            raise BagExistsError(f"{self.path}: exists already, not overwriting")
        self.topics, self.storage, self.count = dict(topics), storage, 0
        self._staging = self.path.parent / f".{self.path.name}.partial-{os.getpid()}"

    def __enter__(self) -> "BagWriter":
        shutil.rmtree(self._staging, ignore_errors=True)
        self._staging.mkdir(parents=True)
        self._store = typestore()
        # the writer names its data file after the bag directory, hence the staging parent
        self._writer = Writer(self._staging / self.path.name, version=BAG_VERSION,
                              storage_plugin=STORAGES[self.storage])
        try:
            self._writer.open()
            self._connections = {t: self._writer.add_connection(t, m, typestore=self._store)
                                 for t, m in self.topics.items()}
        except BaseException:
            shutil.rmtree(self._staging, ignore_errors=True)
            raise
        return self

    def write(self, topic: str, log_ns: int, msg: object) -> None:
        conn = self._connections[topic]
        data = msg if isinstance(msg, (bytes, bytearray, memoryview)) else self._store.serialize_cdr(msg, conn.msgtype)
        self._writer.write(conn, log_ns, data)
        self.count += 1

    def __exit__(self, exc_type, exc, tb) -> bool:
        try:
            self._writer.close()
            if exc_type is None:
                os.rename(self._staging / self.path.name, self.path)
        finally:
            shutil.rmtree(self._staging, ignore_errors=True)
        return False


def write_bag(path: Path | str, topics: dict[str, str], messages: Iterable[tuple[str, int, object]],
              storage: str = "mcap") -> int:
    """Write ``messages`` (topic, log time [ns], message) to a new bag; returns the count."""
    with BagWriter(path, topics, storage) as writer:
        for topic, log_ns, msg in messages:
            writer.write(topic, log_ns, msg)
    return writer.count
