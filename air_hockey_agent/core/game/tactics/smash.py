"""Smash (thesis sec. 4.6): a puck at rest (or slow) in the smash area is shot at the opponent's goal,
straight or off one of the long rims.

Beyond the thesis and S (REFERENCE_FACTS 2.2: a variant drawn at random, banks aimed by the reflection
law, a static puck only): the puck is taken where the tracker predicts it at the hit time, each variant
is aimed with the puck model and the fastest speed the arm allows along its direction
(:class:`~air_hockey_agent.core.game.shots.ShotPredictor`), and the most likely goal is played. A puck
creeping faster than ``drift_speed`` is also taken where it will be, not where it lies.

A puck beyond the smash area's far edge (between it and the centre line) is shot where the prediction
puts it at the hit time when it is slower than ``beyond_smash_speed`` there (a slow puck leaving the area
toward the line, or one at rest). The arm's reach ends there (a resting puck up to 0.85 m deep at y = 0, ``config/motion.yaml``
max_reach), so it can mostly push such a puck only forward: of the strategy test's 29 Prepare positions there (seed 0), 5 had
a push that stops in the area, and the others were pushed toward the line, out of reach, until the
referee's possession limit gave the puck away. Where no shot reaches the goal line (no room ahead of
the hit point), Smash does not apply and Prepare does what it can.
"""
from __future__ import annotations

import math

import numpy as np

from air_hockey_agent.core.game.shots import VARIANTS
from air_hockey_agent.core.game.situation import Situation
from air_hockey_agent.core.game.tactics.base import (SMASH, Context, Proposal, Tactic, approach_clear,
                                                    self_timed_hit_time)

CACHE_SIZE = 64
KEY_POSITION = 0.005  # [m] puck positions closer than this share an aimed shot
KEY_VELOCITY = 0.05   # [m/s]


class Smash(Tactic):
    tactic = SMASH

    def __init__(self) -> None:
        self._cache: dict[tuple, object] = {}

    def propose(self, situation: Situation | None, ctx: Context) -> Proposal | None:
        st = ctx.settings
        if situation is None:
            return None
        t_hit = self_timed_hit_time(SMASH, ctx)
        puck = situation.expected(t_hit, st.drift_speed)
        speed = math.hypot(puck[2], puck[3])
        if speed > st.smash_puck_speed:
            return None
        if not (st.in_smash_area(puck[0], puck[1]) or (speed <= st.beyond_smash_speed and st.beyond_smash_area(puck[0]))):
            return None
        shot = ctx.shots.pick([s for s in self._shots(puck, ctx) if approach_clear(puck, s.hit_point, s.mallet_speed * s.direction, ctx)])
        if shot is None:
            return None
        reason = (f"smash {shot.variant}: puck at ({puck[0]:.2f}, {puck[1]:.2f}), {shot.mallet_speed:.2f} m/s, "
                  f"predicted goal y {shot.goal_y:+.3f} m in {shot.arrival:.2f} s, p(goal) {shot.success:.2f}")
        return Proposal(SMASH, shot.hit_point, shot.mallet_speed * shot.direction, t_hit, reason, puck=puck[:2],
                        target=np.array([st.table.length / 2, 0.0]), flexible_time=True)

    def _shots(self, puck: np.ndarray, ctx: Context) -> list:
        cap = None if math.isinf(ctx.speed_cap) else ctx.speed_cap
        key = (round(puck[0] / KEY_POSITION), round(puck[1] / KEY_POSITION), round(puck[2] / KEY_VELOCITY),
               round(puck[3] / KEY_VELOCITY), cap, ctx.variant)
        if key not in self._cache:
            if len(self._cache) >= CACHE_SIZE:
                self._cache.clear()
            variants = (ctx.variant,) if ctx.variant else VARIANTS
            self._cache[key] = ctx.shots.candidates(puck, variants=variants, speed=cap)
        return self._cache[key]
