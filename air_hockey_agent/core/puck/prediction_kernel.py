"""The model's step-by-step prediction, compiled: mean and covariance, rim impacts, goal mouths, crossings, samples.

:func:`.prediction.predict_fast` runs here. The model's own step (:meth:`.model.PuckModel.step`: fly to each rim
or post contact, Routh's impact with the speed-dependent restitution and the tangential restitution
(:func:`.impact.rim_impact`), fly on, then the decay of eq. 3.1 with the table acceleration, and the spin's
decay) runs step after step in compiled code in the same order of arithmetic, with its exact Jacobian ``F``
(the 7x7 event Jacobians over the state and the remaining time, as :func:`.model.event_jacobian`)
and ``P <- F P F^T + Q`` (thesis sec. 4.2), the impact covariance (:func:`.prediction.impact_covariance`) after
a step with a rim impact; the crossings and samples are taken as :class:`.prediction._Recorder` takes them. A
step that cannot reach a rim on a flat table (its straight ray's first contact more than ``GLIDE_MARGIN``
beyond the step's travel) skips the contact search and only moves and decays along the ray. SI units, the table frame
(:mod:`air_hockey_agent.core.table`). ``test_prediction.py`` checks it against the Python steps
(:func:`.prediction.predict_stepwise`): the means to 1e-10, the covariances to 1e-9 relative.

In Python the same prediction took about a millisecond (1.5 s at 120 Hz), the closed-form jumps that replaced
it 130 us with a covariance (and 1.3 ms with samples every 50 ms, as the agents' predictions take them) and
about 40 us per rim impact without. The angle is wrapped to (-pi, pi] by the nearest multiple of 2 pi (numba
has no ``math.remainder``): equal to :func:`.model.wrap_angle` up to rounding.

``cache=True`` keeps the machine code under the package's ``__pycache__`` (or numba's user cache); numba is
imported by the first prediction of a process, or by :func:`warm_up`.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from air_hockey_agent.core.table import (FIRST_POST, POST_COUNT, SHORT_WALLS, WALL_NORMALS, contact_rim,
                                         post_contact_time, post_position)

# rows of the parameter vector (:func:`kernel_params`)
(P_RESTITUTION, P_FRICTION_RIM, P_SLOPE, P_FLOOR, P_KNEE, P_TANGENTIAL, P_DAMPING, P_FRICTION_SURFACE, P_GX, P_GY,
 P_X_LIMIT, P_Y_LIMIT, P_MOUTH, P_RADIUS, P_SPIN_DAMPING, P_IMPACT_DELAY) = range(16)
IMPACT_COLUMNS = 5    # time [s], rim, x, y [m], sliding (0/1)
CROSSING_COLUMNS = 5  # crossed (0/1), time [s], y [m], vx, vy [m/s]
SAMPLE_COLUMNS = 7    # time [s], state (6)
MAX_IMPACTS_PER_STEP = 4  # as model.MAX_IMPACTS_PER_STEP
GLIDE_MARGIN = 1e-9  # [m] a step ending closer than this to its ray's rim contact is taken as the model takes it
IMPACT_ROWS = 8  # impacts room to start with (doubled when full): a prediction's impacts are a few
TWO_PI = 2.0 * math.pi
NORMAL_X = tuple(n[0] for n in WALL_NORMALS)  # the rims' inward normals, by rim id (core/table.py)
NORMAL_Y = tuple(n[1] for n in WALL_NORMALS)
SHORT_A, SHORT_B = SHORT_WALLS  # the goal-line rims
# the table's own post geometry (core/table.py), compiled
_post_contact_time = njit(cache=True)(post_contact_time)
_post_position = njit(cache=True)(post_position)
_contact_rim = njit(cache=True)(contact_rim)


def kernel_params(model) -> np.ndarray:
    """The parameter vector of a :class:`.model.PuckModel` (rows ``P_*``)."""
    p, table = model.params, model.table
    return np.array([p.restitution, p.friction_rim, p.restitution_slope, p.restitution_min, p.restitution_knee,
                     p.tangential_restitution, p.damping, p.friction_surface, float(p.table_acceleration[0]),
                     float(p.table_acceleration[1]), table.x_limit, table.y_limit, table.goal_mouth,
                     table.puck_radius, p.spin_damping, p.impact_delay])


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
def _first_impact(p: np.ndarray, x: float, y: float, vx: float, vy: float, horizon: float,
                  delay: float) -> tuple[float, int]:
    """Earliest impact of straight flight within ``horizon`` [s], ``delay`` [s] after the touch: (time,
    contact), contact -1 for none, a rim's id or a post's (:meth:`.model.PuckModel.first_impact`)."""
    best_tau, best_wall = 0.0, -1
    for wall in range(4):
        nx, ny = NORMAL_X[wall], NORMAL_Y[wall]
        vn = nx * vx + ny * vy
        short = wall == SHORT_A or wall == SHORT_B
        if vn >= 0.0 and not short:
            continue
        distance = nx * x + ny * y + (p[P_X_LIMIT] if short else p[P_Y_LIMIT])
        if short:
            tau, contact = _short_rim_contact(p, wall, x, y, vx, vy, vn, distance, horizon, delay)
        else:
            tau, contact = max(0.0, distance / -vn + delay), wall
        if contact >= 0 and tau <= horizon and (best_wall < 0 or tau < best_tau):
            best_tau, best_wall = tau, contact
    return best_tau, best_wall


@njit(cache=True)
def _short_rim_contact(p: np.ndarray, wall: int, x: float, y: float, vx: float, vy: float, vn: float,
                       distance: float, horizon: float, delay: float) -> tuple[float, int]:
    """First impact on short rim ``wall``: (time, contact), contact -1 for none
    (:meth:`.model.PuckModel._short_rim_contact`)."""
    radius = p[P_RADIUS]
    if vn < 0.0:
        touch = distance / -vn
        if touch > horizon:
            return 0.0, -1
        if touch + delay >= 0.0 and abs(y + touch * vy) >= p[P_MOUTH] + radius:
            return max(0.0, touch + delay), wall
    elif distance >= 0.0:
        return 0.0, -1
    best_tau, best = 0.0, -1
    for contact in range(FIRST_POST, FIRST_POST + POST_COUNT):
        if _contact_rim(contact) != wall:
            continue
        px, py = _post_position(contact, p[P_X_LIMIT] + radius, p[P_MOUTH] + radius)
        tau = _post_contact_time(x, y, vx, vy, px, py, radius)
        if tau != math.inf and (best < 0 or tau < best_tau):
            best_tau, best = tau, contact
    return (max(0.0, best_tau + delay), best) if best >= 0 else (0.0, -1)


@njit(cache=True)
def _contact_normal(p: np.ndarray, contact: int, xc: float, yc: float) -> tuple[float, float, float]:
    """Inward normal and curvature [1/m] of ``contact`` for a centre touching it at (xc, yc)
    (:meth:`.model.PuckModel.contact_normal`)."""
    if contact < FIRST_POST:
        return NORMAL_X[contact], NORMAL_Y[contact], 0.0
    radius = p[P_RADIUS]
    px, py = _post_position(contact, p[P_X_LIMIT] + radius, p[P_MOUTH] + radius)
    gap = math.hypot(xc - px, yc - py)
    return (xc - px) / gap, (yc - py) / gap, 1.0 / gap


@njit(cache=True)
def _restitution(p: np.ndarray, vn: float) -> tuple[float, float]:
    """The impact's restitution at normal velocity ``vn`` [m/s] and d e / d vn (:func:`.impact.speed_restitution`)."""
    e0, slope = p[P_RESTITUTION], p[P_SLOPE]
    e = e0 - slope * (abs(vn) - p[P_KNEE])
    if slope == 0.0 or e >= e0:
        return e0, 0.0
    if e <= p[P_FLOOR]:
        return min(p[P_FLOOR], e0), 0.0
    return e, (slope if vn < 0.0 else -slope)


@njit(cache=True)
def _rim_impact(p: np.ndarray, vb: float, vn: float, omega: float) -> tuple:
    """Post-impact (vb, vn, omega) in the impact frame, whether the impact slid, and its 3x3 Jacobian
    d(vb', vn', omega') / d(vb, vn, omega) as a row-major 9-tuple (:func:`.impact.rim_impact`)."""
    e, de = _restitution(p, vn)
    dvn = -e - vn * de
    r, mu, beta = p[P_RADIUS], p[P_FRICTION_RIM], p[P_TANGENTIAL]
    slip = vb + r * omega
    if (1.0 + beta) * abs(slip) > 3.0 * mu * (1.0 + e) * abs(vn):
        s = 1.0 if slip > 0.0 else -1.0
        k = mu * s * (1.0 + e)
        dk = k + mu * s * de * vn
        return (vb + k * vn, -e * vn, omega + 2.0 * k * vn / r, True,
                (1.0, dk, 0.0, 0.0, dvn, 0.0, 0.0, 2.0 * dk / r, 1.0))
    q = (1.0 + beta) / 3.0
    return (vb - q * slip, -e * vn, omega - 2.0 * q * slip / r, False,
            (1.0 - q, 0.0, -q * r, 0.0, dvn, 0.0, -2.0 * q / r, 0.0, 1.0 - 2.0 * q))


@njit(cache=True)
def _decay(p: np.ndarray, vx: float, vy: float, dt: float) -> tuple[float, float, float, float, float, float]:
    """Velocity after the table acceleration and the friction/damping of a step, and its 2x2 Jacobian
    (j00, j01, j10, j11) (:meth:`.model.PuckModel.decay`)."""
    gx, gy = p[P_GX], p[P_GY]
    if gx != 0.0 or gy != 0.0:
        vx, vy = vx + dt * gx, vy + dt * gy
    a = 1.0 - dt * p[P_DAMPING]
    mu_dt = dt * p[P_FRICTION_SURFACE]
    speed = math.hypot(vx, vy)
    ux, uy = (vx / speed, vy / speed) if speed > 0.0 else (0.0, 0.0)
    d00, d01, d11 = _decay_jacobian(a, mu_dt, speed, ux, uy)
    if mu_dt == 0.0:
        return a * vx, a * vy, d00, d01, d01, d11
    new_speed = a * speed - mu_dt
    if speed == 0.0 or new_speed <= 0.0:
        return 0.0, 0.0, d00, d01, d01, d11
    return ux * new_speed, uy * new_speed, d00, d01, d01, d11


@njit(cache=True)
def _decay_jacobian(keep: float, mu_dt: float, speed: float, ux: float, uy: float) -> tuple[float, float, float]:
    """The decay's 2x2 Jacobian (d00, d01 = d10, d11) for a velocity of ``speed`` [m/s] along (ux, uy), with
    ``keep = 1 - dt d`` and ``mu_dt = dt mu_s`` [m/s]: ``keep`` I without friction, zero where the friction
    stops the puck (:meth:`.model.PuckModel.decay`)."""
    if mu_dt == 0.0:
        return keep, 0.0, keep
    if speed == 0.0 or keep * speed - mu_dt <= 0.0:
        return 0.0, 0.0, 0.0
    k = mu_dt / speed
    return keep - k + k * ux * ux, k * ux * uy, keep - k + k * uy * uy


@njit(cache=True)
def _event_jacobian(x: float, y: float, vx: float, vy: float, om: float, tau: float, nx: float, ny: float,
                    curvature: float, vb: float, vn: float, vb_out: float, vn_out: float, s_local: tuple,
                    delay: float, out: np.ndarray) -> None:
    """7x7 Jacobian of one impact event over (x, y, vx, vy, theta, omega, remaining time), written to ``out``,
    from the contact's normal and curvature, the impact-frame velocities before and after and the impact's
    own 3x3 Jacobian ``s_local`` (:func:`.model.event_jacobian`)."""
    gx = gy = gvx = gvy = 0.0  # gradient of the impact time tau
    if tau > 0.0:
        gx, gy = -nx / vn, -ny / vn
        gvx, gvy = -(tau - delay) * nx / vn, -(tau - delay) * ny / vn
    bx, by = ny, -nx
    s00, s01, s02, s10, s11, s12, s20, s21, s22 = s_local
    cb, cn = s00 * bx + s01 * nx, s10 * bx + s11 * nx
    db, dn = s00 * by + s01 * ny, s10 * by + s11 * ny
    _zero(out)
    out[0, 0], out[0, 1], out[0, 2], out[0, 3] = 1.0 + vx * gx, vx * gy, tau + vx * gvx, vx * gvy
    out[1, 0], out[1, 1], out[1, 2], out[1, 3] = vy * gx, 1.0 + vy * gy, vy * gvx, tau + vy * gvy
    out[2, 2], out[2, 3], out[2, 5] = bx * cb + nx * cn, bx * db + nx * dn, bx * s02 + nx * s12
    out[3, 2], out[3, 3], out[3, 5] = by * cb + ny * cn, by * db + ny * dn, by * s02 + ny * s12
    out[4, 0], out[4, 1], out[4, 2], out[4, 3], out[4, 4], out[4, 5] = om * gx, om * gy, om * gvx, om * gvy, 1.0, tau
    out[5, 2], out[5, 3], out[5, 5] = s20 * bx + s21 * nx, s20 * by + s21 * ny, s22
    out[6, 0], out[6, 1], out[6, 2], out[6, 3], out[6, 6] = -gx, -gy, -gvx, -gvy, 1.0
    if curvature != 0.0:  # a post: the impact frame turns with the touch point (the event's, delay earlier)
        wb, wn = s00 * vn - s01 * vb, s10 * vn - s11 * vb
        kx = bx * wb + nx * wn + vb_out * nx - vn_out * bx
        ky = by * wb + ny * wn + vb_out * ny - vn_out * by
        kw = s20 * vn - s21 * vb
        for j in range(4):
            turn = -curvature * (bx * out[0, j] + by * out[1, j])
            if j == 2:
                turn += curvature * delay * bx
            elif j == 3:
                turn += curvature * delay * by
            out[2, j] += kx * turn
            out[3, j] += ky * turn
            out[5, j] += kw * turn


@njit(cache=True)
def _free_jacobian(f: np.ndarray, h: float, j00: float, j01: float, j10: float, j11: float, spin_keep: float) -> None:
    """``f`` (6x6) := the Jacobian of a step of ``h`` [s] without an impact, decay Jacobian (j00, j01, j10, j11),
    the spin kept by ``spin_keep``."""
    _zero(f)
    f[0, 0] = f[1, 1] = f[4, 4] = 1.0
    f[5, 5] = spin_keep
    f[0, 2] = f[1, 3] = f[4, 5] = h
    f[2, 2], f[2, 3], f[3, 2], f[3, 3] = j00, j01, j10, j11


@njit(cache=True)
def _step(p: np.ndarray, x: float, y: float, vx: float, vy: float, th: float, om: float, dt: float, t0: float,
          impacts: np.ndarray, count: int, f: np.ndarray, work: np.ndarray) -> tuple:
    """One model step of the state (x, y, vx, vy, th, om) from time ``t0`` [s] (:meth:`.model.PuckModel.step`);
    its impacts are written to ``impacts`` from row ``count``, its Jacobian to ``f`` (6x6) unless ``f`` is
    empty. ``work``: room for three 7x7 matrices. Returns the new state and impact count, or the count -1 when
    ``impacts`` is full (the caller grows it and retakes the step)."""
    with_jac, start = f.shape[0] > 0, count
    h = dt
    delay = p[P_IMPACT_DELAY]
    tau, wall = _first_impact(p, x, y, vx, vy, dt, delay)
    if with_jac and wall >= 0:
        jac, event, product = work[0], work[1], work[2]
        _zero(jac)
        for k in range(7):
            jac[k, k] = 1.0
    for _ in range(MAX_IMPACTS_PER_STEP):
        if wall < 0:
            break
        if count == impacts.shape[0]:
            return x, y, vx, vy, th, om, -1
        xc, yc = x + tau * vx, y + tau * vy
        nx, ny, curvature = _contact_normal(p, wall, xc - delay * vx, yc - delay * vy)
        bx, by = ny, -nx
        vb_in, vn_in = bx * vx + by * vy, nx * vx + ny * vy
        vb, vn, new_om, sliding, s_local = _rim_impact(p, vb_in, vn_in, om)
        if with_jac:
            _event_jacobian(x, y, vx, vy, om, tau, nx, ny, curvature, vb_in, vn_in, vb, vn, s_local, delay, event)
            _matmul(event, jac, product)
            _copy_into(product, jac, 7, 7)
        x, y, th, h = xc, yc, th + tau * om, h - tau
        vx, vy, om = bx * vb + nx * vn, by * vb + ny * vn, new_om
        impacts[count, 0], impacts[count, 1], impacts[count, 2] = t0 + (dt - h), _contact_rim(wall), x
        impacts[count, 3], impacts[count, 4] = y, 1.0 if sliding else 0.0
        count += 1
        tau, wall = _first_impact(p, x, y, vx, vy, h, delay)
    nvx, nvy, j00, j01, j10, j11 = _decay(p, vx, vy, dt)
    spin_keep = 1.0 - dt * p[P_SPIN_DAMPING]
    if with_jac:
        _free_jacobian(f, h, j00, j01, j10, j11, spin_keep)
        if count > start:  # impacts in this step: the flight's 6x7 Jacobian times the events'
            flight = work[1]
            _zero(flight)
            _copy_into(f, flight, 6, 6)
            flight[0, 6], flight[1, 6], flight[4, 6] = vx, vy, om
            _matmul(flight, work[0], work[2])
            _copy_into(work[2], f, 6, 6)
    return x + h * vx, y + h * vy, nvx, nvy, _wrap(th + h * om), spin_keep * om, count


@njit(cache=True)
def _room(p: np.ndarray, x: float, y: float, vx: float, vy: float) -> tuple[float, float, float, float]:
    """Direction (ux, uy), speed [m/s] and the distance [m] along the straight ray to its first rim contact
    (inf: none; the goal mouths as :func:`_first_impact`): where the centre touches, before any delay; 0 for a
    puck past a rim line (within a compliant rim's contact, or in a goal: the steps decide)."""
    speed = math.hypot(vx, vy)
    if speed == 0.0:
        return 0.0, 0.0, 0.0, math.inf
    ux, uy = vx / speed, vy / speed
    if abs(x) > p[P_X_LIMIT] or abs(y) > p[P_Y_LIMIT]:
        return ux, uy, speed, 0.0
    distance, wall = _first_impact(p, x, y, ux, uy, math.inf, 0.0)
    return ux, uy, speed, (math.inf if wall < 0 else distance)


@njit(cache=True)
def _cross_step(crossings: np.ndarray, lines: np.ndarray, t0: float, dt: float, x0: float, y0: float, vx0: float,
                vy0: float, x1: float, y1: float, impacts: np.ndarray, first: int, last: int) -> None:
    """First crossings of the lines x = ``lines`` inside one step of ``dt`` [s] from (x0, y0) at ``t0`` [s]
    with velocity (vx0, vy0) to (x1, y1), along the step's path: straight to the centre at each of its
    impacts (``impacts`` rows ``first`` to ``last`` - 1) in turn, then to the end; the model moves at one
    velocity between them, whose secant is recorded after an impact (:meth:`.prediction._Recorder.step`)."""
    ta, xa, ya, vxa, vya = t0, x0, y0, vx0, vy0
    for k in range(first, last + 1):
        if k < last:
            tb, xb, yb = impacts[k, 0], impacts[k, 2], impacts[k, 3]
        else:
            tb, xb, yb = t0 + dt, x1, y1
        if k > first and tb > ta:
            vxa, vya = (xb - xa) / (tb - ta), (yb - ya) / (tb - ta)
        _cross(crossings, lines, ta, tb - ta, xa, ya, vxa, vya, xb, yb)
        ta, xa, ya = tb, xb, yb


@njit(cache=True)
def _cross(crossings: np.ndarray, lines: np.ndarray, t0: float, dt: float, x0: float, y0: float, vx0: float,
           vy0: float, x1: float, y1: float) -> None:
    """First crossings of the lines x = ``lines`` on a straight piece of ``dt`` [s] from (x0, y0) at ``t0``
    with velocity (vx0, vy0) to (x1, y1), interpolated linearly."""
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
    _copy_into(rows, grown, count, rows.shape[1])
    return grown


@njit(cache=True)
def _zero(a: np.ndarray) -> None:
    """``a[:] = 0`` for a matrix, in loops (numba compiles a slice assignment slowly: seconds each)."""
    for i in range(a.shape[0]):
        for j in range(a.shape[1]):
            a[i, j] = 0.0


@njit(cache=True)
def _copy_into(src: np.ndarray, dst: np.ndarray, rows: int, cols: int) -> None:
    """``dst[:rows, :cols] = src[:rows, :cols]``, in loops (see :func:`_zero`)."""
    for i in range(rows):
        for j in range(cols):
            dst[i, j] = src[i, j]


@njit(cache=True)
def _matmul(a: np.ndarray, b: np.ndarray, out: np.ndarray) -> None:
    """``out := a b`` for small square matrices (loops: no BLAS call for 7x7)."""
    n = a.shape[0]
    for i in range(n):
        for j in range(n):
            acc = 0.0
            for k in range(n):
                acc += a[i, k] * b[k, j]
            out[i, j] = acc


@njit(cache=True)
def _propagate_scored(cov: np.ndarray, q: np.ndarray, q_scale: float) -> None:
    """``cov <- f cov f^T + q_scale q`` (in place) for a puck in a goal: ``f`` keeps position and angle and
    zeroes velocity and spin."""
    for i in range(6):
        for j in range(6):
            kept = i in (0, 1, 4) and j in (0, 1, 4)
            cov[i, j] = (cov[i, j] if kept else 0.0) + q_scale * q[i, j]


@njit(cache=True)
def _propagate(f: np.ndarray, cov: np.ndarray, q: np.ndarray, q_scale: float, tmp: np.ndarray) -> None:
    """``cov <- f cov f^T + q_scale q`` (6x6, in place; ``tmp`` 6x6 scratch)."""
    _matmul(f, cov, tmp)
    for i in range(6):
        for j in range(6):
            acc = q_scale * q[i, j]
            for k in range(6):
                acc += tmp[i, k] * f[j, k]
            cov[i, j] = acc


@njit(cache=True)
def _propagate_free(cov: np.ndarray, h: float, d00: float, d01: float, d10: float, d11: float, spin_keep: float,
                    q: np.ndarray, q_scale: float, tmp: np.ndarray) -> None:
    """:func:`_propagate` for the Jacobian of a step without an impact (:func:`_free_jacobian`), using its
    blocks: position += h velocity, velocity by the decay's 2x2, angle += h spin, spin by ``spin_keep``."""
    for j in range(6):
        tmp[0, j] = cov[0, j] + h * cov[2, j]
        tmp[1, j] = cov[1, j] + h * cov[3, j]
        tmp[2, j] = d00 * cov[2, j] + d01 * cov[3, j]
        tmp[3, j] = d10 * cov[2, j] + d11 * cov[3, j]
        tmp[4, j] = cov[4, j] + h * cov[5, j]
        tmp[5, j] = spin_keep * cov[5, j]
    for i in range(6):
        cov[i, 0] = tmp[i, 0] + h * tmp[i, 2] + q_scale * q[i, 0]
        cov[i, 1] = tmp[i, 1] + h * tmp[i, 3] + q_scale * q[i, 1]
        cov[i, 2] = d00 * tmp[i, 2] + d01 * tmp[i, 3] + q_scale * q[i, 2]
        cov[i, 3] = d10 * tmp[i, 2] + d11 * tmp[i, 3] + q_scale * q[i, 3]
        cov[i, 4] = tmp[i, 4] + h * tmp[i, 5] + q_scale * q[i, 4]
        cov[i, 5] = spin_keep * tmp[i, 5] + q_scale * q[i, 5]


@njit(cache=True)
def predict(p: np.ndarray, state: np.ndarray, cov: np.ndarray, q: np.ndarray, impact_noise: float,
            contact_time: float, steps: int, remainder: float, dt: float, lines: np.ndarray,
            sample_every: int) -> tuple:
    """``steps`` model steps of ``dt`` [s] from ``state`` (6) and ``cov`` (6x6, or 0x0 for the mean alone),
    then one of ``remainder`` [s] (none when 0); process noise ``q`` per step (scaled by the length of the
    last), ``impact_noise`` the impact covariance's ratio and ``contact_time`` [s] its position part.

    Returns the final state (6) and covariance (as given: 0x0 without), the impacts (rows: ``IMPACT_COLUMNS``),
    the crossings of ``lines`` (one row each: ``CROSSING_COLUMNS``), the samples every ``sample_every`` steps
    (0: none; rows: ``SAMPLE_COLUMNS``) and their covariances (n x 6 x 6, or n x 0 x 0).
    """
    x, y, vx, vy, th, om = state[0], state[1], state[2], state[3], state[4], state[5]
    with_cov = cov.shape[0] > 0
    n_cov = 6 if with_cov else 0
    p_now, f, tmp, work = cov.copy(), np.empty((n_cov, n_cov)), np.empty((6, 6)), np.empty((3, 7, 7))
    flat = p[P_GX] == 0.0 and p[P_GY] == 0.0
    impacts = np.empty((IMPACT_ROWS, IMPACT_COLUMNS))
    crossings = np.zeros((lines.shape[0], CROSSING_COLUMNS))
    n_samples = steps // sample_every if sample_every > 0 else 0
    samples, sample_covs = np.empty((n_samples, SAMPLE_COLUMNS)), np.empty((n_samples, n_cov, n_cov))
    ux, uy, speed, room = _room(p, x, y, vx, vy)
    scored_x = p[P_X_LIMIT] + 2.0 * p[P_RADIUS]  # TableGeometry.scored_x
    count = taken = 0
    for i in range(steps + 1):
        h = dt if i < steps else remainder
        if h == 0.0:
            break
        x0, y0, vx0, vy0, before = x, y, vx, vy, count
        if abs(x) > scored_x:  # in a goal: it stays (:meth:`.model.PuckModel.step`)
            vx, vy, om, speed = 0.0, 0.0, 0.0, 0.0
            if with_cov:
                _propagate_scored(p_now, q, h / dt)
        elif flat and h * speed < room - GLIDE_MARGIN:
            keep, mu_h, spin_keep = 1.0 - h * p[P_DAMPING], h * p[P_FRICTION_SURFACE], 1.0 - h * p[P_SPIN_DAMPING]
            if with_cov:  # from the speed and direction kept here
                d00, d01, d11 = _decay_jacobian(keep, mu_h, speed, ux, uy)
                _propagate_free(p_now, h, d00, d01, d01, d11, spin_keep, q, h / dt, tmp)
            x, y, room = x + h * vx, y + h * vy, room - h * speed
            if mu_h == 0.0:
                vx, vy, speed = keep * vx, keep * vy, keep * speed
            else:
                speed = keep * speed - mu_h
                if speed <= 0.0:
                    vx, vy, speed = 0.0, 0.0, 0.0
                else:
                    vx, vy = ux * speed, uy * speed
            th, om = _wrap(th + h * om), spin_keep * om
        else:
            new = _step(p, x, y, vx, vy, th, om, h, i * dt, impacts, count, f, work)
            while new[6] < 0:
                impacts = _grown(impacts, count)
                new = _step(p, x, y, vx, vy, th, om, h, i * dt, impacts, count, f, work)
            x, y, vx, vy, th, om, count = new
            if flat:
                ux, uy, speed, room = _room(p, x, y, vx, vy)
            if with_cov and count == before:  # no impact: the free Jacobian's blocks
                _propagate_free(p_now, h, f[2, 2], f[2, 3], f[3, 2], f[3, 3], f[5, 5], q, h / dt, tmp)
            elif with_cov:
                _propagate(f, p_now, q, h / dt, tmp)
        if with_cov:
            if count > before and (impact_noise != 0.0 or contact_time != 0.0):
                spread, offset, speed2 = impact_noise * impact_noise, contact_time * contact_time, vx * vx + vy * vy
                p_now[0, 0] += offset * speed2
                p_now[1, 1] += offset * speed2
                p_now[2, 2] += spread * speed2
                p_now[3, 3] += spread * speed2
                p_now[5, 5] += spread * om * om
        _cross_step(crossings, lines, i * dt, h, x0, y0, vx0, vy0, x, y, impacts, before, count)
        if sample_every > 0 and i < steps and (i + 1) % sample_every == 0:
            samples[taken, 0] = (i + 1) * dt
            samples[taken, 1], samples[taken, 2], samples[taken, 3] = x, y, vx
            samples[taken, 4], samples[taken, 5], samples[taken, 6] = vy, th, om
            _copy_into(p_now, sample_covs[taken], n_cov, n_cov)
            taken += 1
    return np.array([x, y, vx, vy, th, om]), p_now, impacts[:count], crossings, samples, sample_covs


def warm_up() -> None:
    """Compile (or load from the cache) :func:`predict` now, with and without a covariance, not in the first
    prediction."""
    p = np.array([0.9, 0.1, 0.1, 0.5, 0.5, 0.0, 0.1, 0.01, 0.0, 0.01, 0.9, 0.5, 0.1, 0.03, 0.1, 0.001])
    state, q = np.array([0.0, 0.0, 3.0, 2.0, 0.0, 1.0]), np.eye(6)
    for cov in (np.empty((0, 0)), np.eye(6)):
        predict(p, state, cov, q, 0.1, 0.001, 2, 0.005, 0.01, np.array([0.0]), 1)
