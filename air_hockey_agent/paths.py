"""Where the package's installed data (config/, models/, package.xml) lives.

On a colcon install the data is under ``<prefix>/share/air_hockey_agent`` (found through the ament
index); in a source checkout or editable venv install it is the repository root.
"""
from __future__ import annotations

import os
from pathlib import Path

PACKAGE = "air_hockey_agent"
SOURCE_ROOT = Path(__file__).resolve().parents[1]


def share_dir() -> Path:
    """Return the package share directory (the one holding ``config/``)."""
    try:
        from ament_index_python.packages import PackageNotFoundError, get_package_share_directory
    except ImportError:  # plain Python without the ROS wheels
        return SOURCE_ROOT
    try:
        share = Path(get_package_share_directory(PACKAGE))
    except (PackageNotFoundError, KeyError, ValueError):
        return SOURCE_ROOT
    return share if (share / "config").is_dir() else SOURCE_ROOT


def config_dir() -> Path:
    """Directory of the default parameter files (``config/*.yaml``)."""
    override = os.environ.get("AIR_HOCKEY_CONFIG_DIR")
    return Path(override) if override else share_dir() / "config"


def config_file(name: str) -> Path:
    """Path of one default parameter file, e.g. ``config_file("tracker.yaml")``."""
    return config_dir() / name


def model_path(name: str) -> str:
    """Path of one URDF in ``models/``, e.g. ``model_path("iiwa14_striker.urdf")``."""
    return str(share_dir() / "models" / name)
