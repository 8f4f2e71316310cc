"""Cut (thesis sec. 4.6; S: CUT): a puck approaching the own goal is deflected toward the near long rim
by a mallet that waits on its path at the defend line, so it stays on the own half (and can be smashed).

Geometry as S (REFERENCE_FACTS 2.2): the mallet centre is at the predicted crossing point plus
``unit(v_in - v_out) (r_puck + r_mallet)`` with ``v_out`` along the near rim, so the contact normal turns
the incoming direction toward it; it is reached and the mallet stopped just before the crossing.
"""
from __future__ import annotations

import math

import numpy as np

from air_hockey_agent.core.game.situation import Situation
from air_hockey_agent.core.game.tactics.base import CUT, Context, Proposal, Tactic


class Cut(Tactic):
    tactic = CUT

    def propose(self, situation: Situation | None, ctx: Context) -> Proposal | None:
        st = ctx.settings
        if situation is None:
            return None
        c = situation.crossing(st.defend_x)
        if c is None or c.time - ctx.now < st.min_plan_time:
            return None
        speed = math.hypot(c.vx, c.vy)
        v_in = np.array([c.vx, c.vy]) / speed if speed > 0.0 else np.array([-1.0, 0.0])
        v_out = np.array([0.0, 1.0 if c.y >= 0.0 else -1.0])
        n = v_in - v_out
        puck = np.array([st.defend_x, c.y])
        point = ctx.reach.clamp(puck + n / np.linalg.norm(n) * st.contact_distance)
        reason = (f"cut: puck crosses the defend line at y {c.y:+.2f} m in {c.time - ctx.now:.2f} s "
                  f"after {c.impacts_before} rim impact(s)")
        return Proposal(CUT, point, np.zeros(2), c.time - st.cut_arrive_early, reason, puck=puck)
