"""Recorded puck trajectories for system identification: bags -> preprocessed model-grid trajectories."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from air_hockey_agent.bags.reader import PUCK_FRAME, ROS1_SUFFIX, BagError, read_frame_transform, read_poses
from air_hockey_agent.core.frames import TABLE_FRAME, pose_to_measurement, yaw_from_quaternion
from air_hockey_agent.core.estimation.ekf import PuckEKF
from air_hockey_agent.core.identification.preprocess import preprocess, push_limits
from air_hockey_agent.core.table import TableGeometry


@dataclass
class LoadedTrajectories:
    trajectories: list          # GridTrajectory, in bag order
    sources: list               # the bag of each trajectory
    errors: list                # one-line messages for bags that could not be used
    bags: int                   # bags read successfully
    frozen: int = 0             # frozen frames interpolated
    warnings: list = field(default_factory=list)  # one-line notes on data repaired while loading
    at_rest: int = 0            # pieces dropped because the puck never moved in them
    too_short: int = 0          # pieces dropped because their motion was shorter than min_duration
    pushes: int = 0             # trajectories ended where a hand or mallet took the puck (cut_pushes)
    table_poses: list = field(default_factory=list)  # per bag read: the table pose (x, y, z, yaw) its poses were
    #                                                   read through, None for poses in the table frame

    def common_table_pose(self, *others: "LoadedTrajectories") -> tuple | None:
        """The one table pose every bag's poses were read through (mocap_table_pose, or each bag's transform
        to --table-frame when they all agree), here and in ``others``, or None (they differ, or poses came in
        the table frame)."""
        poses = {None if p is None else tuple(float(v) for v in p)
                 for p in self.table_poses + [q for other in others for q in other.table_poses]}
        return next(iter(poses)) if len(poses) == 1 else None

    def why_none(self, prep: Mapping[str, Any]) -> str:
        """Why pieces were dropped, as a clause for an error message ('' when none were)."""
        parts = []
        if self.at_rest:
            parts.append(f"{self.at_rest} with the puck at rest throughout (slower than rest_speed "
                         f"{prep['rest_speed']:g} m/s: nothing moved it)")
        if self.too_short:
            parts.append(f"{self.too_short} moving for less than min_duration {prep['min_duration']:g} s")
        return ("; pieces dropped: " + ", ".join(parts)) if parts else ""


def find_bags(paths: Sequence[Path]) -> tuple[list[Path], list[str]]:
    """Bags named directly or found below directories (any folder with a metadata.yaml, any ROS 1 .bag
    file), sorted."""
    bags, errors = [], []
    for path in map(Path, paths):
        if (path / "metadata.yaml").is_file() or path.suffix in (".mcap", ".db3", ROS1_SUFFIX):
            bags.append(path)
        elif path.is_dir():
            found = sorted([p.parent for p in path.rglob("metadata.yaml")] + list(path.rglob("*" + ROS1_SUFFIX)))
            bags.extend(found) if found else errors.append(f"{path}: no bags (rosbag2 or ROS 1) in this directory")
        elif path.exists():
            bags.append(path)  # not named like a bag: reading it says what it is not
        else:
            errors.append(f"{path}: does not exist")
    return bags, errors


def load_trajectories(paths: Sequence[Path], topic: str, tracker: Mapping[str, Any],
                      prep: Mapping[str, Any], frame: str = PUCK_FRAME, table_frame: str = "") -> LoadedTrajectories:
    """Read, grid, clean, split and cut every bag (thesis sec. 4.5.1); bad bags are reported, not fatal."""
    bags, errors = find_bags(paths)
    result = LoadedTrajectories([], [], errors, 0)
    dt = 1.0 / tracker["frequency"]
    limits = push_limits(TableGeometry.from_params(tracker), prep["push_rim_margin"])
    for bag in bags:
        try:
            records, measurements, off_table, table_pose = bag_measurements(bag, topic, frame, table_frame, tracker)
        except BagError as exc:
            result.errors.append(str(exc))
            continue
        result.bags += 1
        result.table_poses.append(None if any(r.frame_id == TABLE_FRAME for r in records) else table_pose)
        for note in (_stream_problems([r.stamp for r in records], measurements), off_table):
            if note:
                result.warnings.append(f"{bag}: {note}")
        done = preprocess([r.stamp for r in records], measurements, dt, prep, tracker["glitch_speed"], limits)
        result.frozen += done.frozen
        result.pushes += done.pushes
        result.at_rest += done.at_rest
        result.too_short += done.too_short
        result.trajectories.extend(done.trajectories)
        result.sources.extend([str(bag)] * len(done.trajectories))
    return result


def split_train_validation(n: int, fraction: float, seed: int) -> tuple[list[int], list[int]]:
    """Shuffle trajectory indices and split them (at least one of each when n >= 2)."""
    import numpy as np
    order = np.random.default_rng(seed).permutation(n).tolist()
    cut = min(max(1, int(round(fraction * n))), n - 1) if n >= 2 else n
    return sorted(order[:cut]), sorted(order[cut:])




def bag_measurements(bag: Path, topic: str, frame: str, table_frame: str,
                     tracker: Mapping[str, Any]) -> tuple[list, list, str, tuple]:
    """(pose records, table-frame measurements, off-table warning or "", the table pose used) of one bag:
    the puck's poses on ``topic`` (``frame`` on a TF topic), in the table frame of ``mocap_table_pose`` or,
    with ``table_frame``, of the bag's own transform to that frame (the ROS 1 lab's ``world -> Table``).
    Raises :class:`BagError`."""
    records = read_poses(bag, topic, frame)
    gap = tracker["max_prediction_gap"]
    glitches = set(stamp_glitches([r.stamp for r in records], gap))
    records = [r for i, r in enumerate(records) if i not in glitches]
    table_pose = tracker["mocap_table_pose"]
    if table_frame:
        table_pose = table_pose_from_tf(bag, table_frame, records)
    measurements = measurements_of(records, table_pose)
    notes = [off_table_warning(measurements, tracker, table_pose)]
    if glitches:
        notes.append(f"{len(glitches)} pose(s) whose header stamp lies more than max_prediction_gap {gap:g} s "
                     f"from both neighbours' (a stamp glitch, e.g. an empty stamp): left out")
    return records, measurements, "; ".join(n for n in notes if n), tuple(table_pose)


def stamp_glitches(stamps: Sequence[float], gap: float) -> list[int]:
    """Indices (in recorded order) of stamps that are no time of the stream: non-finite, or farther than
    ``gap`` [s] from both neighbours while the neighbours lie within ``gap`` of each other (one message with
    an empty or foreign stamp). Left in, such a stamp stretches the recording's span (the evaluation's
    re-initialisations per second) and restarts the filter twice."""
    t = np.asarray(stamps, float)
    before, here, after = t[:-2], t[1:-1], t[2:]
    lone = (np.abs(here - before) > gap) & (np.abs(here - after) > gap) & (np.abs(after - before) <= gap)
    return np.flatnonzero(~np.isfinite(t) | np.concatenate([[False], lone, [False]])[:len(t)]).tolist()


def table_pose_from_tf(bag: Path, table_frame: str, records: Sequence) -> tuple[float, float, float, float]:
    """(x, y, z, yaw) of ``table_frame`` in the frame the puck's poses are in, from the bag's transform to
    it (the table taken as level: its roll and pitch are not used). Raises :class:`BagError`."""
    table = read_frame_transform(bag, table_frame)
    parents = sorted({r.frame_id for r in records})
    if parents != [table.frame_id]:
        raise BagError(bag, f"the puck's poses are in frame {', '.join(parents)}, {table_frame}'s transform in "
                            f"{table.frame_id}: set mocap_table_pose instead of --table-frame")
    return (*table.position, yaw_from_quaternion(*table.orientation))


def measurements_of(records: Sequence, table_pose: Sequence[float]) -> list:
    """Table-frame measurements (x, y, theta) of pose records (None for unusable poses); a pose whose
    frame_id is the table frame needs no table pose."""
    return [pose_to_measurement(r.position, r.orientation, table_pose, r.frame_id) for r in records]


def off_table_warning(measurements: Sequence, tracker: Mapping[str, Any],
                      table_pose: Sequence[float] | None = None) -> str:
    """One line when most usable poses lie off the table (beyond ``outside_table_margin``): the filter
    drops them all, which usually means a bag recorded in another frame than the table pose (by default
    ``mocap_table_pose``) says."""
    ekf = PuckEKF.from_params(tracker)
    usable = [m for m in measurements if m is not None]
    off = sum(not ekf.plausible(m) for m in usable)
    if not usable or off <= len(usable) / 2:
        return ""
    pose = tracker["mocap_table_pose"] if table_pose is None else table_pose
    return (f"{off / len(usable):.0%} of the poses lie off the table with the table pose "
            f"{[round(float(v), 4) for v in pose]} (dropped by the filter); recorded in another frame? "
            f"Poses whose frame_id is '{TABLE_FRAME}' need no table pose; a bag with the table's transform "
            f"gives it with --table-frame")


def _stream_problems(stamps: Sequence[float], measurements: Sequence) -> str:
    """What preprocessing repairs in a stream, as one line ('' when nothing): out-of-order and repeated
    stamps are put in order / dropped by the model grid, unusable poses become lost frames."""
    steps = np.diff(np.asarray(stamps, float))
    problems = [(int(np.sum(steps < 0.0)), "stamps out of order (sorted)"),
                (int(np.sum(steps == 0.0)), "repeated stamps (one kept)"),
                (sum(m is None for m in measurements), "poses with NaN or an invalid quaternion (treated as lost)")]
    return ", ".join(f"{n} {what}" for n, what in problems if n)
