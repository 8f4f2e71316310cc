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

A puck moving away from the own goal ahead of the mallet is *chased* (:func:`chased`): smashed up to
``smash_chase_speed`` at the hit time, and when at ``smash_lead_time`` it has left the arm's reach, at an
earlier hit time (:func:`hit_times`). Held to ``smash_puck_speed`` now and at the hit time, such a puck
crossed the arm's reach unplayed and came to rest in the neutral zone: in self-play most neutral-zone
pauses. With ``smash_checks_way`` a shot at a moving puck is played only when the mallet's way to the
strike keeps clear of the puck's predicted path (:func:`~air_hockey_agent.core.game.tactics.base.strike_way_clear`).
"""
from __future__ import annotations

import math

import numpy as np

from air_hockey_agent.core.game.shots import VARIANTS
from air_hockey_agent.core.game.situation import Situation
from air_hockey_agent.core.game.tactics.base import (SMASH, Context, Proposal, Tactic, approach_clear,
                                                    self_timed_hit_time, strike_way_clear)

CACHE_SIZE = 64
KEY_POSITION = 0.005  # [m] puck positions closer than this share an aimed shot
KEY_VELOCITY = 0.05   # [m/s]


class Smash(Tactic):
    tactic = SMASH

    def __init__(self) -> None:
        self._cache: dict[tuple, object] = {}

    def propose(self, situation: Situation | None, ctx: Context) -> Proposal | None:
        if situation is None:
            return None
        chase = chased(situation, ctx)
        if situation.speed > ctx.settings.smash_speed_limit(chase):
            return None
        for t_hit in hit_times(chase, ctx):
            proposal = self._shot_at(t_hit, situation, chase, ctx)
            if proposal is not None:
                return proposal
        return None

    def _shot_at(self, t_hit: float, situation: Situation, chase: bool, ctx: Context) -> Proposal | None:
        """The best shot at the puck where the prediction puts it at ``t_hit`` [s], if it may be smashed there."""
        st = ctx.settings
        puck = situation.expected(t_hit, st.drift_speed, st.drift_significance)
        if not st.smashable(puck, chase):
            return None
        shot = ctx.shots.pick([s for s in self._shots(puck, ctx) if self._clear(s, puck, t_hit, situation, ctx)])
        if shot is None:
            return None
        reason = (f"smash {shot.variant}: puck at ({puck[0]:.2f}, {puck[1]:.2f}), {shot.mallet_speed:.2f} m/s, "
                  f"predicted goal y {shot.goal_y:+.3f} m in {shot.arrival:.2f} s, p(goal) {shot.success:.2f}")
        return Proposal(SMASH, shot.hit_point, shot.mallet_speed * shot.direction, t_hit, reason, puck=puck[:2],
                        target=np.array([st.table.length / 2, 0.0]), flexible_time=True)

    @staticmethod
    def _clear(shot, puck: np.ndarray, t_hit: float, situation: Situation, ctx: Context) -> bool:
        """The mallet's way to ``shot`` keeps clear of the puck: :func:`approach_clear`, and for a moving puck
        (faster than ``static_speed``), with ``smash_checks_way``, :func:`strike_way_clear` along its path."""
        st, velocity = ctx.settings, shot.mallet_speed * shot.direction
        if not approach_clear(puck, shot.hit_point, velocity, ctx):
            return False
        moving = st.smash_checks_way and situation.speed > st.static_speed
        return not moving or strike_way_clear(situation, shot.hit_point, velocity, t_hit, ctx)

    def _shots(self, puck: np.ndarray, ctx: Context) -> list:
        """The aimed shots at ``puck`` (own-frame state), kept for pucks in the same cell of ``KEY_POSITION``
        and ``KEY_VELOCITY`` while the shots' physics stay (a resting puck is aimed at once, not every tick)."""
        cap = None if math.isinf(ctx.speed_cap) else ctx.speed_cap
        key = (round(puck[0] / KEY_POSITION), round(puck[1] / KEY_POSITION), round(puck[2] / KEY_VELOCITY),
               round(puck[3] / KEY_VELOCITY), cap, ctx.variant, ctx.shots.physics_version)
        if key not in self._cache:
            if len(self._cache) >= CACHE_SIZE:
                self._cache.clear()
            variants = (ctx.variant,) if ctx.variant else VARIANTS
            self._cache[key] = ctx.shots.candidates(puck, variants=variants, speed=cap)
        return self._cache[key]


def chased(situation: Situation, ctx: Context) -> bool:
    """The puck is chased (``smash_chase_speed``, earlier hit times): it moves away from the own goal (own vx
    above ``approach_speed``) and lies ahead of the mallet, farther from the goal by a clear distance or
    more, or a smash is under way (its mallet comes up behind the puck). A puck leaving from behind the
    mallet crosses its way to the strike: in the Guard trials such chases hit it early and turned it into
    the goal."""
    st = ctx.settings
    if st.smash_chase_speed <= st.smash_puck_speed or not situation.leaving(st.approach_speed) or ctx.mallet is None:
        return False
    smashing = ctx.running is not None and ctx.running.tactic == SMASH
    return smashing or situation.puck[0] > ctx.mallet[0] + st.clear_distance


def hit_times(chase: bool, ctx: Context) -> list[float]:
    """When to hit [s]: :func:`self_timed_hit_time`; for a chased puck not yet under a smash also earlier,
    ``lead_time_step`` by step, down to ``smash_chase_lead`` from now (plus any "too late" extra): at
    ``smash_lead_time`` such a puck has often left the arm's reach."""
    st = ctx.settings
    times = [self_timed_hit_time(SMASH, ctx)]
    if not chase or (ctx.running is not None and ctx.running.tactic == SMASH and ctx.running.time == times[0]):
        return times
    earliest = ctx.now + st.smash_chase_lead + ctx.lead_extra
    while times[-1] - st.lead_time_step >= earliest - 1e-9:
        times.append(times[-1] - st.lead_time_step)
    return times
