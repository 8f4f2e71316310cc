"""One arm's command bookkeeping (ROS-free): the measured state, the running motion, where a new one starts.

The ``trajectory_generator`` node and the in-process game (:mod:`air_hockey_agent.sim.game_loop`) both
turn a hit command into a joint trajectory with it: every motion starts ``planning_delay`` [s] after
now, from the running motion's planned state then or from the measured posture at rest, so its first
point is still ahead when the controller gets it and the arm never jumps. When the measured joints leave
the running plan by more than ``max_tracking_error`` [rad] (the arm was reset), the next motion starts
from the measured state. The planning itself is :class:`~air_hockey_agent.core.motion.planner.MotionPlanner`.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from air_hockey_agent.core.motion.joint_trajectory import JointTrajectory
from air_hockey_agent.core.motion.planner import INVALID, ArmState, Command, MotionPlanner, Plan, refused


class ArmCommander:
    def __init__(self, planner: MotionPlanner, planning_delay: float, max_tracking_error: float) -> None:
        self.planner = planner
        self.planning_delay = planning_delay
        self.max_tracking_error = max_tracking_error
        self.measured: ArmState | None = None
        self.running: JointTrajectory | None = None

    def measure(self, t: float, q: Sequence[float], dq: Sequence[float]) -> float | None:
        """A joint state at ``t`` [s] (planner's joint order). Returns the tracking error [rad] when it
        made the running plan be dropped (the arm is not where the plan says: reset, stopped, collided)."""
        self.measured = ArmState(t, np.asarray(q, float), np.asarray(dq, float))
        if self.running is None or t > self.running.start + self.running.duration:
            return None
        error = float(np.max(np.abs(self.running.sample(t)[0] - self.measured.q)))
        if error <= self.max_tracking_error:
            return None
        self.running = None
        return error

    def start_state(self, now: float) -> ArmState | None:
        """Where a new motion starts, ``planning_delay`` after ``now``: the running plan's state then, or
        the measured posture at rest (None before any joint state)."""
        t = now + self.planning_delay
        if self.running is not None and now < self.running.start + self.running.duration:
            q, dq = self.running.sample(t)
            return ArmState(t, q, dq)
        if self.measured is None:
            return None
        return ArmState(t, self.measured.q, np.zeros(len(self.measured.q)))

    def plan(self, command: Command, now: float) -> Plan:
        """The motion for ``command`` received at ``now`` [s], or the refusal; nothing runs until
        :meth:`accept`."""
        start = self.start_state(now)
        if start is None:
            return refused(INVALID, "no joint_states received yet")
        return self.planner.plan(command, start)

    def accept(self, plan: Plan, now: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Make an accepted ``plan`` the running motion, sent at ``now`` [s]. Returns its points as a
        trajectory message carries them: times from ``now`` [s] (a start at ``now`` itself left out: the
        controller's implicit first point), positions [rad] and velocities [rad/s]."""
        times = np.concatenate([[plan.start.t], plan.times]) - now
        q = np.vstack([plan.start.q, plan.q])
        dq = np.vstack([plan.start.dq, plan.dq])
        if times[0] <= 1e-9:
            times, q, dq = times[1:], q[1:], dq[1:]
        current_q, current_dq = self.running.sample(now) if self.running is not None else (plan.start.q, plan.start.dq)
        self.running = JointTrajectory.from_points(self.planner.kin.joint_names, now, times, q, dq, current_q,
                                                   current_dq)
        return times, q, dq
