"""Where a robot's mallet may go, in its own table frame (x toward the opponent; README "Frames and units").

The allowed region of the mallet centre is its own half of the table less the mallet radius and a
margin from every rim and from the centre line, intersected with a disc of radius ``max_reach``
about the robot base's vertical axis (the stretched arm is singular and slow). Both sets are convex,
so a Bézier curve whose control points lie in the region lies in it too.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Region:
    """Rectangle ``x_min <= x <= x_max``, ``|y| <= y_max`` [m] intersected with the reach disc about ``base_xy``."""

    x_min: float
    x_max: float
    y_max: float
    base_xy: tuple[float, float]
    reach: float

    @classmethod
    def for_table(cls, length: float, width: float, mallet_radius: float, margin: float,
                  base_xy: tuple[float, float], reach: float) -> "Region":
        """The own half (x <= 0 in the robot's own frame) of a table ``length`` x ``width`` [m]."""
        inset = mallet_radius + margin
        return cls(-length / 2 + inset, -inset, width / 2 - inset, (float(base_xy[0]), float(base_xy[1])), reach)

    def contains(self, p: np.ndarray, tol: float = 1e-9) -> bool:
        """True when the point(s) ``p`` (..., 2) are all inside the region (up to ``tol`` [m])."""
        return bool(np.all(self.excess(p) <= tol))

    def excess(self, p: np.ndarray) -> np.ndarray:
        """How far [m] each of the points ``p`` (n, 2) or (2,) lies outside the region: the larger of its
        distances beyond the box and beyond the reach disc (0 inside; a lower bound of the distance to the
        region)."""
        p = np.atleast_2d(p)
        x, y = p[:, 0], p[:, 1]
        box = np.maximum(np.maximum(self.x_min - x, x - self.x_max), np.abs(y) - self.y_max)
        disc = np.hypot(x - self.base_xy[0], y - self.base_xy[1]) - self.reach
        return np.maximum(np.maximum(box, disc), 0.0)

    def first_outside(self, p: np.ndarray, tol: float = 1e-9) -> int | None:
        """Index of the first of the points ``p`` (n, 2) outside the region (by more than ``tol`` [m]), or None."""
        outside = np.flatnonzero(self.excess(p) > tol)
        return int(outside[0]) if outside.size else None

    def random_point(self, rng: np.random.Generator) -> np.ndarray:
        """A point drawn uniformly from the region [m] (rejection sampling in its bounding box)."""
        while True:
            p = np.array([rng.uniform(self.x_min, self.x_max), rng.uniform(-self.y_max, self.y_max)])
            if self.contains(p):
                return p

    def why_outside(self, p: np.ndarray) -> str:
        """A short reason why the point ``p`` is outside ("" when inside)."""
        x, y = float(p[0]), float(p[1])
        if x > self.x_max:
            return f"x = {x:.3f} m is beyond the own half (x <= {self.x_max:.3f} m)"
        if x < self.x_min:
            return f"x = {x:.3f} m is behind the goal-side rim (x >= {self.x_min:.3f} m)"
        if abs(y) > self.y_max:
            return f"|y| = {abs(y):.3f} m is beyond a long rim (|y| <= {self.y_max:.3f} m)"
        distance = math.hypot(x - self.base_xy[0], y - self.base_xy[1])
        if distance > self.reach:
            return f"{distance:.3f} m from the robot base is beyond its reach ({self.reach:.3f} m)"
        return ""

    def distance_along(self, p: np.ndarray, d: np.ndarray) -> float:
        """How far [m] one can go from ``p`` (inside) along the unit direction ``d`` and stay inside."""
        limits = []
        for axis, lo, hi in ((0, self.x_min, self.x_max), (1, -self.y_max, self.y_max)):
            if d[axis] > 1e-12:
                limits.append((hi - p[axis]) / d[axis])
            elif d[axis] < -1e-12:
                limits.append((lo - p[axis]) / d[axis])
        # the reach disc: |p - c + s d| = R, the positive root
        rel = np.asarray(p, float) - np.asarray(self.base_xy)
        b = float(rel @ d)
        disc = b * b - (float(rel @ rel) - self.reach ** 2)
        limits.append(-b + math.sqrt(disc) if disc >= 0.0 else 0.0)
        return max(0.0, min(limits))
