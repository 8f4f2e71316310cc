"""Joint trajectories that follow a task-space mallet path: differential IK with a null-space QP.

For each sample k of a task-space path (own table frame, uniform time step dt) the joint step dq_k is

    min ||dq - dq_ref||^2  subject to  J(q) dq = x_k - x(q),  lo <= dq <= hi          (one QP per sample)

with dq_ref = min(1, gain dt) (q_anchor - q) pulling the redundancy toward an anchor posture, and the
bounds holding the planning limits: velocity |dq| <= dq_max dt, position q + dq in [q_min, q_max],
acceleration |dq - dq_{k-1}| <= ddq_max dt^2 (REFERENCE_FACTS 3.3: the ROS 1 stack's null-space QP,
with its forgotten bound shift and missing acceleration limits fixed). The equality aims at the
sample itself (dead-beat position feedback), so errors do not accumulate. When the unconstrained
minimiser (closed form) already satisfies the bounds it is the QP's solution; otherwise OSQP solves
the QP. A sample whose QP is infeasible ends the tracking with the reason.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import osqp
import scipy.sparse as sparse

from air_hockey_agent.core.motion.kinematics import MalletKinematics
from air_hockey_agent.core.motion.limits import JointLimits

JOINTS = 7
DAMPING = 1e-8  # [m^2] regularises J J^T at the (excluded) singular configurations


@dataclass
class Tracked:
    """Joint positions (n, 7) [rad] at the samples; when ``ok`` is False, ``q`` ends before the sample
    that failed and ``reason`` says why. ``overload`` [-] is then the ratio of the broken limit that the
    unconstrained step needed (velocity or acceleration, as ``limit`` says), when one was broken."""

    q: np.ndarray
    ok: bool
    reason: str = ""
    overload: float = float("nan")
    limit: str = ""

    def slower_speed(self, speed: float) -> float:
        """The speed [m/s] at which a path traced ``speed`` times faster per metre would have kept the broken
        limit: joint velocities scale with the path speed, accelerations with its square (same path). NaN
        when no velocity or acceleration limit was broken."""
        if self.limit == "velocity":
            return speed / self.overload
        if self.limit == "acceleration":
            return speed / math.sqrt(self.overload)
        return float("nan")


class StepQP:
    """The per-sample QP, set up once with OSQP and updated in place (a fixed sparsity pattern)."""

    def __init__(self) -> None:
        rows = np.concatenate([[0, 1, 2, 3 + j] for j in range(JOINTS)])
        indptr = np.arange(0, 4 * JOINTS + 1, 4)
        pattern = sparse.csc_matrix((np.ones(4 * JOINTS), rows, indptr), shape=(3 + JOINTS, JOINTS))
        self._solver = osqp.OSQP()
        self._solver.setup(sparse.identity(JOINTS, format="csc"), np.zeros(JOINTS), pattern,
                           -np.ones(3 + JOINTS), np.ones(3 + JOINTS), verbose=False, eps_abs=1e-9,
                           eps_rel=1e-9, polishing=True, max_iter=4000)

    def solve(self, jac: np.ndarray, dx: np.ndarray, ref: np.ndarray, lo: np.ndarray,
              hi: np.ndarray) -> np.ndarray | None:
        """min ||dq - ref||^2 s.t. jac dq = dx, lo <= dq <= hi; None when infeasible."""
        data = np.vstack([jac, np.ones((1, JOINTS))]).T.ravel()
        self._solver.update(q=-ref, l=np.concatenate([dx, lo]), u=np.concatenate([dx, hi]), Ax=data)
        result = self._solver.solve(raise_error=False)
        if result.info.status_val not in (1, 2):  # solved, solved inaccurate
            return None
        dq = result.x
        if np.max(np.abs(jac @ dq - dx)) > 1e-6 or np.any(dq < lo - 1e-7) or np.any(dq > hi + 1e-7):
            return None
        return np.clip(dq, lo, hi)


def track(kin: MalletKinematics, limits: JointLimits, qp: StepQP, q0: np.ndarray, dq0: np.ndarray,
          targets: np.ndarray, dt: float, anchor: np.ndarray, gain: float, settle: float = 0.0) -> Tracked:
    """Joint positions following the mallet ``targets`` (n, 3) [m] every ``dt`` [s] from the state
    ``q0`` [rad], ``dq0`` [rad/s]; the redundancy converges to ``anchor`` at ``gain`` [1/s], each joint's
    pull capped at half its velocity limit. With ``settle`` > 0, once the target stops changing, the arm
    is at rest and within ``settle`` [rad] of the anchor, the remaining samples hold that posture."""
    q = np.asarray(q0, float).copy()
    previous = np.asarray(dq0, float) * dt
    v_step, a_step = limits.dq_max * dt, limits.ddq_max * dt * dt
    pull, pull_cap = min(1.0, gain * dt), 0.5 * limits.dq_max * dt
    out = np.empty((len(targets), JOINTS))
    for k, target in enumerate(targets):
        p, jac = kin.position_and_jacobian(q)
        dx = target - p
        ref = np.clip(pull * (anchor - q), -pull_cap, pull_cap)
        step = ref + jac.T @ _solve3(jac @ jac.T, dx - jac @ ref)
        # the first step gets half the acceleration room: knot velocities are central differences,
        # and the one at the first knot spans this step and the next
        lo, hi = _bounds(q, previous, limits, v_step, a_step if k else 0.5 * a_step, dt)
        if (lo > hi).any():
            j = int(np.argmax(lo - hi))
            return Tracked(out[:k], False, f"cannot brake joint {j + 1} before its position limit")
        if (step < lo).any() or (step > hi).any():
            solved = qp.solve(jac, dx, ref, lo, hi)
            if solved is None:
                return _failed(out[:k], step, previous, q, limits, dt)
            step = solved
        q = q + step
        out[k] = q
        previous = step
        if settle > 0.0 and _settled(targets, k, step, q, anchor, settle):
            out[k + 1:] = q
            break
    return Tracked(out, True)


def _settled(targets: np.ndarray, k: int, step: np.ndarray, q: np.ndarray, anchor: np.ndarray,
             tolerance: float) -> bool:
    """At rest (steps below a tenth of ``tolerance``) within ``tolerance`` [rad] of the anchor posture,
    at a target that no longer changes."""
    return (k + 1 < len(targets) and float(np.max(np.abs(step))) < 0.1 * tolerance
            and float(np.max(np.abs(q - anchor))) < tolerance and bool(np.all(targets[k + 1:] == targets[k])))


def _solve3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Solve the symmetric 3x3 system ``a x = b`` by cofactors (numpy's solver costs more than the
    arithmetic at this size); ``a`` is J J^T, regularised by DAMPING."""
    (a00, a01, a02), (_, a11, a12), (_, _, a22) = a.tolist()
    a00, a11, a22 = a00 + DAMPING, a11 + DAMPING, a22 + DAMPING
    c00, c01, c02 = a11 * a22 - a12 * a12, a02 * a12 - a01 * a22, a01 * a12 - a02 * a11
    c11, c12, c22 = a00 * a22 - a02 * a02, a01 * a02 - a00 * a12, a00 * a11 - a01 * a01
    det = a00 * c00 + a01 * c01 + a02 * c02
    b0, b1, b2 = b.tolist()
    return np.array([c00 * b0 + c01 * b1 + c02 * b2, c01 * b0 + c11 * b1 + c12 * b2,
                     c02 * b0 + c12 * b1 + c22 * b2]) / det


def _bounds(q: np.ndarray, previous: np.ndarray, limits: JointLimits, v_step: np.ndarray, a_step: np.ndarray,
            dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Bounds of one joint step: velocity, acceleration, and position with braking room (a joint may
    only move as fast toward a limit as it can still stop before it: |dq| <= sqrt(2 ddq_max d))."""
    room_up = np.maximum(limits.q_max - q, 0.0)
    room_down = np.maximum(q - limits.q_min, 0.0)
    brake_up = dt * np.sqrt(2.0 * limits.ddq_max * room_up)
    brake_down = dt * np.sqrt(2.0 * limits.ddq_max * room_down)
    lo = np.maximum(np.maximum(-v_step, -np.minimum(room_down, brake_down)), previous - a_step)
    hi = np.minimum(np.minimum(v_step, np.minimum(room_up, brake_up)), previous + a_step)
    return lo, hi


def _failed(done: np.ndarray, step: np.ndarray, previous: np.ndarray, q: np.ndarray, limits: JointLimits,
            dt: float) -> Tracked:
    """The failed tracking, with which limit the unconstrained step broke and by how much."""
    velocity = np.abs(step) / dt / limits.dq_max
    acceleration = np.abs(step - previous) / dt / dt / limits.ddq_max
    for name, ratio in (("velocity", velocity), ("acceleration", acceleration)):
        if np.max(ratio) > 1.0:
            j = int(np.argmax(ratio))
            return Tracked(done, False, f"needs joint {j + 1} at {ratio[j] * 100:.0f} % of its {name} limit",
                           float(ratio[j]), name)
    room = np.minimum(limits.q_max - q, q - limits.q_min)
    j = int(np.argmin(room))
    return Tracked(done, False, f"cannot follow the path within the joint limits (joint {j + 1} is "
                                f"{room[j]:.3f} rad from its limit)")
