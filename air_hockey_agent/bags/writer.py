"""Writing rosbag2 bags (MCAP by default, or sqlite3) atomically: a finished bag or nothing.

The bag is written into a hidden sibling directory and renamed into place when complete, so an
interrupted run never leaves a half-written bag under the requested name, and an existing path is
never overwritten.
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


def write_bag(path: Path | str, topics: dict[str, str], messages: Iterable[tuple[str, int, object]],
              storage: str = "mcap") -> int:
    """Write ``messages`` (topic, log time [ns], message object) to a new bag; returns the count.

    ``topics`` maps each topic to its type name (e.g. ``geometry_msgs/msg/PoseStamped``).
    """
    path = Path(path)
    if path.exists():
        raise BagExistsError(f"{path}: exists already, not overwriting")
    staging = path.parent / f".{path.name}.partial-{os.getpid()}"
    shutil.rmtree(staging, ignore_errors=True)
    staging.mkdir(parents=True)
    partial = staging / path.name  # the writer names its data file after the directory
    store = typestore()
    count = 0
    try:
        with Writer(partial, version=BAG_VERSION, storage_plugin=STORAGES[storage]) as writer:
            connections = {t: writer.add_connection(t, msgtype, typestore=store) for t, msgtype in topics.items()}
            for topic, log_ns, msg in messages:
                conn = connections[topic]
                writer.write(conn, log_ns, store.serialize_cdr(msg, conn.msgtype))
                count += 1
        os.rename(partial, path)
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return count
