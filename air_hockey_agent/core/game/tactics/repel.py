"""Repel (thesis sec. 4.6; S: REPEL): a puck coming straight at the own goal (no rim impact before the
defend line) is struck back, using its speed for a counter-attack.

S hit back along the incoming line at 1.2 m/s at the defend line. Here the puck is met at ``repel_line``
(where the arm has room for its run-up) and the direction is aimed at the opponent's goal with the
puck model, its incoming velocity included (:meth:`ShotPredictor.best`, straight variant); when no
aimed shot reaches the goal, it is struck straight at the goal centre.
"""
from __future__ import annotations

import numpy as np

from air_hockey_agent.core.game.situation import Situation
from air_hockey_agent.core.game.tactics.base import REPEL, Context, Proposal, Tactic


class Repel(Tactic):
    tactic = REPEL

    def propose(self, situation: Situation | None, ctx: Context) -> Proposal | None:
        st = ctx.settings
        if situation is None:
            return None
        line = st.x_at_depth(st.repel_line)
        c = situation.crossing(line)
        if c is None or c.impacts_before > 0 or abs(c.y) >= st.repel_width:
            return None
        lead = c.time - ctx.now
        if not st.repel_time[0] <= lead <= st.repel_time[1]:
            return None
        puck = np.array([line, c.y, c.vx, c.vy, 0.0, 0.0])
        speed = min(st.repel_speed, ctx.speed_cap)
        shot = ctx.shots.best(puck, variants=("straight",), speed=speed)
        if shot is not None:
            d, hit, v, why = shot.direction, shot.hit_point, shot.mallet_speed, f"p(goal) {shot.success:.2f}"
        else:
            d = np.array([st.table.length / 2, 0.0]) - puck[:2]
            d /= np.linalg.norm(d)
            hit, v, why = puck[:2] - d * st.contact_distance, speed, "no aimed shot; at the goal centre"
            if ctx.reach.max_speed(hit, d) < v:
                return None
        reason = f"repel: puck straight at y {c.y:+.2f} m in {lead:.2f} s, {v:.2f} m/s, {why}"
        return Proposal(REPEL, hit, v * d, c.time, reason, puck=puck[:2], target=np.array([st.table.length / 2, 0.0]))
