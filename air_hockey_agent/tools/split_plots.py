"""Plots of ``air-hockey sysid --method split --plot DIR``: what the split identification fitted.

* ``split_flight.png``: each free-flight window's acceleration along its motion, with the table
  acceleration's share removed, against its speed, and the fitted flight law ``-d v - mu_s`` (eq. 3.1).
* ``split_impacts.png``: each rim impact's restitution (outgoing over incoming normal speed) against the
  incoming normal speed, and the fitted ``e(vn) = max(e - slope max(|vn| - knee, 0), e_min)``.
* ``split_tangential.png``: each rim impact's tangential impulse against the incoming slip of the contact
  point ``c = vb + r omega``, both per unit normal impulse ``(1 + e) |vn|`` (the impact's measured e), so
  the law is one curve for all impacts: ``(1 + beta) c / 3`` while sticking, capped at ``mu_rim``
  (sliding; Routh's impact is beta = 0). The impulse is read from the change of the slip, ``-dc / 3``.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from air_hockey_agent.core.identification.impact_fit import restitution_law
from air_hockey_agent.core.identification.split import AXES, SplitResult
from air_hockey_agent.tools.files import save_figure


def write_split_plots(out: Path, result: SplitResult) -> list[Path]:
    """The PNGs of the parts that were identified, written atomically into ``out`` (created)."""
    import matplotlib
    matplotlib.use("Agg")
    out.mkdir(parents=True, exist_ok=True)
    written = []
    if result.flight is not None and result.flight.used:
        written.append(_flight(out, result.flight))
    if result.impacts is not None and result.impacts.used:
        written.append(_impacts(out, result.impacts))
        written.append(_tangential(out, result.impacts))
    return written


def _flight(out: Path, flight) -> Path:
    import matplotlib.pyplot as plt
    values = flight.values
    g = np.array([values[AXES[0]], values[AXES[1]]])
    speed = np.array([float(np.linalg.norm(w.v)) for w in flight.used])
    along = np.array([float((w.a - g) @ w.v) / s for w, s in zip(flight.used, speed)])
    grid = np.linspace(0.0, float(speed.max()), 100)
    fig, ax = plt.subplots(figsize=(7, 4.5))
    ax.plot(speed, along, ".", ms=3, alpha=0.5, label=f"{len(speed)} free-flight windows")
    ax.plot(grid, -values["damping"] * grid - values["friction_surface"], "k-",
            label=f"fit: -{values['damping']:.4g} v - {values['friction_surface']:.3g}")
    ax.set(xlabel="speed [m/s]", ylabel="acceleration along the motion, tilt removed [m/s^2]",
           title="Flight law (split identification)")
    return _finish(fig, ax, out / "split_flight.png")


def _impacts(out: Path, impacts) -> Path:
    import matplotlib.pyplot as plt
    vn = np.array([-o.before[1] for o in impacts.used])
    e = np.array([o.after[1] for o in impacts.used]) / vn
    grid = np.linspace(0.0, float(vn.max()), 200)
    law = impacts.values
    fig, ax = plt.subplots(figsize=(7, 4.5))
    ax.plot(vn, e, ".", ms=4, alpha=0.6, label=f"{len(vn)} rim impacts")
    ax.plot(grid, restitution_law(grid, law), "k-",
            label=f"fit: {law['restitution']:.3g} up to {law['restitution_knee']:.3g} m/s, then falling by "
                  f"{law['restitution_slope']:.3g} s/m to {law['restitution_min']:.3g}")
    ax.set(xlabel="incoming normal speed [m/s]", ylabel="restitution [-]", ylim=(0.0, 1.1),
           title="Rim restitution (split identification)")
    return _finish(fig, ax, out / "split_impacts.png")


def _tangential(out: Path, impacts) -> Path:
    import matplotlib.pyplot as plt
    r = impacts.radius
    before, after = np.array([o.before for o in impacts.used]), np.array([o.after for o in impacts.used])
    normal = after[:, 1] - before[:, 1]  # (1 + e) |vn| [m/s]
    slip_in, slip_out = before[:, 0] + r * before[:, 2], after[:, 0] + r * after[:, 2]
    x, y = slip_in / normal, -(slip_out - slip_in) / 3.0 / normal
    mu, beta = impacts.values["friction_rim"], impacts.values["tangential_restitution"]
    top = float(np.max(np.abs(x)))
    grid = np.linspace(-top, top, 401)
    fig, ax = plt.subplots(figsize=(7, 4.5))
    ax.plot(x, y, ".", ms=4, alpha=0.6, label=f"{len(x)} rim impacts")
    ax.plot(grid, np.sign(grid) * np.minimum((1.0 + beta) * np.abs(grid) / 3.0, mu), "k-",
            label=f"fit: tangential restitution {beta:.3g}, rim friction {mu:.3g}")
    ax.plot(grid, np.sign(grid) * np.minimum(np.abs(grid) / 3.0, mu), "k:", lw=1, label="Routh's impact (beta 0), same friction")
    ax.set(xlabel="incoming slip / normal impulse, c / ((1 + e) |vn|) [-]",
           ylabel="tangential impulse / normal impulse [-]", title="Rim tangential impulse (split identification)")
    return _finish(fig, ax, out / "split_tangential.png", legend="lower right")


def _finish(fig, ax, path: Path, legend: str = "best") -> Path:
    """Grid, legend (at ``legend``) and layout, then the PNG written atomically and the figure closed."""
    ax.grid(alpha=0.3)
    ax.legend(loc=legend)
    fig.tight_layout()
    return save_figure(fig, path)
