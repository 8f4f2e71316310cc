"""Prediction of the puck state and covariance over a horizon (thesis sec. 4.2, 5.1.1).

Two predictors with one result type:

* :func:`predict_stepwise`: the reference, in Python. Applies the model step (:class:`PuckModel`) ``k``
  times, ``P <- F P F^T + Q`` each step (and :func:`impact_covariance` after a step with a rim impact), then
  one shorter step for the remainder of the horizon (its noise scaled by its length).
* :func:`predict_fast`: the same steps in compiled code (:mod:`.prediction_kernel`, numba), where a step that
  cannot reach a rim on a flat table skips the contact search; with ``cov=None`` the mean alone. It agrees
  with :func:`predict_stepwise` up to rounding (``test_prediction.py``).

Line crossings (e.g. the robots' defend lines) are interpolated linearly inside the step that
crosses, along the step's path (to each rim impact's centre in turn, then to the step's end: a line
crossed just before a rim is crossed even when the impact in the same step sends the puck back),
identically in both predictors.
"""
from __future__ import annotations

import math
import weakref
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from air_hockey_agent.core.puck.model import PuckModel

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


def impact_covariance(state: np.ndarray, ratio: float, contact_time: float = 0.0) -> np.ndarray:
    """Process noise [6x6] of a rim impact, from the state after it: velocity and spin uncertain by ``ratio``
    of their size (restitution and rim friction of real rims vary with the impact: issue #13), the position
    by the distance the puck travels in ``contact_time`` [s] (a real rim's contact lasts milliseconds,
    where the model's impact is instantaneous: the outgoing path is offset by up to that travel)."""
    q = np.zeros((6, 6))
    speed2 = state[2] ** 2 + state[3] ** 2
    q[0, 0] = q[1, 1] = contact_time ** 2 * speed2
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
        """A step of ``dt`` [s] from ``t0`` [s]: its impacts, and the lines its path crosses (straight from
        ``before`` to each impact's centre in turn, then to ``after``; the velocity recorded is ``before``'s,
        after an impact the piece's secant: the model moves at one velocity between them)."""
        for imp in impacts:
            self.result.impacts.append((t0 + imp.time, imp.wall, imp.x, imp.y, imp.sliding))
        ta, xa, ya, vxa, vya = t0, before[0], before[1], before[2], before[3]
        ends = [(t0 + imp.time, imp.x, imp.y) for imp in impacts] + [(t0 + dt, after[0], after[1])]
        for k, (tb, xb, yb) in enumerate(ends):
            if k > 0 and tb > ta:
                vxa, vya = (xb - xa) / (tb - ta), (yb - ya) / (tb - ta)
            self._cross_piece(ta, tb - ta, xa, ya, vxa, vya, xb, yb)
            ta, xa, ya = tb, xb, yb

    def _cross_piece(self, t0: float, dt: float, x0: float, y0: float, vx: float, vy: float, x1: float,
                     y1: float) -> None:
        """The pending lines crossed on a straight piece of ``dt`` [s] from (x0, y0) at ``t0`` to (x1, y1)."""
        for line in list(self.pending):
            d0, d1 = x0 - line, x1 - line
            if d0 == 0.0 or d0 * d1 < 0.0 or (d1 == 0.0 and d0 != 0.0):
                frac = 0.0 if d0 == 0.0 else d0 / (d0 - d1)
                self.cross(line, t0 + frac * dt, y0 + frac * (y1 - y0), vx, vy)

    def cross(self, line: float, time: float, y: float, vx: float, vy: float) -> None:
        self.result.crossings[line] = Crossing(line, time, y, vx, vy)
        self.pending.remove(line)

    def sample(self, step_index: int, t: float, state: np.ndarray, cov: np.ndarray | None) -> None:
        if self.sample_every and step_index % self.sample_every == 0:
            self.result.samples.append((t, state.copy(), None if cov is None else cov.copy()))


def _finish(model: PuckModel, rec: _Recorder, s: np.ndarray, p: np.ndarray | None, t: float, remainder: float,
            dt: float, q: np.ndarray, impact_noise: float, contact_time: float) -> Prediction:
    """Last, shorter step of the horizon (noise scaled by its length); store the final state."""
    if remainder:
        res = model.step(s, remainder, with_jacobian=p is not None)
        rec.step(t, remainder, s, res.state, res.impacts)
        s = res.state
        if p is not None:
            p = with_impact_noise(res.jacobian @ p @ res.jacobian.T + q * (remainder / dt), s, res.impacts,
                                  impact_noise, contact_time)
    rec.result.state, rec.result.covariance = s, p
    return rec.result


def with_impact_noise(p: np.ndarray | float, state: np.ndarray, impacts, ratio: float,
                      contact_time: float = 0.0) -> np.ndarray | float:
    """``p`` plus the impact covariance when the step had a rim impact (and ``ratio`` or ``contact_time`` > 0);
    ``p`` 0.0 gives the impact's covariance alone (or 0.0)."""
    return p + impact_covariance(state, ratio, contact_time) if impacts and (ratio or contact_time) else p


def predict_stepwise(model: PuckModel, state: np.ndarray, cov: np.ndarray | None, horizon: float, dt: float,
                     q: np.ndarray, lines: Sequence[float] = (), sample_every: int = 0,
                     impact_noise: float = 0.0, impact_contact_time: float = 0.0) -> Prediction:
    """Reference prediction: ``horizon`` [s] in model steps of ``dt`` [s] with per-step noise ``q`` (and
    :func:`impact_covariance` of ``impact_noise`` and ``impact_contact_time`` after each step with a rim
    impact); ``cov=None`` propagates the mean only."""
    steps, remainder = _split_horizon(horizon, dt)
    rec = _Recorder(lines, sample_every)
    s, p = np.asarray(state, float), (None if cov is None else np.asarray(cov, float))
    for i in range(steps):
        res = model.step(s, dt, with_jacobian=p is not None)
        rec.step(i * dt, dt, s, res.state, res.impacts)
        s = res.state
        if p is not None:
            p = with_impact_noise(res.jacobian @ p @ res.jacobian.T + q, s, res.impacts, impact_noise,
                                  impact_contact_time)
        rec.sample(i + 1, (i + 1) * dt, s, p)
    return _finish(model, rec, s, p, steps * dt, remainder, dt, q, impact_noise, impact_contact_time)


_KERNEL: list = []  # the compiled kernel module (:mod:`.prediction_kernel`), loaded by the first use
_KERNEL_PARAMS: "weakref.WeakKeyDictionary[PuckModel, np.ndarray]" = weakref.WeakKeyDictionary()
_NO_COVARIANCE = np.empty((0, 0))  # the kernel's "mean alone"
_NO_Q = np.zeros((6, 6))


def prepare_prediction():
    """Load the compiled prediction (:mod:`.prediction_kernel`) now instead of in the first prediction (numba's
    import and the cached machine code: about half a second; compiling it the first time on a machine:
    seconds). Returns the kernel module."""
    if not _KERNEL:
        from . import prediction_kernel
        prediction_kernel.warm_up()
        _KERNEL.append(prediction_kernel)
    return _KERNEL[0]


def _compiled(model: PuckModel, state: np.ndarray, cov: np.ndarray | None, horizon: float, dt: float,
              q: np.ndarray, lines: Sequence[float], sample_every: int, impact_noise: float,
              contact_time: float) -> Prediction:
    """:func:`predict_fast` (its arguments): inputs checked, the kernel's arrays turned into a :class:`Prediction`."""
    kernel = _KERNEL[0] if _KERNEL else prepare_prediction()
    params = _KERNEL_PARAMS.get(model)
    if params is None:
        params = _KERNEL_PARAMS[model] = kernel.kernel_params(model)
    steps, remainder = _split_horizon(horizon, dt) if horizon > 0.0 else (0, 0.0)
    lines = list(lines)
    with_cov = cov is not None
    state = np.ascontiguousarray(state, float)
    if with_cov:
        cov, q = np.ascontiguousarray(cov, float), np.ascontiguousarray(q, float)
        if state.shape != (6,) or cov.shape != (6, 6) or q.shape != (6, 6):
            raise ValueError(f"prediction needs a state (6,), covariance (6, 6) and process noise (6, 6), got "
                             f"{state.shape}, {cov.shape} and {q.shape}")
    elif state.shape != (6,):
        raise ValueError(f"prediction needs a state (6,), got {state.shape}")
    final, p, impacts, crossings, samples, sample_covs = kernel.predict(
        params, state, cov if with_cov else _NO_COVARIANCE, q if with_cov else _NO_Q, float(impact_noise),
        float(contact_time), steps, remainder, dt, np.array(lines, float), sample_every)
    result = Prediction(final, p if with_cov else None)
    result.impacts = [(t, int(wall), x, y, sliding != 0.0) for t, wall, x, y, sliding in impacts.tolist()]
    result.samples = [(float(row[0]), row[1:], c if with_cov else None) for row, c in zip(samples, sample_covs)]
    for line, (crossed, time, y, vx, vy) in zip(lines, crossings.tolist()):
        if crossed and line not in result.crossings:
            result.crossings[line] = Crossing(line, time, y, vx, vy)
    return result


def predict_fast(model: PuckModel, state: np.ndarray, cov: np.ndarray | None, horizon: float, dt: float,
                 q: np.ndarray, lines: Sequence[float] = (), sample_every: int = 0,
                 impact_noise: float = 0.0, impact_contact_time: float = 0.0) -> Prediction:
    """:func:`predict_stepwise` in compiled code (:mod:`.prediction_kernel`): ``horizon`` [s] in model steps of
    ``dt`` [s] with per-step noise ``q`` (6x6) and the impact covariance of ratio ``impact_noise`` and contact
    time ``impact_contact_time`` [s]; with ``cov=None`` the mean alone (``Prediction.covariance`` None: the tactics, the offline evaluation and system
    identification need no covariance)."""
    return _compiled(model, state, cov, horizon, dt, q, lines, sample_every, impact_noise, impact_contact_time)
