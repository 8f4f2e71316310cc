"""The motion planner behind the ``trajectory_generator`` node (thesis sec. 4.1; issue #10 item 3).

A command asks the mallet to be at a point in the table plane at a time, either moving with a hit
velocity (*hit*) or at rest (*reach and stop*: ready, home, cut, defend). Everything is in the robot's
own table frame (x toward the opponent) at the playing height, inside the allowed :class:`Region`.

Hit: the posture of the fastest hit along the hit direction (:mod:`hit_config`) is fixed at the hit
point; the strike (run-up from rest along the hit direction) is tracked backward from it and the
follow-through (stop along the same line) forward, so the hit posture and velocity are met exactly.
The arm first reaches the run-up's start at rest in the strike's posture and waits there (*staged*);
when there is no time for that, a cubic from the current state straight into the hit velocity is
tracked instead (*direct*). Reach and stop: the shortest cubic within the task acceleration bound
and the joint limits. Joint trajectories come from :mod:`tracking` (null-space QP, DAQP).
A command the arm cannot do is refused with a reason, never clipped.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np

from air_hockey_agent.core.motion import task_motion as tm
from air_hockey_agent.core.motion.hit_config import best_hit_configuration
from air_hockey_agent.core.motion.ik import solve_ik, weighted_pinv
from air_hockey_agent.core.motion.kinematics import MalletKinematics
from air_hockey_agent.core.motion.limits import JointLimits
from air_hockey_agent.core.motion.region import Region
from air_hockey_agent.core.motion.tracking import StepQP, track
from air_hockey_agent.core.motion.kernels import warm_up

# Outcome codes (same values as air_hockey_msgs/TrajectoryStatus)
ACCEPTED, INVALID, OUTSIDE_REGION, TOO_LATE, UNREACHABLE, TOO_FAST, LIMITS = range(7)
OUTCOME_NAMES = ("accepted", "invalid", "outside the region", "too late", "unreachable",
                 "faster than the arm allows", "beyond the joint limits")
AT_REST = 1e-6  # [m/s] a hit velocity below this is a reach-and-stop command
REACH_RETRIES = 6
REACH_SLOWDOWN = 1.25  # duration factor per retry of a reach motion that broke a joint limit
SETTLE_TIME = 0.3      # [s] longest hold at a reach target while the arm comes to rest in its posture
# [m] a planned path may leave the region by this much between checks: its samples are a grid step apart,
# and the region's own margin (config/motion.yaml region_margin, 0.02 m) keeps such a graze off the rims
PATH_TOLERANCE = 1e-3


@dataclass(frozen=True)
class Command:
    """Mallet at ``point`` (x, y [m]) at ``time`` [s] with ``velocity`` (vx, vy [m/s]; zero: reach and stop)."""

    point: np.ndarray
    velocity: np.ndarray
    time: float

    @property
    def is_hit(self) -> bool:
        return float(np.linalg.norm(self.velocity)) > AT_REST


@dataclass(frozen=True)
class ArmState:
    """Joint positions [rad] and velocities [rad/s] at time ``t`` [s]."""

    t: float
    q: np.ndarray
    dq: np.ndarray


@dataclass
class Plan:
    """A planned joint trajectory: knots at ``times`` [s, absolute] after ``start`` (the start state),
    or the reason it was refused. ``hit_time``/``hit_speed`` [s, m/s] describe the planned hit;
    ``max_speed`` [m/s] is the fastest hit the arm allows there along the commanded direction (for a
    strike or follow-through refused for a joint's velocity or acceleration limit: the speed at which
    that limit would have held, by the scaling of :meth:`Tracked.slower_speed`)."""

    outcome: int
    message: str
    start: ArmState | None = None
    times: np.ndarray = field(default_factory=lambda: np.empty(0))
    q: np.ndarray = field(default_factory=lambda: np.empty((0, 7)))
    dq: np.ndarray = field(default_factory=lambda: np.empty((0, 7)))
    hit_time: float = math.nan
    hit_speed: float = math.nan
    max_speed: float = math.nan
    mode: str = ""

    @property
    def ok(self) -> bool:
        return self.outcome == ACCEPTED


@dataclass(frozen=True)
class MotionSettings:
    """``config/motion.yaml`` values the planner needs."""

    height: float
    dt: float
    run_up: tuple[float, float]
    run_up_time: float
    follow_through: tuple[float, float]
    follow_through_time: float
    follow_through_deceleration: float
    posture_gain: float
    posture_tolerance: float
    reach_acceleration: float
    ik_iterations: int
    ik_tolerance: float
    planning_delay: float
    height_transition: float
    hit_posture_range: float
    reference: np.ndarray

    @classmethod
    def from_params(cls, p: Mapping[str, Any]) -> "MotionSettings":
        return cls(p["playing_height"], p["sample_period"], tuple(p["run_up_length"]), p["run_up_time"],
                   tuple(p["follow_through_length"]), p["follow_through_time"],
                   p["follow_through_deceleration"], p["posture_gain"],
                   p["posture_tolerance"], p["reach_acceleration"], p["ik_iterations"], p["ik_tolerance"],
                   p["planning_delay"], p["height_transition"], p["hit_posture_range"],
                   np.asarray(p["reference_posture"], float))


def _without_repeats(q: np.ndarray, keep: int) -> np.ndarray:
    """Knots ``q`` without the trailing copies of the last one (a settled hold), keeping at least ``keep``."""
    end = len(q)
    while end > max(keep, 1) and np.array_equal(q[end - 1], q[end - 2]):
        end -= 1
    return q[:end]


def refused(outcome: int, message: str, **extra: float) -> Plan:
    return Plan(outcome, f"{OUTCOME_NAMES[outcome]}: {message}", **extra)


class MotionPlanner:
    """Plans hits and reach-and-stop motions for one arm (ROS-free)."""

    def __init__(self, kin: MalletKinematics, limits: JointLimits, region: Region, settings: MotionSettings) -> None:
        self.kin, self.limits, self.region, self.s = kin, limits, region, settings
        self.qp = StepQP()
        # compile (or load) the tracking's numba code now, not in the first command's planning time
        warm_up(kin.position_and_jacobian(settings.reference)[1])

    # --- entry point ---------------------------------------------------------------------------
    def plan(self, command: Command, start: ArmState) -> Plan:
        """Plan ``command`` from ``start`` (the current planned state); a refused plan moves nothing."""
        values = np.concatenate([command.point, command.velocity, [command.time]])
        if not np.all(np.isfinite(values)):
            return refused(INVALID, "the command has non-finite values")
        if not (math.isfinite(start.t) and np.all(np.isfinite(start.q)) and np.all(np.isfinite(start.dq))):
            return refused(INVALID, "the arm's start state has non-finite values")  # else NaN knots, accepted
        if not self.region.contains(command.point):
            return refused(OUTSIDE_REGION, self.region.why_outside(command.point))
        if command.time < start.t + self.s.planning_delay:
            return refused(TOO_LATE, f"the hit time is {start.t - command.time:+.3f} s from now "
                                     f"(at least {self.s.planning_delay:.3f} s ahead needed)")
        return self._plan_hit(command, start) if command.is_hit else self._plan_reach(command, start)

    # --- reach and stop ------------------------------------------------------------------------
    def _plan_reach(self, command: Command, start: ArmState) -> Plan:
        s, dt = self.s, self.s.dt
        p0, v0 = self._mallet(start)
        target = np.asarray(command.point, float)
        ik = solve_ik(self.kin, self.limits, self._at_height(target), start.q, s.reference,
                      s.ik_iterations, s.ik_tolerance)
        if not ik.ok:
            return refused(UNREACHABLE, ik.reason)
        duration = tm.shortest_hermite_duration(p0, v0, target, s.reach_acceleration, dt)
        available = command.time - start.t
        reason = ""
        for _ in range(REACH_RETRIES):
            if duration > available + 1e-9:
                return refused(TOO_LATE, f"reaching ({target[0]:.3f}, {target[1]:.3f}) needs {duration:.2f} s, "
                                         f"{available:.2f} s are left" + (f" ({reason})" if reason else ""))
            steps = tm.steps_for(duration, dt)
            pos, _ = tm.hermite(p0, v0, target, np.zeros(2), steps, dt)
            leaves = self._leaves_region(pos, v0, "the reach")
            if leaves is not None:
                return leaves
            # then hold the target until the arm is at rest in the IK posture (the cubic ends decelerating)
            hold = min(tm.steps_for(SETTLE_TIME, dt), max(0, int((available - steps * dt) / dt)))
            pos = np.vstack([pos, np.repeat(target[None], hold, axis=0)])
            tracked = track(self.kin, self.limits, self.qp, start.q, start.dq, self._from_start(pos, start), dt,
                            ik.q, s.posture_gain, settle=s.posture_tolerance)
            if tracked.ok:
                q = _without_repeats(tracked.q, steps)
                times = start.t + np.arange(1, len(q) + 1) * dt
                return self._finish(start, times, q, math.nan, math.nan, "reach")
            reason = tracked.reason
            duration *= REACH_SLOWDOWN
        return refused(LIMITS, reason)

    # --- hits ----------------------------------------------------------------------------------
    def _plan_hit(self, command: Command, start: ArmState) -> Plan:
        s = self.s
        hit = np.asarray(command.point, float)
        speed = float(np.linalg.norm(command.velocity))
        direction = np.asarray(command.velocity, float) / speed
        ik = solve_ik(self.kin, self.limits, self._at_height(hit), start.q, s.reference, s.ik_iterations,
                      s.ik_tolerance)
        if not ik.ok:
            return refused(UNREACHABLE, ik.reason)
        config = best_hit_configuration(self.kin, self.limits, ik.q, direction, s.ik_tolerance,
                                        s.hit_posture_range)
        if speed > config.max_speed:
            return refused(TOO_FAST, f"{speed:.2f} m/s asked, the arm reaches at most {config.max_speed:.2f} m/s "
                                     f"along ({direction[0]:.2f}, {direction[1]:.2f}) at this point",
                           max_speed=config.max_speed)
        start, steps = self._on_hit_grid(command.time, start)
        plan = self._staged_hit(hit, direction, speed, config, start, steps)
        if not plan.ok:
            direct = self._direct_hit(hit, direction, speed, config, start, steps)
            plan = direct if direct.ok else plan
        # a strike or follow-through refused for a limit keeps the speed that would have kept it
        plan.max_speed = min(config.max_speed, plan.max_speed) if math.isfinite(plan.max_speed) else config.max_speed
        return plan

    def _on_hit_grid(self, hit_time: float, start: ArmState) -> tuple[ArmState, int]:
        """The start moved onto the hit's time grid (knots fall exactly on the hit time), and the number of
        grid steps from there to the hit. The grid origin lies within half a step of the start, and after
        the start's own ``now`` (``start.t - planning_delay``: the trajectory's first point must still be
        ahead); the start state is carried there along its velocity (half a step at most: about 1 mrad
        off the running motion at the arm's accelerations), so every step of the plan, the first
        included, lasts the grid step the tracking assumes (a first step half as long doubled its joint
        velocities: up to 166 % of a limit in a game)."""
        dt = self.s.dt
        steps = max(1, int(round((hit_time - start.t) / dt)))
        if steps > 1 and hit_time - steps * dt <= start.t - self.s.planning_delay:
            steps -= 1
        origin = hit_time - steps * dt
        return ArmState(origin, start.q + (origin - start.t) * start.dq, start.dq), steps

    def _run_up(self, hit, direction, speed) -> tuple[int, Plan | None]:
        """Grid steps of the strike (the longest run-up that fits behind the hit point), and a refusal
        when even the shortest does not fit."""
        s = self.s
        behind = self.region.distance_along(hit, -direction)
        steps = max(1, int(2 * tm.straight_length(behind, speed, s.run_up, s.run_up_time) / speed / s.dt))
        if behind < s.run_up[0]:
            return steps, refused(LIMITS, f"no room for a run-up: {behind:.3f} m behind the hit point "
                                          f"(at least {s.run_up[0]:.3f} m needed)")
        return steps, None

    def _stop_steps(self, hit, direction, speed) -> int | Plan:
        """Grid steps of the follow-through (the longest stop that fits ahead of the hit point, at most
        ``follow_through_time`` long, shorter where the optional ``follow_through_deceleration`` brakes sooner:
        :func:`task_motion.stop_length`), or a refusal."""
        s = self.s
        ahead = self.region.distance_along(hit, direction)
        if ahead < s.follow_through[0]:
            return refused(LIMITS, f"no room to stop: {ahead:.3f} m ahead of the hit point "
                                   f"(at least {s.follow_through[0]:.3f} m needed)")
        length = tm.stop_length(ahead, speed, s.follow_through, s.follow_through_time, s.follow_through_deceleration)
        return max(1, int(2 * length / speed / s.dt))

    def _strike(self, hit, direction, speed, n_strike, q_hit, dq_hit) -> np.ndarray | Plan:
        """Joint knots of the strike, tracked backward from (q_hit, dq_hit): from the run-up start
        (index 0) to just before the hit; or a refusal."""
        dt = self.s.dt
        run_pos, _ = tm.strike(hit, direction, speed, n_strike, dt)
        run_start = tm.run_up_start(hit, direction, speed, n_strike, dt)
        backward = np.vstack([run_pos[-2::-1], run_start[None]]) if n_strike > 1 else run_start[None]
        back = track(self.kin, self.limits, self.qp, q_hit, -dq_hit, self._at_height(backward), dt,
                     q_hit, self.s.posture_gain)
        if not back.ok:
            return refused(LIMITS, f"the strike {back.reason}", max_speed=back.slower_speed(speed))
        return back.q[::-1]

    def _follow_through(self, hit, direction, speed, q_hit, dq_hit, n_stop):
        """Joint knots of the stop after the hit (no posture pull: the arm just brakes), or a refusal."""
        stop_pos, _ = tm.stop(hit, direction, speed, n_stop, self.s.dt)
        fwd = track(self.kin, self.limits, self.qp, q_hit, dq_hit, self._at_height(stop_pos), self.s.dt, q_hit, 0.0)
        if not fwd.ok:
            return refused(LIMITS, f"the follow-through {fwd.reason}", max_speed=fwd.slower_speed(speed))
        return fwd.q

    def _staged_hit(self, hit, direction, speed, config, start: ArmState, steps: int) -> Plan:
        s, dt = self.s, self.s.dt
        p0, v0 = self._mallet(start)
        n_strike, no_room = self._run_up(hit, direction, speed)
        run_start = tm.run_up_start(hit, direction, speed, n_strike, dt)
        reach = tm.shortest_hermite_duration(p0, v0, run_start, s.reach_acceleration, dt)
        n_approach = steps - n_strike
        if n_approach * dt < reach:
            return refused(TOO_LATE, f"the run-up start is {reach:.2f} s away, "
                                     f"{n_approach * dt:.2f} s are left before the strike")
        if no_room is not None:
            return no_room
        n_stop = self._stop_steps(hit, direction, speed)
        if isinstance(n_stop, Plan):
            return n_stop
        dq_hit = self._hit_joint_velocity(config, direction, speed)
        strike_q = self._strike(hit, direction, speed, n_strike, config.q, dq_hit)
        if isinstance(strike_q, Plan):
            return strike_q
        n_move = tm.steps_for(reach, dt)
        pos, _ = tm.hermite(p0, v0, run_start, np.zeros(2), n_move, dt)
        leaves = self._leaves_region(pos, v0, "the approach")
        if leaves is not None:
            return leaves
        targets = np.vstack([pos, np.repeat(run_start[None], n_approach - n_move, axis=0)])
        approach = track(self.kin, self.limits, self.qp, start.q, start.dq, self._from_start(targets, start), dt,
                         strike_q[0], s.posture_gain, settle=s.posture_tolerance, must_settle=True)
        if not approach.ok:
            if approach.limit == "posture":
                return refused(TOO_LATE, f"the arm cannot take the hit posture in time ({approach.reason})")
            return refused(LIMITS, f"the approach {approach.reason}")
        gap = float(np.max(np.abs(approach.q[-1] - strike_q[0])))
        if gap > s.posture_tolerance:
            return refused(TOO_LATE, f"the arm cannot take the hit posture in time ({gap:.3f} rad away)")
        # the follow-through last: most staged hits that fail, fail in the approach (posture)
        stop_q = self._follow_through(hit, direction, speed, config.q, dq_hit, n_stop)
        if isinstance(stop_q, Plan):
            return stop_q
        q = np.vstack([approach.q[:-1], strike_q, [config.q], stop_q])
        times = start.t + np.arange(1, len(q) + 1) * dt
        return self._finish(start, times, q, start.t + steps * dt, speed, "staged", steps - 1, dq_hit)

    def _direct_hit(self, hit, direction, speed, config, start: ArmState, steps: int) -> Plan:
        s, dt = self.s, self.s.dt
        p0, v0 = self._mallet(start)
        velocity = speed * direction
        pos, _ = tm.hermite(p0, v0, hit, velocity, steps, dt)
        outside = self.region.first_outside(pos, PATH_TOLERANCE)
        if outside is not None:  # too late, not outside: with more time the staged hit keeps inside
            return refused(TOO_LATE, "no time to stage the hit, and a direct path leaves the region: "
                                     + self.region.why_outside(pos[outside]))
        approach = track(self.kin, self.limits, self.qp, start.q, start.dq, self._from_start(pos, start), dt,
                         config.q, s.posture_gain)
        if not approach.ok:
            return refused(LIMITS, f"the direct hit {approach.reason}")
        q_hit = approach.q[-1]
        _, jac = self.kin.position_and_jacobian(q_hit)
        dq_hit = (approach.q[-1] - (approach.q[-2] if steps > 1 else start.q)) / dt
        dq_hit = dq_hit + weighted_pinv(jac) @ (np.array([*velocity, 0.0]) - jac @ dq_hit)
        n_stop = self._stop_steps(hit, direction, speed)
        if isinstance(n_stop, Plan):
            return n_stop
        fwd = self._follow_through(hit, direction, speed, q_hit, dq_hit, n_stop)
        if isinstance(fwd, Plan):
            return fwd
        q = np.vstack([approach.q, fwd])
        times = start.t + np.arange(1, len(q) + 1) * dt
        return self._finish(start, times, q, start.t + steps * dt, speed, "direct", steps - 1, dq_hit)

    def _hit_joint_velocity(self, config, direction, speed) -> np.ndarray:
        """Joint velocities at the hit: the smallest that give the hit velocity, or the LP's when those
        break a velocity limit."""
        _, jac = self.kin.position_and_jacobian(config.q)
        dq = weighted_pinv(jac) @ np.array([*(speed * direction), 0.0])
        return dq if np.all(np.abs(dq) <= self.limits.dq_max) else config.dq_unit * speed

    # --- helpers -------------------------------------------------------------------------------
    def _leaves_region(self, pos: np.ndarray, v0: np.ndarray, what: str) -> Plan | None:
        """A refusal when the planar path ``pos`` (n, 2) [m] leaves the region: a cubic from a moving mallet
        bulges along its start velocity ``v0`` [m/s] before it turns (a mallet at 2 m/s toward a rim
        overshoots about 0.5 m at the reach acceleration of 5 m/s^2), so the running plan, which stops
        inside, is kept instead."""
        i = self.region.first_outside(pos, PATH_TOLERANCE)
        if i is None:
            return None
        return refused(OUTSIDE_REGION, f"{what} from the mallet's motion ({float(np.linalg.norm(v0)):.2f} m/s) "
                                       f"leaves the region: {self.region.why_outside(pos[i])}")

    def _mallet(self, state: ArmState) -> tuple[np.ndarray, np.ndarray]:
        return self.kin.planar_motion(state.q, state.dq)

    def _from_start(self, xy: np.ndarray, start: ArmState) -> np.ndarray:
        """Targets (n, 3) for planar points ``xy`` (n, 2) that leave the start's height for the playing
        height smoothly: a cubic Hermite from the start's height and vertical velocity to the playing height
        at rest, over ``height_transition`` s, e.g. from a raised home pose. From an arm still descending
        (a Smash forced during Ready's descent from home) it continues the descent, over less time where
        the full transition would carry the mallet past the playing height (Hermite end slope limit 3,
        Fritsch and Carlson 1980: then z - height falls as (1 - s)^3); stopping the descent at once asked a
        joint for several times its acceleration limit."""
        targets = self._at_height(xy)
        position, jac = self.kin.position_and_jacobian(start.q)
        above, vz = float(position[2]) - self.s.height, float(jac[2] @ start.dq)
        duration = self.s.height_transition
        if vz * above < 0.0 and abs(vz) * duration > 3.0 * abs(above):
            duration = 3.0 * abs(above) / abs(vz)
        s = np.clip(np.arange(1, len(targets) + 1) * self.s.dt / duration, 0.0, 1.0)
        targets[:, 2] += above * (2 * s ** 3 - 3 * s ** 2 + 1) + vz * duration * (s ** 3 - 2 * s ** 2 + s)
        return targets

    def _at_height(self, xy: np.ndarray) -> np.ndarray:
        """Planar point(s) (2,) or (n, 2) -> the same at the playing height, (3,) or (n, 3)."""
        xy = np.asarray(xy, float)
        if xy.ndim == 1:
            return np.array([xy[0], xy[1], self.s.height])
        return np.hstack([xy, np.full((len(xy), 1), self.s.height)])

    def _finish(self, start: ArmState, times: np.ndarray, q: np.ndarray, hit_time: float, hit_speed: float,
                mode: str, hit_index: int = -1, dq_hit: np.ndarray | None = None) -> Plan:
        """Knot velocities (central differences; the start's velocity before, rest at the end, the exact
        hit velocity at the hit knot) and a last check against the real joint limits."""
        dt = self.s.dt
        padded = np.vstack([start.q, q])
        dq = np.gradient(padded, dt, axis=0)[1:]
        dq[-1] = 0.0
        if hit_index >= 0 and dq_hit is not None:
            dq[hit_index] = dq_hit
        if self.limits.velocity_use(dq) > 100.0 or self.limits.position_use(q) > 100.0:
            return refused(LIMITS, f"the planned knots use {self.limits.velocity_use(dq):.0f} % of a velocity "
                                   f"limit and {self.limits.position_use(q):.0f} % of a position range")
        return Plan(ACCEPTED, f"{OUTCOME_NAMES[ACCEPTED]} ({mode})", start, times, q, dq, hit_time, hit_speed,
                    mode=mode)
