"""Joint limits the motion layer plans with (``config/motion.yaml``).

Positions [rad] are the URDF's range shrunk about its centre by ``position_limit_scale``; velocities
[rad/s] and accelerations [rad/s^2] are the data-sheet values times their scales. The unscaled
values are kept too: plans use the scaled ones, checks report use of the real ones.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np


@dataclass(frozen=True)
class JointLimits:
    """Limits of the seven arm joints: ``q_min``/``q_max`` [rad], ``dq_max`` [rad/s], ``ddq_max`` [rad/s^2]."""

    q_min: np.ndarray
    q_max: np.ndarray
    dq_max: np.ndarray
    ddq_max: np.ndarray
    q_min_real: np.ndarray
    q_max_real: np.ndarray
    dq_max_real: np.ndarray

    @classmethod
    def build(cls, q_lower: np.ndarray, q_upper: np.ndarray, params: Mapping[str, Any]) -> "JointLimits":
        """Planning limits from the URDF position range and the motion parameters."""
        lo, hi = np.asarray(q_lower, float), np.asarray(q_upper, float)
        centre, half = (lo + hi) / 2, (hi - lo) / 2 * params["position_limit_scale"]
        dq = np.asarray(params["joint_velocity_limits"], float)
        ddq = np.asarray(params["joint_acceleration_limits"], float)
        return cls(centre - half, centre + half, dq * params["velocity_limit_scale"],
                   ddq * params["acceleration_limit_scale"], lo, hi, dq)

    def position_use(self, q: np.ndarray) -> float:
        """Largest use of the real position range, in % of the half-range from the centre (100 = at a limit)."""
        centre, half = (self.q_min_real + self.q_max_real) / 2, (self.q_max_real - self.q_min_real) / 2
        return float(np.max(np.abs((np.atleast_2d(q) - centre) / half)) * 100.0)

    def velocity_use(self, dq: np.ndarray) -> float:
        """Largest use of the real velocity limits, in % (100 = at a limit)."""
        return float(np.max(np.abs(np.atleast_2d(dq)) / self.dq_max_real) * 100.0)
