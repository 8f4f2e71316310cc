"""Environment for ROS processes started by our tools and tests (no ROS needed to import)."""
from __future__ import annotations

import os
import shutil
import sys
from pathlib import Path
from typing import Mapping

from air_hockey_agent.paths import PACKAGE, config_file


def ros_environment(domain_id: int | None = None, ros_home: Path | None = None,
                    base: Mapping[str, str] | None = None) -> dict[str, str]:
    """Environment with our Fast DDS profile, a ROS domain and a writable ROS_HOME.

    ``domain_id`` must be in 1..101 (domain 0 is everyone's default; ids above 101 failed here).
    """
    env = dict(os.environ if base is None else base)
    if domain_id is not None:
        if not 1 <= domain_id <= 101:
            raise ValueError(f"ROS_DOMAIN_ID must be in 1..101, got {domain_id}")
        env["ROS_DOMAIN_ID"] = str(domain_id)
    env.setdefault("AMENT_PREFIX_PATH", sys.prefix)
    env["FASTRTPS_DEFAULT_PROFILES_FILE"] = str(config_file("fastdds.xml"))
    env["RMW_IMPLEMENTATION"] = "rmw_fastrtps_cpp"
    if ros_home is not None:
        env["ROS_HOME"] = str(ros_home)
        env["ROS_LOG_DIR"] = str(Path(ros_home) / "log")
    env["PYTHONUNBUFFERED"] = "1"
    env.setdefault("RCUTILS_CONSOLE_OUTPUT_FORMAT", "[{severity}] [{name}]: {message}")
    return env


def display_available() -> bool:
    """A window can open: not Linux, or an X11 / Wayland display is set (pybullet's GUI needs one)."""
    return not sys.platform.startswith("linux") or bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def node_executable(name: str) -> list[str]:
    """Command that runs node ``name``: the venv console script, else ``lib/air_hockey_agent/<name>``."""
    beside = Path(sys.executable).parent / name
    if beside.exists():
        return [str(beside)]
    for prefix in os.environ.get("AMENT_PREFIX_PATH", sys.prefix).split(os.pathsep):
        candidate = Path(prefix) / "lib" / PACKAGE / name
        if candidate.exists():
            return [str(candidate)]
    found = shutil.which(name)
    if found:
        return [found]
    raise FileNotFoundError(f"node executable '{name}' not found (is air_hockey_agent installed?)")
