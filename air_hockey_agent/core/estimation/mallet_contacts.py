"""The robots' mallets in the tracker (ROS-free): a puck the estimate carries into a mallet between two
frames is hit there, seen or not.

Without the mallets the filter learns of a hit only from the frames after it: it rejects them, then
restarts from them (:mod:`.ekf`), and when the mocap loses the puck over the hit (a dropout, or the arm
above the puck) the estimate goes on as if nothing had happened until frames come back: a puck smashed
unseen stays at rest in the estimate, and both robots' tactics act on that (README "Tactics and the game":
the traced goals of a shot that crossed unseen). The mallets' positions are known without the mocap,
from the robots' joint states (forward kinematics, table frame), so the tracker can apply the contact the
moment the estimate meets a mallet: seed 004's mallet-contact mode with the mallet's state known.

* each mallet: its last position and velocity (from the joint velocities, or else by finite difference
  from the sample before; :class:`MalletTracks`), extrapolated in a straight line; a sample older than
  ``max_age`` is not used.
* the first contact within a frame (:func:`first_contact`): puck and mallet each in a straight line over
  the frame, their centres at the sum of the radii and closing.
* the contact (:func:`apply_contact`): the law the tactics aim with
  (:func:`~air_hockey_agent.core.puck.mallet_impact.puck_after_contact`: the mallet a moving wall, Routh's
  impact with ``restitution`` and ``friction``); the covariance through the contact's velocity Jacobian
  (the frictionless law's, ``I - (1 + e) n n^T``) plus ``velocity_noise`` of the velocity and spin change
  as std: the contact time, the mallet's finite-difference velocity and the law are all approximate.

The earlier stack (REFERENCE_FACTS 1.3, "S: mallet collision") used the opponent's mallet alone, ignored the
mallet's motion in the time of impact and left the covariance as it was.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np

from air_hockey_agent.core.puck.mallet_impact import puck_after_contact


@dataclass(frozen=True)
class MalletContactSettings:
    """``mallet_contact.*`` in config/tracker.yaml (sources there) and the mallet's radius [m]."""

    enabled: bool = False
    radius: float = 0.04815          # [m] mallet radius (config/table.yaml)
    restitution: float = 0.8         # [-] normal restitution of the contact
    friction: float = 0.1            # [-] Coulomb friction between the mallet's and the puck's edges
    velocity_noise: float = 0.3      # [-] std of the velocity and spin after, as a fraction of their change
    max_age: float = 0.05            # [s] a mallet sample older than this is not used
    coast_after: float = 0.025       # [s] with no frame for this long the tracker coasts (PuckEKF.coast)

    @classmethod
    def from_params(cls, params: Mapping[str, Any]) -> "MalletContactSettings":
        return cls(enabled=bool(params["mallet_contact.enabled"]), radius=float(params["mallet.radius"]),
                   restitution=float(params["mallet_contact.restitution"]),
                   friction=float(params["mallet_contact.friction"]),
                   velocity_noise=float(params["mallet_contact.velocity_noise"]),
                   max_age=float(params["mallet_contact.max_age"]),
                   coast_after=float(params["mallet_contact.coast_after"]))


class MalletTracks:
    """Each named mallet's last sample: time [s], position and velocity [m, m/s], table frame."""

    def __init__(self, max_age: float) -> None:
        self.max_age = max_age
        self._last: dict[str, tuple[float, np.ndarray, np.ndarray]] = {}

    def observe(self, name: str, t: float, position: Sequence[float],
                velocity: Sequence[float] | None = None) -> None:
        """Mallet ``name``'s centre (x, y) [m] at ``t`` [s] and its ``velocity`` [m/s] (from the joint
        velocities); without one (a joint state without velocities), the difference from the sample before
        when that one is at most ``max_age`` older (else 0: a first sample, or after a pause). A sample older
        than the last one is ignored unless time jumped back (a simulation restart)."""
        p = np.array(position[:2], float)
        v = None if velocity is None else np.array(velocity[:2], float)
        if not np.all(np.isfinite(p)) or (v is not None and not np.all(np.isfinite(v))):
            return
        last = self._last.get(name)
        if last is not None and -self.max_age < t - last[0] <= 0.0:
            return
        if v is None:
            dt = np.inf if last is None else t - last[0]
            v = (p - last[1]) / dt if 0.0 < dt <= self.max_age else np.zeros(2)
        self._last[name] = (t, p, v)

    def at(self, t: float) -> list[tuple[str, np.ndarray, np.ndarray]]:
        """(name, position, velocity) of each mallet at ``t`` [s], extrapolated from its last sample, when
        that sample is at most ``max_age`` from ``t``."""
        out = []
        for name, (ts, p, v) in self._last.items():
            if abs(t - ts) <= self.max_age:
                out.append((name, p + v * (t - ts), v))
        return out

    def forget(self) -> None:
        self._last.clear()


def first_contact(puck_position: np.ndarray, puck_velocity: np.ndarray, mallet_position: np.ndarray,
                  mallet_velocity: np.ndarray, distance: float, horizon: float) -> float | None:
    """Time [s] from now, within [0, ``horizon``], at which puck and mallet (each in a straight line) first
    have their centres ``distance`` [m] apart while closing; None if they do not. Overlapping now and
    closing: 0 (the contact began within the frame before)."""
    d = np.asarray(puck_position, float) - mallet_position
    w = np.asarray(puck_velocity, float) - mallet_velocity
    closing = float(d @ w)
    c = float(d @ d) - distance * distance
    if c <= 0.0:
        return 0.0 if closing < 0.0 else None
    a = float(w @ w)
    if closing >= 0.0 or a == 0.0:
        return None
    disc = closing * closing - a * c
    if disc < 0.0:
        return None
    s = (-closing - math.sqrt(disc)) / a
    return s if s <= horizon else None


def apply_contact(x: np.ndarray, p: np.ndarray, mallet_position: np.ndarray, mallet_velocity: np.ndarray,
                  settings: MalletContactSettings, puck_radius: float) -> tuple[np.ndarray, np.ndarray]:
    """State (x, y, vx, vy, theta, omega) and covariance right after the puck in ``x`` meets the mallet at
    ``mallet_position`` moving at ``mallet_velocity`` (module docstring)."""
    offset = x[:2] - mallet_position
    n = offset / max(float(np.hypot(*offset)), 1e-9)
    after = puck_after_contact(x, mallet_velocity, n, settings.restitution, settings.friction, puck_radius)
    jacobian = np.eye(6)
    jacobian[2:4, 2:4] -= (1.0 + settings.restitution) * np.outer(n, n)
    cov = jacobian @ p @ jacobian.T
    dv = float(np.hypot(*(after[2:4] - x[2:4])))
    dw = abs(float(after[5] - x[5]))
    k = settings.velocity_noise
    cov[2, 2] += (k * dv) ** 2
    cov[3, 3] += (k * dv) ** 2
    cov[5, 5] += (k * dw) ** 2
    return after, 0.5 * (cov + cov.T)
