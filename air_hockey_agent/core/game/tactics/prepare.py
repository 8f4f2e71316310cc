"""Prepare (thesis sec. 4.6; S: PREPARE): a puck at rest where it cannot be smashed (near a rim, near the
own goal, or beyond the smash area) is pushed so that it stops inside the smash area.

S pushed at a fixed 0.8 m/s along a rule with an asymmetric branch (REFERENCE_FACTS 2.2); with the
table's damping that sends the puck 1.6 m, out of the smash area. Here every push the arm can make is
predicted with the puck model, rim impacts included (:meth:`ShotPredictor.push`): ``prepare_directions``
directions around the puck and ``prepare_speed_steps`` mallet speeds spaced geometrically over
``prepare_speed``. A push whose puck crosses the centre line or enters the own goal is discarded; of the
rest, the one whose stopping point lies deepest inside the smash area, also when the direction is off by
the aim noise, is played (the slower one when two are as deep), so a puck against a rim is banked off it
into the area and one the arm cannot push into it is left as near to it as the arm can.

Where no push keeps the puck on the own half (a creeping puck that stopped beyond the smash area at the
arm's reach, next to a rim: every push the arm can make there runs forward), or when the puck has been on
the own half for ``clear_after`` (a puck in a corner, which pushes move only a little at a time), the puck
is **cleared**:
pushed across the centre line, the slowest push whose puck stops at least ``clear_depth`` past it with the
aim noise either way (else the one that gets it farthest). Left alone, it would stay until the referee's
possession limit gave it to the opponent with a foul.
"""
from __future__ import annotations

import math

import numpy as np

from air_hockey_agent.core.game.shots import Push
from air_hockey_agent.core.game.situation import Situation
from air_hockey_agent.core.game.tactics.base import (PREPARE, Context, Proposal, Tactic, approach_clear,
                                                    self_timed_hit_time)
from air_hockey_agent.core.game.tactics.outcome import LazyRanked, Ranked, lazy_candidate, margin_steps

CACHE_SIZE = 64
KEY_POSITION = 0.005  # [m] puck positions closer than this share a chosen push


class Prepare(Tactic):
    tactic = PREPARE

    def __init__(self) -> None:
        self._cache: dict[tuple, Ranked] = {}

    def propose(self, situation: Situation | None, ctx: Context) -> Proposal | None:
        st = ctx.settings
        if situation is None or situation.speed > st.static_speed:
            return None
        t = self_timed_hit_time(PREPARE, ctx)
        # where a creeping puck will be; pushed as from rest
        puck = situation.expected(t, st.drift_speed, st.drift_significance)
        puck[2:4] = 0.0
        p = puck[:2]
        if p[0] >= 0.0 or st.in_smash_area(p[0], p[1]):
            return None
        late = ctx.possession >= st.clear_after  # time is running out: clear rather than set up a smash
        order = [(self._ranked, "prepare"), (self._clears, "prepare (clear)")]
        order = order[::-1] if late else order
        for ranking, verb in order:
            push = self._best(puck, ctx, ranking, verb)
            if push is not None:
                break
        else:
            return None
        reason = (f"{verb}: puck at rest at ({p[0]:.2f}, {p[1]:.2f}) outside the smash area"
                  f"{f' for {ctx.possession:.1f} s on the own half' if late else ''}, pushed "
                  f"{push.mallet_speed:.2f} m/s to stop at ({push.rest[0]:.2f}, {push.rest[1]:.2f})")
        return Proposal(PREPARE, push.hit_point, push.mallet_velocity, t, reason, puck=p.copy(),
                        target=push.rest, flexible_time=True)

    def _best(self, puck: np.ndarray, ctx: Context, ranking, kind: str) -> Push | None:
        """The first push of ``ranking(puck, ctx)`` whose approach keeps off the puck and whose puck does not
        rebound into the mallet."""
        cap = None if math.isinf(ctx.speed_cap) else round(ctx.speed_cap, 3)
        key = (kind, round(puck[0] / KEY_POSITION), round(puck[1] / KEY_POSITION), cap)
        if key not in self._cache:
            if len(self._cache) >= CACHE_SIZE:
                self._cache.clear()
            self._cache[key] = LazyRanked(ranking(puck, ctx))
        st = ctx.settings
        best = self._cache[key].first(
            lambda p, run_on: approach_clear(puck, p.hit_point, p.mallet_velocity, ctx),
            lambda p, run_on: not ctx.shots.rebounds_into_mallet(p, run_on, st.recontact_watch))
        return None if best is None else best[0]

    def _ranked(self, puck: np.ndarray, ctx: Context) -> list[tuple]:
        """Every push the arm can make that keeps the puck on the own half, for :class:`LazyRanked`: each
        item is (push, follow-through [m]), ranked by how deep inside the smash area it stops in the worst
        of the aimed direction and the direction off by ``aim_noise`` either way (negative: outside; then
        the nearest to the area), the slower first among equals."""
        st = ctx.settings
        return self._candidates(puck, ctx, lambda pushed: pushed.crosses_centre or pushed.enters_goal,
                                lambda pushed: margin_steps(st, pushed), lambda worst, v: (worst, -v))

    def _clears(self, puck: np.ndarray, ctx: Context) -> list[tuple]:
        """Every push that sends the puck across the centre line and not into the own goal with the aim
        noise either way, for :class:`LazyRanked` (items: (push, follow-through [m])): first those whose
        puck stops ``clear_depth`` or more past the line in the worst case, slowest first; then the others,
        farthest first."""
        st = ctx.settings

        def key(worst: float, v: float) -> tuple:
            deep = worst >= st.clear_depth
            return deep, (-v if deep else worst)
        return self._candidates(puck, ctx, lambda pushed: pushed.enters_goal or not pushed.crosses_centre,
                                lambda pushed: float(pushed.rest[0]), key)

    def _candidates(self, puck: np.ndarray, ctx: Context, rejected, score, key) -> list[tuple]:
        """(key bound, exact key and item) of every push (:meth:`_pushes`): ``key(worst score, speed)`` of
        the aimed push's score bounds that of the worst case (``key`` must not decrease with the score)."""
        candidates = [lazy_candidate(ctx.settings, push, rejected, score, lambda worst, v=v: key(worst, v),
                                     lambda pushed, run_on=run_on: (pushed, run_on))
                      for v, run_on, push in self._pushes(puck, ctx)]
        return [c for c in candidates if c is not None]

    @staticmethod
    def _pushes(puck: np.ndarray, ctx: Context):
        """(mallet speed [m/s], follow-through [m], push(turn)) of every push the arm can make:
        ``prepare_directions`` directions, the ``prepare_speed_steps`` speeds the arm allows there under the
        speed cap; ``push(turn)`` predicts it aimed off by ``turn`` [rad]."""
        st = ctx.settings
        speeds = np.geomspace(st.prepare_speed[0], st.prepare_speed[1], st.prepare_speed_steps)
        for angle in np.linspace(-math.pi, math.pi, st.prepare_directions, endpoint=False):
            d = np.array([math.cos(angle), math.sin(angle)])
            hit = puck[:2] - d * st.contact_distance
            top = ctx.reach.max_speed(hit, d) * st.hit_speed_fraction
            for v in speeds[speeds <= min(top, ctx.speed_cap)]:
                run_on = ctx.reach.follow_through_length(hit, d, float(v))
                yield float(v), run_on, (lambda turn, a=float(angle), v=float(v):
                                         ctx.shots.push(puck, a + turn, v, st.prepare_end_speed, st.prepare_horizon))

