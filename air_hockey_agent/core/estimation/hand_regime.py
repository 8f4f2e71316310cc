"""A hand (or a mallet) moving the puck: when the filter follows it with a hand's noise (issue #13).

The lab's recordings end with a human carrying the puck to the next start (thesis sec. 4.5.1 cuts "the
adjustment of the puck in the end for the next trajectory" out of them); the game's mallets push it
too. The model's flight law does not hold then: without a regime of its own a carry restarts the filter
every few frames and its frames pass for free flight's process noise. :class:`HandRegime` decides when
the filter (:class:`~air_hockey_agent.core.estimation.ekf.PuckEKF`) is in the *hand regime*, in which its
process noise gains a hand's white-noise acceleration (:meth:`HandSettings.noise`), its frames are
fused, and the process noise learns nothing from them. ROS-free; ``hand.*`` in config/tracker.yaml.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np


@dataclass(frozen=True)
class HandSettings:
    """A hand (or a mallet) moving the puck: ``hand.*`` in config/tracker.yaml (sources there).

    A restart from rejected frames starts the *hand regime* when it kept less than ``stop_fraction`` of
    the speed the model predicted and its frames fit a constant velocity (a hand took the puck; no rim
    returns so little), or when it came within ``window`` [s] of the restart before or of the regime's end
    (a hand moves the puck on): the model's flight law no longer holds, so the process noise gains a
    white-noise acceleration of ``acceleration`` [m/s^2] and ``spin_acceleration`` [rad/s^2] (per model
    step as a std; continuous density ``a^2 dt``) and the frames are fused rather than rejected; the
    process noise learns nothing from them (the table's learning goes on: its own gates refuse a hand's
    motion, and on a table far from the configured physics it is what ends the misfit).
    It ends when the velocity the updates added over ``calm_time`` [s] (the acceleration the model did
    not predict) has stayed below ``calm_acceleration`` [m/s^2] for ``calm_time``: the hand let go or holds
    it still (one calm window is not enough: a hand's acceleration passes zero halfway through a carry),
    or at a restart that sped the puck up by more than ``hit_speed`` [m/s]: a hit, after which the puck
    flies (such a restart starts none either). ``acceleration`` 0 turns it off."""

    acceleration: float = 0.0
    spin_acceleration: float = 0.0
    window: float = 0.5
    calm_time: float = 0.2
    calm_acceleration: float = 1.0
    stop_fraction: float = 0.0
    hit_speed: float = 0.0

    @classmethod
    def from_params(cls, params: Mapping[str, Any], prefix: str = "hand.") -> "HandSettings":
        return cls(**{name: float(params[prefix + name]) for name in cls.__dataclass_fields__})

    @property
    def enabled(self) -> bool:
        return self.acceleration > 0.0

    def noise(self, dt: float, nominal_dt: float) -> np.ndarray:
        """Process noise [6x6] of the hand over ``dt`` [s]: continuous white-noise acceleration of density
        a^2 ``nominal_dt`` on (x, vx), (y, vy) and (theta, omega)."""
        a, spin = self.acceleration, self.spin_acceleration
        return white_noise_acceleration((a * a * nominal_dt, a * a * nominal_dt, spin * spin * nominal_dt), dt)


def white_noise_acceleration(densities: tuple[float, float, float], dt: float) -> np.ndarray:
    """Process noise [6x6] over ``dt`` [s] of continuous white-noise accelerations of the spectral
    ``densities`` (on (x, vx), (y, vy), (theta, omega)): D (dt^3/3, dt^2/2, dt) per (value, rate) pair."""
    q = np.zeros((6, 6))
    for (pos, vel), density in zip(((0, 2), (1, 3), (4, 5)), densities):
        q[pos, pos] = density * dt ** 3 / 3.0
        q[pos, vel] = q[vel, pos] = density * dt * dt / 2.0
        q[vel, vel] = density * dt
    return q


@dataclass
class HandRegime:
    """Whether the hand regime holds (``active``), told of the filter's restarts (:meth:`after_restart`)
    and of the velocity its updates add while it holds (:meth:`watch`); :class:`HandSettings` says when it
    starts and ends. Times [s] are the frames' stamps."""

    settings: HandSettings
    active: bool = False
    _last_event: float | None = None      # [s] the last restart, or the regime's end
    _since: float = 0.0                   # [s] when it started
    _calm_since: float | None = None      # [s] since when its updates have been calm
    _corrections: list = field(default_factory=list)  # (t, dvx, dvy) of its updates within calm_time

    def after_restart(self, t: float, predicted_speed: float, fitted_speed: float, steady: bool) -> bool:
        """The filter restarted at ``t`` from a rejected run whose constant-velocity fit gave
        ``fitted_speed`` [m/s] where the model predicted ``predicted_speed``; ``steady``: the run fits a
        constant velocity. Starts the regime when the fit kept less than ``stop_fraction`` of the speed and
        is steady (a hand took the puck, where no rim returns so little; a fit across a mallet's reversal is
        slow too, but does not fit), or when the restart comes within ``window`` of the restart before or
        of the regime's end; one under way goes on. A restart that sped the puck up by more than
        ``hit_speed`` was a hit (a human's or a mallet's), after which the puck flies: it starts none and
        ends one. True when the regime started."""
        hand, previous, active = self.settings, self._last_event, self.active
        self._corrections.clear()  # the velocity the updates added before belongs to the track that ended
        hit = 0.0 < hand.hit_speed < fitted_speed - predicted_speed
        self._last_event, self.active = t, active and not hit
        stopped = steady and fitted_speed < hand.stop_fraction * predicted_speed
        soon = previous is not None and t - previous <= hand.window
        if active or hit or not hand.enabled or not (stopped or soon):
            return False
        self.active, self._since, self._calm_since = True, t, None
        return True

    def watch(self, t: float, dvx: float, dvy: float) -> None:
        """An update at ``t`` in the regime changed the velocity by (dvx, dvy) [m/s]: the regime ends once
        the updates of the last ``calm_time`` added less than ``calm_acceleration`` for ``calm_time`` (the
        model explains the motion again)."""
        hand, corrections = self.settings, self._corrections
        corrections.append((t, dvx, dvy))
        while corrections[0][0] <= t - hand.calm_time:
            corrections.pop(0)
        if t - self._since < hand.calm_time:
            return
        ax = sum(c[1] for c in corrections) / hand.calm_time
        ay = sum(c[2] for c in corrections) / hand.calm_time
        if math.hypot(ax, ay) >= hand.calm_acceleration:
            self._calm_since = None
        elif self._calm_since is None:
            self._calm_since = t
        elif t - self._calm_since >= hand.calm_time:
            self.active, self._last_event = False, t
            corrections.clear()
