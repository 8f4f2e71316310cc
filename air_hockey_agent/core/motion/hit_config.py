"""Hit planning: the arm posture that hits fastest along a direction, and that speed (issue #10 item 2).

For a hit point p and a unit hit direction d in the table plane (own table frame), the fastest
mallet speed the arm reaches along d at a posture q is the linear programme (REFERENCE_FACTS 3.2, the
ROS 1 stack's LP):

    max s  subject to  J(q) dq = s (d, 0),  |dq_i| <= dq_max_i,

solved through its dual, min over lambda in R^3 with lambda . (d, 0) = 1 of sum_i dq_max_i |J_i . lambda|
(J_i: column i). That is a convex piecewise-linear function on a plane, least where two of its terms
vanish, so all such points (at most 21 for 7 joints) are compared in one vectorised step, and the primal
joint velocities follow from complementary slackness. Cases this does not settle (no two independent
columns, more than one free direction) go to scipy's HiGHS, which is also the tests' reference. The
closed form gives the same optimum (to 1e-13) in about a seventh of HiGHS's time; the LP had been half
of the hit planning time. The posture is chosen in the arm's redundancy (q with mallet(q) = p) by
projected gradient ascent on the smooth surrogate m(q) = 1 / ((d,0)^T (J D^2 J^T)^-1 (d,0)), D =
diag(dq_max): the squared speed along d reachable with unit weighted joint-velocity norm.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from air_hockey_agent.core.motion.kernels import min_norm_step, surrogate
from air_hockey_agent.core.motion.kinematics import MalletKinematics
from air_hockey_agent.core.motion.limits import JointLimits

FD_STEP = 1e-5      # [rad] finite-difference step of the surrogate's gradient
ASCENT_STEP = 0.15  # [rad] largest posture change per ascent iteration
ASCENT_ITERATIONS = 10
ON_POINT = 1e-9     # [m] Newton steps back onto the hit point stop at this distance (numerical)


@dataclass(frozen=True)
class HitConfiguration:
    """Posture ``q`` [rad] at the hit, the fastest speed ``max_speed`` [m/s] along the hit direction there,
    and the joint velocities ``dq_unit`` [rad/s] per 1 m/s of mallet speed along it."""

    q: np.ndarray
    max_speed: float
    dq_unit: np.ndarray


def max_speed_along(jac: np.ndarray, direction: np.ndarray, dq_max: np.ndarray) -> tuple[float, np.ndarray]:
    """Fastest mallet speed [m/s] along the planar unit ``direction`` under ``|dq| <= dq_max`` at Jacobian
    ``jac`` (3x7), and the joint velocities that reach it (the LP above: the closed form, HiGHS where it
    does not settle the case). Joints that do not move the mallet stay still."""
    closed = max_speed_closed_form(jac, direction, dq_max)
    return closed if closed is not None else max_speed_along_highs(jac, direction, dq_max)


def max_speed_closed_form(jac: np.ndarray, direction: np.ndarray,
                          dq_max: np.ndarray) -> tuple[float, np.ndarray] | None:
    """:func:`max_speed_along` from the dual's vertices (module docstring), or None when they do not settle it."""
    task = np.array([direction[0], direction[1], 0.0])
    moving = np.any(np.abs(jac) >= 1e-12, axis=0)
    vertex = _dual_vertex_solution(jac[:, moving], task, np.asarray(dq_max, float)[moving])
    if vertex is None:
        return None
    dq = np.zeros(jac.shape[1])
    dq[moving] = vertex[1]
    return vertex[0], dq


def _dual_vertex_solution(jac: np.ndarray, task: np.ndarray, dq_max: np.ndarray) -> tuple[float, np.ndarray] | None:
    """The LP's optimum from its dual's vertices (module docstring), or None when no vertex gives a
    primal solution within the limits (parallel columns, ties the vertex does not resolve)."""
    n = jac.shape[1]
    if n < 3:
        return None
    across = np.array([-task[1], task[0], 0.0])
    # lambda = task / |task|^2 + a * across / |across| + b * z; term k is |alpha_k + beta_k a + gamma_k b|
    alpha = jac.T @ task / float(task @ task)
    beta = jac.T @ across / float(np.linalg.norm(across))
    gamma = jac[2]
    i, j = np.triu_indices(n, 1)
    det = beta[i] * gamma[j] - beta[j] * gamma[i]
    crossing = np.abs(det) > 1e-12
    i, j, det = i[crossing], j[crossing], det[crossing]
    a = (alpha[j] * gamma[i] - alpha[i] * gamma[j]) / det
    b = (alpha[i] * beta[j] - alpha[j] * beta[i]) / det
    terms = alpha[None] + a[:, None] * beta[None] + b[:, None] * gamma[None]
    values = np.abs(terms) @ dq_max
    if len(values) == 0:
        return None
    best = float(np.min(values))
    scale = max(1.0, best)
    for k in np.flatnonzero(values <= best + 1e-12 * scale):
        dq = _primal_at_vertex(jac, task, dq_max, best, terms[k], 1e-9 * scale)
        if dq is not None:
            return best, dq
    return None


def _primal_at_vertex(jac: np.ndarray, task: np.ndarray, dq_max: np.ndarray, speed: float, terms: np.ndarray,
                      tol: float) -> np.ndarray | None:
    """Joint velocities of the LP's optimum from the dual optimum's terms (complementary slackness): a joint
    whose term is not zero is at its limit with the term's sign; the others solve J dq = speed (d, 0)
    within their limits. Their columns can be dependent: three joint axes through one point (the iiwa's
    shoulder, its wrist) have coplanar position columns, so one free direction is searched for a
    solution within the limits; None when none is found."""
    free = np.abs(terms) <= tol
    dq = np.where(free, 0.0, dq_max * np.sign(terms))
    sub, bound = jac[:, free], dq_max[free]
    rhs = speed * task - jac @ dq
    x = np.linalg.lstsq(sub, rhs, rcond=None)[0]
    if np.max(np.abs(sub @ x - rhs), initial=0.0) > 1e-9 * max(1.0, speed):
        return None
    if np.any(np.abs(x) > bound):
        _, sv, vt = np.linalg.svd(sub)
        rank = int(np.sum(sv > 1e-10))
        if vt.shape[0] - rank != 1:
            return None
        x = _inside_box_along(x, vt[-1], bound)
        if x is None:
            return None
    dq[free] = np.clip(x, -bound, bound)
    return dq


def _inside_box_along(x: np.ndarray, direction: np.ndarray, bound: np.ndarray) -> np.ndarray | None:
    """The middle of the segment of the line ``x + t direction`` inside ``|.| <= bound``, or None."""
    lo, hi = -np.inf, np.inf
    for xk, nk, bk in zip(x, direction, bound):
        if abs(nk) < 1e-12:
            if abs(xk) > bk * (1 + 1e-9):
                return None
            continue
        t1, t2 = (-bk - xk) / nk, (bk - xk) / nk
        lo, hi = max(lo, min(t1, t2)), min(hi, max(t1, t2))
    if lo > hi + 1e-12:
        return None
    return x + 0.5 * (lo + hi) * direction


def max_speed_along_highs(jac: np.ndarray, direction: np.ndarray, dq_max: np.ndarray) -> tuple[float, np.ndarray]:
    """:func:`max_speed_along` by scipy's HiGHS (the fallback, and the tests' reference). scipy.optimize is
    imported here, when needed: at module level it was half of every ``air-hockey`` command's start-up
    (0.47 of 1.1 s: the command line imports every tool to list them)."""
    from scipy.optimize import linprog
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
    dq[np.all(np.abs(jac) < 1e-12, axis=0)] = 0.0
    return float(result.x[-1]), dq


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
    best_value = surrogate(jac, task, limits.dq_max)
    for _ in range(ASCENT_ITERATIONS):
        basis = _null_basis(jac)
        grad = np.array([(surrogate(kin.position_and_jacobian(q + FD_STEP * b)[1], task, limits.dq_max)
                          - best_value) / FD_STEP for b in basis])
        step = grad @ basis
        norm = float(np.linalg.norm(step))
        if norm < 1e-9:
            break
        candidate = _back_on_point(kin, lo, hi, q + step * (ASCENT_STEP / norm), target)
        p, jac = kin.position_and_jacobian(candidate)
        value = surrogate(jac, task, limits.dq_max)
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
    step = np.empty(len(q))
    for _ in range(3):
        p, jac = kin.position_and_jacobian(q)
        error = target - p
        if float(error @ error) < ON_POINT ** 2:
            break
        min_norm_step(jac, error, 0.0, step)
        q = np.clip(q + step, lo, hi)
    return q
