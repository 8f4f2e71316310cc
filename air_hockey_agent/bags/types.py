"""The rosbags type store: ROS 2 Jazzy's standard messages plus our ``air_hockey_msgs``."""
from __future__ import annotations

from functools import lru_cache
from pathlib import Path

from rosbags.typesys import Stores, get_typestore, get_types_from_msg
from rosbags.typesys.store import Typestore

INTERFACE_PACKAGE = "air_hockey_msgs"
_SOURCE_MSG_DIR = Path(__file__).resolve().parents[2] / "msg_defs" / "msg"


def _msg_dir() -> Path:
    """Directory with our .msg files: the installed interface package, else the source tree."""
    try:
        from ament_index_python.packages import get_package_share_directory

        installed = Path(get_package_share_directory(INTERFACE_PACKAGE)) / "msg"
        if installed.is_dir():
            return installed
    except Exception:  # no ROS wheels, or the package is not installed: use the source tree
        pass
    return _SOURCE_MSG_DIR


@lru_cache(maxsize=1)
def typestore() -> Typestore:
    """Jazzy type store with every ``air_hockey_msgs/msg/*`` type registered."""
    store = get_typestore(Stores.ROS2_JAZZY)
    types = {}
    for path in sorted(_msg_dir().glob("*.msg")):
        types.update(get_types_from_msg(path.read_text(), f"{INTERFACE_PACKAGE}/msg/{path.stem}"))
    store.register(types)
    return store
