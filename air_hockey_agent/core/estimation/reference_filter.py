"""A reference filter to measure the tracker against: a linear Kalman filter built as the Air Hockey Challenge
baseline's tracker is described in REFERENCE_FACTS sec. 1.2-1.9 (``air-hockey eval-prediction --reference``;
issue #13 sets our target as a ratio to that baseline's error). Written from the description, with its
identified constants (``config/reference_filter.yaml``); not a filter to track with.

* free flight: linear damping per axis, ``v' = (1 - dt d) v``, ``p' = p + dt v``, ``theta' = theta + dt
  omega`` (wrapped); process noise ``process_noise * dt / step``;
* rim impact: the first rim line (the table's rims inset by the puck's radius, short rims full width) the
  step's straight displacement crosses; the step flies to it, maps the velocity and spin in the rim's frame
  (tangent t, inward normal n, a right-handed pair) by the identified linear map, and flies the rest of the
  step; no damping within that step; its process noise is the rim's (``rim.noise``, turned into the table
  frame) instead of the flight's;
* a puck within half the goal width of the centre line whose step would cross a short rim line is scored,
  and a centre beyond the rim lines elsewhere is off the table: the step holds the state (F = I, no noise);
* update: every pose on the table, no gate; a track starts at its first pose with zero velocity and spin
  and P = ``initial_covariance`` I, and again after ``max_prediction_gap`` without frames (as the tracker).

It offers what :mod:`.evaluation` uses of a filter (``process``, ``reset``, ``x``, ``P``, ``stamp``,
``initialised``, ``last_nis``, ``stats``, ``model``, ``marker_offset``, ``plausible``, ``predict_from``),
so both are evaluated on one definition, against the same valid poses.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence

import numpy as np

from air_hockey_agent.core.estimation.ekf import FilterStats
from air_hockey_agent.core.puck.model import wrap_angle
from air_hockey_agent.core.puck.prediction import Prediction
from air_hockey_agent.core.table import SHORT_WALLS, WALL_NORMALS, TableGeometry

_H = np.zeros((3, 6))
_H[0, 0] = _H[1, 1] = _H[2, 4] = 1.0
_VELOCITY_SPIN = (2, 3, 5)  # the state rows and columns the rim map and its noise act on


@dataclass(frozen=True)
class ReferenceSettings:
    """The reference filter's constants (``config/reference_filter.yaml``) and the evaluation's own."""

    damping: tuple[float, float]     # [1/s] along x, y
    step: float                      # [s] the step process_noise is given for
    q: np.ndarray                    # (6, 6) process noise per step
    r: np.ndarray                    # (3, 3) measurement noise
    p0: float                        # [-] a track's first covariance times the identity
    rim_map: np.ndarray              # (3, 3) on (vt, vn, omega); the [*, vn] entries of vt and omega take s
    rim_noise: np.ndarray            # (3, 3) on (vt, vn, omega)
    dt: float                        # [s] model step (the tracker's frequency)
    max_prediction_gap: float        # [s] longer without frames: a new track (the tracker's)
    glitch_speed: float | None       # [m/s] marker glitches are no ground truth (the tracker's)
    outside_table_margin: float      # [m] poses farther off the table are no measurement (the tracker's)

    @classmethod
    def from_params(cls, reference: Mapping[str, Any], tracker: Mapping[str, Any]) -> "ReferenceSettings":
        """From ``reference_params.load_reference_params`` and the tracker's parameters (its step, gap,
        glitch speed and table margin, so both filters are judged against the same poses)."""
        a, b = reference["rim.tangential"]
        ws, wn, ww = reference["rim.spin"]
        rim_map = np.array([[a, 0.0, b], [0.0, -reference["rim.restitution"], 0.0], [ws, wn, ww]])
        tt, nn, tn, tw, nw, ww = reference["rim.noise"]
        rim_noise = np.array([[tt, tn, tw], [tn, nn, nw], [tw, nw, ww]])
        return cls(tuple(reference["damping"]), reference["step"], np.diag(reference["process_noise"]),
                   np.diag(reference["measurement_noise"]), reference["initial_covariance"], rim_map, rim_noise,
                   1.0 / tracker["frequency"], tracker["max_prediction_gap"],
                   tracker["glitch_speed"], tracker["outside_table_margin"])


@dataclass(frozen=True)
class ReferenceModel:
    """The reference's motion model on a table: one step's matrix and noise (module docstring)."""

    table: TableGeometry
    settings: ReferenceSettings

    def step(self, x: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray, int | None]:
        """(F, Q, the rim met or None) of a step of ``dt`` [s] from state ``x``; the next state is F x
        (angle wrapped), its covariance F P F^T + Q."""
        if self._held(x, dt):
            return np.eye(6), np.zeros((6, 6)), None
        px, py, vx, vy = x[:4]
        hit = self._first_crossing(px, py, vx * dt, vy * dt)
        if hit is None:
            return self._flight(dt), self.settings.q * (dt / self.settings.step), None
        wall, fraction = hit
        rotation = _rim_frame(wall)
        local = rotation @ np.array([vx, vy])
        impact = self.settings.rim_map.copy()
        slide = 1.0 if local[0] + x[5] * self.table.puck_radius >= 0.0 else -1.0
        impact[0, 1] *= slide
        impact[2, 1] *= slide
        to_local = np.eye(3)
        to_local[:2, :2] = rotation
        f_rim = np.eye(6)
        f_rim[np.ix_(_VELOCITY_SPIN, _VELOCITY_SPIN)] = to_local.T @ impact @ to_local
        q = np.zeros((6, 6))
        q[np.ix_(_VELOCITY_SPIN, _VELOCITY_SPIN)] = to_local.T @ self.settings.rim_noise @ to_local
        return _drift((1.0 - fraction) * dt) @ f_rim @ _drift(fraction * dt), q, wall

    def propagate(self, x: np.ndarray, dt: float, steps: int) -> tuple[np.ndarray, list]:
        """The state after ``steps`` steps of ``dt`` [s] from ``x`` and the rims met on the way ((step, wall)),
        as :meth:`step` gives them one by one, but the flight between impacts in closed form."""
        x = np.array(x, float)
        impacts, k = [], 0
        while k < steps:
            if self._held(x, dt):
                break  # a held state is held for good
            clear = min(self._clear_steps(x, dt), steps - k)
            if clear > 0:
                x, k = self._fly(x, dt, clear), k + clear
                continue
            f, _, wall = self.step(x, dt)
            x = f @ x
            x[4] = wrap_angle(x[4])
            k += 1
            if wall is not None:
                impacts.append((k, wall))
        return x, impacts

    def _held(self, x: np.ndarray, dt: float) -> bool:
        """Whether a step of ``dt`` [s] holds state ``x``: a puck in the goal band (within half the goal
        width of the centre line) whose step would cross a short rim line is scored; a centre beyond the
        rim lines elsewhere is off the table."""
        t = self.table
        if abs(x[1]) < 0.5 * t.goal_width:
            return abs(x[0] + x[2] * dt) > t.x_limit
        return abs(x[0]) > t.x_limit or abs(x[1]) > t.y_limit

    def _clear_steps(self, x: np.ndarray, dt: float) -> int | float:
        """Whole flight steps from ``x`` that surely end inside the rim lines (one step short of the first
        that might not, against rounding; inf when the damping stops the puck first)."""
        clear = math.inf
        for axis, limit in ((0, self.table.x_limit), (1, self.table.y_limit)):
            v = x[axis + 2]
            if v == 0.0:
                continue
            a = 1.0 - dt * self.settings.damping[axis]
            if a <= 0.0:
                return 0
            room = limit - (x[axis] if v > 0.0 else -x[axis])  # to the rim line ahead
            per_step = dt * abs(v)
            if a == 1.0:
                crossing = math.floor(room / per_step) + 1
            else:
                c = room * (1.0 - a) / per_step
                if c >= 1.0:
                    continue  # it stops short of that rim line
                crossing = math.floor(math.log1p(-c) / math.log(a)) + 1
            clear = min(clear, max(crossing - 2, 0))
        return clear

    def _fly(self, x: np.ndarray, dt: float, n: int) -> np.ndarray:
        """``n`` flight steps in closed form: v_n = a^n v, p_n = p + dt v (1 - a^n) / (1 - a), a = 1 - dt d."""
        out = x.copy()
        for axis in (0, 1):
            a = 1.0 - dt * self.settings.damping[axis]
            power = a ** n
            out[axis] += dt * x[axis + 2] * (n if a == 1.0 else (1.0 - power) / (1.0 - a))
            out[axis + 2] = x[axis + 2] * power
        out[4] = wrap_angle(x[4] + n * dt * x[5])
        return out

    def _flight(self, dt: float) -> np.ndarray:
        """F of a flight step of ``dt`` [s]: the drift, and the velocity damped per axis."""
        f = _drift(dt)
        f[2, 2] = 1.0 - dt * self.settings.damping[0]
        f[3, 3] = 1.0 - dt * self.settings.damping[1]
        return f

    def _first_crossing(self, px: float, py: float, ux: float, uy: float) -> tuple[int, float] | None:
        """The rim line (inset by the radius, short rims full width) the displacement (ux, uy) [m] from
        (px, py) crosses first, and the fraction of the step at which; None when it crosses none."""
        best = None
        for wall, (nx, ny) in enumerate(WALL_NORMALS):
            before = nx * px + ny * py + self.table.wall_offset(wall)
            after = before + nx * ux + ny * uy
            if before > 0.0 and after < 0.0:
                fraction = before / (before - after)
                along = (py + fraction * uy) if wall in SHORT_WALLS else (px + fraction * ux)
                limit = self.table.y_limit if wall in SHORT_WALLS else self.table.x_limit
                if abs(along) <= limit and (best is None or fraction < best[1]):
                    best = (wall, fraction)
        return best


def _drift(dt: float) -> np.ndarray:
    """Positions and angle move with the velocity and spin for ``dt`` [s]; velocity and spin kept."""
    f = np.eye(6)
    f[0, 2] = f[1, 3] = f[4, 5] = dt
    return f


def _rim_frame(wall: int) -> np.ndarray:
    """Rows: the rim's tangent t and inward normal n in the table frame (t = n turned by -90 degrees, so
    (t, n) is right-handed and the spin keeps its sign)."""
    nx, ny = WALL_NORMALS[wall]
    return np.array([[ny, -nx], [nx, ny]])


@dataclass
class ReferenceFilter:
    """The reference Kalman filter (module docstring) on irregular mocap frames."""

    model: ReferenceModel
    settings: ReferenceSettings
    x: np.ndarray = field(default_factory=lambda: np.zeros(6))
    P: np.ndarray = field(default_factory=lambda: np.eye(6))
    stamp: float | None = None
    initialised: bool = False
    last_nis: float | None = None
    stats: FilterStats = field(default_factory=FilterStats)
    marker_offset: tuple[float, float] = (0.0, 0.0)  # the reference knows no marker offset

    @classmethod
    def from_params(cls, reference: Mapping[str, Any], tracker: Mapping[str, Any]) -> "ReferenceFilter":
        settings = ReferenceSettings.from_params(reference, tracker)
        return cls(ReferenceModel(TableGeometry.from_params(tracker), settings), settings)

    def reset(self) -> None:
        """Forget the track: the next pose starts a new one."""
        self.initialised, self.stamp = False, None

    def plausible(self, z: Sequence[float]) -> bool:
        """A pose that can be the puck: finite and on the table within the tracker's margin."""
        margin = self.settings.outside_table_margin
        return all(math.isfinite(v) for v in z) and self.model.table.contains(z[0], z[1], margin)

    def process(self, t: float, z: Sequence[float] | None) -> None:
        """One mocap frame at ``t`` [s]: pose ``z`` (x, y, theta) or None (lost)."""
        self.stats.frames += 1
        self.last_nis = None
        if z is not None and not self.plausible(z):
            self.stats.off_table += 1
            z = None
        gap = self.settings.max_prediction_gap
        if self.initialised and not -gap <= t - self.stamp <= gap:
            self.reset()  # a gap, or time ran back far (a replay loop): a new track, as the tracker's
        if not self.initialised:
            if z is not None:
                self.x = np.array([z[0], z[1], 0.0, 0.0, wrap_angle(z[2]), 0.0])
                self.P = self.settings.p0 * np.eye(6)
                self.initialised, self.stamp = True, t
                self.stats.reinitialisations += 1
            return
        if t <= self.stamp:  # a repeated or late stamp: not fused, as by the tracker
            self.stats.repeated_frames += 1
            return
        self.x, self.P, _ = self._propagate(self.x, self.P, t - self.stamp)
        self.stamp = t
        if z is None:
            self.stats.lost_frames += 1
            return
        self._update(np.asarray(z, float))

    def _update(self, z: np.ndarray) -> None:
        y = z - _H @ self.x
        y[2] = wrap_angle(y[2])
        s = _H @ self.P @ _H.T + self.settings.r
        gain = np.linalg.solve(s, _H @ self.P).T
        self.last_nis = float(y @ np.linalg.solve(s, y))
        self.x = self.x + gain @ y
        self.x[4] = wrap_angle(self.x[4])
        self.P = (np.eye(6) - gain @ _H) @ self.P

    def _propagate(self, x: np.ndarray, p: np.ndarray | None, horizon: float) -> tuple:
        """State (and covariance unless None) ``horizon`` [s] on, in model steps (the last one shorter),
        and the impacts met: (time [s], wall, x, y, sliding False; without covariance x, y are the state's
        at the horizon)."""
        steps = max(1, round(horizon / self.settings.dt))
        dt = horizon / steps
        if p is None:  # the evaluation's predictions: the flight between impacts in closed form
            x, met = self.model.propagate(x, dt, steps)
            return x, None, [(k * dt, wall, float(x[0]), float(x[1]), False) for k, wall in met]
        impacts = []
        for k in range(steps):
            f, q, wall = self.model.step(x, dt)
            x = f @ x
            x[4] = wrap_angle(x[4])
            p = f @ p @ f.T + q
            if wall is not None:
                impacts.append(((k + 1) * dt, wall, float(x[0]), float(x[1]), False))
        return x, p, impacts

    def predict_from(self, model: ReferenceModel, x: np.ndarray, p: np.ndarray | None, horizon: float) -> Prediction:
        """Prediction ``horizon`` [s] ahead of a recorded state (``model`` is the one it was recorded with:
        the reference's never changes)."""
        state, covariance, impacts = self._propagate(np.asarray(x, float), p, horizon)  # x itself is not changed
        return Prediction(state, covariance, impacts)
