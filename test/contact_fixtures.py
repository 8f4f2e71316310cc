"""Contacts made with a known law, as game-check and the online learner measure them (shared by the contact
tests): the puck's positions at the mocap's rate and the mallet's samples around one contact."""
from __future__ import annotations

import math

import numpy as np

from air_hockey_agent.core.game.contact_check import ContactGeometry, law_exit

RATE = 120.0  # [Hz] the mocap's
GEOMETRY = ContactGeometry(contact_distance=0.0798, puck_radius=0.03165, half_length=0.978, half_width=0.521,
                           restitution=0.8, friction=0.1)


def made_contact(t_contact: float, at: np.ndarray, v_in: np.ndarray, normal_angle: float, v_mallet: np.ndarray,
             e: float, mu: float, rng: np.random.Generator, noise: float = 0.0002, spin: float = 0.0,
             damping: float = 0.0, speeding_up: float = 0.0, mallet_rate: float = 500.0):
    """Positions of a puck (120 Hz, 0.2 s either side) meeting a mallet moving at ``v_mallet`` at ``t_contact``
    with the normal at ``normal_angle`` (mallet to puck), the puck leaving by the law with ``e``, ``mu``; the
    mallet's positions and velocities at ``mallet_rate`` [Hz]. The frames are not aligned with the contact's
    time. With ``spin`` [rad/s] the puck turns so before the contact (``contact_yaw``); with ``damping``
    [1/s] it slides under eq. 3.1's viscous term alone; with ``speeding_up`` [m/s^2] the mallet accelerates
    along its way until the contact and holds ``v_mallet`` from then on (a hit's approach ending at it)."""
    n = np.array([math.cos(normal_angle), math.sin(normal_angle)])
    mallet_at = at - n * GEOMETRY.contact_distance
    v_out = law_exit(np.array([*at, *v_in]), v_mallet, n, e, mu, GEOMETRY.puck_radius, spin)
    t = np.arange(t_contact - 0.2, t_contact + 0.2, 1.0 / RATE) + 0.3 / RATE
    ds = (t - t_contact)[:, None]
    slid = ds if damping == 0.0 else (1.0 - np.exp(-damping * ds)) / damping  # eq. 3.1's v e^{-d t}, integrated
    puck = np.where(ds < 0.0, at + slid * v_in, at + slid * v_out) + rng.normal(0.0, noise, (len(t), 2))
    tm = np.arange(t_contact - 0.25, t_contact + 0.25, 1.0 / mallet_rate) + 0.37 / mallet_rate
    tau = (tm - t_contact)[:, None]
    way, early = v_mallet / max(float(np.hypot(*v_mallet)), 1e-12), np.minimum(tau, 0.0)
    mallet = mallet_at + tau * v_mallet + way * speeding_up * early ** 2 / 2.0
    return t, puck, tm, mallet, v_mallet + way * speeding_up * early, v_out


def contact_yaw(t: np.ndarray, t_contact: float, spin: float) -> np.ndarray:
    """The puck's yaw [rad] wrapped to (-pi, pi], turning at ``spin`` before the contact and -spin after."""
    ds = t - t_contact
    return np.angle(np.exp(1j * (1.0 + np.where(ds < 0.0, spin * ds, -spin * ds))))
