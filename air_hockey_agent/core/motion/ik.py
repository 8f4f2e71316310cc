"""Inverse kinematics of a mallet point (thesis sec. 4.1's trajectory generator; issue #10 item 1).

Damped least squares on the 3-D mallet position with the arm's redundancy (7 joints, 3 task
dimensions) used in the null space: toward a reference posture, and away from the joint limits,
whose planning range clips every iterate. Frames: the robot's own table frame (:class:`MalletKinematics`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from air_hockey_agent.core.linalg3 import inverse_sym3
from air_hockey_agent.core.motion.kinematics import MalletKinematics
from air_hockey_agent.core.motion.limits import JointLimits

DAMPING = 1e-4        # [m^2] damped least squares regularisation (numerical, far below a reachable step)
NULL_SPACE_GAIN = 0.2  # fraction of the posture error removed per iteration in the null space
MAX_STEP = 0.3         # [rad] largest joint change per iteration (keeps Newton steps in the linear range)


@dataclass(frozen=True)
class IKResult:
    """Joint positions [rad]; ``ok`` when the mallet is within tolerance; ``reason`` says why not."""

    q: np.ndarray
    ok: bool
    error: float  # [m] remaining mallet position error
    reason: str = ""


def weighted_pinv(jac: np.ndarray, damping: float = 0.0) -> np.ndarray:
    """Right pseudo-inverse J^T (J J^T + damping I)^-1 of a 3x7 Jacobian."""
    return jac.T @ inverse_sym3(jac @ jac.T, damping)


def solve_ik(kin: MalletKinematics, limits: JointLimits, target: np.ndarray, seed: np.ndarray,
             reference: np.ndarray, iterations: int, tolerance: float) -> IKResult:
    """Joint positions that put the mallet at ``target`` (x, y, z [m], own table frame).

    Starts from ``seed``; refuses, with a reason, a target out of the arm's reach or one it cannot
    reach inside the planning joint limits.
    """
    q = np.clip(np.asarray(seed, float), limits.q_min, limits.q_max)
    error = np.inf
    for _ in range(iterations):
        p, jac = kin.position_and_jacobian(q)
        e = target - p
        error = float(np.linalg.norm(e))
        if error < tolerance:
            return IKResult(q, True, error)
        pinv = weighted_pinv(jac, DAMPING)
        null = np.eye(7) - weighted_pinv(jac) @ jac  # exact projector: the posture pull leaves the mallet
        step = pinv @ e + null @ (NULL_SPACE_GAIN * (reference - q))
        norm = float(np.linalg.norm(step))
        if norm > MAX_STEP:
            step *= MAX_STEP / norm
        q = np.clip(q + step, limits.q_min, limits.q_max)
    error = float(np.linalg.norm(target - kin.position(q)))
    if error < tolerance:
        return IKResult(q, True, error)
    return IKResult(q, False, error, f"unreachable: the mallet stays {error * 1000:.1f} mm from "
                                     f"({target[0]:.3f}, {target[1]:.3f}, {target[2]:.3f}) within the joint limits")
