"""Closed form of free (impact-free) puck flight over many model steps, for :func:`.prediction.predict_fast`
(the recurrence and the exact Jacobian are explained in :mod:`.prediction`'s docstring)."""
from __future__ import annotations

import math

import numpy as np

from air_hockey_agent.core.puck.model import PuckModel, as_floats, wrap_angle


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


def record_free_crossings(rec, free: FreeMotion, t0: float, n: int) -> None:
    """Crossings of ``rec``'s pending lines (a prediction's recorder) during n free steps, interpolated inside
    the crossing step."""
    for line in list(rec.pending):
        if free.ux == 0.0:
            continue
        target = (line - free.x0) / free.ux
        if target < 0.0:
            continue
        i = 1 if target == 0.0 else free.first_step_reaching(target, n)
        if i is None:
            continue
        before, after = free.distance(i - 1), free.distance(i)
        frac = 0.0 if after == before else (target - before) / (after - before)
        speed = free.speed(i - 1)
        rec.cross(line, t0 + (i - 1 + frac) * free.dt, free.y0 + free.uy * target, free.ux * speed,
                   free.uy * speed)
