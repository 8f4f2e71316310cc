"""A puck on a table with the effects of real tables that the tracker's model lacks (issue #13 item 1).

This is the physics of the test bed, written separately from :mod:`.model` so that a filter or an
identification tested on it meets effects its own model does not contain. State and frame as in
:mod:`.model`: ``(x, y, vx, vy, theta, omega)`` in the table frame [m, m/s, rad, rad/s].

Integrated with a fixed fine step (semi-implicit Euler), the puck accelerates by

    a = -d v - mu_s v/|v|                 flight law of the same form as the model's (eq. 3.1), with the
                                          test bed's own d, mu_s
      + g sin(tilt) (cos h, sin h)        a surface that falls toward heading h
      + A (sin(2 pi y / L + p1), sin(2 pi x / L + p2))   an uneven air film: a smooth field of amplitude A
                                          [m/s^2] and wavelength L [m] (both :mod:`.surface_field`)
      + w(t)                              random accelerations: a Gaussian value of std sigma held for a
                                          correlation time, then drawn again

and at a rim (the centre on the rim line where the rim's face is, not in a goal opening) or a post (a
rim's end beside a goal opening, met at its corner: the normal from the post to the centre, as the model
meets it) the normal velocity reverses with a
restitution that falls with the normal speed, from ``restitution_slow`` below the first of
``restitution_speeds`` linearly to ``restitution_fast`` above the second (rim rubber: faster impacts lose
more), while the tangential impulse is the Routh/Coulomb one (thesis eq. 3.2-3.3) scaled by
``tangential_scale``: below one it is softer than Coulomb's. With constant restitution and scale one
the impact is the thesis's Routh impact (tested against :func:`.impact.rim_impact`).

A *human hit* sets the velocity of a puck at rest: :func:`hit_from_rest` draws one. At the end of a
shot a human may *carry* the puck to where the next shot starts (:class:`HandCarry`: thesis sec. 4.5.1
cuts "the adjustment of the puck in the end for the next trajectory" out of the lab's recordings, so the
recordings hold it): the hand takes the puck wherever it is, stopping it, and slides it along a
minimum-jerk path (Flash and Hogan 1985) to a new place and angle, where it holds it still.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any, Mapping

import numpy as np

from air_hockey_agent.core.puck.model import wrap_angle
from air_hockey_agent.core.puck.surface_field import RandomPush, SurfaceField, slide_from_rest
from air_hockey_agent.core.table import SHORT_WALLS, WALL_NORMALS, TableGeometry


@dataclass(frozen=True)
class TableEffects:
    """The real table's physics (``testbed.*`` in ``config/synthetic.yaml``; every effect may be zero)."""

    damping: float = 0.0                      # d [1/s]
    friction_surface: float = 0.0             # mu_s [m/s^2]
    tilt: float = 0.0                         # [rad] slope of the surface
    tilt_heading: float = 0.0                 # [rad] direction (table frame) the surface falls toward
    air_film_amplitude: float = 0.0           # [m/s^2] peak acceleration of the air film's field
    air_film_wavelength: float = 1.0          # [m]
    random_acceleration: float = 0.0          # [m/s^2] std of the random acceleration
    random_acceleration_time: float = 0.1     # [s] how long one random acceleration holds
    restitution_slow: float = 0.9             # [-] restitution at low normal speed ...
    restitution_fast: float = 0.9             # [-] ... and at high normal speed
    restitution_speed_low: float = 0.5        # [m/s] normal speed up to which restitution_slow holds
    restitution_speed_high: float = 2.0       # [m/s] normal speed from which restitution_fast holds
    friction_rim: float = 0.1                 # mu_rim [-] of the Coulomb bound
    tangential_scale: float = 1.0             # [-] tangential impulse as a fraction of Routh/Coulomb's
    hit_duration: float = 0.0                 # [s] a human hit's push (0: an impulse)

    @classmethod
    def from_params(cls, params: Mapping[str, Any], prefix: str = "testbed.") -> "TableEffects":
        """From parameters named ``<prefix><field>`` (e.g. ``testbed.tilt``)."""
        return cls(**{f.name: float(params[prefix + f.name]) for f in fields(cls)})

    def restitution(self, normal_speed: float) -> float:
        """Restitution [-] at normal speed ``normal_speed`` [m/s] (>= 0)."""
        low, high = self.restitution_speed_low, self.restitution_speed_high
        share = float(normal_speed > low) if high <= low else min(1.0, max(0.0, (normal_speed - low) / (high - low)))
        return self.restitution_slow + share * (self.restitution_fast - self.restitution_slow)


def real_rim_impact(vb: float, vn: float, omega: float, radius: float,
                    effects: TableEffects) -> tuple[float, float, float]:
    """Post-impact (vb, vn, omega) in the impact frame of :mod:`.impact` (``vn < 0`` approaching): the
    normal velocity reverses with the speed-dependent restitution, the tangential impulse is the Routh
    one scaled by ``tangential_scale``."""
    e = effects.restitution(abs(vn))
    slip = vb + radius * omega  # contact point velocity along the rim
    coulomb = effects.friction_rim * (1.0 + e) * abs(vn)  # |P_b| / m when sliding
    impulse = -math.copysign(min(abs(slip) / 3.0, coulomb), slip) * effects.tangential_scale
    return vb + impulse, -e * vn, omega + 2.0 * impulse / radius


@dataclass(frozen=True)
class HandCarry:
    """A human carrying the puck at the end of a shot (``testbed.carry_time`` and ``testbed.carry_hold``
    in ``config/synthetic.yaml``): the carry takes a time drawn from ``time`` [s] (both 0: no carry) and
    ends ``hold`` [s] before the shot's recording does; the new place is anywhere ``margin`` [m] inside
    the rims, the new angle anywhere."""

    time: tuple[float, float] = (0.0, 0.0)
    hold: float = 0.0
    margin: float = 0.1

    @classmethod
    def from_params(cls, params: Mapping[str, Any], prefix: str = "testbed.") -> "HandCarry":
        """From ``<prefix>carry_time`` and ``<prefix>carry_hold`` (e.g. ``testbed.carry_time``)."""
        low, high = params[prefix + "carry_time"]
        return cls((float(low), float(high)), float(params[prefix + "carry_hold"]))

    @property
    def enabled(self) -> bool:
        return self.time[1] > 0.0

    def draw(self, table: TableGeometry, duration: float, rng: np.random.Generator) -> tuple[float, float, np.ndarray]:
        """(start [s] within a shot of ``duration`` [s], carry time [s], target pose (x, y, theta))."""
        carry = float(rng.uniform(*self.time))
        x = rng.uniform(-table.x_limit + self.margin, table.x_limit - self.margin)
        y = rng.uniform(-table.y_limit + self.margin, table.y_limit - self.margin)
        return max(0.0, duration - self.hold - carry), carry, np.array([x, y, rng.uniform(-math.pi, math.pi)])


def minimum_jerk(start: np.ndarray, end: np.ndarray, share: float, duration: float) -> tuple[np.ndarray, np.ndarray]:
    """Pose and its rate on the minimum-jerk path from ``start`` to ``end`` (same units, e.g. (x, y, theta)
    [m, m, rad]) at ``share`` (0..1) of ``duration`` [s]: p = a + (b - a)(10 s^3 - 15 s^4 + 6 s^5)."""
    s = min(1.0, max(0.0, share))
    delta = np.asarray(end, float) - np.asarray(start, float)
    return start + delta * (10 * s ** 3 - 15 * s ** 4 + 6 * s ** 5), \
        delta * (30 * s ** 2 - 60 * s ** 3 + 30 * s ** 4) / duration


def carried_state(grabbed: np.ndarray, target: np.ndarray, elapsed: float, duration: float) -> np.ndarray:
    """State (x, y, vx, vy, theta, omega) ``elapsed`` [s] into a hand's carry of ``duration`` [s] from the
    state ``grabbed`` to the pose ``target`` (x, y, theta); the angle turns the short way."""
    start = np.array([grabbed[0], grabbed[1], grabbed[4]])
    end = np.array([target[0], target[1], grabbed[4] + wrap_angle(target[2] - grabbed[4])])
    pose, rate = minimum_jerk(start, end, elapsed / duration, duration)
    return np.array([pose[0], pose[1], rate[0], rate[1], wrap_angle(pose[2]), rate[2]])


def carry_from(times: np.ndarray, states: np.ndarray, start: int, duration: float, target: np.ndarray) -> None:
    """Rows ``start`` on of ``states`` (at ``times`` [s]) become a hand's carry (:func:`carried_state`) of
    ``duration`` [s] from the state at row ``start - 1`` to the pose ``target``, then the hold."""
    grabbed = states[start - 1].copy()
    for i in range(start, len(states)):
        states[i] = carried_state(grabbed, target, times[i] - times[start - 1], duration)


def with_hand_carries(simulate, table: TableGeometry, carry: "HandCarry", rng: np.random.Generator):
    """A shot simulator (``simulate(state, duration) -> (times, states)``, any engine's) whose shots end in a
    hand's ``carry`` (drawn from ``rng``) where it is enabled: the states from the carry's start on are the
    hand's (:func:`carry_from`), whatever the engine did then."""
    if not carry.enabled:
        return simulate

    def carried(state: np.ndarray, duration: float) -> tuple[np.ndarray, np.ndarray]:
        times, states = simulate(state, duration)
        start, time, target = carry.draw(table, duration, rng)
        carry_from(times, states, max(1, int(np.searchsorted(times, start))), time, target)
        return times, states
    return carried


class RealTablePuck:
    """Integrates a puck on a :class:`TableEffects` table; ``rng`` draws the air film's phases and the
    random accelerations."""

    def __init__(self, table: TableGeometry, effects: TableEffects, rng: np.random.Generator) -> None:
        self.table, self.effects, self.rng = table, effects, rng
        phases = rng.uniform(0.0, 2.0 * math.pi, 2)
        self.surface = SurfaceField(effects.tilt, effects.tilt_heading, effects.air_film_amplitude,
                                    effects.air_film_wavelength, (float(phases[0]), float(phases[1])))
        self.random = RandomPush(effects.random_acceleration, effects.random_acceleration_time, rng)

    def external(self, x: float, y: float, t: float) -> np.ndarray:
        """Acceleration [m/s^2] at (x, y) and time ``t`` [s] that does not depend on the velocity: the
        surface's field plus the random acceleration held at ``t``."""
        a = self.field(x, y)
        if self.effects.random_acceleration > 0.0:
            a = a + self.random.at(t)
        return a

    def field(self, x: float, y: float) -> np.ndarray:
        """Acceleration of the surface [m/s^2] at (x, y): tilt plus the air film (:mod:`.surface_field`)."""
        return np.array(self.surface.at(x, y))

    def step(self, state: np.ndarray, t: float, dt: float) -> np.ndarray:
        """State after ``dt`` [s] from ``state`` at ``t`` [s]: flight, then any rim contact. Surface friction
        (mu_s) opposes the motion and, at rest, holds the puck against a weaker external acceleration."""
        fx = self.effects
        s = np.array(state, float)
        v = s[2:4]
        external = self.external(s[0], s[1], t)
        speed = math.hypot(v[0], v[1])
        if speed == 0.0:
            new_v = np.array(slide_from_rest(external[0], external[1], fx.friction_surface, dt))
        else:
            new_v = v + dt * (external - fx.damping * v - fx.friction_surface * v / speed)
            if float(new_v @ v) <= 0.0:
                new_v = np.zeros(2)  # friction stopped it within the step
        before = (s[0], s[1])
        s[2:4] = new_v
        s[0:2] += dt * new_v
        s[4] = wrap_angle(s[4] + dt * s[5])
        return self._rims(s, before)

    def _rims(self, s: np.ndarray, before: tuple[float, float]) -> np.ndarray:
        """Reflect a puck whose centre crossed a rim line in this step from ``before`` (where the rim's face
        is: not in a goal opening) and apply the impact; then the posts. A puck that went into a goal stays
        there: behind a short rim line there is no rim to bounce it back, wherever its y drifts."""
        table = self.table
        for wall, (nx, ny) in enumerate(WALL_NORMALS):
            distance = nx * s[0] + ny * s[1] + table.wall_offset(wall)
            vn = nx * s[2] + ny * s[3]
            if distance >= 0.0 or vn >= 0.0:
                continue
            opening = abs(s[1]) < table.goal_width / 2  # the contact point would be in the goal's opening
            if wall in SHORT_WALLS and (opening or table.distance_to_wall(wall, *before) < 0.0):
                continue
            s[0] -= 2.0 * distance * nx  # mirror the overshoot back onto the table
            s[1] -= 2.0 * distance * ny
            self._impact(s, nx, ny)
        return self._posts(s)

    def _posts(self, s: np.ndarray) -> np.ndarray:
        """A puck whose edge overlaps a post (a rim's end beside a goal opening, at x = +-L/2, y =
        +-goal_width/2) while moving toward it: the impact of a rim whose normal points from the post to
        the centre, and the centre put back at one radius (a corner contact, as the model meets it, with the
        test bed's own impact law)."""
        r, table = self.table.puck_radius, self.table
        for px in (table.length / 2, -table.length / 2):
            for py in (table.goal_width / 2, -table.goal_width / 2):
                dx, dy = s[0] - px, s[1] - py
                gap = math.hypot(dx, dy)
                if gap >= r or gap == 0.0 or dx * s[2] + dy * s[3] >= 0.0:
                    continue
                nx, ny = dx / gap, dy / gap
                s[0], s[1] = px + r * nx, py + r * ny
                self._impact(s, nx, ny)
        return s

    def _impact(self, s: np.ndarray, nx: float, ny: float) -> None:
        """The test bed's impact (:func:`real_rim_impact`) on ``s`` with the rim's inward normal (nx, ny)."""
        bx, by = ny, -nx
        vb, vn, s[5] = real_rim_impact(bx * s[2] + by * s[3], nx * s[2] + ny * s[3], s[5], self.table.puck_radius,
                                       self.effects)
        s[2], s[3] = bx * vb + nx * vn, by * vb + ny * vn

    def simulate(self, state: np.ndarray, duration: float, dt: float,
                 hit_at: float | None = None, hit_velocity: np.ndarray | None = None,
                 carry: tuple[float, float, np.ndarray] | None = None) -> tuple[np.ndarray, np.ndarray]:
        """True states every ``dt`` [s] for ``duration`` [s] from ``state``; with ``hit_at`` [s], the puck's
        velocity becomes ``hit_velocity`` [m/s] then (a human hit; the puck is held still before), growing
        evenly over ``effects.hit_duration`` [s] (a mallet's push; 0: at once); with ``carry`` (start [s],
        carry time [s], target pose, :meth:`HandCarry.draw`) a hand takes the puck at the start and carries
        it (:func:`carried_state`), then holds it still. Returns times (n,), states (n, 6)."""
        n = int(round(duration / dt)) + 1
        states = np.empty((n, 6))
        states[0] = state
        hit_step = 0 if hit_at is None else int(round(hit_at / dt))
        push = max(1, int(round(self.effects.hit_duration / dt)))  # steps of the push
        carry_step = n if carry is None else min(n, max(hit_step + 1, int(round(carry[0] / dt))))
        for i in range(1, carry_step):
            if i < hit_step:  # held by the hand until the hit
                states[i] = states[i - 1]
                continue
            if hit_at is not None and i - hit_step < push:
                states[i - 1, 2:4] = hit_velocity * (i - hit_step + 1) / push
            states[i] = self.step(states[i - 1], (i - 1) * dt, dt)
        times = np.arange(n) * dt
        if carry_step < n:  # in the hand again
            carry_from(times, states, carry_step, carry[1], carry[2])
        return times, states


def hit_from_rest(table: TableGeometry, speed: tuple[float, float], rng: np.random.Generator,
                  margin: float = 0.1) -> tuple[np.ndarray, np.ndarray]:
    """A resting puck anywhere on the table at least ``margin`` [m] inside the rims, and the velocity a
    human hit gives it: toward the table's centre region (within 60 deg of the direction to the
    centre), ``speed`` [m/s] uniform."""
    x = rng.uniform(-table.x_limit + margin, table.x_limit - margin)
    y = rng.uniform(-table.y_limit + margin, table.y_limit - margin)
    heading = math.atan2(-y, -x) + rng.uniform(-math.pi / 3, math.pi / 3)
    v = rng.uniform(*speed)
    return np.array([x, y, 0.0, 0.0, rng.uniform(-math.pi, math.pi), 0.0]), \
        v * np.array([math.cos(heading), math.sin(heading)])


def held_then_hit(state: np.ndarray, table: TableGeometry, hit_delay: tuple[float, float],
                  rng: np.random.Generator, margin: float = 0.1) -> tuple[np.ndarray, float, np.ndarray]:
    """A human hit of a session's shot ``state`` (x, y, vx, vy, theta, omega): the puck rests where the shot
    starts (at least ``margin`` [m] inside the rims, no spin), held for a random delay in ``hit_delay``
    [s], then hit to the shot's velocity. Returns (resting state, delay [s], hit velocity [m/s])."""
    rest = np.array(state, float)
    rest[0] = np.clip(rest[0], -table.x_limit + margin, table.x_limit - margin)
    rest[1] = np.clip(rest[1], -table.y_limit + margin, table.y_limit - margin)
    rest[2:4], rest[5] = 0.0, 0.0
    return rest, float(rng.uniform(*hit_delay)), np.array(state[2:4], float)


def testbed_shots(effects: TableEffects, table: TableGeometry, hit_delay: tuple[float, float], fine_dt: float,
                  rng: np.random.Generator, carry: HandCarry = HandCarry(), carry_rng: np.random.Generator | None = None):
    """Shots on the test bed's table (``simulate(state, duration) -> (times, states)`` for
    :func:`~air_hockey_agent.core.estimation.synthetic.synthetic_session`): each a human hit
    (:func:`held_then_hit`), ended by a hand's ``carry`` where it is enabled (drawn from ``carry_rng``, its
    own stream: shots without carries draw as they did before carries existed; with them, the shots after
    the first differ, as the hand shortens the physics each shot draws for); ``fine_dt`` [s] is the
    integration step."""

    def simulate(state: np.ndarray, duration: float) -> tuple[np.ndarray, np.ndarray]:
        puck = RealTablePuck(table, effects, rng)
        rest, delay, velocity = held_then_hit(state, table, hit_delay, rng)
        drawn = carry.draw(table, duration, carry_rng) if carry.enabled else None
        return puck.simulate(rest, duration, fine_dt, delay, velocity, drawn)
    return simulate
