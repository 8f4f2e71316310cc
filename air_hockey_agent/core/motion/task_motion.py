"""Task-space motions of the mallet in the table plane, sampled on a uniform time grid.

Each function returns ``(positions (n, 2) [m], velocities (n, 2) [m/s])`` at the times
``dt, 2 dt, ..., n dt`` after the motion's start (the start itself is the previous motion's end).
Frames: the robot's own table frame. Time laws (REFERENCE_FACTS 3.1, the ROS 1 stack's hit):

* strike: from rest to speed v along a straight run-up of length l, s(t) = a3 t^3 + a4 t^4 with
  a3 = v^3 / (4 l^2), a4 = -v^4 / (16 l^3): duration 2 l / v, zero acceleration at both ends;
* stop: from speed v to rest over length l, s(t) = v t - v t^3 / T^2 + v t^4 / (2 T^3), T = 2 l / v:
  the strike's mirror image, zero acceleration at the hit, so the two join smoothly;
* hermite: a cubic in time between two (position, velocity) pairs (reach-and-stop, direct hits).
"""
from __future__ import annotations

import math

import numpy as np


def steps_for(duration: float, dt: float) -> int:
    """Number of grid steps that covers ``duration`` [s] (at least one)."""
    return max(1, int(math.ceil(duration / dt - 1e-9)))


def run_up_start(hit: np.ndarray, direction: np.ndarray, speed: float, steps: int, dt: float) -> np.ndarray:
    """Where the run-up of :func:`strike` begins [m]: ``speed * steps * dt / 2`` (its length at the mean
    speed v/2) behind ``hit`` along unit ``direction``."""
    return hit - speed * steps * dt / 2 * direction


def strike(hit: np.ndarray, direction: np.ndarray, speed: float, steps: int, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Run-up from rest to ``hit`` with ``speed`` [m/s] along unit ``direction``, over ``steps`` grid steps,
    from :func:`run_up_start`; the last sample is the hit."""
    length = speed * steps * dt / 2
    t = np.arange(1, steps + 1) * dt
    a3, a4 = speed ** 3 / (4 * length ** 2), -speed ** 4 / (16 * length ** 3)
    s = a3 * t ** 3 + a4 * t ** 4
    ds = 3 * a3 * t ** 2 + 4 * a4 * t ** 3
    return run_up_start(hit, direction, speed, steps, dt) + s[:, None] * direction, ds[:, None] * direction


def straight_length(room: float, speed: float, lengths: tuple[float, float], longest_time: float) -> float:
    """Length [m] of the straight run-up before, or the stop after, a hit at ``speed`` [m/s] with ``room`` [m]
    behind the hit point (or ahead of it): the longest that fits, at most ``lengths[1]``, and at most what
    the mallet covers in ``longest_time`` [s] at its mean speed v/2 (a slow push gets a short run-up and a
    short stop instead of a long crawl), but never below ``lengths[0]`` (the planner refuses when even that
    does not fit)."""
    return min(room, lengths[1], max(lengths[0], 0.5 * speed * longest_time))


def stop_length(room: float, speed: float, lengths: tuple[float, float], longest_time: float,
                deceleration: float) -> float:
    """Length [m] of the stop after a hit at ``speed`` [m/s] with ``room`` [m] ahead of the hit point: the one
    lasting ``longest_time`` [s] (v T / 2), or, with a ``deceleration`` [m/s^2] (0: none), the one whose peak
    deceleration along the stop's law (:func:`stop_fraction`: 3 v^2 / (4 L)) is that if it is shorter; at
    most ``lengths[1]`` and the room, never below ``lengths[0]`` (the planner refuses when even that does not
    fit). Braking at 5 m/s^2 a slow push stops within millimetres, so a puck it sends along a rim or off a
    near one clears the mallet."""
    timed = straight_length(room, speed, lengths, longest_time)
    return timed if deceleration <= 0.0 else min(timed, max(lengths[0], 0.75 * speed ** 2 / deceleration))


def stop_fraction(u):
    """Fraction of the stopping distance covered at the fraction ``u`` in [0, 1] of the stop's duration
    (quartic: speed 2 L / T at u = 0, zero speed and acceleration at u = 1)."""
    return 2.0 * u - 2.0 * u ** 3 + u ** 4


def stop(hit: np.ndarray, direction: np.ndarray, speed: float, steps: int, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """From ``hit`` at ``speed`` along unit ``direction`` to rest over ``steps`` grid steps, along a
    straight line of length ``speed * steps * dt / 2``."""
    duration = steps * dt
    t = np.arange(1, steps + 1) * dt
    s = 0.5 * speed * duration * stop_fraction(t / duration)
    ds = speed - 3 * speed * t ** 2 / duration ** 2 + 2 * speed * t ** 3 / duration ** 3
    return hit + s[:, None] * direction, ds[:, None] * direction


def hermite(p0: np.ndarray, v0: np.ndarray, p1: np.ndarray, v1: np.ndarray, steps: int,
            dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Cubic in time from (``p0``, ``v0``) to (``p1``, ``v1``) over ``steps`` grid steps."""
    return hermite_at(p0, v0, p1, v1, steps * dt, np.arange(1, steps + 1) * dt)


def hermite_at(p0: np.ndarray, v0: np.ndarray, p1: np.ndarray, v1: np.ndarray, duration: float,
               t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The cubic in time from (``p0``, ``v0``) to (``p1``, ``v1``) over ``duration`` [s]: positions and
    velocities (n, 2) at times ``t`` (n,) [s] from its start, within [0, duration]."""
    s = (np.asarray(t, float) / duration)[:, None]
    h00, h10, h01, h11 = 2 * s ** 3 - 3 * s ** 2 + 1, s ** 3 - 2 * s ** 2 + s, -2 * s ** 3 + 3 * s ** 2, s ** 3 - s ** 2
    d00, d10, d01, d11 = 6 * s ** 2 - 6 * s, 3 * s ** 2 - 4 * s + 1, -6 * s ** 2 + 6 * s, 3 * s ** 2 - 2 * s
    pos = h00 * p0 + h10 * duration * v0 + h01 * p1 + h11 * duration * v1
    vel = (d00 * p0 + d10 * duration * v0 + d01 * p1 + d11 * duration * v1) / duration
    return pos, vel


def hermite_peak_acceleration(p0: np.ndarray, v0: np.ndarray, p1: np.ndarray, v1: np.ndarray,
                              duration: float) -> float:
    """Largest |acceleration| [m/s^2] of the cubic (it is linear in time, so at an end)."""
    a0 = (6 * (p1 - p0) - 4 * v0 * duration - 2 * v1 * duration) / duration ** 2
    a1 = (-6 * (p1 - p0) + 2 * v0 * duration + 4 * v1 * duration) / duration ** 2
    return float(max(np.linalg.norm(a0), np.linalg.norm(a1)))


def shortest_hermite_duration(p0: np.ndarray, v0: np.ndarray, p1: np.ndarray, acceleration: float,
                              dt: float) -> float:
    """A short duration [s] (a multiple of ``dt``) of the cubic from (p0, v0) to (p1, rest) whose
    acceleration stays within ``acceleration`` [m/s^2]: from the rest-to-rest value sqrt(6 d / a) plus
    the time to brake v0, shortened in 10 % steps while the bound holds (grown while it does not)."""
    zero = np.zeros(2)
    distance, speed = float(np.linalg.norm(p1 - p0)), float(np.linalg.norm(v0))
    duration = max(dt, math.sqrt(6 * distance / acceleration) + 2 * speed / acceleration)
    while hermite_peak_acceleration(p0, v0, p1, zero, duration) > acceleration and duration < 30.0:
        duration *= 1.1
    while duration * 0.9 >= dt and hermite_peak_acceleration(p0, v0, p1, zero, duration * 0.9) <= acceleration:
        duration *= 0.9
    return steps_for(duration, dt) * dt
