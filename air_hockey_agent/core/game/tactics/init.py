"""Init (thesis sec. 4.6; S: INIT): the game is stopped. The arm holds where it is; no command."""
from __future__ import annotations

from air_hockey_agent.core.game.tactics.base import INIT, Context, Proposal, Tactic


class Init(Tactic):
    tactic = INIT

    def propose(self, situation, ctx: Context) -> Proposal | None:
        return None
