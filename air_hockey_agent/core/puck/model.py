"""Discrete-time puck model: linear motion (eq. 3.1) with rim impacts (eq. 3.2-3.4) and its Jacobian.

State ``s = (x, y, vx, vy, theta, omega)`` in the table frame [m, m, m/s, m/s, rad, rad/s].

One step of length ``dt`` (thesis eq. 3.1, with the surface friction acting along the velocity):

* flight: the puck moves with constant velocity for ``dt``; when its centre reaches a rim line within
  the step it moves to the contact point, the Routh impact (:mod:`.impact`) changes (vx, vy, omega),
  and it flies on with the new velocity for the rest of the step (several impacts per step allowed,
  e.g. in a corner). Crossing a short rim line inside the goal opening is no impact; a post (the rim's
  end beside the opening) is, when the puck's edge reaches it before its centre is past the rim's face:
  the same impact with the normal from the post to the centre (a corner contact,
  :func:`~air_hockey_agent.core.table.post_contact_time`); a puck whose centre passes the face is in the goal.
  One whose centre is a radius past the face (no post within its reach) has scored and stays where it is,
  its velocity and spin 0 (a real goal swallows the puck; flying on it would be metres from anywhere a
  puck can be measured).
  A compliant rim (``impact_delay`` s > 0) takes the impact s after the touch, the puck flying on into the rim
  meanwhile, so the paths before and after meet s |vn| beyond its line (0: the thesis's rigid rim).
* decay: ``v <- v - dt (d v + mu_s v/|v|)``, i.e. speed ``|v| <- max(a |v| - dt mu_s, 0)`` with
  ``a = 1 - dt d``; the direction is kept. The spin decays as ``omega <- b omega`` with ``b = 1 - dt k``,
  ``k`` the spin damping (0: the thesis's eq. 3.1, whose spin is constant; a uniform viscous air film damps
  the spin at the velocity's own rate d, a MuJoCo hinge as it is set). The angle advances with the spin
  before its decay, as the position with the velocity.
* table acceleration (issue #13 item 3; zero unless identified): before the decay, ``v <- v + dt g``
  with a constant ``g`` [m/s^2] in the table frame (a tilted surface gives g sin(tilt) downhill). The
  surface friction then holds a resting puck when ``|g| <= mu_s``.

The Jacobian ``F = ds'/ds`` is exact for the whole step, including how the impact time moves with
the state (and, at a post, how the normal turns with the contact point); on a rim impact it contains the
thesis's ``A_i^-1 S_j A_i`` (sec. 4.2) as its velocity block.
It is built from 7x7 Jacobians over the augmented state (s, remaining time).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace
from typing import Any, Mapping, NamedTuple

import numpy as np

from air_hockey_agent.core.puck.impact import rim_impact
from air_hockey_agent.core.table import (FIRST_POST, POST_COUNT, SHORT_WALLS, WALL_NORMALS, TableGeometry, contact_rim,
                                         post_contact_time)

TWO_PI = 2.0 * math.pi
MAX_IMPACTS_PER_STEP = 4  # a corner gives two; more means a degenerate state
_IDENTITY7 = np.eye(7)  # marker for "no event yet" (never modified)
_SCORED_JACOBIAN = np.diag([1.0, 1.0, 0.0, 0.0, 1.0, 0.0])  # a puck in a goal stays (never modified)


def wrap_angle(angle: float) -> float:
    """Wrap an angle to (-pi, pi] [rad]."""
    wrapped = math.remainder(angle, TWO_PI)
    return math.pi if wrapped == -math.pi else wrapped


def as_floats(state: np.ndarray | list) -> list[float]:
    """A state vector as a list of Python floats (scalar math on floats is faster than on numpy items)."""
    return state.tolist() if isinstance(state, np.ndarray) else [float(v) for v in state]


def flight_acceleration(damping: float, friction_surface: float, table_acceleration):
    """The flight law's acceleration ``v -> a`` [m/s -> m/s^2] (eq. 3.1 with the table acceleration g,
    table frame): ``g - d v - mu_s v / |v|``, as a function of a velocity (2,)."""
    g = np.array([float(a) for a in table_acceleration])

    def acceleration(v: np.ndarray) -> np.ndarray:
        speed = float(np.hypot(v[0], v[1]))
        return g - damping * v - (friction_surface * v / speed if speed > 0.0 else 0.0)
    return acceleration


@dataclass(frozen=True)
class PuckParams:
    """Physical parameters of the puck model (thesis sec. 4.3, table 4.1)."""

    friction_surface: float  # mu_s [m/s^2]: constant deceleration along the velocity
    damping: float           # d [1/s]: viscous damping
    restitution: float       # e [-] in [0, 1]
    friction_rim: float      # mu_rim [-]
    restitution_slope: float = 0.0  # [s/m] e falls by this per m/s of normal impact speed (0: the thesis's e)
    restitution_min: float = 0.0    # [-] ... but not below this (nor above restitution)
    restitution_knee: float = 0.0   # [m/s] ... and only beyond this normal speed (below it e is restitution)
    table_acceleration: tuple[float, float] = (0.0, 0.0)  # g [m/s^2], table frame: tilt / air film (issue #13)
    tangential_restitution: float = 0.0  # beta [-] in [-1, 1] of a sticking rim impact (0: Routh's, the thesis's)
    spin_damping: float = 0.0  # k [1/s]: the spin's decay rate in flight (0: constant spin, the thesis's)
    impact_delay: float = 0.0  # s [s]: the impact comes this long after the centre reaches the rim (0: rigid)

    @classmethod
    def from_params(cls, params: Mapping[str, Any]) -> "PuckParams":
        return cls(params["friction_surface"], params["damping"], params["restitution"], params["friction_rim"],
                   params["restitution_slope"], params["restitution_min"],
                   params["restitution_knee"], tuple(float(g) for g in params["table_acceleration"]),
                   params["tangential_restitution"], params["spin_damping"], params["impact_delay"])

    @property
    def accelerated(self) -> bool:
        """True when the table acceleration is not zero."""
        return self.table_acceleration[0] != 0.0 or self.table_acceleration[1] != 0.0

    def validate(self) -> None:
        """Raise ValueError naming the first physically invalid parameter."""
        checks = (("friction_surface", self.friction_surface >= 0.0, ">= 0"),
                  ("damping", self.damping >= 0.0, ">= 0"),
                  ("restitution", 0.0 <= self.restitution <= 1.0, "in [0, 1]"),
                  ("friction_rim", self.friction_rim >= 0.0, ">= 0"),
                  ("restitution_slope", self.restitution_slope >= 0.0, ">= 0"),
                  ("restitution_min", 0.0 <= self.restitution_min <= 1.0, "in [0, 1]"),
                  ("restitution_knee", self.restitution_knee >= 0.0, ">= 0"),
                  ("tangential_restitution", -1.0 <= self.tangential_restitution <= 1.0, "in [-1, 1]"),
                  ("spin_damping", self.spin_damping >= 0.0, ">= 0"),
                  ("impact_delay", self.impact_delay >= 0.0, ">= 0"))
        for name, ok, rule in checks:
            value = getattr(self, name)
            if not ok or not math.isfinite(value):
                raise ValueError(f"{name} must be {rule}, got {value}")
        if len(self.table_acceleration) != 2 or not all(map(math.isfinite, self.table_acceleration)):
            raise ValueError(f"table_acceleration must be two finite numbers, got {self.table_acceleration}")

    def with_values(self, **values: float) -> "PuckParams":
        return replace(self, **values)

    @classmethod
    def from_attributes(cls, source: Any) -> "PuckParams":
        """The parameters of ``source``, an object with one attribute per parameter (a PuckPhysics
        message), unchecked (:meth:`validate`)."""
        return cls(**{f.name: (tuple(float(g) for g in getattr(source, f.name)) if f.name == "table_acceleration"
                               else float(getattr(source, f.name))) for f in fields(cls)})

    def values(self) -> dict[str, Any]:
        """Every parameter by name, as Python floats (``table_acceleration`` a list of two): the fields
        of ``air_hockey_msgs/PuckPhysics`` besides its stamp and counts."""
        return {f.name: ([float(g) for g in getattr(self, f.name)] if f.name == "table_acceleration"
                         else float(getattr(self, f.name))) for f in fields(self)}


class Impact(NamedTuple):
    """A rim impact inside a step: time after the step's start [s], rim id, contact position [m]."""

    time: float
    wall: int
    x: float
    y: float
    sliding: bool


class StepResult(NamedTuple):
    state: np.ndarray          # (6,)
    jacobian: np.ndarray | None  # (6, 6) ds'/ds, or None when not requested
    impacts: tuple[Impact, ...]


def event_jacobian(z: list[float], tau: float, normal: tuple, velocities: tuple, s_local: tuple,
                   delay: float = 0.0) -> np.ndarray:
    """7x7 Jacobian of one impact event over the augmented state z = (x, y, vx, vy, theta, omega, h).

    ``normal`` = (nx, ny, curvature): the contact's inward normal and its curvature [1/m] (0 for a rim's
    line; a post's circle turns the normal with the contact point c: dn = dc / r, so the impact frame turns
    by d phi = -b . dc / r); ``velocities`` = (vb, vn, vb', vn') in the impact frame before and after;
    ``s_local`` the impact's own 3x3 Jacobian (thesis sec. 4.2: the velocity block is A^T S A on a rim).
    The impact comes ``delay`` [s] after the touch at t = tau - delay, whose point c_t = c - delay v fixes
    the normal: d tau = -n . (dp + t dv) / vn (none when the impact is due at once, tau = 0), and a post's
    frame turns by d phi = -b . dc_t / r."""
    x, y, vx, vy, th, om, h = z
    nx, ny, curvature = normal
    vb, vn, vb_out, vn_out = velocities
    gx = gy = gvx = gvy = 0.0  # gradient of the impact time tau
    if tau > 0.0:
        gx, gy = -nx / vn, -ny / vn
        gvx, gvy = -(tau - delay) * nx / vn, -(tau - delay) * ny / vn
    bx, by = ny, -nx  # impact frame rows (b, n): A = [[bx, by], [nx, ny]]; velocity block A^T S A
    (s00, s01, s02), (s10, s11, s12), (s20, s21, s22) = s_local
    cb, cn = s00 * bx + s01 * nx, s10 * bx + s11 * nx  # S A, first column
    db, dn = s00 * by + s01 * ny, s10 * by + s11 * ny  # S A, second column
    vel = ((bx * cb + nx * cn, bx * db + nx * dn), (by * cb + ny * cn, by * db + ny * dn))
    vel_om = (bx * s02 + nx * s12, by * s02 + ny * s12)
    om_vel = (s20 * bx + s21 * nx, s20 * by + s21 * ny)
    jac = np.array([
        [1.0 + vx * gx, vx * gy, tau + vx * gvx, vx * gvy, 0.0, 0.0, 0.0],
        [vy * gx, 1.0 + vy * gy, vy * gvx, tau + vy * gvy, 0.0, 0.0, 0.0],
        [0.0, 0.0, vel[0][0], vel[0][1], 0.0, vel_om[0], 0.0],
        [0.0, 0.0, vel[1][0], vel[1][1], 0.0, vel_om[1], 0.0],
        [om * gx, om * gy, om * gvx, om * gvy, 1.0, tau, 0.0],
        [0.0, 0.0, om_vel[0], om_vel[1], 0.0, s22, 0.0],
        [-gx, -gy, -gvx, -gvy, 0.0, 0.0, 1.0]])
    if curvature != 0.0:  # the frame turns: du = A dv + d phi (vn, -vb), dv' = A^T du' + d phi (vb' n - vn' b)
        turn = -curvature * (bx * jac[0] + by * jac[1])  # d phi over z, from the touch point's rows
        turn[2] += curvature * delay * bx
        turn[3] += curvature * delay * by
        wb, wn = s00 * vn - s01 * vb, s10 * vn - s11 * vb
        jac[2] += (bx * wb + nx * wn + vb_out * nx - vn_out * bx) * turn
        jac[3] += (by * wb + ny * wn + vb_out * ny - vn_out * by) * turn
        jac[5] += (s20 * vn - s21 * vb) * turn
    return jac


class PuckModel:
    """The puck's motion model on one table with one set of physical parameters."""

    def __init__(self, table: TableGeometry, params: PuckParams) -> None:
        params.validate()
        self.table = table
        self.params = params
        self._offsets = tuple(table.wall_offset(w) for w in range(4))
        self._half_goal = table.goal_mouth + table.puck_radius  # as the compiled prediction computes it
        self._scored_x = table.scored_x
        self._posts = {w: tuple(c for c in range(FIRST_POST, FIRST_POST + POST_COUNT) if contact_rim(c) == w)
                       for w in SHORT_WALLS}

    def with_params(self, params: PuckParams) -> "PuckModel":
        return PuckModel(self.table, params)

    # --- flight -------------------------------------------------------------------------------
    def first_impact(self, x: float, y: float, vx: float, vy: float, horizon: float) -> tuple[float, int] | None:
        """Earliest impact of a puck flying straight for ``horizon`` seconds: (time, contact) or None; the
        contact a rim's id or a post's (``FIRST_POST`` + k, :mod:`air_hockey_agent.core.table`). The impact
        comes ``impact_delay`` after the centre reaches the rim line or touches the post (0 when that is
        already past)."""
        best = None
        delay = self.params.impact_delay
        for wall, (nx, ny) in enumerate(WALL_NORMALS):
            vn = nx * vx + ny * vy
            if vn >= 0.0 and wall not in SHORT_WALLS:
                continue
            distance = nx * x + ny * y + self._offsets[wall]
            if wall in SHORT_WALLS:
                hit = self._short_rim_contact(wall, x, y, vx, vy, vn, distance, horizon)
            else:
                hit = (max(0.0, distance / -vn + delay), wall)
            if hit is not None and hit[0] <= horizon and (best is None or hit[0] < best[0]):
                best = hit
        return best

    def _short_rim_contact(self, wall: int, x: float, y: float, vx: float, vy: float, vn: float,
                           distance: float, horizon: float) -> tuple[float, int] | None:
        """First impact on short rim ``wall``: its face where the line is crossed beside the goal opening,
        else one of its posts (touched before the puck's centre is past the face); None for none (a goal).
        A puck past the line by more than the delay's travel is in the goal."""
        delay = self.params.impact_delay
        if vn < 0.0:
            touch = distance / -vn  # [s] until the centre is on the line (< 0: past it)
            if touch > horizon:
                return None  # the posts stand behind the line
            if touch + delay >= 0.0 and abs(y + touch * vy) >= self._half_goal:
                return max(0.0, touch + delay), wall
        elif distance >= 0.0:
            return None
        best = None  # crossing inside the opening, or in its strip between the line and the face
        for contact in self._posts[wall]:
            px, py = self.table.post_position(contact)
            touch = post_contact_time(x, y, vx, vy, px, py, self.table.puck_radius)
            if touch != math.inf and (best is None or touch < best[0]):
                best = (touch, contact)
        return None if best is None else (max(0.0, best[0] + delay), best[1])

    def contact_normal(self, contact: int, xc: float, yc: float) -> tuple[float, float, float]:
        """Inward unit normal (nx, ny) of ``contact`` for a puck centre touching it at (xc, yc) [m], and the
        contact's curvature [1/m] (0 for a rim; one over the centre's distance from a post)."""
        if contact < FIRST_POST:
            nx, ny = WALL_NORMALS[contact]
            return nx, ny, 0.0
        px, py = self.table.post_position(contact)
        gap = math.hypot(xc - px, yc - py)
        return (xc - px) / gap, (yc - py) / gap, 1.0 / gap

    def _impact_event(self, z: list[float], tau: float, contact: int, jac: np.ndarray | None):
        """Fly to the impact point and apply the impact to augmented state z = (s, remaining time); the
        normal is the one where the centre touched (``impact_delay`` earlier on the same straight path)."""
        x, y, vx, vy, th, om, h = z
        xc, yc = x + tau * vx, y + tau * vy
        delay = self.params.impact_delay
        nx, ny, curvature = self.contact_normal(contact, xc - delay * vx, yc - delay * vy)
        bx, by = ny, -nx
        vb, vn = bx * vx + by * vy, nx * vx + ny * vy
        p = self.params
        res = rim_impact(vb, vn, om, self.table.puck_radius, p.restitution, p.friction_rim, p.restitution_slope,
                         p.restitution_min, p.tangential_restitution, p.restitution_knee)
        new_z = [xc, yc, bx * res.vb + nx * res.vn, by * res.vb + ny * res.vn, th + tau * om, res.omega, h - tau]
        if jac is not None:
            event = event_jacobian(z, tau, (nx, ny, curvature), (vb, vn, res.vb, res.vn), res.jacobian, delay)
            jac = event if jac is _IDENTITY7 else event @ jac
        return new_z, jac, Impact(0.0, contact_rim(contact), xc, yc, res.sliding)

    # --- decay --------------------------------------------------------------------------------
    def decay(self, vx: float, vy: float, dt: float) -> tuple[float, float, tuple]:
        """Velocity after the table-acceleration and friction/damping part of a step, and its 2x2 Jacobian
        as row tuples (eq. 3.1)."""
        gx, gy = self.params.table_acceleration
        if gx != 0.0 or gy != 0.0:
            vx, vy = vx + dt * gx, vy + dt * gy
        a = 1.0 - dt * self.params.damping
        mu_dt = dt * self.params.friction_surface
        speed = math.hypot(vx, vy)
        if mu_dt == 0.0:
            return a * vx, a * vy, ((a, 0.0), (0.0, a))
        new_speed = a * speed - mu_dt
        if speed == 0.0 or new_speed <= 0.0:
            return 0.0, 0.0, ((0.0, 0.0), (0.0, 0.0))
        ux, uy = vx / speed, vy / speed
        k = mu_dt / speed
        cross = k * ux * uy
        return ux * new_speed, uy * new_speed, ((a - k + k * ux * ux, cross), (cross, a - k + k * uy * uy))

    # --- one step -----------------------------------------------------------------------------
    def step(self, state: np.ndarray, dt: float, with_jacobian: bool = True) -> StepResult:
        """Advance ``state`` by ``dt`` seconds (one model step, eq. 3.1-3.4)."""
        x, y, vx, vy, th, om = as_floats(state)
        if abs(x) > self._scored_x:  # in a goal: it stays (velocity and spin 0, whatever they were)
            return StepResult(np.array([x, y, 0.0, 0.0, th, 0.0]), _SCORED_JACOBIAN if with_jacobian else None, ())
        first = self.first_impact(x, y, vx, vy, dt)
        if first is None:  # the common case: straight flight, cheap Jacobian
            nvx, nvy, jd = self.decay(vx, vy, dt)
            b = 1.0 - dt * self.params.spin_damping
            new = np.array([x + dt * vx, y + dt * vy, nvx, nvy, wrap_angle(th + dt * om), b * om])
            if not with_jacobian:
                return StepResult(new, None, ())
            jac = np.array([[1.0, 0.0, dt, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, dt, 0.0, 0.0],
                            [0.0, 0.0, jd[0][0], jd[0][1], 0.0, 0.0], [0.0, 0.0, jd[1][0], jd[1][1], 0.0, 0.0],
                            [0.0, 0.0, 0.0, 0.0, 1.0, dt], [0.0, 0.0, 0.0, 0.0, 0.0, b]])
            return StepResult(new, jac, ())
        return self._step_with_impacts([x, y, vx, vy, th, om, dt], first, dt, with_jacobian)

    def _step_with_impacts(self, z: list[float], first: tuple[float, int], dt: float,
                           with_jacobian: bool) -> StepResult:
        jac = _IDENTITY7 if with_jacobian else None
        impacts = []
        hit: tuple[float, int] | None = first
        for _ in range(MAX_IMPACTS_PER_STEP):
            if hit is None:
                break
            tau, contact = hit
            z, jac, impact = self._impact_event(z, tau, contact, jac)
            impacts.append(impact._replace(time=dt - z[6]))
            hit = self.first_impact(z[0], z[1], z[2], z[3], z[6])
        x, y, vx, vy, th, om, h = z
        nvx, nvy, jd = self.decay(vx, vy, dt)
        b = 1.0 - dt * self.params.spin_damping
        new = np.array([x + h * vx, y + h * vy, nvx, nvy, wrap_angle(th + h * om), b * om])
        if jac is None:
            return StepResult(new, None, tuple(impacts))
        flight = np.array([[1.0, 0.0, h, 0.0, 0.0, 0.0, vx], [0.0, 1.0, 0.0, h, 0.0, 0.0, vy],
                           [0.0, 0.0, jd[0][0], jd[0][1], 0.0, 0.0, 0.0], [0.0, 0.0, jd[1][0], jd[1][1], 0.0, 0.0, 0.0],
                           [0.0, 0.0, 0.0, 0.0, 1.0, h, om], [0.0, 0.0, 0.0, 0.0, 0.0, b, 0.0]])
        return StepResult(new, (flight @ jac)[:, :6], tuple(impacts))
