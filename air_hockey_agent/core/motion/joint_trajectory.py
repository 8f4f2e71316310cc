"""Joint trajectories as the robots execute them: timed waypoints, sampled by cubic Hermite interpolation.

A trajectory is what ``trajectory_msgs/JointTrajectory`` carries: joint names and points with
``time_from_start`` [s], positions [rad] and optionally velocities [rad/s]. Like ros2_control's
joint trajectory controller (:func:`received_at`), execution starts from the robot's state when the
message arrives (an implicit first point), interpolates each segment with a cubic Hermite polynomial
(linear velocities between points when the message has none), and holds the last point afterwards.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np


HOLD_STEP = 1e-6  # [s] the one segment of a trajectory that only holds a passed trajectory's last point


class TrajectoryError(ValueError):
    """A trajectory that cannot be executed (the message says which field is wrong)."""


@dataclass
class JointTrajectory:
    """Waypoints (times [s] from ``start`` [s], positions and velocities per joint) in ``joint_names`` order."""

    joint_names: tuple[str, ...]
    start: float
    times: np.ndarray       # (n,) strictly increasing, times[0] == 0 (the implicit current-state point)
    positions: np.ndarray   # (n, joints)
    velocities: np.ndarray  # (n, joints)

    @classmethod
    def from_points(cls, joint_names: Sequence[str], start: float, times: Sequence[float],
                    positions: Sequence[Sequence[float]], velocities: Sequence[Sequence[float]] | None,
                    current_q: Sequence[float], current_dq: Sequence[float]) -> "JointTrajectory":
        """Build from message data, starting from the current joint state; raises :class:`TrajectoryError`."""
        names = tuple(joint_names)
        if not names or len(set(names)) != len(names):
            raise TrajectoryError(f"joint_names must be non-empty and unique, got {list(names)}")
        t = np.asarray(times, float)
        q = np.asarray(positions, float)
        if t.size == 0:
            raise TrajectoryError("points is empty")
        if q.shape != (t.size, len(names)):
            raise TrajectoryError(f"points[].positions must have {len(names)} values each")
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(q))):
            raise TrajectoryError("points contain non-finite times or positions")
        if t[0] <= 0.0 or np.any(np.diff(t) <= 0.0):
            raise TrajectoryError("points[].time_from_start must be positive and strictly increasing")
        if velocities is None:
            dq = _slopes(np.concatenate([[0.0], t]), np.vstack([current_q, q]))[1:]
        else:
            dq = np.asarray(velocities, float)
            if dq.shape != q.shape or not np.all(np.isfinite(dq)):
                raise TrajectoryError(f"points[].velocities must be empty or have {len(names)} finite values each")
        return cls(names, float(start), np.concatenate([[0.0], t]), np.vstack([current_q, q]),
                   np.vstack([current_dq, dq]))

    @property
    def duration(self) -> float:
        return float(self.times[-1])

    def sample(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Positions and velocities at absolute time ``t`` [s] (held at the ends)."""
        tau = t - self.start
        if tau <= 0.0:
            return self.positions[0].copy(), np.zeros(len(self.joint_names))
        if tau >= self.times[-1]:
            return self.positions[-1].copy(), np.zeros(len(self.joint_names))
        i = int(np.searchsorted(self.times, tau, side="right")) - 1
        h = self.times[i + 1] - self.times[i]
        s = (tau - self.times[i]) / h
        p0, p1 = self.positions[i], self.positions[i + 1]
        m0, m1 = self.velocities[i] * h, self.velocities[i + 1] * h
        s2, s3 = s * s, s * s * s
        q = (2 * s3 - 3 * s2 + 1) * p0 + (s3 - 2 * s2 + s) * m0 + (-2 * s3 + 3 * s2) * p1 + (s3 - s2) * m1
        dq = ((6 * s2 - 6 * s) * p0 + (3 * s2 - 4 * s + 1) * m0 + (-6 * s2 + 6 * s) * p1 + (3 * s2 - 2 * s) * m1) / h
        return q, dq


def received_at(joint_names: Sequence[str], start: float, times: Sequence[float], positions: Sequence[Sequence[float]],
                velocities: Sequence[Sequence[float]] | None, now: float, current_q: Sequence[float],
                current_dq: Sequence[float]) -> JointTrajectory:
    """A trajectory message (points at ``start + times`` [s]) as a controller that receives it at ``now`` [s]
    executes it, the way ros2_control's joint trajectory controller does: from the current state at ``now``
    to the first point still ahead (also when ``start`` lies in the future: no hold before it); when points
    have already passed, the arm goes on from the segment in progress, between the message's own points,
    and after the last point it holds that. Raises :class:`TrajectoryError` for a malformed message."""
    full = JointTrajectory.from_points(joint_names, start, times, positions, velocities, current_q, current_dq)
    t_abs = full.start + full.times[1:]
    ahead = int(np.searchsorted(t_abs, now, side="right"))  # first message point after now
    if ahead == 0:
        return JointTrajectory(full.joint_names, now, np.concatenate([[0.0], t_abs - now]), full.positions.copy(),
                               full.velocities.copy())
    if ahead == len(t_abs):
        q = full.positions[-1]
        return JointTrajectory(full.joint_names, now, np.array([0.0, HOLD_STEP]), np.vstack([q, q]),
                               np.zeros((2, len(full.joint_names))))
    # from the latest passed point: message point ahead - 1, index ahead in full's arrays (implicit point first)
    passed = float(t_abs[ahead - 1])
    return JointTrajectory(full.joint_names, passed, np.concatenate([[0.0], t_abs[ahead:] - passed]),
                           full.positions[ahead:].copy(), full.velocities[ahead:].copy())


def _slopes(t: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Velocities at waypoints without given ones: mean of adjacent segment slopes, zero at the ends."""
    seg = np.diff(q, axis=0) / np.diff(t)[:, None]
    v = np.zeros_like(q)
    v[1:-1] = 0.5 * (seg[:-1] + seg[1:])
    return v
