"""Prepare (thesis sec. 4.6; S: PREPARE): a puck at rest where it cannot be smashed (near a rim or the
own goal) is pushed into the smash area.

S pushed at a fixed 0.8 m/s along a rule with an asymmetric branch (REFERENCE_FACTS 2.2); with the
table's damping that sends the puck 1.6 m, out of the smash area. Here the direction is toward the
smash area's centre (turned by up to ``TURNS`` when the arm has no room for it) and the speed is the one
after which the puck model stops the puck there: the puck's speed ``d D`` for a distance ``D`` under
damping ``d`` (eq. 3.1 without the tiny friction term), divided by ``1 + e`` for the mallet's impact.
"""
from __future__ import annotations

import math

import numpy as np

from air_hockey_agent.core.game.situation import Situation
from air_hockey_agent.core.game.tactics.base import PREPARE, Context, Proposal, Tactic

TURNS = (0.0, 0.3, -0.3, 0.6, -0.6, 0.9, -0.9, 1.2, -1.2)  # [rad] direction changes tried in order


def _rotate(v: np.ndarray, angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([c * v[0] - s * v[1], s * v[0] + c * v[1]])


class Prepare(Tactic):
    tactic = PREPARE

    def propose(self, situation: Situation | None, ctx: Context) -> Proposal | None:
        st = ctx.settings
        if situation is None or situation.speed > st.static_speed:
            return None
        p = situation.puck[:2]
        if p[0] >= 0.0 or st.in_smash_area(p[0], p[1]):
            return None
        target = st.point((0.5 * (st.smash_depth[0] + st.smash_depth[1]), 0.0))
        distance = float(np.linalg.norm(target - p))
        toward = (target - p) / distance
        damping = ctx.shots.model.params.damping
        for turn in TURNS:
            d = _rotate(toward, turn)
            hit = p - d * st.contact_distance
            top = ctx.reach.max_speed(hit, d)
            if top <= 0.0:
                continue
            wanted = damping * distance / (1.0 + st.mallet_restitution)
            v = min(max(wanted, st.prepare_speed[0]), st.prepare_speed[1], top * st.hit_speed_fraction, ctx.speed_cap)
            t = ctx.now + st.smash_lead_time + ctx.lead_extra
            reason = f"prepare: puck at rest at ({p[0]:.2f}, {p[1]:.2f}) outside the smash area, pushed {v:.2f} m/s"
            return Proposal(PREPARE, hit, v * d, t, reason, puck=p.copy(), target=target, flexible_time=True)
        return None
