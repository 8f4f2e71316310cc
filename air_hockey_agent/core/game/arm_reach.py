"""What the tactics know of the arm (ROS-free): where it may put the mallet, how fast it can hit there,
and how long a reach takes. All from the motion layer's own region, settings and speed table, so the
tactics only ask the trajectory generator for what it can do."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from air_hockey_agent.core.game.speed_map import SpeedMap
from air_hockey_agent.core.motion.region import Region
from air_hockey_agent.core.motion.task_motion import (hermite_at, shortest_hermite_duration, stop_length,
                                                     straight_length)


UNKNOWN_START_DISTANCE = 0.5  # [m] a reach from an unknown mallet position is timed as one this long


@dataclass(frozen=True)
class ArmReach:
    region: Region            # the planner's allowed region (own frame)
    run_up: float             # [m] shortest run-up the planner needs behind a hit point
    run_up_max: float         # [m] longest run-up it takes when there is room
    run_up_time: float        # [s] longest time a run-up takes (slow hits get short run-ups)
    follow_through: float     # [m] shortest follow-through it needs ahead of it
    follow_through_max: float  # [m] longest follow-through it takes when there is room
    follow_through_time: float  # [s] longest time a follow-through takes
    follow_through_deceleration: float  # [m/s^2] peak deceleration of a follow-through (0: none; slow hits stop sooner)
    reach_acceleration: float  # [m/s^2] task acceleration of reach-and-stop motions
    height_transition: float  # [s] the planner's descent from a raised start to the playing height
    reach_time_margin: float  # [-] multiple of the shortest cubic time given to a reach
    speeds: SpeedMap
    planning_delay: float     # [s] the planner starts a motion this long after it is asked
    dt: float                 # [s] the planner's step

    @classmethod
    def of_planner(cls, planner, reach_time_margin: float, speeds: SpeedMap | None) -> "ArmReach":
        """What the tactics know of ``planner`` (a :class:`~air_hockey_agent.core.motion.planner.MotionPlanner`):
        its region and the run-up, stop and reach settings it plans with, and ``speeds``, its fastest-hit
        table."""
        s = planner.s
        return cls(planner.region, s.run_up[0], s.run_up[1], s.run_up_time, s.follow_through[0], s.follow_through[1],
                   s.follow_through_time, s.follow_through_deceleration, s.reach_acceleration, s.height_transition,
                   reach_time_margin, speeds, s.planning_delay, s.dt)

    @property
    def min_reach_time(self) -> float:
        """Shortest time [s] a reach is given: the planner's delay plus its height transition."""
        return self.planning_delay + self.height_transition

    def can_hit(self, point: np.ndarray, direction: np.ndarray) -> bool:
        """The hit point is in the region with room for the run-up behind it and the follow-through ahead."""
        if not self.region.contains(point):
            return False
        return (self.region.distance_along(point, -direction) >= self.run_up
                and self.region.distance_along(point, direction) >= self.follow_through)

    def run_up_start(self, point: np.ndarray, direction: np.ndarray, speed: float) -> np.ndarray:
        """Where the planner starts the strike of a hit at ``point`` along ``direction`` at ``speed`` [m/s]
        (the planner's own rule, :func:`task_motion.straight_length`)."""
        behind = self.region.distance_along(point, -direction)
        length = straight_length(behind, speed, (self.run_up, self.run_up_max), self.run_up_time)
        return np.asarray(point) - length * np.asarray(direction)

    def follow_through_length(self, point: np.ndarray, direction: np.ndarray, speed: float) -> float:
        """How far [m] the mallet runs on after a hit at ``point`` along ``direction`` at ``speed`` [m/s] before
        it stops (the planner's own rule, :meth:`MotionPlanner._stop_steps`)."""
        ahead = self.region.distance_along(point, direction)
        lengths = (self.follow_through, self.follow_through_max)
        return stop_length(ahead, speed, lengths, self.follow_through_time, self.follow_through_deceleration)

    def max_speed(self, point: np.ndarray, direction: np.ndarray) -> float:
        """Fastest hit [m/s] at ``point`` along ``direction``; 0 where the arm cannot hit."""
        return self.speeds.max_speed(point, direction) if self.can_hit(point, direction) else 0.0

    def clamp(self, point: np.ndarray) -> np.ndarray:
        """The nearest point of the region's box, pulled toward the base until inside the reach disc."""
        r = self.region
        p = np.array([min(max(point[0], r.x_min), r.x_max), min(max(point[1], -r.y_max), r.y_max)])
        base = np.asarray(r.base_xy)
        rel = p - base
        dist = float(np.hypot(*rel))
        if dist > r.reach:
            p = base + rel * (r.reach - 1e-6) / dist
        return p

    def reach_time(self, start: np.ndarray | None, target: np.ndarray, velocity: np.ndarray | None = None) -> float:
        """Time [s] from now a reach-and-stop from ``start`` [m], moving at ``velocity`` [m/s] (None: at
        rest), to ``target`` needs: the planner's delay plus its own shortest cubic within the reach
        acceleration (:func:`task_motion.shortest_hermite_duration`: sqrt(6 D / a) from rest, longer
        while the mallet still moves away) with a margin, never less than ``min_reach_time``; 0.5 m from
        rest when the start is unknown. (From rest alone, a Ready after a hit was refused as too late
        151 times in ten games: the follow-through still carried the mallet away.)"""
        target = np.asarray(target, float)
        if start is None:
            start, velocity = target + np.array([UNKNOWN_START_DISTANCE, 0.0]), None
        v0 = np.zeros(2) if velocity is None else np.asarray(velocity, float)
        cubic = shortest_hermite_duration(np.asarray(start, float), v0, target, self.reach_acceleration, self.dt)
        return max(self.min_reach_time, self.planning_delay + self.reach_time_margin * cubic)

    def reach_way(self, start: np.ndarray, velocity: np.ndarray | None, target: np.ndarray,
                  t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Where a reach-and-stop to ``target`` [m] sent now puts the mallet, at ``velocity`` [m/s] (None: at
        rest) in ``start`` [m] now: positions and velocities (n, 2) at times ``t`` (n,) [s from now]. The arm
        runs on at its velocity for the planner's delay, then follows the planner's shortest cubic to the target
        (:meth:`MotionPlanner._plan_reach`) and rests there."""
        t = np.asarray(t, float)
        v0 = np.zeros(2) if velocity is None else np.asarray(velocity, float)
        p0 = np.asarray(start, float) + v0 * self.planning_delay
        target = np.asarray(target, float)
        duration = shortest_hermite_duration(p0, v0, target, self.reach_acceleration, self.dt)
        pos, vel = hermite_at(p0, v0, target, np.zeros(2), duration,
                              np.clip(t - self.planning_delay, 0.0, duration))
        before = t < self.planning_delay
        pos[before] = np.asarray(start, float) + np.outer(t[before], v0)
        vel[before] = v0
        return pos, vel
