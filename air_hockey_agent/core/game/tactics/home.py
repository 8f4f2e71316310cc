"""Home (S: HOME): the game is paused; the mallet goes to the home point and stops there."""
from __future__ import annotations

from air_hockey_agent.core.game.tactics.base import HOME, Context, Proposal, Tactic, reach_proposal


class Home(Tactic):
    tactic = HOME

    def propose(self, situation, ctx: Context) -> Proposal | None:
        return reach_proposal(HOME, ctx.settings.point(ctx.settings.home_point), ctx, "game paused: home")
