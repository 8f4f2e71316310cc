"""Mallet-puck contacts in the simulated world, as events (ROS-free).

pybullet reports contact points per physics step; :class:`ContactLog` turns the per-step "touching or
not" of each robot's mallet into one :class:`MalletContact` per contact: when it began, where the puck
was then, and the puck's velocity when it ended (the speed the hit gave it). A contact that pauses for
fewer than ``merge_steps`` steps is the same contact (a mallet pushing a puck touches it on and off).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

# the true puck state's flags saying whose mallet is in a contact (air_hockey_msgs/PuckState.FLAG_TOUCHED_*)
TOUCHED_FLAGS = {"iiwa_front": 16, "iiwa_back": 32}


@dataclass(frozen=True)
class MalletContact:
    """One contact: robot, start time [s], duration [s], puck (x, y) at the start and (vx, vy) at the end
    [m, m/s], table frame."""

    robot: str
    time: float
    duration: float
    x: float
    y: float
    vx: float
    vy: float

    @property
    def speed(self) -> float:
        return math.hypot(self.vx, self.vy)


@dataclass
class _Open:
    start: float
    x: float
    y: float
    last: float          # [s] last step in contact
    apart: int = 0       # steps since then


class ContactLog:
    """Per-robot contact state; :meth:`step` returns the contacts that ended at this step."""

    def __init__(self, merge_steps: int = 5) -> None:
        self.merge_steps = merge_steps
        self._open: dict[str, _Open] = {}

    def step(self, t: float, touching: dict[str, bool], puck: Sequence[float]) -> list[MalletContact]:
        """``touching``: robot -> mallet touches the puck after the step at time ``t``; ``puck``: the
        puck state (x, y, vx, vy, ...) after the step."""
        ended = []
        for robot, touch in touching.items():
            contact = self._open.get(robot)
            if touch:
                if contact is None:
                    self._open[robot] = _Open(t, float(puck[0]), float(puck[1]), t)
                else:
                    contact.last, contact.apart = t, 0
            elif contact is not None:
                contact.apart += 1
                if contact.apart >= self.merge_steps:
                    del self._open[robot]
                    ended.append(MalletContact(robot, contact.start, contact.last - contact.start, contact.x,
                                               contact.y, float(puck[2]), float(puck[3])))
        return ended

    def open_robots(self) -> tuple[str, ...]:
        """The robots with a contact begun and not yet ended."""
        return tuple(self._open)

    def reset(self) -> None:
        """Forget open contacts (the puck was moved by hand)."""
        self._open.clear()
