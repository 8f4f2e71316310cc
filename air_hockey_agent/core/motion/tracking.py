"""Joint trajectories that follow a task-space mallet path: differential IK with a null-space QP.

For each sample k of a task-space path (own table frame, uniform time step dt) the joint step dq_k is

    min ||dq - dq_ref||^2  subject to  J(q) dq = x_k - x(q),  lo <= dq <= hi          (one QP per sample)

with dq_ref = min(1, gain dt) (q_anchor - q) pulling the redundancy toward an anchor posture, and the
bounds holding the planning limits: velocity |dq| <= dq_max dt, position q + dq in [q_min, q_max],
acceleration |dq - dq_{k-1}| <= ddq_max dt^2 (REFERENCE_FACTS 3.3: the ROS 1 stack's null-space QP,
with its forgotten bound shift and missing acceleration limits fixed). The equality aims at the
sample itself (dead-beat position feedback), so errors do not accumulate. When the unconstrained
minimiser (closed form) already satisfies the bounds it is the QP's solution; otherwise DAQP solves
the QP. A sample whose QP is infeasible ends the tracking with the reason.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import daqp

from air_hockey_agent.core.linalg3 import solve_sym3
from air_hockey_agent.core.motion.kinematics import MalletKinematics
from air_hockey_agent.core.motion.limits import JointLimits
from air_hockey_agent.core.motion.kernels import inside_simple_bounds, unconstrained_step

JOINTS = 7
DAMPING = 1e-8  # [m^2] regularises J J^T at the (excluded) singular configurations
INEQUALITY, EQUALITY = 0, 5  # DAQP constraint senses
DAQP_SOLVED = 1
POSTURE_MARGIN = 1.5  # [-] must_settle gives up when the best-case end error exceeds this times settle


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
    """The per-sample QP, solved by DAQP (a dual active-set solver for small dense QPs: exact up to its
    feasibility tolerance, about 1e-7 rad here, and several times faster than an ADMM solver at 7 variables)."""

    def __init__(self) -> None:
        self._hessian = np.eye(JOINTS)
        self._sense = np.array([INEQUALITY] * JOINTS + [EQUALITY] * 3, dtype=np.intc)

    def solve(self, jac: np.ndarray, dx: np.ndarray, ref: np.ndarray, lo: np.ndarray,
              hi: np.ndarray) -> np.ndarray | None:
        """min ||dq - ref||^2 s.t. jac dq = dx, lo <= dq <= hi; None when infeasible."""
        # the first JOINTS bounds are simple bounds on dq, the last three rows jac dq = dx
        dq, _, flag, _ = daqp.solve(self._hessian, -ref, np.ascontiguousarray(jac), np.concatenate([hi, dx]),
                                    np.concatenate([lo, dx]), self._sense)
        if flag != DAQP_SOLVED:
            return None
        dq = np.clip(dq, lo, hi)  # within the solver's feasibility tolerance of the box
        if np.max(np.abs(jac @ dq - dx)) > 1e-6:
            return None
        return dq


def track(kin: MalletKinematics, limits: JointLimits, qp: StepQP, q0: np.ndarray, dq0: np.ndarray,
          targets: np.ndarray, dt: float, anchor: np.ndarray, gain: float, settle: float = 0.0,
          must_settle: bool = False) -> Tracked:
    """Joint positions following the mallet ``targets`` (n, 3) [m] every ``dt`` [s] from the state
    ``q0`` [rad], ``dq0`` [rad/s]; the redundancy converges to ``anchor`` at ``gain`` [1/s], each joint's
    pull capped at half its velocity limit. With ``settle`` > 0, once the target stops changing, the arm
    is at rest and within ``settle`` [rad] of the anchor, the remaining samples hold that posture. With
    ``must_settle``, the tracking fails (``limit`` "posture") as soon as the arm can no longer come within
    ``settle`` of the anchor by the last sample (:func:`_posture_too_far`)."""
    q = np.asarray(q0, float).copy()
    previous = np.asarray(dq0, float) * dt
    steps = _StepLimits(limits, dt)
    pull = min(1.0, gain * dt)
    pull_cap = 0.5 * steps.velocity
    ref, step = np.empty(JOINTS), np.empty(JOINTS)
    out = np.empty((len(targets), JOINTS))
    hold_from = _hold_start(targets)
    for k, target in enumerate(targets):
        p, jac = kin.position_and_jacobian(q)
        if must_settle:
            late = _posture_too_far(q - anchor, jac, (1.0 - pull) ** (len(targets) - k), POSTURE_MARGIN * settle)
            if late:
                return Tracked(out[:k], False, f"{late:.3f} rad away in the redundancy {(len(targets) - k) * dt:.2f} s "
                                               f"before the end, more than the posture pull closes", limit="posture")
        dx = target - p
        unconstrained_step(jac, dx, q, anchor, pull, pull_cap, DAMPING, ref, step)
        # the first step gets half the acceleration room: knot velocities are central differences,
        # and the one at the first knot spans this step and the next
        share = 1.0 if k else 0.5
        if not inside_simple_bounds(q, step, previous, steps.velocity, steps.acceleration * share,
                                    steps.clear_min, steps.clear_max):
            lo, hi = steps.bounds(q, previous, share)
            if ((step < lo) | (step > hi)).any():  # always so when lo > hi somewhere
                if (lo > hi).any():
                    j = int(np.argmax(lo - hi))
                    return Tracked(out[:k], False, f"cannot brake joint {j + 1} before its position limit")
                solved = qp.solve(jac, dx, ref, lo, hi)
                if solved is None:
                    return _failed(out[:k], step, previous, q, limits, dt)
                step = solved
        q = q + step
        out[k] = q
        if settle > 0.0 and k >= hold_from and _settled(k, len(targets), step, q, anchor, settle):
            out[k + 1:] = q
            break
        previous, step = step, previous  # the next sample writes its step over the old previous one
    return Tracked(out, True)


def _posture_too_far(error: np.ndarray, jac: np.ndarray, decay: float, allowed: float) -> float:
    """The posture error's null-space part [rad, max norm] when even its fastest decay (``decay`` over
    the samples left) leaves more than ``allowed`` at the end, else 0. The null-space pull shrinks that
    part by at most (1 - gain dt) per sample while the task part vanishes as the mallet reaches its
    target; on 2000 planned hits the prediction stayed within 7 % of the error actually left, and
    POSTURE_MARGIN covers that."""
    if math.sqrt(float(error @ error)) * decay <= allowed:  # the max norm of a projection is at most this
        return 0.0
    null = error - jac.T @ solve_sym3(jac @ jac.T, jac @ error, DAMPING)
    gap = float(np.max(np.abs(null)))
    return gap if gap * decay > allowed else 0.0


def _hold_start(targets: np.ndarray) -> int:
    """Index of the first sample from which the target no longer changes (len(targets) if the last differs)."""
    if len(targets) < 2:
        return len(targets)
    moving = np.flatnonzero(np.any(targets[1:] != targets[:-1], axis=1))
    return int(moving[-1]) + 1 if len(moving) else 0


def _settled(k: int, n: int, step: np.ndarray, q: np.ndarray, anchor: np.ndarray, tolerance: float) -> bool:
    """At rest (steps below a tenth of ``tolerance``) within ``tolerance`` [rad] of the anchor posture,
    with samples left (``k`` of ``n``); the caller checks that the target no longer changes."""
    return (k + 1 < n and float(np.max(np.abs(step))) < 0.1 * tolerance
            and float(np.max(np.abs(q - anchor))) < tolerance)


class _StepLimits:
    """Bounds of one joint step [rad] at sample period ``dt``: velocity, acceleration, and position with
    braking room (a joint may only move as fast toward a limit as it can still stop before it:
    |dq| <= sqrt(2 ddq_max d))."""

    def __init__(self, limits: JointLimits, dt: float) -> None:
        self.q_min, self.q_max = limits.q_min, limits.q_max
        self.velocity = limits.dq_max * dt
        self.acceleration = limits.ddq_max * dt * dt
        self.braking = 2.0 * limits.ddq_max * dt * dt  # (step to stop in room d)^2 = braking * d
        self.velocity2, self.braking2 = np.tile(self.velocity, 2), np.tile(self.braking, 2)  # up, then down
        # farther than this from both limits, only the velocity caps a step (room >= v and braking room >= v^2):
        # there the compiled kernels.inside_simple_bounds decides without computing the bounds
        clear = np.maximum(self.velocity, self.velocity ** 2 / self.braking)
        self.clear_max, self.clear_min = self.q_max - clear, self.q_min + clear

    def bounds(self, q: np.ndarray, previous: np.ndarray, acceleration_share: float) -> tuple[np.ndarray, np.ndarray]:
        """(lo, hi) of the step after ``previous`` from ``q``, with ``acceleration_share`` of the acceleration room."""
        accel = self.acceleration if acceleration_share == 1.0 else self.acceleration * acceleration_share
        room = np.maximum(np.concatenate([self.q_max - q, q - self.q_min]), 0.0)
        cap = np.minimum(np.minimum(self.velocity2, room), np.sqrt(self.braking2 * room))
        return np.maximum(-cap[JOINTS:], previous - accel), np.minimum(cap[:JOINTS], previous + accel)


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
