"""Ranking contacts by where they leave the puck (ROS-free): shared by Prepare and Cut, which both want
the puck to stop inside the smash area.

A contact is scored by its worst case: aimed as planned and turned by the aim noise either way, three
predictions. Ranking every candidate that way cost a Cut about 0.12 s (180 candidates, 540 predictions;
a third of an in-process game's time), though the first one the checks accept is nearly always among the
best few. So candidates are ranked lazily (:class:`LazyRanked`): each is first predicted aimed only,
which bounds its worst case from above, and its two turned predictions are made only when it comes to
the top; the order is exactly that of scoring them all.
"""
from __future__ import annotations

import heapq
from typing import Callable, Iterable

import numpy as np

from air_hockey_agent.core.game.shots import Push
from air_hockey_agent.core.game.tactics.settings import TacticsSettings

TIE = 0.005  # [m] margins closer than this count as equal


def area_margin(st: TacticsSettings, point: np.ndarray) -> float:
    """Distance [m] of ``point`` (own frame) inside the smash area's box; negative outside."""
    depth = point[0] + st.table.length / 2
    half_width = st.table.y_limit - st.smash_rim_margin
    return min(depth - st.smash_depth[0], st.smash_depth[1] - depth, half_width - abs(point[1]))


def lazy_candidate(st: TacticsSettings, contact: Callable[[float], Push], rejected: Callable[[Push], bool],
                   score: Callable[[Push], float], key: Callable[[float], tuple], item: Callable[[Push], tuple],
                   risks: tuple[float, ...] = ()):
    """One contact as a :class:`LazyRanked` candidate, scored by its worst case: the smallest ``score`` over
    the contact aimed as planned (``contact(0)``) and turned by the aim noise either way, dropped when any
    of them is ``rejected``. The contact turned by each of ``risks`` [rad] (what else may turn it) is only
    checked: when one of those is ``rejected`` the candidate ranks below every one without such a risk
    (its score does not count: ranked by a worst case over those too, a Cut played too cautiously, strategy
    test 88 -> 79 %). Keys are (no risk rejected, *``key``(worst score)*). Returns (the key of the aimed
    contact's score, which bounds the worst case's when ``key`` does not decrease with the score;
    ``exact()``: (the key of the worst case, ``item`` of the aimed contact), or None), or None when the
    aimed contact is rejected: only it is predicted here, the turned ones when ``exact`` is called."""
    aimed = contact(0.0)
    if rejected(aimed):
        return None
    first = score(aimed)

    def exact() -> tuple[tuple, tuple] | None:
        scores = [first]
        for turn in (-st.aim_noise, st.aim_noise):
            push = contact(turn)
            if rejected(push):
                return None
            scores.append(score(push))
        safe = not any(rejected(contact(turn)) for turn in risks)
        return (safe, *key(min(scores))), item(aimed)
    return (True, *key(first)), exact


def margin_steps(st: TacticsSettings, push: Push) -> int:
    """The smash-area margin of where ``push`` leaves the puck, in TIE steps (rounding keeps the order of
    margins, so the aimed contact's bounds the worst case's)."""
    return round(area_margin(st, push.rest) / TIE)


class Ranked:
    """Ranked candidates (tuples); :meth:`first` returns the best that passes both checks, remembering the
    outcome of the ``lasting`` check (one that does not change while the prediction stays)."""

    def __init__(self, items: list[tuple]) -> None:
        self.items = items
        self._lasting: dict[int, bool] = {}

    def item(self, i: int) -> tuple | None:
        """The ``i``-th best candidate; None past the last."""
        return self.items[i] if i < len(self.items) else None

    def first(self, now_check, lasting_check) -> tuple | None:
        i = 0
        while (item := self.item(i)) is not None:
            if now_check(*item):
                if i not in self._lasting:
                    self._lasting[i] = lasting_check(*item)
                if self._lasting[i]:
                    return item
            i += 1
        return None


class LazyRanked(Ranked):
    """:class:`Ranked` built as far as :meth:`first` asks: ``candidates`` are (an upper bound of the key,
    ``exact()`` returning (the key, the item) or None to drop it), keys compared as tuples, best (largest)
    first; among equal keys the earlier candidate, as a stable sort of all exact keys would order them."""

    def __init__(self, candidates: Iterable[tuple[tuple, Callable[[], tuple[tuple, tuple] | None]]]) -> None:
        super().__init__([])
        self._heap = [(_negated(bound), i, None, exact) for i, (bound, exact) in enumerate(candidates)]
        heapq.heapify(self._heap)

    def item(self, i: int) -> tuple | None:
        while len(self.items) <= i and self._heap:
            key, index, item, exact = heapq.heappop(self._heap)
            if item is not None:
                self.items.append(item)  # an exact key not below any bound left: its place is final
                continue
            scored = exact()
            if scored is not None:
                heapq.heappush(self._heap, (_negated(scored[0]), index, scored[1], None))
        return super().item(i)


def _negated(key: tuple) -> tuple:
    return tuple(-v for v in key)
