"""Where the mocap's rigid body has its pivot on the puck: the marker offset (``marker_offset``).

The mocap reports the pose of a rigid body defined by the puck's markers. The thesis's lab calibrates its
pivot to the disc's centre "with a precision of 1 mm" (sec. 4.5); a pivot ``o`` [m] off the centre, in
the puck's frame, is measured at ``p + R(theta) o``: a spinning puck's measured position circles its
centre, its measured velocity swings by ``omega |o|`` (10 mm/s at 10 rad/s and 1 mm), and its apparent
acceleration by ``omega^2 |o|``. The filter takes each measured position back to the centre with the
measured angle (its noise, 9.5 mrad, moves the correction by 1 % of ``|o|``).

The offset is learned online from free-flight windows, in one Gaussian with the flight law
(:class:`~air_hockey_agent.core.estimation.flight_adaptation.AccelerationAdaptation`): per window the
positions are a parabola in time per axis plus ``R(theta_i) o``; with each window's parabola projected
out, the windows' normal equations in ``o`` add up, and the parabola's acceleration depends on ``o`` by
:func:`offset_sensitivity`. A puck that does not turn gives nothing (its
``R(theta) o`` is a constant the parabola takes), a spinning one pins ``o`` down. ``sysid --method
split`` identifies it the same way (:func:`~air_hockey_agent.core.identification.split.identify_offset`), and
the evaluation compares a measured position with the pivot at the predicted angle
(:mod:`.evaluation`).
"""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np


def pivot_shift(theta: float, offset: Sequence[float]) -> tuple[float, float]:
    """``R(theta) o`` [m]: where the pivot ``offset`` (puck frame) sits from the centre at angle ``theta``."""
    ox, oy = offset
    cos, sin = math.cos(theta), math.sin(theta)
    return cos * ox - sin * oy, sin * ox + cos * oy


def centre_of(z: np.ndarray, offset: Sequence[float]) -> np.ndarray:
    """The measured pose ``z`` (x, y, theta) with its position taken from the pivot back to the centre."""
    dx, dy = pivot_shift(float(z[2]), offset)
    return np.array([z[0] - dx, z[1] - dy, z[2]])


def centres_of(poses: np.ndarray, offset: Sequence[float]) -> np.ndarray:
    """:func:`centre_of` of each measured pose (n, 3)."""
    poses = np.asarray(poses, float)
    cos, sin = np.cos(poses[:, 2]), np.sin(poses[:, 2])
    ox, oy = offset
    return np.column_stack([poses[:, 0] - cos * ox + sin * oy, poses[:, 1] - sin * ox - cos * oy, poses[:, 2]])


def _parabola_design(times: Sequence[float]) -> np.ndarray:
    """(n, 3) The columns 1, tau, tau^2 / 2 of a per-axis parabola, ``tau`` the times [s] about the window's
    middle."""
    tau = np.asarray(times, float) - 0.5 * (times[0] + times[-1])
    return np.column_stack([np.ones_like(tau), tau, 0.5 * tau * tau])


def offset_sensitivity(times: Sequence[float], thetas: Sequence[float]) -> np.ndarray:
    """``M`` (2, 2) [1/s^2]: a window's positions taken back to the centre by an offset o' (puck frame)
    while the pivot sits at o have their quadratic fit's acceleration (table frame) off by ``M (o - o')``,
    ``M = sum_i w_i R(theta_i)`` with ``w`` the fit's acceleration weights (the times about the window's
    middle, as :func:`~air_hockey_agent.core.estimation.flight_adaptation.quadratic_fit`). A puck turning
    slowly over the window circles its centre like an acceleration of ``omega^2 |o - o'|`` (0.2 m/s^2 at
    10 rad/s and 2 mm); one that does not turn gives 0 (its offset is a constant shift)."""
    x = _parabola_design(times)
    weights = np.linalg.solve(x.T @ x, x.T)[2]
    c, s = float(weights @ np.cos(thetas)), float(weights @ np.sin(thetas))
    return np.array([[c, -s], [s, c]])


def offset_normal_equations(times: Sequence[float], poses: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """One window's information on the offset: ``(N, b, residual_variance)`` with ``N o = b`` the least
    squares of the pivot positions ``poses`` (n, 3: x, y, theta) at ``times`` [s] against a parabola per
    axis plus ``R(theta) o`` (the parabolas projected out), unweighted; the residual variance [m^2] per
    coordinate of the joint fit."""
    poses = np.asarray(poses, float)
    x = _parabola_design(times)
    gram_inv = np.linalg.inv(x.T @ x)

    def project(v: np.ndarray) -> np.ndarray:  # what a parabola in tau cannot take of v (n, ...)
        return v - x @ (gram_inv @ (x.T @ v))

    cos, sin = np.cos(poses[:, 2]), np.sin(poses[:, 2])
    columns = (np.column_stack([cos, -sin]), np.column_stack([sin, cos]))  # d(x, y) / d(ox, oy)
    normal, rhs, residual = np.zeros((2, 2)), np.zeros(2), 0.0
    for axis, b in enumerate(columns):
        normal += b.T @ project(b)
        rhs += b.T @ project(poses[:, axis])
    offset = np.linalg.lstsq(normal, rhs, rcond=None)[0]
    for axis, b in enumerate(columns):
        r = project(poses[:, axis] - b @ offset)
        residual += float(r @ r)
    dof = max(1, 2 * len(x) - 8)
    return normal, rhs, residual / dof
