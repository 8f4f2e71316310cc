"""The mallet's contact law learned online from the robot's own contacts (ROS-free).

The tactics aim every Cut, Prepare and Smash with :func:`~air_hockey_agent.core.puck.mallet_impact.puck_after_contact`,
whose restitution and friction (``mallet_restitution`` 0.8, ``mallet_friction`` 0.1 in ``config/agent.yaml``)
were never measured on a real mallet. Told 0.8 on a simulated table whose mallet returns 0.6, the Cut fell from
91 to 68 % (README "Tactics and the game"). The tracker learns the rims' law from its impacts; here the robot
learns its mallet's from its contacts, measured as `air-hockey game-check` measures them
(:mod:`~air_hockey_agent.core.game.contact_check`) on the last ``MEMORY`` seconds of the tracker's fused
estimates and the joint states: each new contact is kept (the newest ``contact_learning_max``), and from
``contact_learning_min`` on the two constants are fitted to them within their bounds.
"""
from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np

from air_hockey_agent.core.game.contact_check import (FIT_GUARD, FIT_WINDOW, Acceleration, ContactGeometry,
                                                      MeasuredContact, fit_law, measure_contacts)

MEMORY = 1.0          # [s] samples kept: a contact's windows (60 ms each side) with room for a slow one's
SEARCH_PERIOD = 0.1   # [s] the samples are searched for new contacts this often
SETTLED = FIT_GUARD + FIT_WINDOW + 0.02  # [s] a contact is measured once its after-window lies this far back


@dataclass(frozen=True)
class LearnedLaw:
    """A fit: restitution and friction [-], the contacts it used, the median error it leaves [m/s], and how many
    contacts were measured in all."""

    restitution: float
    friction: float
    contacts: int
    error_median: float
    seen: int


class ContactLearner:
    """Puck estimates (own frame: x, y [m], yaw [rad], fused frames only) and mallet samples (position [m],
    velocity [m/s], own frame) in; the mallet's law out, at most every ``SEARCH_PERIOD``."""

    def __init__(self, geometry: ContactGeometry, min_contacts: int, max_contacts: int,
                 restitution_bounds: tuple[float, float], friction_bounds: tuple[float, float]) -> None:
        self.geometry, self.min_contacts = geometry, min_contacts
        self.bounds = ((restitution_bounds[0], friction_bounds[0]), (restitution_bounds[1], friction_bounds[1]))
        self.contacts: deque[MeasuredContact] = deque(maxlen=max_contacts)
        self._puck: deque[tuple[float, float, float, float]] = deque()
        self._mallet: deque[tuple[float, float, float, float, float]] = deque()
        self._searched = -np.inf   # [s] when the samples were last searched
        self._last = -np.inf       # [s] the newest contact kept
        self.seen = 0              # contacts measured in all

    def puck(self, t: float, x: float, y: float, yaw: float) -> None:
        """A fused estimate at ``t`` [s] (a later one than the last)."""
        if self._puck and t <= self._puck[-1][0]:
            return
        self._puck.append((t, x, y, yaw))
        _forget(self._puck, t)

    def mallet(self, t: float, position: np.ndarray, velocity: np.ndarray) -> None:
        """The mallet at ``t`` [s] (a later time than the last)."""
        if self._mallet and t <= self._mallet[-1][0]:
            return
        self._mallet.append((t, float(position[0]), float(position[1]), float(velocity[0]), float(velocity[1])))
        _forget(self._mallet, t)

    def update(self, now: float, acceleration: Acceleration | None) -> LearnedLaw | None:
        """Search the samples for contacts settled since the last search (the puck's lines carried under the flight
        law ``acceleration``, own frame); the law fitted to the kept contacts when a new one came and there are at
        least ``min_contacts``, else None."""
        if now - self._searched < SEARCH_PERIOD or len(self._puck) < 2 or len(self._mallet) < 2:
            return None
        self._searched = now
        puck, mallet = np.array(self._puck), np.array(self._mallet)
        found = measure_contacts(puck[:, 0], puck[:, 1:3], mallet[:, 0], mallet[:, 1:3], mallet[:, 3:5],
                                 self.geometry, puck[:, 3], None if acceleration is None else lambda t: acceleration)
        new = [c for c in found if self._last + FIT_GUARD < c.time <= now - SETTLED]
        if not new:
            return None
        self.contacts.extend(new)
        self._last, self.seen = new[-1].time, self.seen + len(new)
        if len(self.contacts) < self.min_contacts:
            return None
        e, mu, left = fit_law(list(self.contacts), self.geometry.puck_radius, self.bounds)
        return LearnedLaw(e, mu, len(self.contacts), left, self.seen)


def contact_learner(st) -> ContactLearner:
    """The learner of a robot's tactics settings (:class:`~air_hockey_agent.core.game.tactics.settings.
    TacticsSettings`: table, contact distance, the configured law, ``contact_learning_*``)."""
    return ContactLearner(ContactGeometry.from_settings(st), st.contact_learning_min, st.contact_learning_max,
                          st.contact_restitution_bounds, st.contact_friction_bounds)


def _forget(samples: deque, now: float) -> None:
    while samples and samples[0][0] < now - MEMORY:
        samples.popleft()
