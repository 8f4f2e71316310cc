"""Initial puck states of strategy-test trials (thesis sec. 4.6), table frame, tested robot iiwa_front.

Beyond the thesis, "guard": a puck left between the ready line and the own goal (slow, in any
direction, as a Cut or a rim leaves it in a game) with nothing forced: the agent's state machine
defends its goal as in a game (README "Ready guards a puck behind the ready line").

A trial is (strategy, index); its initial state depends only on the seed, the strategy and the index,
so a run gives the same trials whatever number of workers shares them. No puck starts on the mallet
waiting at the ready point (the simulation pushed such a puck out of the mallet before the tactic
played: 4 of seed 0's 100 Prepare trials started there); a draw there is drawn again.
"""
from __future__ import annotations

import math

import zlib
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from air_hockey_agent.core.table import TableGeometry

STRATEGIES = ("smash_straight", "smash_left", "smash_right", "cut", "prepare", "repel", "guard")
FORCED = {"smash_straight": ("smash", "straight"), "smash_left": ("smash", "left_bank"),
          "smash_right": ("smash", "right_bank"), "cut": ("cut", ""), "prepare": ("prepare", ""),
          "repel": ("repel", ""), "guard": ("", "")}  # "": nothing forced
ROBOT, OPPONENT = "iiwa_front", "iiwa_back"  # the tested robot (its goal at x = -L/2), and the other (--defended)
PARK = (0.6, 0.0)  # [m] where the puck waits between trials: the opponent's half, away from its mallet


@dataclass(frozen=True)
class TrialSettings:
    table: TableGeometry
    smash_depth: tuple[float, float]
    smash_rim_margin: float
    prepare_depth: tuple[float, float]
    prepare_rim_margin: float
    defend_line: float
    start_y: float
    shot_speed: float
    cut_impact_x: tuple[float, float]
    guard_depth: tuple[float, float]
    guard_rim_margin: float
    guard_speed: float
    guard_exit_depth: float
    guard_time: float
    rest_speed: float
    timeout: float
    hit_timeout: float
    after_hit: float
    settle: float
    start_gap: float
    damping: float = 0.0  # [1/s] the simulated table's viscous damping (0: outcomes are only known at rest)
    waiting: tuple[float, float] = (math.nan, math.nan)  # [m] where the tested mallet's centre waits (table frame)
    contact_distance: float = 0.0  # [m] puck and mallet centres touch at this distance

    @classmethod
    def from_params(cls, p: Mapping[str, Any], damping: float = 0.0,
                    waiting: tuple[float, float] = (math.nan, math.nan),
                    contact_distance: float = 0.0) -> "TrialSettings":
        names = [f for f in cls.__dataclass_fields__ if f not in ("table", "damping", "waiting", "contact_distance")]
        return cls(TableGeometry.from_params(p), **{n: tuple(p[n]) if isinstance(p[n], list) else p[n] for n in names},
                   damping=damping, waiting=tuple(waiting), contact_distance=contact_distance)

    def on_waiting_mallet(self, x: float, y: float) -> bool:
        """A puck centred at (x, y) [m] would start closer than ``start_gap`` to the waiting mallet."""
        gap = math.hypot(x - self.waiting[0], y - self.waiting[1]) - self.contact_distance
        return gap < self.start_gap  # False when the waiting point is unknown (NaN)

    def area_margin(self, x: float, y: float) -> float:
        """Distance [m] of (x, y) inside the smash area's box; negative outside (then minus the distance
        to the box, where that is the nearer edge)."""
        depth = x + self.table.length / 2
        dx = max(self.smash_depth[0] - depth, depth - self.smash_depth[1])
        dy = abs(y) - (self.table.y_limit - self.smash_rim_margin)
        if dx <= 0.0 and dy <= 0.0:
            return min(-dx, -dy)
        return -math.hypot(max(dx, 0.0), max(dy, 0.0))

    def in_smash_area(self, x: float, y: float) -> bool:
        depth = x + self.table.length / 2
        return (self.smash_depth[0] <= depth <= self.smash_depth[1]
                and abs(y) <= self.table.y_limit - self.smash_rim_margin)


@dataclass(frozen=True)
class Trial:
    strategy: str
    index: int
    state: tuple  # (x, y, vx, vy, theta, omega), table frame

    @property
    def tactic(self) -> str:
        """The forced tactic's name; "" for none (the state machine decides)."""
        return FORCED[self.strategy][0]

    @property
    def variant(self) -> str:
        return FORCED[self.strategy][1]


def make_trial(strategy: str, index: int, seed: int, s: TrialSettings) -> Trial:
    if strategy not in FORCED:
        raise ValueError(f"unknown strategy '{strategy}' (known: {', '.join(STRATEGIES)})")
    rng = np.random.default_rng([seed, zlib.crc32(strategy.encode()), index])
    t, half = s.table, s.table.length / 2
    if strategy.startswith("smash"):
        while True:
            x = -half + rng.uniform(*s.smash_depth)
            y = rng.uniform(-1, 1) * (t.y_limit - s.smash_rim_margin)
            if not s.on_waiting_mallet(x, y):
                break
        state = (x, y, 0.0, 0.0, 0.0, 0.0)
    elif strategy == "prepare":
        while True:
            x = -half + rng.uniform(*s.prepare_depth)
            y = rng.uniform(-1, 1) * (t.y_limit - s.prepare_rim_margin)
            if not (s.in_smash_area(x, y) or s.on_waiting_mallet(x, y)):
                break
        state = (x, y, 0.0, 0.0, 0.0, 0.0)
    elif strategy == "guard":
        while True:
            x = -half + rng.uniform(*s.guard_depth)
            y = rng.uniform(-1, 1) * (t.y_limit - s.guard_rim_margin)
            speed, heading = rng.uniform(0.0, s.guard_speed), rng.uniform(-math.pi, math.pi)
            if not s.on_waiting_mallet(x, y):
                break
        state = (x, y, speed * math.cos(heading), speed * math.sin(heading), 0.0, 0.0)
    else:
        x0, y0 = half - s.defend_line, rng.uniform(-s.start_y, s.start_y)
        if strategy == "repel":
            target = (-half, 0.0)
        else:
            side = 1.0 if rng.uniform() < 0.5 else -1.0
            target = (rng.uniform(*s.cut_impact_x), side * t.y_limit)
        d = np.array([target[0] - x0, target[1] - y0])
        v = s.shot_speed * d / np.linalg.norm(d)
        state = (x0, y0, float(v[0]), float(v[1]), 0.0, 0.0)
    return Trial(strategy, index, tuple(float(v) for v in state))
