"""Ready (S: READY): nothing to hit or defend; the mallet waits at the ready point in front of the goal.

Beyond the thesis and S, a puck closer to the own goal line than ``ready_guard_depth`` is not left behind
the waiting mallet: slower than ``ready_guard_speed``, the mallet waits between it and the goal
(:func:`guard_point`); else, or when it is too deep for that, at the ready point moved away from the goal
until the puck's predicted path passes clear of it (:func:`clear_of`). In in-process self-play (seeds
31-46, 60 s) 4 of 8 goals had been such pucks, met from behind by the waiting mallet or crept into the
goal mouth past it (README "Tactics and the game").
"""
from __future__ import annotations

import numpy as np

from air_hockey_agent.core.game.tactics.base import READY, Context, Proposal, Tactic, reach_proposal


def guard_point(puck: np.ndarray, gap: float, ctx: Context) -> np.ndarray | None:
    """Where the mallet waits for a puck at ``puck`` (x, y [m], own frame) behind the ready line: on the line
    from the own goal's centre to the puck, ``gap`` [m] short of the puck. None when this point lies outside
    the arm's region (behind its back edge, 0.07 m deep, for a puck that deep): a mallet nearer the goal line
    than the puck can only push it goal-ward, and one pulled into the region beside such a puck sat in its
    way along the end rim and turned it into the goal (:class:`Ready` then keeps the mallet clear of it)."""
    puck = np.asarray(puck[:2], float)
    rel = puck - np.array([ctx.settings.x_at_depth(0.0), 0.0])
    distance = float(np.hypot(*rel))
    if distance <= 0.0:
        return None
    point = puck - gap * rel / distance
    return point if ctx.reach.region.contains(point) else None


def clear_of(point: np.ndarray, path: np.ndarray, gap: float, x_max: float) -> np.ndarray:
    """``point`` [m], moved away from the own goal (+x, at most to ``x_max``) until every position of the
    puck's predicted ``path`` (n, 2) [m] nearer the goal than it lies ``gap`` [m] or more from it: a mallet
    waiting in front of a puck nearer the goal can only push it in."""
    x = float(point[0])
    for _ in range(len(path)):
        dy = path[:, 1] - point[1]
        near = (path[:, 0] < x) & (np.abs(dy) < gap)
        need = float(np.max(path[near, 0] + np.sqrt(gap ** 2 - dy[near] ** 2), initial=-np.inf))
        if need <= x + 1e-9:
            break
        x = need
    return np.array([min(x, x_max), point[1]])


class Ready(Tactic):
    tactic = READY

    def propose(self, situation, ctx: Context) -> Proposal | None:
        st = ctx.settings
        ready = st.point(st.ready_point)
        if situation is None or situation.puck[0] + st.table.length / 2 >= st.ready_guard_depth:
            return reach_proposal(READY, ready, ctx, "waiting at the ready point")
        puck, gap = situation.puck[:2], st.contact_distance + st.approach_clearance
        guard = guard_point(puck, gap, ctx) if situation.speed <= st.ready_guard_speed else None
        if guard is not None:
            return reach_proposal(READY, guard, ctx,
                                  f"guarding the goal from the puck at ({puck[0]:.2f}, {puck[1]:.2f})")
        path = situation.samples_until(np.inf)[1][:, :2]
        clear = clear_of(ready, path, gap, ctx.reach.region.x_max)
        return reach_proposal(READY, clear, ctx, "waiting at the ready point" if clear[0] == ready[0] else
                              f"waiting in front of the puck at ({puck[0]:.2f}, {puck[1]:.2f}), clear of it")
