"""Ready (S: READY): nothing to hit or defend; the mallet waits at the ready point in front of the goal."""
from __future__ import annotations

from air_hockey_agent.core.game.tactics.base import READY, Context, Proposal, Tactic, reach_proposal


class Ready(Tactic):
    tactic = READY

    def propose(self, situation, ctx: Context) -> Proposal | None:
        return reach_proposal(READY, ctx.settings.point(ctx.settings.ready_point), ctx, "waiting at the ready point")
