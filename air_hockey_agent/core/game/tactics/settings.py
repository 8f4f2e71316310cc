"""Thresholds of the tactics layer (``config/agent.yaml``) in one frozen record.

Lengths are in the robot's own frame (x toward the opponent, origin at the table centre; README
"Frames and units"); a *depth* is a distance from the robot's own goal line (x = -L/2).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from air_hockey_agent.core.table import TableGeometry

BLOCK_CHOICES = ("first", "margin")  # ready_block_choice: which block point ready.block_point tries first


@dataclass(frozen=True)
class TacticsSettings:
    table: TableGeometry
    mallet_radius: float
    defend_line: float
    ready_point: tuple[float, float]
    ready_guard_depth: float
    ready_guard_speed: float
    ready_checks_way: bool
    ready_dodge_steps: int
    ready_blocks: bool
    ready_block_step: float
    ready_block_in_way: bool
    ready_block_keep: bool
    ready_block_choice: str
    ready_switch_time: float
    ready_unseen_time: float
    ready_unseen_point: tuple[float, float]
    home_point: tuple[float, float]
    smash_depth: tuple[float, float]
    smash_rim_margin: float
    static_speed: float
    drift_speed: float
    drift_significance: float
    smash_puck_speed: float
    beyond_smash_speed: float
    smash_chase_speed: float
    smash_chase_lead: float
    smash_checks_way: bool
    approach_speed: float
    min_plan_time: float
    repel_time: tuple[float, float]
    repel_line: float
    repel_width: float
    repel_speed: float
    smash_lead_time: float
    lead_time_step: float
    hit_speed_fraction: float
    max_hit_speed: float
    speed_cap_fraction: float
    prepare_speed: tuple[float, float]
    prepare_speed_steps: int
    prepare_directions: int
    prepare_end_speed: float
    prepare_horizon: float
    clear_depth: float
    clear_after: float
    recontact_watch: float
    mallet_restitution: float
    mallet_friction: float
    aim_noise: float
    approach_clearance: float
    guard_margin: float
    guarded_factor: float
    shot_horizon: float
    goal_aim_margin: float
    aim_search_steps: int
    resend_distance: float
    resend_time: float
    resend_speed: float
    hit_replan_distance: float
    hit_correction_distance: float
    hit_correction_time: float
    retry_delay: float
    max_lead_extra: float
    limits_slowdown: float
    cut_arrive_early: float
    cut_contact_steps: int
    cut_normal_steps: int
    cut_normal_range: float
    cut_offset_noise: float
    cut_catch: tuple[float, ...]
    reach_time_margin: float
    stale_estimate: float
    unseen_after_own_contact: bool
    settle_time: float
    keep_checks_outcome: bool
    contact_learning: bool
    contact_learning_min: int
    contact_learning_max: int
    contact_restitution_bounds: tuple[float, float]
    contact_friction_bounds: tuple[float, float]

    @classmethod
    def from_params(cls, p: Mapping[str, Any]) -> "TacticsSettings":
        names = [f for f in cls.__dataclass_fields__ if f not in ("table", "mallet_radius")]
        values = {n: tuple(p[n]) if isinstance(p[n], list) else p[n] for n in names}
        return cls(TableGeometry.from_params(p), p["mallet.radius"], **values)

    # --- geometry in the own frame ---------------------------------------------------------------
    def x_at_depth(self, depth: float) -> float:
        """Own-frame x [m] of a point ``depth`` [m] in front of the own goal line."""
        return -self.table.length / 2 + depth

    def point(self, depth_y: tuple[float, float]) -> np.ndarray:
        return np.array([self.x_at_depth(depth_y[0]), depth_y[1]])

    @property
    def defend_x(self) -> float:
        return self.x_at_depth(self.defend_line)

    @property
    def contact_distance(self) -> float:
        """Puck and mallet centres touch at this distance [m]."""
        return self.table.puck_radius + self.mallet_radius

    @property
    def clear_distance(self) -> float:
        """A mallet this far [m] from the puck's centre (a contact distance plus ``approach_clearance``) is
        clear of it."""
        return self.contact_distance + self.approach_clearance

    def in_smash_area(self, x: float, y: float) -> bool:
        depth = x + self.table.length / 2
        return (self.smash_depth[0] <= depth <= self.smash_depth[1]
                and abs(y) <= self.table.y_limit - self.smash_rim_margin)

    def smash_speed_limit(self, chased: bool) -> float:
        """The fastest [m/s] a puck may move at the hit time to be smashed: ``smash_puck_speed``, or for a
        chased puck (:func:`~air_hockey_agent.core.game.tactics.smash.chased`) ``smash_chase_speed`` when
        that is larger."""
        return max(self.smash_puck_speed, self.smash_chase_speed) if chased else self.smash_puck_speed

    def smashable(self, puck: np.ndarray, chased: bool = False) -> bool:
        """A puck with own-frame state ``puck`` at the hit time may be smashed: no faster than
        :meth:`smash_speed_limit`, and in the smash area, or beyond it (toward the centre line) and no faster
        than ``beyond_smash_speed`` there (a chased puck: than the larger of the two)."""
        speed, limit = float(np.hypot(puck[2], puck[3])), self.smash_speed_limit(chased)
        if speed > limit:
            return False
        beyond = max(self.beyond_smash_speed, limit) if chased else self.beyond_smash_speed
        return self.in_smash_area(puck[0], puck[1]) or (speed <= beyond and self.beyond_smash_area(puck[0]))

    def beyond_smash_area(self, x: float) -> bool:
        """Own-frame ``x`` [m] lies between the smash area's far edge and the centre line."""
        return self.smash_depth[1] < x + self.table.length / 2 and x < 0.0
