"""Hit planning: the arm posture that hits fastest along a direction, and that speed (issue #10 item 2).

For a hit point p and a unit hit direction d in the table plane (own table frame), the fastest
mallet speed the arm reaches along d at a posture q is the linear programme (REFERENCE_FACTS 3.2, the
ROS 1 stack's LP):

    max s  subject to  J(q) dq = s (d, 0),  |dq_i| <= dq_max_i,

solved with scipy's HiGHS. The posture is chosen in the arm's redundancy (q with mallet(q) = p) by
projected gradient ascent on the smooth surrogate m(q) = 1 / ((d,0)^T (J D^2 J^T)^-1 (d,0)), D =
diag(dq_max): the squared speed along d reachable with unit weighted joint-velocity norm.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import linprog

from air_hockey_agent.core.motion.ik import weighted_pinv
from air_hockey_agent.core.motion.kinematics import MalletKinematics
from air_hockey_agent.core.motion.limits import JointLimits

FD_STEP = 1e-5      # [rad] finite-difference step of the surrogate's gradient
ASCENT_STEP = 0.15  # [rad] largest posture change per ascent iteration
ASCENT_ITERATIONS = 10


@dataclass(frozen=True)
class HitConfiguration:
    """Posture ``q`` [rad] at the hit, the fastest speed ``max_speed`` [m/s] along the hit direction there,
    and the joint velocities ``dq_unit`` [rad/s] per 1 m/s of mallet speed along it."""

    q: np.ndarray
    max_speed: float
    dq_unit: np.ndarray


def max_speed_along(jac: np.ndarray, direction: np.ndarray, dq_max: np.ndarray) -> tuple[float, np.ndarray]:
    """Fastest mallet speed [m/s] along the planar unit ``direction`` under ``|dq| <= dq_max`` at Jacobian
    ``jac`` (3x7), and the joint velocities that reach it (the LP above; HiGHS)."""
    n = jac.shape[1]
    task = np.array([direction[0], direction[1], 0.0])
    cost = np.zeros(n + 1)
    cost[-1] = -1.0
    a_eq = np.hstack([jac, -task[:, None]])
    bounds = [(-v, v) for v in dq_max] + [(0.0, None)]
    result = linprog(cost, A_eq=a_eq, b_eq=np.zeros(3), bounds=bounds, method="highs")
    if result.status != 0:
        return 0.0, np.zeros(n)
    dq = result.x[:n].copy()
    dq[np.all(np.abs(jac) < 1e-12, axis=0)] = 0.0  # joints that do not move the mallet stay still
    return float(result.x[-1]), dq


def _surrogate(jac: np.ndarray, task: np.ndarray, scale: np.ndarray) -> float:
    js = jac * scale
    return 1.0 / float(task @ np.linalg.solve(js @ js.T, task))


def best_hit_configuration(kin: MalletKinematics, limits: JointLimits, q_start: np.ndarray,
                           direction: np.ndarray, tolerance: float = 1e-4,
                           range_scale: float = 1.0) -> HitConfiguration:
    """Starting from ``q_start`` (an IK solution at the hit point), move in the null space toward the
    posture of fastest hits along ``direction``, keeping the mallet at the hit point (within
    ``tolerance`` [m]) and the joints within ``range_scale`` of their planning range (room for the
    strike and the follow-through around the hit); return it with its LP speed."""
    lo, hi = _scaled_range(limits, range_scale)
    task = np.array([direction[0], direction[1], 0.0])
    best = q = np.asarray(q_start, float).copy()
    target, jac = kin.position_and_jacobian(q)
    best_value = _surrogate(jac, task, limits.dq_max)
    for _ in range(ASCENT_ITERATIONS):
        basis = _null_basis(jac)
        grad = np.array([(_surrogate(kin.position_and_jacobian(q + FD_STEP * b)[1], task, limits.dq_max)
                          - best_value) / FD_STEP for b in basis])
        step = grad @ basis
        norm = float(np.linalg.norm(step))
        if norm < 1e-9:
            break
        candidate = _back_on_point(kin, lo, hi, q + step * (ASCENT_STEP / norm), target)
        p, jac = kin.position_and_jacobian(candidate)
        value = _surrogate(jac, task, limits.dq_max)
        if np.linalg.norm(p - target) > tolerance or value <= best_value:
            break
        best, best_value, q = candidate, value, candidate
    _, jac = kin.position_and_jacobian(best)
    speed, dq = max_speed_along(jac, direction, limits.dq_max)
    return HitConfiguration(best, speed, dq / speed if speed > 0 else dq)


def _null_basis(jac: np.ndarray) -> np.ndarray:
    """Orthonormal basis (rows) of the null space of the 3x7 position Jacobian among the joints that move
    the mallet (the last joint turns the vertical striker about itself and is left alone)."""
    moving = jac[:, :-1]
    _, _, vt = np.linalg.svd(moving)
    basis = np.zeros((vt.shape[0] - 3, jac.shape[1]))
    basis[:, :-1] = vt[3:]
    return basis


def _scaled_range(limits: JointLimits, scale: float) -> tuple[np.ndarray, np.ndarray]:
    centre, half = (limits.q_min + limits.q_max) / 2, (limits.q_max - limits.q_min) / 2 * scale
    return centre - half, centre + half


def _back_on_point(kin: MalletKinematics, lo: np.ndarray, hi: np.ndarray, q: np.ndarray,
                   target: np.ndarray) -> np.ndarray:
    """Newton steps that put the mallet back on ``target`` after a null-space move, inside [lo, hi]."""
    for _ in range(3):
        p, jac = kin.position_and_jacobian(q)
        q = np.clip(q + weighted_pinv(jac) @ (target - p), lo, hi)
    return q
