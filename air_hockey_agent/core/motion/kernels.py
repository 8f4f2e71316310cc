"""The motion layer's innermost arithmetic, compiled with numba.

On 3x7 Jacobians numpy's call overhead, not arithmetic, dominated the planning time (about 25 calls
per tracked sample, 70 % of it). Compiled here, with the same formulas:

* one tracked sample of :func:`tracking.track` (tracking.py's module docstring), for the 3x7 position
  Jacobian J:  ref = clip(pull (anchor - q), -pull_cap, pull_cap) (the posture pull in the redundancy)
  and step = ref + J^T (J J^T + damping I)^-1 (dx - J ref) (the unconstrained minimiser); and the check
  that the step is inside the step bounds where they are simple: every joint farther from its position
  limits than ``clear``, where only |step| <= velocity and |step - previous| <= acceleration bound it
  (:class:`tracking._StepLimits`);
* the hit posture search's surrogate m = 1 / (t^T (J D^2 J^T)^-1 t) (:mod:`hit_config`).

``cache=True`` keeps the machine code under the package's ``__pycache__`` (or numba's user cache): a
process compiles once (about a second), later ones load it; :func:`warm_up` does that at start-up
instead of in the first planned command.
"""
from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def _solve_sym3(a00: float, a01: float, a02: float, a11: float, a12: float, a22: float, b0: float, b1: float,
                b2: float) -> tuple[float, float, float]:
    """x with A x = b for the symmetric 3x3 A given by its upper triangle, by cofactors (the compiled
    twin of core/linalg3.py's solve_sym3, which numba code cannot call)."""
    c00, c01, c02 = a11 * a22 - a12 * a12, a02 * a12 - a01 * a22, a01 * a12 - a02 * a11
    c11, c12, c22 = a00 * a22 - a02 * a02, a01 * a02 - a00 * a12, a00 * a11 - a01 * a01
    det = a00 * c00 + a01 * c01 + a02 * c02
    return ((c00 * b0 + c01 * b1 + c02 * b2) / det, (c01 * b0 + c11 * b1 + c12 * b2) / det,
            (c02 * b0 + c12 * b1 + c22 * b2) / det)


@njit(cache=True)
def unconstrained_step(jac: np.ndarray, dx: np.ndarray, q: np.ndarray, anchor: np.ndarray, pull: float,
                       pull_cap: np.ndarray, damping: float, ref: np.ndarray, step: np.ndarray) -> None:
    """Write the posture pull ``ref`` and the step ``step`` [rad] (module docstring) into the given arrays.
    ``jac`` (3, 7) [m/rad], ``dx`` (3,) [m] the mallet's error to its target, ``q``/``anchor`` (7,) [rad]."""
    n = q.shape[0]
    for j in range(n):
        r = pull * (anchor[j] - q[j])
        ref[j] = min(max(r, -pull_cap[j]), pull_cap[j])
    e0, e1, e2 = dx[0], dx[1], dx[2]
    a00, a01, a02, a11, a12, a22 = damping, 0.0, 0.0, damping, 0.0, damping
    for j in range(n):
        j0, j1, j2 = jac[0, j], jac[1, j], jac[2, j]
        e0 -= j0 * ref[j]
        e1 -= j1 * ref[j]
        e2 -= j2 * ref[j]
        a00 += j0 * j0
        a01 += j0 * j1
        a02 += j0 * j2
        a11 += j1 * j1
        a12 += j1 * j2
        a22 += j2 * j2
    y0, y1, y2 = _solve_sym3(a00, a01, a02, a11, a12, a22, e0, e1, e2)
    for j in range(n):
        step[j] = ref[j] + jac[0, j] * y0 + jac[1, j] * y1 + jac[2, j] * y2


@njit(cache=True)
def inside_simple_bounds(q: np.ndarray, step: np.ndarray, previous: np.ndarray, velocity: np.ndarray,
                         acceleration: np.ndarray, clear_min: np.ndarray, clear_max: np.ndarray) -> bool:
    """True when every joint is within [clear_min, clear_max] [rad] (far from its limits) and ``step``
    keeps |step| <= velocity and |step - previous| <= acceleration [rad per sample]. False says only
    that the full bounds must be computed, not that the step breaks them."""
    for j in range(q.shape[0]):
        if q[j] < clear_min[j] or q[j] > clear_max[j]:
            return False
        if abs(step[j]) > velocity[j] or abs(step[j] - previous[j]) > acceleration[j]:
            return False
    return True


@njit(cache=True)
def min_norm_step(jac: np.ndarray, dx: np.ndarray, damping: float, step: np.ndarray) -> None:
    """Write J^T (J J^T + damping I)^-1 dx [rad] into ``step``: the smallest joint step that moves the
    mallet by ``dx`` [m] to first order (:func:`unconstrained_step` without the posture pull)."""
    zero = np.zeros(step.shape[0])
    unconstrained_step(jac, dx, zero, zero, 0.0, zero, damping, np.empty_like(zero), step)


@njit(cache=True)
def surrogate(jac: np.ndarray, task: np.ndarray, scale: np.ndarray) -> float:
    """1 / (task^T (J D^2 J^T)^-1 task) with D = diag(``scale``): the squared speed along ``task`` (3,)
    that a unit weighted joint-velocity norm reaches (:mod:`hit_config`'s module docstring)."""
    a00 = a01 = a02 = a11 = a12 = a22 = 0.0
    for j in range(jac.shape[1]):
        w = scale[j] * scale[j]
        j0, j1, j2 = jac[0, j], jac[1, j], jac[2, j]
        a00 += w * j0 * j0
        a01 += w * j0 * j1
        a02 += w * j0 * j2
        a11 += w * j1 * j1
        a12 += w * j1 * j2
        a22 += w * j2 * j2
    t0, t1, t2 = task[0], task[1], task[2]
    x0, x1, x2 = _solve_sym3(a00, a01, a02, a11, a12, a22, t0, t1, t2)
    return 1.0 / (t0 * x0 + t1 * x1 + t2 * x2)


def warm_up(jac: np.ndarray) -> None:
    """Compile (or load from the cache) every function here for the Jacobian's array layout ``jac`` (3, 7)."""
    z, dx = np.zeros(jac.shape[1]), np.array([1e-3, 0.0, 0.0])
    unconstrained_step(jac, dx, z, z, 0.0, z, 1e-8, np.empty_like(z), np.empty_like(z))
    min_norm_step(jac, dx, 0.0, np.empty_like(z))
    inside_simple_bounds(z, z, z, z, z, z, z)
    surrogate(jac, dx, np.ones_like(z))
