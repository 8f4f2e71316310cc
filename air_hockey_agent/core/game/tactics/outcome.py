"""Ranking contacts by where they leave the puck (ROS-free): shared by Prepare and Cut, which both want
the puck to stop inside the smash area."""
from __future__ import annotations

from typing import Callable

import numpy as np

from air_hockey_agent.core.game.shots import Push
from air_hockey_agent.core.game.tactics.settings import TacticsSettings

TIE = 0.005  # [m] margins closer than this count as equal


def area_margin(st: TacticsSettings, point: np.ndarray) -> float:
    """Distance [m] of ``point`` (own frame) inside the smash area's box; negative outside."""
    depth = point[0] + st.table.length / 2
    half_width = st.table.y_limit - st.smash_rim_margin
    return min(depth - st.smash_depth[0], st.smash_depth[1] - depth, half_width - abs(point[1]))


def worst_case(st: TacticsSettings, contact: Callable[[float], Push], rejected: Callable[[Push], bool],
               score: Callable[[Push], float]) -> tuple[float, Push] | None:
    """(the smallest ``score``, the aimed contact) over the contact aimed as planned (``contact(0)``) and
    turned by the aim noise either way; None when any of them is ``rejected``."""
    scores = []
    for turn in (0.0, -st.aim_noise, st.aim_noise):
        push = contact(turn)
        if rejected(push):
            return None
        scores.append(score(push))
        if turn == 0.0:
            aimed = push
    return min(scores), aimed


def worst_margin(st: TacticsSettings, contact: Callable[[float], Push],
                 rejected: Callable[[Push], bool]) -> tuple[int, Push] | None:
    """:func:`worst_case` of the smash-area margin, in TIE steps."""
    worst = worst_case(st, contact, rejected, lambda push: area_margin(st, push.rest))
    return None if worst is None else (round(worst[0] / TIE), worst[1])


class Ranked:
    """Ranked candidates (tuples); :meth:`first` returns the best that passes both checks, remembering the
    outcome of the ``lasting`` check (one that does not change while the prediction stays)."""

    def __init__(self, items: list[tuple]) -> None:
        self.items = items
        self._lasting: dict[int, bool] = {}

    def first(self, now_check, lasting_check) -> tuple | None:
        for i, item in enumerate(self.items):
            if not now_check(*item):
                continue
            if i not in self._lasting:
                self._lasting[i] = lasting_check(*item)
            if self._lasting[i]:
                return item
        return None
