"""Free model steps with a table acceleration and surface friction, marched in compiled code.

:class:`.free_flight.MarchedMotion` needs the model's step-by-step velocity decay wherever no closed form
exists (both a table acceleration ``g`` and a surface friction ``mu_s``: the friction acts along a direction
the acceleration keeps turning). In Python each step cost about 1.7 us in :meth:`.model.PuckModel.decay`
alone, and a 1.0 s prediction marches up to 120 of them; a tilt learned online (issue #13) with the surface
friction ``sysid`` identifies made every prediction of the tracker do that. Here the same arithmetic, in
the same order, is compiled with numba: the compiled twin of ``PuckModel.decay`` (eq. 3.1 read as
``v <- (1 - dt d) v' - dt mu_s v'/|v'|`` with ``v' = v + dt g``; SI units, table frame) and the
transition blocks of :class:`.free_flight.MarchedMotion`. ``test_prediction.py`` checks it against the
stepwise prediction (``PuckModel.step``) to 1e-10.

``cache=True`` keeps the machine code under the package's ``__pycache__`` (or numba's user cache): a
process compiles once (about a second), later ones load it; numba itself is imported only by the first
marched prediction of a process (or :func:`warm_up`), not by every tool that predicts.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

PATH_COLUMNS = 4    # x, y [m], vx, vy [m/s] after m steps
BLOCK_COLUMNS = 8   # A (2x2, row-major) and B (2x2): d(velocity)/d(v0) and d(position)/d(v0) after m steps


@njit(cache=True)
def march(x: float, y: float, vx: float, vy: float, gx: float, gy: float, keep: float, mu_dt: float, dt: float,
          bounds: np.ndarray, max_steps: int, rest_holds: bool, path: np.ndarray,
          blocks: np.ndarray) -> tuple[int, bool]:
    """March up to ``max_steps`` free steps from (x, y, vx, vy).

    ``keep = 1 - dt d``, ``mu_dt = dt mu_s`` [m/s], ``bounds = (x_lo, x_hi, y_lo, y_hi)`` [m] the rim lines
    (a step ending on or beyond one stops the march), ``rest_holds`` whether friction holds a resting puck
    against ``g``. Rows 0..n of ``path`` (n+1, 4) and ``blocks`` (n+1, 8) are written. Returns
    ``(n, hit)``: the steps marched and whether the last one ended on or beyond a rim line.
    """
    a00, a01, a10, a11, b00, b01, b10, b11 = 1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0
    _write(path, blocks, 0, x, y, vx, vy, a00, a01, a10, a11, b00, b01, b10, b11)
    tilted = gx != 0.0 or gy != 0.0
    for n in range(1, max_steps + 1):
        x, y = x + dt * vx, y + dt * vy
        b00, b01, b10, b11 = b00 + dt * a00, b01 + dt * a01, b10 + dt * a10, b11 + dt * a11
        if tilted:
            vx, vy = vx + dt * gx, vy + dt * gy
        speed = math.hypot(vx, vy)
        if mu_dt == 0.0:
            vx, vy, d00, d01, d10, d11 = keep * vx, keep * vy, keep, 0.0, 0.0, keep
        else:
            new_speed = keep * speed - mu_dt
            if speed == 0.0 or new_speed <= 0.0:
                vx, vy, d00, d01, d10, d11 = 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
            else:
                ux, uy = vx / speed, vy / speed
                k = mu_dt / speed
                cross = k * ux * uy
                vx, vy = ux * new_speed, uy * new_speed
                d00, d01, d10, d11 = keep - k + k * ux * ux, cross, cross, keep - k + k * uy * uy
        a00, a01, a10, a11 = (d00 * a00 + d01 * a10, d00 * a01 + d01 * a11,
                              d10 * a00 + d11 * a10, d10 * a01 + d11 * a11)
        _write(path, blocks, n, x, y, vx, vy, a00, a01, a10, a11, b00, b01, b10, b11)
        if x <= bounds[0] or x >= bounds[1] or y <= bounds[2] or y >= bounds[3]:
            return n, True
        if vx == 0.0 and vy == 0.0 and rest_holds:
            return n, False  # held at rest: every later step is this one
    return max_steps, False


@njit(cache=True)
def _write(path: np.ndarray, blocks: np.ndarray, n: int, x: float, y: float, vx: float, vy: float, a00: float,
           a01: float, a10: float, a11: float, b00: float, b01: float, b10: float, b11: float) -> None:
    path[n, 0], path[n, 1], path[n, 2], path[n, 3] = x, y, vx, vy
    blocks[n, 0], blocks[n, 1], blocks[n, 2], blocks[n, 3] = a00, a01, a10, a11
    blocks[n, 4], blocks[n, 5], blocks[n, 6], blocks[n, 7] = b00, b01, b10, b11


def warm_up() -> None:
    """Compile (or load from the cache) :func:`march` now, not in the first marched prediction."""
    march(0.0, 0.0, 1.0, 0.0, 0.0, 0.1, 0.99, 1e-4, 1e-2, np.array([-1.0, 1.0, -1.0, 1.0]), 2, False,
          np.empty((3, PATH_COLUMNS)), np.empty((3, BLOCK_COLUMNS)))
