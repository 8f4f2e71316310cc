"""Prediction of the puck state and covariance over a horizon (thesis sec. 4.2, 5.1.1).

Two predictors with one result type:

* :func:`predict_stepwise`: the reference. Applies the model step (:class:`PuckModel`) ``k`` times,
  ``P <- F P F^T + Q`` each step, then one shorter step for the remainder of the horizon.
* :func:`predict_fast`: the same discrete model, jumping from impact to impact. Between impacts the
  direction of motion is constant and the speed follows the linear recurrence
  ``s_{m+1} = a s_m - dt mu_s`` (``a = 1 - dt d``), so ``k`` free steps have a closed form: speed,
  travelled distance, and the exact ``k``-step Jacobian (along the motion ``a^k``, across it
  ``s_k / s_0``, because each step scales the cross-track part by ``a - dt mu_s / s_m = s_{m+1}/s_m``).
  The step that contains an impact is found by bisection on the closed-form distance and is computed
  with the model's exact step. The process noise added over ``k`` free steps is taken from a cached
  table ``G_k = sum_i F_d^i Q F_d^iT`` of the damping-only transition ``F_d``: exact when
  ``friction_surface = 0``, otherwise it slightly overstates the cross-track velocity noise at low
  speed (conservative). Mean and transition Jacobian are exact in both cases. With a table
  acceleration (``PuckParams.table_acceleration`` not zero) the path bends: without surface friction the
  step is still linear and :class:`.free_flight.AcceleratedMotion` jumps in closed form (the noise table
  is then exact); with both, no closed form is known and :class:`.free_flight.MarchedMotion` takes the free
  steps in compiled scalar arithmetic (:mod:`.march_kernel`), without the matrix products (``bench tracker``
  shows the costs).

Line crossings (e.g. the robots' defend lines) are interpolated linearly inside the step that
crosses, identically in both predictors.
"""
from __future__ import annotations

import math
import weakref
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from air_hockey_agent.core.puck.free_flight import AcceleratedMotion, FreeMotion, MarchedMotion
from air_hockey_agent.core.puck.model import PuckModel, PuckParams

STEP_EPS = 1e-9  # [-] fraction of a step below which a horizon remainder is dropped (float rounding)


@dataclass
class Crossing:
    """First crossing of the line x = line_x: time after the start [s], y [m], velocity [m/s]."""

    line_x: float
    time: float
    y: float
    vx: float
    vy: float


@dataclass
class Prediction:
    """Predicted state and covariance at the horizon, with what happened on the way."""

    state: np.ndarray
    covariance: np.ndarray | None  # None when predicted without covariance
    impacts: list = field(default_factory=list)      # (time [s], wall, x, y, sliding)
    samples: list = field(default_factory=list)      # (time [s], state, covariance) every sample period
    crossings: dict = field(default_factory=dict)    # line_x -> Crossing (first crossing only)


def impact_covariance(state: np.ndarray, ratio: float) -> np.ndarray:
    """Process noise [6x6] of a rim impact: velocity and spin uncertain by ``ratio`` of their size after it
    (restitution and rim friction of real rims vary with the impact: issue #13)."""
    q = np.zeros((6, 6))
    speed2 = state[2] ** 2 + state[3] ** 2
    q[2, 2] = q[3, 3] = ratio ** 2 * speed2
    q[5, 5] = ratio ** 2 * state[5] ** 2
    return q


def _split_horizon(horizon: float, dt: float) -> tuple[int, float]:
    steps = int(math.floor(horizon / dt + STEP_EPS))
    remainder = horizon - steps * dt
    return steps, (remainder if remainder > STEP_EPS * dt else 0.0)


class _Recorder:
    """Collects impacts, samples and line crossings in the same way for both predictors."""

    def __init__(self, lines: Sequence[float], sample_every: int) -> None:
        self.pending = list(lines)
        self.sample_every = sample_every
        self.result = Prediction(np.zeros(6), np.zeros((6, 6)))

    def step(self, t0: float, dt: float, before: np.ndarray, after: np.ndarray, impacts) -> None:
        for imp in impacts:
            self.result.impacts.append((t0 + imp.time, imp.wall, imp.x, imp.y, imp.sliding))
        for line in list(self.pending):
            x0, x1 = before[0] - line, after[0] - line
            if x0 == 0.0 or x0 * x1 < 0.0 or (x1 == 0.0 and x0 != 0.0):
                frac = 0.0 if x0 == 0.0 else x0 / (x0 - x1)
                y = before[1] + frac * (after[1] - before[1])
                self.cross(line, t0 + frac * dt, y, before[2], before[3])

    def cross(self, line: float, time: float, y: float, vx: float, vy: float) -> None:
        self.result.crossings[line] = Crossing(line, time, y, vx, vy)
        self.pending.remove(line)

    def sample(self, step_index: int, t: float, state: np.ndarray, cov: np.ndarray | None) -> None:
        if self.sample_every and step_index % self.sample_every == 0:
            self.result.samples.append((t, state.copy(), None if cov is None else cov.copy()))


def _finish(model: PuckModel, rec: _Recorder, s: np.ndarray, p: np.ndarray | None, t: float, remainder: float,
            dt: float, q: np.ndarray, impact_noise: float) -> Prediction:
    """Last, shorter step of the horizon (noise scaled by its length); store the final state."""
    if remainder:
        res = model.step(s, remainder, with_jacobian=p is not None)
        rec.step(t, remainder, s, res.state, res.impacts)
        s = res.state
        if p is not None:
            p = with_impact_noise(res.jacobian @ p @ res.jacobian.T + q * (remainder / dt), s, res.impacts,
                                   impact_noise)
    rec.result.state, rec.result.covariance = s, p
    return rec.result


def with_impact_noise(p: np.ndarray, state: np.ndarray, impacts, ratio: float) -> np.ndarray:
    """``p`` plus the impact covariance when the step had a rim impact (and ``ratio`` > 0)."""
    return p + impact_covariance(state, ratio) if impacts and ratio else p


def predict_stepwise(model: PuckModel, state: np.ndarray, cov: np.ndarray | None, horizon: float, dt: float,
                     q: np.ndarray, lines: Sequence[float] = (), sample_every: int = 0,
                     impact_noise: float = 0.0) -> Prediction:
    """Reference prediction: ``horizon`` [s] in model steps of ``dt`` [s] with per-step noise ``q`` (and
    :func:`impact_covariance` of ``impact_noise`` after each step with a rim impact); ``cov=None``
    propagates the mean only."""
    steps, remainder = _split_horizon(horizon, dt)
    rec = _Recorder(lines, sample_every)
    s, p = np.asarray(state, float), (None if cov is None else np.asarray(cov, float))
    for i in range(steps):
        res = model.step(s, dt, with_jacobian=p is not None)
        rec.step(i * dt, dt, s, res.state, res.impacts)
        s = res.state
        if p is not None:
            p = with_impact_noise(res.jacobian @ p @ res.jacobian.T + q, s, res.impacts, impact_noise)
        rec.sample(i + 1, (i + 1) * dt, s, p)
    return _finish(model, rec, s, p, steps * dt, remainder, dt, q, impact_noise)


class NoiseTable:
    """``G_k = sum_{i<k} F_d^i Q F_d^iT`` for the damping-only transition F_d, grown on demand."""

    def __init__(self, dt: float, damping: float, q: np.ndarray) -> None:
        self._f = np.eye(6)
        self._f[0, 2] = self._f[1, 3] = self._f[4, 5] = dt
        self._f[2, 2] = self._f[3, 3] = 1.0 - dt * damping
        self._q = np.array(q, float)
        self._table = [np.zeros((6, 6))]

    def get(self, k: int) -> np.ndarray:
        while len(self._table) <= k:
            self._table.append(self._f @ self._table[-1] @ self._f.T + self._q)
        return self._table[k]


_NOISE_TABLES: dict = {}
_MAX_CACHED_TABLES = 16  # sysid tries many damping values; keep the cache small


def noise_table(dt: float, damping: float, q: np.ndarray) -> NoiseTable:
    """Cached :class:`NoiseTable` for these values."""
    key = (dt, damping, np.asarray(q, float).tobytes())
    table = _NOISE_TABLES.get(key)
    if table is None:
        if len(_NOISE_TABLES) >= _MAX_CACHED_TABLES:
            _NOISE_TABLES.pop(next(iter(_NOISE_TABLES)))
        table = _NOISE_TABLES[key] = NoiseTable(dt, damping, q)
    return table


def prepare_prediction(params: PuckParams, learns_tilt: bool = True) -> None:
    """Load the compiled march (:mod:`.march_kernel`) now when these parameters can take it, instead of in
    the first such prediction (about half a second): with a surface friction, a table acceleration
    (configured, or learned online when ``learns_tilt``) makes the prediction march."""
    if params.friction_surface > 0.0 and (params.accelerated or learns_tilt):
        from .march_kernel import warm_up
        warm_up()


_MEAN_KERNEL: list = []  # the compiled kernel module (:mod:`.prediction_kernel`), loaded by the first use
_KERNEL_PARAMS: "weakref.WeakKeyDictionary[PuckModel, np.ndarray]" = weakref.WeakKeyDictionary()


def prepare_mean_prediction():
    """Load the compiled mean (:func:`predict_mean`, :mod:`.prediction_kernel`) now instead of in the first mean-only
    prediction (numba's import and the cached machine code: about half a second; compiling it the first time
    on a machine: seconds). Returns the kernel module."""
    if not _MEAN_KERNEL:
        from . import prediction_kernel
        prediction_kernel.warm_up()
        _MEAN_KERNEL.append(prediction_kernel)
    return _MEAN_KERNEL[0]


def predict_mean(model: PuckModel, state: np.ndarray, horizon: float, dt: float, lines: Sequence[float] = (),
                 sample_every: int = 0) -> Prediction:
    """The mean of :func:`predict_stepwise` (``cov=None``): the same model steps, compiled
    (:mod:`.prediction_kernel`); ``Prediction.covariance`` is None."""
    kernel = _MEAN_KERNEL[0] if _MEAN_KERNEL else prepare_mean_prediction()
    params = _KERNEL_PARAMS.get(model)
    if params is None:
        params = _KERNEL_PARAMS[model] = kernel.kernel_params(model)
    steps, remainder = _split_horizon(horizon, dt)
    lines = list(lines)
    final, impacts, crossings, samples = kernel.predict_mean(params, np.ascontiguousarray(state, float), steps,
                                                             remainder, dt, np.array(lines, float), sample_every)
    result = Prediction(final, None)
    result.impacts = [(t, int(wall), x, y, sliding != 0.0) for t, wall, x, y, sliding in impacts.tolist()]
    result.samples = [(float(row[0]), row[1:], None) for row in samples]
    for line, (crossed, time, y, vx, vy) in zip(lines, crossings.tolist()):
        if crossed and line not in result.crossings:
            result.crossings[line] = Crossing(line, time, y, vx, vy)
    return result


def predict_fast(model: PuckModel, state: np.ndarray, cov: np.ndarray | None, horizon: float, dt: float,
                 q: np.ndarray, lines: Sequence[float] = (), sample_every: int = 0,
                 impact_noise: float = 0.0) -> Prediction:
    """Prediction by closed-form jumps between impacts; agrees with :func:`predict_stepwise`.

    With ``cov=None`` only the mean is propagated (``Prediction.covariance`` is None), by the model's own
    steps in compiled code (:func:`predict_mean`): the tactics, the offline evaluation and system
    identification need no covariance.
    """
    if cov is None:
        return predict_mean(model, state, horizon, dt, lines, sample_every)
    params = model.params
    free_motion = (FreeMotion if not params.accelerated else
                   AcceleratedMotion if params.friction_surface == 0.0 else MarchedMotion)
    table = noise_table(dt, model.params.damping, q)
    steps, remainder = _split_horizon(horizon, dt)
    rec = _Recorder(lines, sample_every)
    s, p = np.asarray(state, float), np.asarray(cov, float)
    # The jumps stop at every sample: the noise table G_n is exact only without surface friction, and
    # shorter jumps keep it closest to the stepwise prediction.
    done = 0
    while done < steps:
        budget = steps - done
        if sample_every:
            budget = min(budget, sample_every - done % sample_every)
        free = free_motion(model, s, dt)
        reach = free.impact_step(budget)
        jump = budget if reach is None else reach - 1
        if jump > 0:
            free.record_crossings(rec, done * dt, jump)
            phi = free.jacobian(jump)
            p = phi @ p @ phi.T + table.get(jump)
            s, done = free.state_after(jump), done + jump
            rec.sample(done, done * dt, s, p)
        if reach is not None:
            res = model.step(s, dt)
            rec.step(done * dt, dt, s, res.state, res.impacts)
            s = res.state
            p = with_impact_noise(res.jacobian @ p @ res.jacobian.T + q, s, res.impacts, impact_noise)
            done += 1
            rec.sample(done, done * dt, s, p)
    return _finish(model, rec, s, p, steps * dt, remainder, dt, q, impact_noise)
