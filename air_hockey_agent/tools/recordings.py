"""Shared start of the recorded-data tools (sysid, noise-estimate, plot): parameters, then trajectories."""
from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

from air_hockey_agent.bags.reader import PUCK_FRAME
from air_hockey_agent.bags.trajectories import LoadedTrajectories, load_trajectories
from air_hockey_agent.params import ParameterFileError, ParameterValueError, check_files_read
from air_hockey_agent.sysid_params import load_sysid_params
from air_hockey_agent.tracker_params import load_tracker_params


class ToolError(Exception):
    """Reported as ``<prog>: error: <message>`` with exit code 2."""


class AlreadyReported(ToolError):
    """Exit code 2 with nothing more to print: every bag named failed, and each failure had its own line."""

    def __init__(self) -> None:
        super().__init__("every bag failed (reported above)")


@dataclass
class Recordings:
    tracker: dict            # tracker parameters (defaults + --params-file)
    settings: dict           # sysid / preprocessing parameters
    loaded: LoadedTrajectories


def add_pose_topic_arguments(parser: argparse.ArgumentParser) -> None:
    """--topic and --frame: where the puck's poses are in a bag (a PoseStamped topic, or /tf's "Puck")."""
    parser.add_argument("--topic", default="/optitrack/puck",
                        help="the puck's poses: a PoseStamped topic, or a tf2_msgs/TFMessage topic such as /tf "
                             "(default /optitrack/puck)")
    parser.add_argument("--frame", default=PUCK_FRAME,
                        help=f"the puck's child frame on a TFMessage --topic (default {PUCK_FRAME}: the ROS 1 lab's)")
    parser.add_argument("--table-frame", default="", metavar="FRAME",
                        help="take the table's pose from the bag's transform to FRAME on /tf_static or /tf (the "
                             "ROS 1 lab's: Table) instead of mocap_table_pose")


def add_recording_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("bags", nargs="+", type=Path, metavar="BAG_DIR",
                        help="bags (rosbag2, or ROS 1 .bag files), or directories of bags")
    add_pose_topic_arguments(parser)
    parser.add_argument("--params-file", type=Path, action="append", default=[],
                        help="tracker / sysid parameter YAML; may be repeated")


def load_recordings(prog: str, args: argparse.Namespace, minimum: int = 1) -> Recordings:
    """Parameters and preprocessed trajectories; bad bags are printed as one-line errors, not fatal."""
    try:
        tracker = load_tracker_params(args.params_file)
        settings = load_sysid_params(args.params_file)
        check_files_read(args.params_file, ("puck_tracker", "sysid"))
    except (ParameterFileError, ParameterValueError) as exc:
        raise ToolError(str(exc)) from None
    loaded = read_trajectories(prog, args, args.bags, tracker, settings)
    if len(loaded.trajectories) < minimum:
        nothing_read(loaded)
        raise ToolError(f"need at least {minimum} usable {'trajectory' if minimum == 1 else 'trajectories'}, "
                        f"found {len(loaded.trajectories)} in {loaded.bags} bag(s){loaded.why_none(settings)}")
    return Recordings(tracker, settings, loaded)


def read_trajectories(prog: str, args: argparse.Namespace, bags: Sequence[Path], tracker: dict, settings: dict,
                      label: str = "") -> LoadedTrajectories:
    """The preprocessed trajectories of ``bags`` (read with ``args``' topic, frame and table frame); each bag
    that cannot be used and each repair is printed as a one-line error or warning, after ``label``."""
    loaded = load_trajectories(bags, args.topic, tracker, settings, frame=args.frame, table_frame=args.table_frame)
    for message in loaded.errors:
        print(f"{prog}: error: {label}{message}", file=sys.stderr)
    for message in loaded.warnings:
        print(f"{prog}: warning: {label}{message}", file=sys.stderr)
    return loaded


def nothing_read(loaded: LoadedTrajectories) -> None:
    """Raise :class:`AlreadyReported` when no bag could be read at all: their one-line errors said why."""
    if loaded.bags == 0 and loaded.errors:
        raise AlreadyReported()


def report_error(prog: str, exc: Exception | str) -> int:
    if not isinstance(exc, AlreadyReported):
        print(f"{prog}: error: {exc}", file=sys.stderr)
    return 2
