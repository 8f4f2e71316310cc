"""The fastest hit the arm allows over its half, as a table the tactics read in microseconds.

The motion layer finds the fastest mallet speed along a direction at a point by IK plus a hit-posture
search and an LP (:func:`air_hockey_agent.core.motion.hit_config.best_hit_configuration`, about 3 ms).
Tactics need that speed for several candidate shots every frame (thesis sec. 4.6 smash variants), so
:class:`SpeedMap` samples it once on a grid of (depth, y, direction angle) in the robot's own frame and
interpolates trilinearly; grid points the arm cannot reach hold 0 and are left out of the interpolation.
The table depends only on the motion parameters, so it is cached on disk under a hash of them and built
once per machine.
"""
from __future__ import annotations

import bisect
import hashlib
import json
import math
import os
import tempfile
import zipfile
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from air_hockey_agent.core.motion.hit_config import best_hit_configuration
from air_hockey_agent.core.motion.ik import solve_ik
from air_hockey_agent.core.motion.planner import MotionPlanner

# [rad] directions from -180 to +180 deg about the own +x axis: smashes go forward, but a Prepare pushes a
# puck that lies beyond the smash area back toward the own goal (atan2's range: both ends are one direction)
ANGLE_RANGE = math.pi
FORMAT_VERSION = 3  # 3: the IK projects its posture pull exactly (tables built before differ slightly)


def _cell(axis: Sequence[float], value: float) -> tuple[int, float]:
    """Index i and weight w with value = (1 - w) axis[i] + w axis[i + 1], clamped to the axis."""
    if value <= axis[0]:
        return 0, 0.0
    if value >= axis[-1]:
        return len(axis) - 2, 1.0
    i = bisect.bisect_right(axis, value) - 1
    return i, (value - axis[i]) / (axis[i + 1] - axis[i])


class SpeedMap:
    """Fastest hit speed [m/s] at own-frame points (x, y) [m] along directions at ``angles`` [rad]."""

    def __init__(self, xs: Sequence[float], ys: Sequence[float], angles: Sequence[float], speeds: np.ndarray) -> None:
        self.xs, self.ys, self.angles = list(map(float, xs)), list(map(float, ys)), list(map(float, angles))
        self.speeds = np.asarray(speeds, float)
        if self.speeds.shape != (len(self.xs), len(self.ys), len(self.angles)):
            raise ValueError(f"speed table shape {self.speeds.shape} does not match the grid")
        self._table = self.speeds.tolist()  # nested lists: scalar look-ups without numpy overhead
        self._reachable = np.any(self.speeds > 0.0, axis=2).tolist()  # grid points with some hit direction

    def max_speed(self, point: Sequence[float], direction: Sequence[float]) -> float:
        """Interpolated fastest hit [m/s] at ``point`` along the unit ``direction``. Grid points the arm cannot
        reach at all (outside its region: every direction 0) are left out and the others' weights rescaled, so
        a point inside the region next to its edge keeps the speed of its reachable neighbours (the 8-corner
        rule left a band of about one grid cell, 5-7 cm, unplayable along the reach limit: pucks at rest 0.2 m
        from the centre line that the arm can push); a direction the arm cannot hit in at a reachable
        neighbour still makes the point 0 along it, and a point with no reachable neighbour is 0."""
        angle = math.atan2(direction[1], direction[0])
        (i, wi), (j, wj), (k, wk) = _cell(self.xs, point[0]), _cell(self.ys, point[1]), _cell(self.angles, angle)
        t = self._table
        total = weight = 0.0
        for di, a in ((0, 1.0 - wi), (1, wi)):
            for dj, b in ((0, 1.0 - wj), (1, wj)):
                if a * b <= 0.0 or not self._reachable[i + di][j + dj]:
                    continue
                for dk, c in ((0, 1.0 - wk), (1, wk)):
                    v = t[i + di][j + dj][k + dk]
                    if v <= 0.0 and c > 0.0:
                        return 0.0
                    total += a * b * c * v
                weight += a * b
        return total / weight if weight > 0.0 else 0.0

    # --- building and caching ----------------------------------------------------------------------
    @classmethod
    def build(cls, planner: MotionPlanner, grid: Sequence[int]) -> "SpeedMap":
        """Sample the planner's own hit-speed search on a grid (depth points, y points, angles) covering
        its region's bounding box."""
        region, s = planner.region, planner.s
        nx, ny, na = (int(g) for g in grid)
        xs = np.linspace(region.x_min, min(region.x_max, region.base_xy[0] + region.reach), nx)
        ys = np.linspace(-region.y_max, region.y_max, ny)
        angles = np.linspace(-ANGLE_RANGE, ANGLE_RANGE, na)
        speeds = np.zeros((nx, ny, na))
        for i, x in enumerate(xs):
            for j, y in enumerate(ys):
                point = np.array([x, y])
                if region.contains(point):
                    ik = solve_ik(planner.kin, planner.limits, np.array([x, y, s.height]), s.reference,
                                  s.reference, s.ik_iterations, s.ik_tolerance)
                    if ik.ok:
                        for k, a in enumerate(angles):
                            d = np.array([math.cos(a), math.sin(a)])
                            speeds[i, j, k] = best_hit_configuration(planner.kin, planner.limits, ik.q, d,
                                                                     s.ik_tolerance, s.hit_posture_range).max_speed
        return cls(xs, ys, angles, speeds)

    def save(self, path: Path) -> None:
        """Write atomically (two nodes may build the same table at once)."""
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".npz.tmp")
        os.close(fd)
        try:
            with open(tmp, "wb") as f:
                np.savez(f, xs=self.xs, ys=self.ys, angles=self.angles, speeds=self.speeds)
            os.replace(tmp, path)
        finally:
            if os.path.exists(tmp):
                os.unlink(tmp)

    @classmethod
    def load(cls, path: Path, grid: Sequence[int] | None = None) -> "SpeedMap":
        """The table saved at ``path``; ValueError when it is not one (of ``grid``'s size, when given)
        or holds a speed that is negative or not finite."""
        with np.load(path) as data:
            table = cls(data["xs"], data["ys"], data["angles"], data["speeds"])
        if grid is not None and table.speeds.shape != tuple(int(g) for g in grid):
            raise ValueError(f"a {table.speeds.shape} grid, not {tuple(grid)}")
        if not np.all(np.isfinite(table.speeds) & (table.speeds >= 0.0)):
            raise ValueError("a speed is negative or not finite")
        return table


def cache_key(motion_params: Mapping[str, Any], grid: Sequence[int]) -> str:
    """Hash of everything the table depends on (the motion parameters and the grid)."""
    text = json.dumps({"v": FORMAT_VERSION, "grid": list(map(int, grid)),
                       "params": {k: motion_params[k] for k in sorted(motion_params) if k != "robot"}},
                      sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def default_cache_dir() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "air_hockey_agent"


def load_or_build(planner: MotionPlanner, motion_params: Mapping[str, Any], grid: Sequence[int],
                  cache_dir: Path | None = None, log: Callable[[str], None] | None = None) -> SpeedMap:
    """The cached table for these parameters, built (and cached) when missing or unreadable."""
    path = (cache_dir or default_cache_dir()) / f"speed_map_{cache_key(motion_params, grid)}.npz"
    if path.exists():
        try:
            return SpeedMap.load(path, grid)
        except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as exc:  # an empty or cut file
            if log:
                log(f"speed map {path} unreadable ({exc}); rebuilding")
    if log:
        log(f"building the fastest-hit table {list(grid)} (once per machine) into {path}")
    table = SpeedMap.build(planner, grid)
    try:
        table.save(path)
    except OSError as exc:
        if log:
            log(f"speed map not cached ({exc})")
    return table
