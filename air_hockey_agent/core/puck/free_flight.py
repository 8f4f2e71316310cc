"""Closed form of free (impact-free) puck flight over many model steps, for :func:`.prediction.predict_fast`
(the recurrence and the exact Jacobian are explained in :mod:`.prediction`'s docstring)."""
from __future__ import annotations

import math

import numpy as np

from air_hockey_agent.core.puck.model import PuckModel, as_floats, wrap_angle
from air_hockey_agent.core.table import SHORT_WALLS, WALL_NORMALS


class FreeMotion:
    """Closed form of ``n`` free (impact-free) model steps from one state (see module docstring)."""

    def __init__(self, model: PuckModel, state: np.ndarray, dt: float) -> None:
        self.dt = dt
        self.x0, self.y0, vx, vy, self.theta0, self.omega = as_floats(state)
        self.a = 1.0 - dt * model.params.damping
        self.mu_dt = dt * model.params.friction_surface
        self.s0 = math.hypot(vx, vy)
        self.ux, self.uy = (vx / self.s0, vy / self.s0) if self.s0 > 0.0 else (0.0, 0.0)
        self.stop = self._stop_step()
        self._model = model

    def impact_step(self, max_steps: int) -> int | None:
        """First step in 1..max_steps that may hold a rim impact (the straight ray's first contact), or None."""
        hit = self._model.first_impact(self.x0, self.y0, self.ux, self.uy, math.inf) if self.s0 > 0.0 else None
        return self.first_step_reaching(hit[0], max_steps) if hit is not None else None

    def _stop_step(self) -> float:
        """First step index m with speed s_m = 0 (inf if the puck never stops)."""
        if self.s0 == 0.0:
            return 0.0 if self.mu_dt > 0.0 else math.inf
        if self.mu_dt == 0.0:
            return math.inf
        if self.a == 1.0:
            return math.ceil(self.s0 / self.mu_dt - 1e-12)
        c = self.mu_dt / (1.0 - self.a)
        return max(1, math.ceil(math.log(c / (self.s0 + c)) / math.log(self.a) - 1e-12))

    def speed(self, m: int) -> float:
        if m >= self.stop:
            return 0.0
        if self.a == 1.0:
            return self.s0 - m * self.mu_dt
        c = self.mu_dt / (1.0 - self.a)
        return (self.s0 + c) * self.a ** m - c

    def distance(self, n: int) -> float:
        """Distance travelled in n steps: dt * sum_{m<n} s_m [m]."""
        n = min(n, self.stop)
        if n <= 0:
            return 0.0
        if self.a == 1.0:
            return self.dt * (n * self.s0 - self.mu_dt * n * (n - 1) / 2.0)
        c = self.mu_dt / (1.0 - self.a)
        return self.dt * ((self.s0 + c) * (1.0 - self.a ** n) / (1.0 - self.a) - c * n)

    def first_step_reaching(self, target: float, max_steps: int) -> int | None:
        """Smallest n in 1..max_steps with distance(n) >= target, or None."""
        if max_steps < 1 or self.distance(max_steps) < target:
            return None
        lo, hi = 1, max_steps
        guess = self._steps_without_friction(target)
        if guess is not None and lo <= guess <= hi:  # friction only slows the puck: guess is a lower bound
            lo = guess
            while lo < hi and self.distance(lo) < target and lo - guess < 4:
                lo += 1
            if self.distance(lo) >= target:
                return lo
        while lo < hi:
            mid = (lo + hi) // 2
            if self.distance(mid) >= target:
                hi = mid
            else:
                lo = mid + 1
        return lo

    def _steps_without_friction(self, target: float) -> int | None:
        """Steps to travel ``target`` with damping only (a lower bound with friction), or None."""
        if self.s0 <= 0.0:
            return None
        if self.a == 1.0:
            return max(1, math.ceil(target / (self.dt * self.s0) - 1e-9))
        rest = 1.0 - target * (1.0 - self.a) / (self.dt * self.s0)
        if rest <= 0.0:
            return None
        return max(1, math.ceil(math.log(rest) / math.log(self.a) - 1e-9))

    def state_after(self, n: int) -> np.ndarray:
        ell, speed = self.distance(n), self.speed(n)
        return np.array([self.x0 + self.ux * ell, self.y0 + self.uy * ell, self.ux * speed, self.uy * speed,
                         wrap_angle(self.theta0 + n * self.dt * self.omega), self.omega])

    def jacobian(self, n: int) -> np.ndarray:
        """Exact Jacobian of n free steps."""
        dt, a = self.dt, self.a
        if self.s0 == 0.0 and self.mu_dt > 0.0:  # at rest: only the first step sees the velocity
            pa = pc = dt if n >= 1 else 0.0
            along = cross = 0.0
            uxx = uxy = uyy = 0.0
        else:
            moving = min(n, self.stop)
            along = a ** n if moving == n else 0.0
            pa = dt * (moving if a == 1.0 else (1.0 - a ** moving) / (1.0 - a))
            if self.s0 > 0.0:
                cross, pc = self.speed(n) / self.s0, self.distance(n) / self.s0
            else:  # mu_s = 0: isotropic damping
                cross, pc = along, pa
            uxx, uxy, uyy = self.ux * self.ux, self.ux * self.uy, self.uy * self.uy
        # blocks: pos_along * uu^T + pos_cross * (I - uu^T), and the same for the velocity
        return np.array([
            [1.0, 0.0, pc + (pa - pc) * uxx, (pa - pc) * uxy, 0.0, 0.0],
            [0.0, 1.0, (pa - pc) * uxy, pc + (pa - pc) * uyy, 0.0, 0.0],
            [0.0, 0.0, cross + (along - cross) * uxx, (along - cross) * uxy, 0.0, 0.0],
            [0.0, 0.0, (along - cross) * uxy, cross + (along - cross) * uyy, 0.0, 0.0],
            [0.0, 0.0, 0.0, 0.0, 1.0, n * dt],
            [0.0, 0.0, 0.0, 0.0, 0.0, 1.0]])

    def record_crossings(self, rec, t0: float, n: int) -> None:
        """Crossings of ``rec``'s pending lines (a prediction's recorder) during n free steps, interpolated inside
        the crossing step."""
        for line in list(rec.pending):
            if self.ux == 0.0:
                continue
            target = (line - self.x0) / self.ux
            if target < 0.0:
                continue
            i = 1 if target == 0.0 else self.first_step_reaching(target, n)
            if i is None:
                continue
            before, after = self.distance(i - 1), self.distance(i)
            frac = 0.0 if after == before else (target - before) / (after - before)
            speed = self.speed(i - 1)
            rec.cross(line, t0 + (i - 1 + frac) * self.dt, self.y0 + self.uy * target, self.ux * speed,
                       self.uy * speed)


class AcceleratedMotion:
    """Closed form of ``n`` free model steps with a table acceleration ``g`` and no surface friction.

    With ``mu_s = 0`` the step is linear, ``v <- a (v + dt g)`` with ``a = 1 - dt d`` (:meth:`PuckModel.decay`),
    so along any direction ``u`` the velocity relaxes geometrically to ``c = a dt g_u / (1 - a)``:
    ``v_m = c + (v_0 - c) a^m`` (``v_m = v_0 + m dt g_u`` without damping), and the distance travelled in
    ``n`` steps is ``dt sum_{m<n} v_m``. The velocity moves monotonically in ``m``, so a signed distance from a
    line (a rim, a defend line) either rises and then falls (its first step at or beyond the line is found by
    bisection) or falls and then rises (the same, among the steps before the motion turns). The Jacobian does
    not depend on ``g``: it is the damping-only transition ``F_d^n``, and the noise table's ``G_n`` is exact.
    """

    def __init__(self, model: PuckModel, state: np.ndarray, dt: float) -> None:
        self.dt = dt
        self.x0, self.y0, self.vx0, self.vy0, self.theta0, self.omega = as_floats(state)
        self.a = 1.0 - dt * model.params.damping
        self.gx, self.gy = model.params.table_acceleration
        self._table = model.table

    def velocity(self, u0: float, g: float, m: int) -> float:
        """Velocity component [m/s] after m steps, starting at u0 with acceleration g along the same axis."""
        if self.a == 1.0:
            return u0 + m * self.dt * g
        c = self.a * self.dt * g / (1.0 - self.a)
        return c + (u0 - c) * self.a ** m

    def travel(self, u0: float, g: float, n: int) -> float:
        """Displacement [m] along that axis in n steps: dt * sum_{m<n} v_m."""
        if self.a == 1.0:
            return self.dt * (n * u0 + self.dt * g * n * (n - 1) / 2.0)
        c = self.a * self.dt * g / (1.0 - self.a)
        return self.dt * (n * c + (u0 - c) * (1.0 - self.a ** n) / (1.0 - self.a))

    def first_step_beyond(self, d0: float, nx: float, ny: float, max_steps: int) -> int | None:
        """First n in 1..max_steps whose end lies on or beyond the line at signed distance ``d0 > 0`` [m] along
        the unit normal (nx, ny) pointing away from it (distance falls by the travel along -normal), or None."""
        u0, g = nx * self.vx0 + ny * self.vy0, nx * self.gx + ny * self.gy
        hi = min(max_steps, self._turn_step(u0, g))  # turning away from the line: only the steps before it
        if hi < 1 or d0 + self.travel(u0, g, hi) > 0.0:
            return None
        return _first_true(lambda n: d0 + self.travel(u0, g, n) <= 0.0, hi, 1)

    def _turn_step(self, u0: float, g: float) -> float:
        """First m with v_m >= 0 when v_m rises from u0 < 0 (the motion turns away from the line); inf when it
        does not (0 when it starts so)."""
        if u0 >= 0.0:
            return 0.0 if self.velocity(u0, g, 1) >= u0 else math.inf
        if self.a == 1.0:
            return math.ceil(-u0 / (self.dt * g) - 1e-12) if g > 0.0 else math.inf
        c = self.a * self.dt * g / (1.0 - self.a)
        if c <= 0.0:
            return math.inf
        m = max(0, math.ceil(math.log(c / (c - u0)) / math.log(self.a) - 1e-9))
        while m > 0 and self.velocity(u0, g, m - 1) >= 0.0:  # rounding of the logarithm
            m -= 1
        while self.velocity(u0, g, m) < 0.0:
            m += 1
        return m

    def impact_step(self, max_steps: int) -> int | None:
        """First step in 1..max_steps whose end crosses a rim line (a step the model must take itself: an
        impact, or a goal mouth), or None. A puck on or beyond a rim line now: step 1."""
        best = None
        for wall, normal in enumerate(WALL_NORMALS):
            d0 = self._table.distance_to_wall(wall, self.x0, self.y0)
            if d0 < 0.0 and wall in SHORT_WALLS:
                continue  # inside a goal: no short-rim impact (PuckModel.first_impact)
            if d0 <= 0.0:
                return 1
            n = self.first_step_beyond(d0, normal[0], normal[1], max_steps if best is None else best)
            best = n if n is not None else best
        return best

    def state_after(self, n: int) -> np.ndarray:
        return np.array([self.x0 + self.travel(self.vx0, self.gx, n), self.y0 + self.travel(self.vy0, self.gy, n),
                         self.velocity(self.vx0, self.gx, n), self.velocity(self.vy0, self.gy, n),
                         wrap_angle(self.theta0 + n * self.dt * self.omega), self.omega])

    def jacobian(self, n: int) -> np.ndarray:
        """Exact Jacobian of n free steps: F_d^n."""
        along = self.a ** n
        pos = self.dt * (n if self.a == 1.0 else (1.0 - along) / (1.0 - self.a))
        jac = np.eye(6)
        jac[0, 2] = jac[1, 3] = pos
        jac[2, 2] = jac[3, 3] = along
        jac[4, 5] = n * self.dt
        return jac

    def record_crossings(self, rec, t0: float, n: int) -> None:
        """Crossings of ``rec``'s pending lines x = line during n free steps, interpolated inside the crossing
        step as :class:`.prediction._Recorder` does."""
        for line in list(rec.pending):
            side = self.x0 - line
            i = 1 if side == 0.0 else self.first_step_beyond(abs(side), math.copysign(1.0, side), 0.0, n)
            if i is None:
                continue
            before, after = self.state_after(i - 1), self.state_after(i)
            x0, x1 = before[0] - line, after[0] - line
            frac = 0.0 if x0 == 0.0 else x0 / (x0 - x1)
            rec.cross(line, t0 + (i - 1 + frac) * self.dt, before[1] + frac * (after[1] - before[1]), before[2],
                      before[3])


class MarchedMotion:
    """Free model steps with a table acceleration and surface friction, marched step by step.

    No closed form is known here (the friction acts along a direction the acceleration keeps turning), so
    the mean takes the model's own decay (:meth:`PuckModel.decay`) step by step, compiled
    (:mod:`.march_kernel`), without the 6x6 matrix products of the stepwise prediction: the transition of
    free steps keeps the form ``[[I, B], [0, A]]`` on (position, velocity), so the Jacobian is two 2x2
    blocks multiplied up (exact), and the noise is taken from the damping-only table ``G_n``, which slightly
    overstates the velocity noise across the motion, as for friction without acceleration. A puck the
    friction holds at rest (``a |g| <= mu_s``) stays there.
    """

    def __init__(self, model: PuckModel, state: np.ndarray, dt: float) -> None:
        self.dt = dt
        self.x0, self.y0, self.vx0, self.vy0, self.theta0, self.omega = as_floats(state)
        self._model = model
        # rows 0..count: position and velocity, then the blocks A and B, after m steps (none marched yet)
        self._path = np.array([[self.x0, self.y0, self.vx0, self.vy0]])
        self._blocks = np.array([[1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0]])
        self._count = 0

    def impact_step(self, max_steps: int) -> int | None:
        """March up to max_steps steps (once per motion); the first whose end lies on or beyond a rim line
        (the model takes it itself), or None. A puck on or beyond a rim line now: step 1."""
        from .march_kernel import BLOCK_COLUMNS, PATH_COLUMNS, march  # numba: loaded by the first march
        table, dt, params = self._model.table, self.dt, self._model.params
        bounds = {(1.0, 0.0): -math.inf, (-1.0, 0.0): math.inf, (0.0, 1.0): -math.inf, (0.0, -1.0): math.inf}
        for wall, normal in enumerate(WALL_NORMALS):  # rims are axis-parallel: distance n.p + h <= 0 is a bound
            d0 = table.distance_to_wall(wall, self.x0, self.y0)
            if d0 < 0.0 and wall in SHORT_WALLS:
                continue  # inside a goal: no short-rim impact (PuckModel.first_impact)
            if d0 <= 0.0:
                return 1
            bounds[normal] = -table.wall_offset(wall) if sum(normal) > 0.0 else table.wall_offset(wall)
        box = np.array([bounds[1.0, 0.0], bounds[-1.0, 0.0], bounds[0.0, 1.0], bounds[0.0, -1.0]])
        self._path, self._blocks = np.empty((max_steps + 1, PATH_COLUMNS)), np.empty((max_steps + 1, BLOCK_COLUMNS))
        gx, gy = params.table_acceleration
        rest_holds = self._model.decay(0.0, 0.0, dt)[:2] == (0.0, 0.0)
        self._count, hit = march(self.x0, self.y0, self.vx0, self.vy0, float(gx), float(gy),
                                 1.0 - dt * params.damping, dt * params.friction_surface, dt, box, max_steps,
                                 rest_holds, self._path, self._blocks)
        return self._count if hit else None

    def _row(self, items: np.ndarray, n: int) -> np.ndarray:
        return items[min(n, self._count)]

    def state_after(self, n: int) -> np.ndarray:
        x, y, vx, vy = self._row(self._path, n)
        return np.array([x, y, vx, vy, wrap_angle(self.theta0 + n * self.dt * self.omega), self.omega])

    def jacobian(self, n: int) -> np.ndarray:
        """Exact Jacobian of n free steps."""
        a00, a01, a10, a11, b00, b01, b10, b11 = self._row(self._blocks, n)
        return np.array([[1.0, 0.0, b00, b01, 0.0, 0.0], [0.0, 1.0, b10, b11, 0.0, 0.0],
                         [0.0, 0.0, a00, a01, 0.0, 0.0], [0.0, 0.0, a10, a11, 0.0, 0.0],
                         [0.0, 0.0, 0.0, 0.0, 1.0, n * self.dt], [0.0, 0.0, 0.0, 0.0, 0.0, 1.0]])

    def record_crossings(self, rec, t0: float, n: int) -> None:
        """Crossings of ``rec``'s pending lines during the n marched steps, found as the stepwise prediction
        finds them (``rec.step`` of each step in turn)."""
        for i in range(1, n + 1):
            if not rec.pending:
                return
            rec.step(t0 + (i - 1) * self.dt, self.dt, self._row(self._path, i - 1), self._row(self._path, i), ())


def _first_true(predicate, hi: int, lo: int = 0) -> int:
    """Smallest m in lo..hi with predicate(m), for a predicate false then true; hi when it never holds."""
    while lo < hi:
        mid = (lo + hi) // 2
        if predicate(mid):
            hi = mid
        else:
            lo = mid + 1
    return lo
