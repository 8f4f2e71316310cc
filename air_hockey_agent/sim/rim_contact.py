"""Puck-rim contacts of the simulated table as rigid-body impacts (ROS-free, pybullet-free).

Why the simulation owns these contacts: pybullet resolves a rim contact over several 1 ms steps with
its sequential-impulse solver, and for a spinning puck the result depends on where in a step the
contact begins (measured for (vb, vn, omega) = (0, 1.5 m/s, 30 rad/s) over seven start phases: the
outgoing spin spread 16.1 +- 2.4 rad/s and the normal speed lost 3 %; a rigid-body impact gives 11.8 rad/s).

Model: a planar rigid body (mass m, yaw inertia I) hits a fixed rim at one point. The impulse follows
the impact process parametrised by the normal impulse p (Darboux-Keller): Coulomb friction
(|P_t| <= mu P_n, opposing slip, sticking when it can) and Poisson's restitution (the restitution phase
delivers e times the compression phase's normal impulse). The process is piecewise linear in p, so it
is integrated exactly phase by phase. This is a general solver (any lever arm, any inertia, inertia
read from the simulated body); for a uniform disc on a straight rim it reduces to Routh's closed form of
thesis eq. 3.2-3.4, which ``test/test_rim_contact.py`` checks against
:func:`air_hockey_agent.core.puck.impact.rim_impact` as independent evidence for both.

Rims: the inner outline of the table frame's rims (README "Frames and units") as line segments: the two
long rims, the four short-rim pieces beside the goals and the goal posts' side faces. A puck whose
centre is over a goal line is handled by the world (it is in the goal).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

from air_hockey_agent.core.puck.impact import speed_restitution
from air_hockey_agent.core.table import TableGeometry

_EPS = 1e-12  # [m/s] slip speeds below this are zero (round-off of the exact phase ends)


@dataclass(frozen=True)
class Segment:
    """A rim edge on the surface plane from ``a`` to ``b`` (table frame, [m])."""

    a: tuple[float, float]
    b: tuple[float, float]

    def closest_point(self, x: float, y: float) -> tuple[float, float]:
        (ax, ay), (bx, by) = self.a, self.b
        dx, dy = bx - ax, by - ay
        s = ((x - ax) * dx + (y - ay) * dy) / (dx * dx + dy * dy)
        s = min(1.0, max(0.0, s))
        return ax + s * dx, ay + s * dy


def rim_segments(table: TableGeometry) -> tuple[Segment, ...]:
    """The rims' inner outline. The goal posts' side faces reach one puck radius behind the goal line:
    a puck centre further back than that is in the goal, so no contact there can matter."""
    hl, hw, hg, depth = table.length / 2, table.width / 2, table.goal_width / 2, table.puck_radius
    segments = [Segment((-hl, -hw), (hl, -hw)), Segment((-hl, hw), (hl, hw))]
    for sx in (-1.0, 1.0):
        x, behind = sx * hl, sx * (hl + depth)
        segments += [Segment((x, hg), (x, hw)), Segment((x, -hw), (x, -hg)),
                     Segment((x, hg), (behind, hg)), Segment((x, -hg), (behind, -hg))]
    return tuple(segments)


@dataclass(frozen=True)
class Impulse:
    normal: float      # [N s] P_n, along the contact normal (into the table)
    tangential: float  # [N s] P_t, along the tangent t = Rz(-90 deg) n
    sliding: bool      # True when the contact point still slips at the end of the impact


def impact_impulse(un: float, ut: float, k: Sequence[Sequence[float]], restitution: float,
                   friction: float) -> Impulse:
    """Impulse of a point impact from the contact point's velocity (``un`` < 0 approaching, ``ut``)
    [m/s] and the contact's inverse mass matrix ``k`` (2x2, normal/tangential rows) [1/kg]."""
    (knn, knt), (ktn, ktt) = k
    p = pt = 0.0
    p_end = math.inf  # known once compression ends
    compressing, slid = True, False
    for _ in range(8):  # at most: slide, stick or reverse slide, end of compression, end of restitution
        if abs(ut) > _EPS:
            s = math.copysign(1.0, ut)
            rate_n, rate_t, rate_pt = knn - friction * s * knt, ktn - friction * s * ktt, -friction * s
        elif abs(ktn) <= friction * ktt:  # sticking can hold: the tangential impulse keeps ut = 0
            rate_pt = -ktn / ktt
            rate_n, rate_t, ut = knn + knt * rate_pt, 0.0, 0.0
        else:  # sticking cannot hold: slides the way the normal impulse drives it
            s = math.copysign(1.0, ktn)
            rate_n, rate_t, rate_pt = knn - friction * s * knt, ktn - friction * s * ktt, -friction * s
        if rate_n <= 0.0:
            raise ValueError("impact jams: the normal impulse does not separate the bodies (Painleve case)")
        steps = [p_end - p]
        if compressing:
            steps.append(-un / rate_n)
        if rate_t != 0.0 and ut != 0.0 and -ut / rate_t > 0.0:
            steps.append(-ut / rate_t)
        dp = min(steps)
        p, pt, un, ut = p + dp, pt + rate_pt * dp, un + rate_n * dp, ut + rate_t * dp
        slid = abs(ut) > _EPS
        if compressing and un >= -_EPS:
            compressing, p_end = False, (1.0 + restitution) * p
        if p >= p_end * (1.0 - 1e-12):
            return Impulse(p, pt, slid)
    raise RuntimeError("impact did not finish in 8 phases")  # cannot happen for a piecewise-linear process


@dataclass(frozen=True)
class RimLaw:
    """The rims' coefficients: Poisson restitution ``restitution`` [-] up to the normal impact speed ``knee``
    [m/s], falling by ``slope`` [s/m] beyond it, never below ``floor`` [-] (``slope`` 0: the thesis's
    constant e; :func:`air_hockey_agent.core.puck.impact.speed_restitution`, the tracker's law), and
    Coulomb friction ``friction`` [-], whose tangential impulse is scaled by ``tangential_scale`` [-] (1:
    the rigid-body impact; below 1 softer, as another engine's rims, issue #13; the test bed's
    :func:`air_hockey_agent.core.puck.real_table.real_rim_impact` scales Routh's the same way)."""

    restitution: float
    friction: float
    slope: float = 0.0
    floor: float = 0.0
    knee: float = 0.0
    tangential_scale: float = 1.0

    def restitution_at(self, vn: float) -> float:
        """The restitution of an impact at normal velocity ``vn`` [m/s]."""
        return speed_restitution(self.restitution, self.slope, vn, self.floor, self.knee)[0]


@dataclass(frozen=True)
class PuckBody:
    """The puck as a planar rigid body: radius [m], mass [kg], yaw inertia [kg m^2]."""

    radius: float
    mass: float
    inertia: float


class RimContacts:
    """Detects puck-rim contacts after a physics step and applies their impacts."""

    def __init__(self, table: TableGeometry, puck: PuckBody, law: RimLaw) -> None:
        self.segments = rim_segments(table)
        self.puck, self.law = puck, law
        # every segment lies on or outside the surface's edge: a centre this far inside touches none
        self.clear_x, self.clear_y = table.x_limit, table.y_limit

    def resolve(self, x: float, y: float, vx: float, vy: float, omega: float) -> tuple[float, ...]:
        """Puck (x, y, vx, vy, omega) after every contact that overlaps and approaches a rim.

        The overlap that built up during the step is mirrored out along the normal, scaled by the
        ratio of outgoing to incoming normal speed (the event-driven position at the step's end)."""
        if abs(x) < self.clear_x and abs(y) < self.clear_y:
            return x, y, vx, vy, omega
        for seg in self.segments:
            cx, cy = seg.closest_point(x, y)
            dist = math.hypot(x - cx, y - cy)
            if dist >= self.puck.radius or dist == 0.0:
                continue
            nx, ny = (x - cx) / dist, (y - cy) / dist
            vx, vy, omega, bounce = self._impact(nx, ny, vx, vy, omega)
            if bounce is not None:
                push = (self.puck.radius - dist) * (1.0 + bounce)
                x, y = x + push * nx, y + push * ny
        return x, y, vx, vy, omega

    def _impact(self, nx: float, ny: float, vx: float, vy: float, omega: float):
        """Velocities after an impact with contact normal n (into the table); ``bounce`` is the ratio of
        outgoing to incoming normal speed, None when the puck is not approaching."""
        body = self.puck
        tx, ty = ny, -nx  # t = Rz(-90 deg) n
        rx, ry = -body.radius * nx, -body.radius * ny  # lever arm: centre -> contact point
        ux, uy = vx - omega * ry, vy + omega * rx  # contact point velocity v + omega x r
        un, ut = ux * nx + uy * ny, ux * tx + uy * ty
        vn_in = vx * nx + vy * ny
        if un >= 0.0 or vn_in >= 0.0:
            return vx, vy, omega, None
        perp_n, perp_t = rx * ny - ry * nx, rx * ty - ry * tx  # r x n, r x t (z components)
        inv_m, inv_i = 1.0 / body.mass, 1.0 / body.inertia
        k = ((inv_m + perp_n * perp_n * inv_i, perp_n * perp_t * inv_i),
             (perp_n * perp_t * inv_i, inv_m + perp_t * perp_t * inv_i))
        imp = impact_impulse(un, ut, k, self.law.restitution_at(vn_in), self.law.friction)
        tangential = imp.tangential * self.law.tangential_scale
        px, py = imp.normal * nx + tangential * tx, imp.normal * ny + tangential * ty
        vx, vy = vx + px * inv_m, vy + py * inv_m
        omega += (rx * py - ry * px) * inv_i
        return vx, vy, omega, -(vx * nx + vy * ny) / vn_in
