"""The model's step-by-step prediction of the mean, compiled: rim impacts, goal mouths, line crossings, samples.

:func:`.prediction.predict_fast` without a covariance (the tactics' shot and contact predictions, the offline
evaluation, system identification) needs only the mean, the rim impacts, the line crossings and the samples.
In Python the closed-form jumps cost about 40 us per rim impact and the objects around them, so a shot's
prediction took about half a millisecond and a Cut ranking up to 100 ms (issue #13's "left open"). Here the
model's own step (:meth:`.model.PuckModel.step` without the Jacobian: fly to each rim contact, Routh's impact
with the speed-dependent restitution and the tangential restitution (:func:`.impact.rim_impact`), fly on, then
the decay of eq. 3.1 with the table acceleration) runs step after step in compiled code, in the same order of
arithmetic, and the crossings and samples are taken as :class:`.prediction._Recorder` takes them. SI units, the
table frame (:mod:`air_hockey_agent.core.table`). ``test_prediction.py`` checks it against
:func:`.prediction.predict_stepwise` to 1e-10.

The angle is wrapped to (-pi, pi] by the nearest multiple of 2 pi (numba has no ``math.remainder``): equal to
:func:`.model.wrap_angle` up to rounding.

``cache=True`` keeps the machine code under the package's ``__pycache__`` (or numba's user cache); numba is
imported by the first mean-only prediction of a process, or by :func:`warm_up`.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

# rows of the parameter vector (:func:`kernel_params`)
(P_RESTITUTION, P_FRICTION_RIM, P_SLOPE, P_FLOOR, P_KNEE, P_TANGENTIAL, P_DAMPING, P_FRICTION_SURFACE, P_GX, P_GY,
 P_X_LIMIT, P_Y_LIMIT, P_MOUTH, P_RADIUS) = range(14)
IMPACT_COLUMNS = 5    # time [s], rim, x, y [m], sliding (0/1)
CROSSING_COLUMNS = 5  # crossed (0/1), time [s], y [m], vx, vy [m/s]
SAMPLE_COLUMNS = 7    # time [s], state (6)
MAX_IMPACTS_PER_STEP = 4  # as model.MAX_IMPACTS_PER_STEP
GLIDE_MARGIN = 1e-9  # [m] a step ending closer than this to its ray's rim contact is taken as the model takes it
IMPACT_ROWS = 8  # impacts room to start with (doubled when full): a prediction's impacts are a few
TWO_PI = 2.0 * math.pi
# rims in the order of core/table.py's WALL_NORMALS: inward normal (nx, ny), short (goal-line) rim or not
NORMAL_X = (0.0, -1.0, 0.0, 1.0)
NORMAL_Y = (1.0, 0.0, -1.0, 0.0)


def kernel_params(model) -> np.ndarray:
    """The parameter vector of a :class:`.model.PuckModel` (rows ``P_*``)."""
    p, table = model.params, model.table
    return np.array([p.restitution, p.friction_rim, p.restitution_slope, p.restitution_min, p.restitution_knee,
                     p.tangential_restitution, p.damping, p.friction_surface, float(p.table_acceleration[0]),
                     float(p.table_acceleration[1]), table.x_limit, table.y_limit, table.goal_mouth,
                     table.puck_radius])


@njit(cache=True)
def _wrap(angle: float) -> float:
    if -math.pi < angle <= math.pi:
        return angle
    wrapped = angle - TWO_PI * np.rint(angle / TWO_PI)
    if wrapped <= -math.pi:
        return wrapped + TWO_PI
    if wrapped > math.pi:
        return wrapped - TWO_PI
    return wrapped


@njit(cache=True)
def _first_impact(p: np.ndarray, x: float, y: float, vx: float, vy: float, horizon: float) -> tuple[float, int]:
    """Earliest rim contact of straight flight within ``horizon`` [s]: (time, rim), rim -1 for none
    (:meth:`.model.PuckModel.first_impact`)."""
    best_tau, best_wall = 0.0, -1
    for wall in range(4):
        nx, ny = NORMAL_X[wall], NORMAL_Y[wall]
        vn = nx * vx + ny * vy
        if vn >= 0.0:
            continue
        short = wall == 1 or wall == 3
        distance = nx * x + ny * y + (p[P_X_LIMIT] if short else p[P_Y_LIMIT])
        if short and distance < 0.0:
            continue  # in a goal
        tau = 0.0 if distance <= 0.0 else distance / -vn
        if tau > horizon or (best_wall >= 0 and tau >= best_tau):
            continue
        if short and abs(y + tau * vy) < p[P_MOUTH]:
            continue
        best_tau, best_wall = tau, wall
    return best_tau, best_wall


@njit(cache=True)
def _rim_impact(p: np.ndarray, vb: float, vn: float, omega: float) -> tuple[float, float, float, bool]:
    """Post-impact (vb, vn, omega) and whether the impact slid (:func:`.impact.rim_impact`)."""
    e0, slope = p[P_RESTITUTION], p[P_SLOPE]
    e = e0 - slope * (abs(vn) - p[P_KNEE])
    if slope == 0.0 or e >= e0:
        e = e0
    elif e <= p[P_FLOOR]:
        e = min(p[P_FLOOR], e0)
    r, mu, beta = p[P_RADIUS], p[P_FRICTION_RIM], p[P_TANGENTIAL]
    slip = vb + r * omega
    if (1.0 + beta) * abs(slip) > 3.0 * mu * (1.0 + e) * abs(vn):
        s = 1.0 if slip > 0.0 else -1.0
        k = mu * s * (1.0 + e)
        return vb + k * vn, -e * vn, omega + 2.0 * k * vn / r, True
    q = (1.0 + beta) / 3.0
    return vb - q * slip, -e * vn, omega - 2.0 * q * slip / r, False


@njit(cache=True)
def _decay(p: np.ndarray, vx: float, vy: float, dt: float) -> tuple[float, float]:
    """Velocity after the table acceleration and the friction/damping of a step (:meth:`.model.PuckModel.decay`)."""
    gx, gy = p[P_GX], p[P_GY]
    if gx != 0.0 or gy != 0.0:
        vx, vy = vx + dt * gx, vy + dt * gy
    a = 1.0 - dt * p[P_DAMPING]
    mu_dt = dt * p[P_FRICTION_SURFACE]
    speed = math.hypot(vx, vy)
    if mu_dt == 0.0:
        return a * vx, a * vy
    new_speed = a * speed - mu_dt
    if speed == 0.0 or new_speed <= 0.0:
        return 0.0, 0.0
    return vx / speed * new_speed, vy / speed * new_speed


@njit(cache=True)
def _step(p: np.ndarray, x: float, y: float, vx: float, vy: float, th: float, om: float, dt: float, t0: float,
          impacts: np.ndarray, count: int) -> tuple[float, float, float, float, float, float, int]:
    """One model step of the state (x, y, vx, vy, th, om) from time ``t0`` [s]
    (:meth:`.model.PuckModel.step`); its impacts are written to ``impacts`` from row ``count``. Returns the
    new state and impact count, or the count -1 when ``impacts`` is full (the caller grows it and retakes
    the step)."""
    h = dt
    tau, wall = _first_impact(p, x, y, vx, vy, dt)
    for _ in range(MAX_IMPACTS_PER_STEP):
        if wall < 0:
            break
        if count == impacts.shape[0]:
            return x, y, vx, vy, th, om, -1
        nx, ny = NORMAL_X[wall], NORMAL_Y[wall]
        bx, by = ny, -nx
        vb, vn, new_om, sliding = _rim_impact(p, bx * vx + by * vy, nx * vx + ny * vy, om)
        x, y, th, h = x + tau * vx, y + tau * vy, th + tau * om, h - tau
        vx, vy, om = bx * vb + nx * vn, by * vb + ny * vn, new_om
        impacts[count, 0], impacts[count, 1], impacts[count, 2] = t0 + (dt - h), wall, x
        impacts[count, 3], impacts[count, 4] = y, 1.0 if sliding else 0.0
        count += 1
        tau, wall = _first_impact(p, x, y, vx, vy, h)
    nvx, nvy = _decay(p, vx, vy, dt)
    return x + h * vx, y + h * vy, nvx, nvy, _wrap(th + h * om), om, count


@njit(cache=True)
def _room(p: np.ndarray, x: float, y: float, vx: float, vy: float) -> tuple[float, float, float, float]:
    """Direction (ux, uy), speed [m/s] and the distance [m] along the straight ray to its first rim contact
    (inf: none; the goal mouths as :func:`_first_impact`)."""
    speed = math.hypot(vx, vy)
    if speed == 0.0:
        return 0.0, 0.0, 0.0, math.inf
    ux, uy = vx / speed, vy / speed
    distance, wall = _first_impact(p, x, y, ux, uy, math.inf)
    return ux, uy, speed, (math.inf if wall < 0 else distance)


@njit(cache=True)
def _cross(crossings: np.ndarray, lines: np.ndarray, t0: float, dt: float, x0: float, y0: float, vx0: float,
           vy0: float, x1: float, y1: float) -> None:
    """First crossings of the lines x = ``lines`` inside one step from (x0, y0) with velocity (vx0, vy0) to
    (x1, y1), interpolated linearly (:meth:`.prediction._Recorder.step`)."""
    for i in range(lines.shape[0]):
        if crossings[i, 0] != 0.0:
            continue
        d0, d1 = x0 - lines[i], x1 - lines[i]
        if d0 == 0.0 or d0 * d1 < 0.0 or (d1 == 0.0 and d0 != 0.0):
            frac = 0.0 if d0 == 0.0 else d0 / (d0 - d1)
            crossings[i, 0], crossings[i, 1] = 1.0, t0 + frac * dt
            crossings[i, 2] = y0 + frac * (y1 - y0)
            crossings[i, 3], crossings[i, 4] = vx0, vy0


@njit(cache=True)
def _grown(rows: np.ndarray, count: int) -> np.ndarray:
    """``rows`` with twice the room, its first ``count`` rows kept."""
    grown = np.empty((2 * rows.shape[0], rows.shape[1]))
    grown[:count] = rows[:count]
    return grown


@njit(cache=True)
def predict_mean(p: np.ndarray, state: np.ndarray, steps: int, remainder: float, dt: float, lines: np.ndarray,
                 sample_every: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``steps`` model steps of ``dt`` [s] from ``state`` (6), then one of ``remainder`` [s] (none when 0).

    A step that cannot reach a rim on a flat table (the straight ray's first contact more than
    ``GLIDE_MARGIN`` beyond the step's travel) only moves and decays along the ray (:func:`_decay`'s speed
    recurrence; the direction is kept); every other step is :func:`_step`.

    Returns the final state (6), the impacts (rows: ``IMPACT_COLUMNS``), the crossings of ``lines`` (one row
    each: ``CROSSING_COLUMNS``) and the samples every ``sample_every`` steps (0: none; rows: ``SAMPLE_COLUMNS``).
    """
    x, y, vx, vy, th, om = state[0], state[1], state[2], state[3], state[4], state[5]
    flat = p[P_GX] == 0.0 and p[P_GY] == 0.0
    impacts = np.empty((IMPACT_ROWS, IMPACT_COLUMNS))
    crossings = np.zeros((lines.shape[0], CROSSING_COLUMNS))
    samples = np.empty((steps // sample_every if sample_every > 0 else 0, SAMPLE_COLUMNS))
    ux, uy, speed, room = _room(p, x, y, vx, vy)
    count = taken = 0
    for i in range(steps + 1):
        h = dt if i < steps else remainder
        if h == 0.0:
            break
        x0, y0, vx0, vy0 = x, y, vx, vy
        if flat and h * speed < room - GLIDE_MARGIN:
            x, y, room = x + h * vx, y + h * vy, room - h * speed
            keep, mu_h = 1.0 - h * p[P_DAMPING], h * p[P_FRICTION_SURFACE]
            if mu_h == 0.0:
                vx, vy, speed = keep * vx, keep * vy, keep * speed
            else:
                speed = keep * speed - mu_h
                if speed <= 0.0:
                    vx, vy, speed = 0.0, 0.0, 0.0
                else:
                    vx, vy = ux * speed, uy * speed
            th = _wrap(th + h * om)
        else:
            new = _step(p, x, y, vx, vy, th, om, h, i * dt, impacts, count)
            while new[6] < 0:
                impacts = _grown(impacts, count)
                new = _step(p, x, y, vx, vy, th, om, h, i * dt, impacts, count)
            x, y, vx, vy, th, om, count = new
            if flat:
                ux, uy, speed, room = _room(p, x, y, vx, vy)
        _cross(crossings, lines, i * dt, h, x0, y0, vx0, vy0, x, y)
        if sample_every > 0 and i < steps and (i + 1) % sample_every == 0:
            samples[taken, 0] = (i + 1) * dt
            samples[taken, 1], samples[taken, 2], samples[taken, 3] = x, y, vx
            samples[taken, 4], samples[taken, 5], samples[taken, 6] = vy, th, om
            taken += 1
    return np.array([x, y, vx, vy, th, om]), impacts[:count], crossings, samples


def warm_up() -> None:
    """Compile (or load from the cache) :func:`predict_mean` now, not in the first mean-only prediction."""
    p = np.array([0.9, 0.1, 0.1, 0.5, 0.5, 0.0, 0.1, 0.01, 0.0, 0.01, 0.9, 0.5, 0.1, 0.03])
    predict_mean(p, np.array([0.0, 0.0, 3.0, 2.0, 0.0, 1.0]), 2, 0.005, 0.01, np.array([0.0]), 1)
