"""How an arm executed its motions in a recorded game (ROS-free): did the mallet stay in its region, did
the joints stay within their velocity limits, and did the planned knots stay in the region.

Mallet positions come from the motion layer's own kinematics (the striker held vertical, as the planner
sees it) in the robot's own frame (README "Frames and units"); the region and the limits are the
planner's (``config/motion.yaml``). A diagnostic for `air-hockey game-check`: in a game the referee stops
play for a mallet 2 cm into a rim, this shows every excursion and where the plan itself went.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Iterable

import numpy as np

from air_hockey_agent.core.motion.planner import MotionPlanner


@dataclass
class ArmExecution:
    """One arm's record over a game; times [s] are the messages' stamps (None: no such sample)."""

    joint_states: int = 0
    worst_outside_m: float = 0.0          # mallet beyond the region, executed
    worst_outside_time: float | None = None
    worst_velocity_use: float = 0.0       # largest |dq| / real velocity limit over all joints, executed
    worst_velocity_time: float | None = None
    trajectories: int = 0
    trajectories_outside: int = 0         # with a planned knot more than ``planned_tolerance`` outside
    worst_planned_outside_m: float = 0.0
    non_finite_skipped: int = 0           # joint states and planned knots with a NaN or inf, left out

    def as_dict(self) -> dict:
        return asdict(self)


class ExecutionCheck:
    """Accumulates one arm's joint states and received trajectories (joint vectors in the planner's order)."""

    def __init__(self, planner: MotionPlanner, planned_tolerance: float, keep_trace: bool = False) -> None:
        self.planner, self.tolerance = planner, planned_tolerance
        self.result = ArmExecution()
        # with keep_trace, every joint state's (time [s], mallet x, y [m] in the own frame, velocity use [-])
        self.trace: list[tuple[float, float, float, float]] | None = [] if keep_trace else None

    def joint_state(self, t: float, q: np.ndarray, dq: np.ndarray) -> None:
        r, p = self.result, self.planner
        if not (np.all(np.isfinite(q)) and np.all(np.isfinite(dq)) and np.isfinite(t)):
            r.non_finite_skipped += 1  # counted apart: an inf velocity would be the game's "worst"
            return
        r.joint_states += 1
        mallet = p.kin.position(q)[:2]
        outside = float(p.region.excess(mallet)[0])
        if outside > r.worst_outside_m:
            r.worst_outside_m, r.worst_outside_time = outside, t
        use = float(np.max(np.abs(dq) / p.limits.dq_max_real))
        if use > r.worst_velocity_use:
            r.worst_velocity_use, r.worst_velocity_time = use, t
        if self.trace is not None:
            self.trace.append((t, float(mallet[0]), float(mallet[1]), use))

    def trajectory(self, knots: Iterable[np.ndarray]) -> None:
        r, p = self.result, self.planner
        r.trajectories += 1
        knots = list(knots)
        finite = [q for q in knots if np.all(np.isfinite(q))]
        r.non_finite_skipped += len(knots) - len(finite)
        points = np.array([p.kin.position(q)[:2] for q in finite])
        outside = float(np.max(p.region.excess(points))) if len(points) else 0.0
        r.worst_planned_outside_m = max(r.worst_planned_outside_m, outside)
        r.trajectories_outside += outside > self.tolerance
