"""The table's own acceleration of a puck, which the tracker's flight law (eq. 3.1) lacks (issue #13).

A real table pushes a sliding puck a little even where nothing touches it: its surface falls slightly
toward one side (a tilt: gravity's component along the surface) and its air film is not even (a smooth
field across the table). In the table frame [m, m/s^2, rad]:

    a(x, y) = g sin(tilt) (cos h, sin h)                          a surface that falls toward heading h
            + A (sin(2 pi y / L + p1), sin(2 pi x / L + p2))      an uneven air film: amplitude A [m/s^2],
                                                                  wavelength L [m], phases p1, p2 [rad]

The air film's field pushes along x with a wave across y and along y with a wave along x, so a puck
sliding straight along a long rim feels a steady sideways push that changes from lane to lane.

On top of the field, small random accelerations (:class:`RandomPush`: the film's turbulence; the test
bed's size, issue #13 does not measure them apart): a Gaussian value of std sigma [m/s^2] per axis, held
for a correlation time [s], then drawn again.

Used by the synthetic test bed (:mod:`.real_table`), the pybullet table (:mod:`air_hockey_agent.sim.world`)
and, for the tilt, the MuJoCo table (:mod:`air_hockey_agent.sim.mujoco_table`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import Any, Mapping

import numpy as np

GRAVITY = 9.81  # [m/s^2]


def tilt_acceleration(tilt: float, heading: float) -> tuple[float, float]:
    """Acceleration [m/s^2] (x, y) in the table's plane of a surface tilted by ``tilt`` [rad] that falls
    toward ``heading`` [rad] (table frame): g sin(tilt) along the heading."""
    slope = GRAVITY * math.sin(tilt)
    return slope * math.cos(heading), slope * math.sin(heading)


@dataclass(frozen=True)
class SurfaceField:
    """A tilted surface and an uneven air film (module docstring); every term may be zero."""

    tilt: float = 0.0                  # [rad] slope of the surface
    tilt_heading: float = 0.0          # [rad] direction (table frame) the surface falls toward
    air_film_amplitude: float = 0.0    # [m/s^2] peak acceleration of the air film's field
    air_film_wavelength: float = 1.0   # [m]
    air_film_phase: tuple[float, float] = (0.0, 0.0)  # [rad] p1, p2

    @classmethod
    def from_params(cls, params: Mapping[str, Any]) -> "SurfaceField":
        """From the simulated table's parameters (``config/sim.yaml``: ``surface_tilt``, ``surface_tilt_heading``,
        ``air_film_amplitude``, ``air_film_wavelength``, ``air_film_phase``)."""
        p1, p2 = params["air_film_phase"]
        return cls(float(params["surface_tilt"]), float(params["surface_tilt_heading"]),
                   float(params["air_film_amplitude"]), float(params["air_film_wavelength"]), (float(p1), float(p2)))

    @property
    def is_zero(self) -> bool:
        """True when the field pushes nowhere (no tilt, no air film)."""
        return self.tilt == 0.0 and self.air_film_amplitude == 0.0

    @cached_property
    def tilt_acceleration(self) -> tuple[float, float]:
        """The tilt's part [m/s^2] (x, y): the same everywhere on the table (computed once: :meth:`at` runs
        at every physics step)."""
        return tilt_acceleration(self.tilt, self.tilt_heading)

    @property
    def max_push(self) -> float:
        """The largest acceleration [m/s^2] the field gives anywhere: each air-film component reaches +-A
        wherever its sine does, independently of the other, so sqrt((|gx| + A)^2 + (|gy| + A)^2). A
        surface friction (constant deceleration) at least this large holds a resting puck everywhere and
        keeps a sliding one from ever speeding up."""
        gx, gy = self.tilt_acceleration
        return math.hypot(abs(gx) + self.air_film_amplitude, abs(gy) + self.air_film_amplitude)

    def at(self, x: float, y: float) -> tuple[float, float]:
        """Acceleration [m/s^2] (x, y) of a puck at (x, y) [m] in the table frame."""
        gx, gy = self.tilt_acceleration
        if self.air_film_amplitude == 0.0:
            return gx, gy
        k, (p1, p2) = 2.0 * math.pi / self.air_film_wavelength, self.air_film_phase
        return gx + self.air_film_amplitude * math.sin(k * y + p1), gy + self.air_film_amplitude * math.sin(k * x + p2)


class RandomPush:
    """Random accelerations [m/s^2] (x, y) of std ``std`` per axis, each held for ``hold`` [s] (module
    docstring), drawn from ``rng``; ``std`` 0 draws nothing."""

    def __init__(self, std: float, hold: float, rng: np.random.Generator) -> None:
        self.std, self.hold, self.rng = std, hold, rng
        self._value = np.zeros(2)
        self._until = -math.inf

    def at(self, t: float) -> np.ndarray:
        """The acceleration [m/s^2] held at time ``t`` [s] (times asked in order: a time at or past the
        current value's end draws the next one, which holds for ``hold`` from ``t``)."""
        if self.std > 0.0 and t >= self._until:
            self._value = self.rng.normal(0.0, self.std, 2)
            self._until = t + self.hold
        return self._value


def slide_from_rest(ax: float, ay: float, friction: float, dt: float) -> tuple[float, float]:
    """Velocity [m/s] after ``dt`` [s] of a puck at rest that the surface pushes by (``ax``, ``ay``) [m/s^2]
    against a surface friction ``friction`` [m/s^2] (a constant deceleration, which holds a resting puck
    like a static friction): none while the push is at most the friction, else the excess along the push."""
    push = math.hypot(ax, ay)
    if push <= friction:
        return 0.0, 0.0
    share = dt * (push - friction) / push
    return share * ax, share * ay
