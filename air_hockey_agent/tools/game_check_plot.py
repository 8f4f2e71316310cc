"""``air-hockey game-check --plot``: one recorded game's arms in a PNG (the table frame, README "Frames and
units"): above, the table with each robot's allowed region (the planner's, drawn where
:meth:`Region.excess` is 0), the mallets' paths and the puck's, the worst excursion of each arm marked;
below, each arm's largest joint velocity as a fraction of its limit over the game's time."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from air_hockey_agent.core.frames import robot_to_table, table_to_robot
from air_hockey_agent.tools.files import save_figure

COLORS = {"iiwa_front": "tab:blue", "iiwa_back": "tab:red"}
GRID = 0.005  # [m] spacing of the grid the regions are drawn on
JUMP = 0.1    # [m] a path is broken where consecutive samples lie farther apart (a reset put it there)


def plot_arms(checks: dict, path: Path) -> Path:
    """Draw ``checks`` (robot -> ExecutionCheck with a trace, and ``"puck"``: table-frame (x, y) list)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    robots = [r for r in checks if r != "puck"]
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(10, 9), gridspec_kw={"height_ratios": [3, 2]})
    _table_outline(top, checks[robots[0]].planner.region)
    puck = np.array(checks.get("puck", []), float)
    if len(puck):
        top.plot(*_broken(puck).T, color="0.6", lw=0.5, label="puck (simulation's truth)")
    for robot in robots:
        _arm(top, bottom, robot, checks[robot])
    top.set_aspect("equal")
    top.set_xlabel("x [m] (table frame)")
    top.set_ylabel("y [m]")
    top.legend(loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=3, frameon=False, fontsize=8)
    bottom.axhline(1.0, color="k", lw=0.8, ls="--", label="limit")
    bottom.set_xlabel("time [s] (stamps)")
    bottom.set_ylabel("largest |dq| / limit")
    bottom.legend(fontsize=8)
    bottom.grid(alpha=0.3)
    fig.tight_layout()
    return save_figure(fig, path, dpi=110)


def _table_half(region) -> tuple[float, float]:
    """Half the playing surface's length and width [m], from a region: its box is the own half less the
    mallet radius and margin (``Region.for_table``), which its x_max is."""
    inset = -region.x_max
    return -region.x_min + inset, region.y_max + inset


def _table_outline(ax, region) -> None:
    """The playing surface's rims and centre line."""
    half_l, half_w = _table_half(region)
    ax.plot([-half_l, half_l, half_l, -half_l, -half_l], [-half_w, -half_w, half_w, half_w, -half_w], color="k", lw=1)
    ax.plot([0.0, 0.0], [-half_w, half_w], color="k", lw=0.5)


def _arm(top, bottom, robot: str, check) -> None:
    region, color = check.planner.region, COLORS.get(robot, "tab:green")
    half_l, half_w = _table_half(region)
    xs = np.arange(-half_l, half_l + GRID, GRID)
    ys = np.arange(-half_w, half_w + GRID, GRID)
    gx, gy = np.meshgrid(xs, ys)
    own = np.array([table_to_robot(x, y, 0.0, robot)[:2] for x, y in zip(gx.ravel(), gy.ravel())])
    inside = (region.excess(own) <= 0.0).reshape(gx.shape).astype(float)
    top.contour(gx, gy, inside, levels=[0.5], colors=[color], linewidths=0.8, linestyles="dotted")
    trace = np.array(check.trace, float).reshape(-1, 4)
    if not len(trace):
        return
    table_xy = np.array([robot_to_table(x, y, 0.0, robot)[:2] for x, y in trace[:, 1:3]])
    top.plot(*_broken(table_xy).T, color=color, lw=0.6, label=f"{robot} mallet (region dotted)")
    r = check.result
    if r.worst_outside_m > 0.0:
        k = int(np.argmin(np.abs(trace[:, 0] - r.worst_outside_time)))
        top.plot(*table_xy[k], "x", color="k", ms=9,
                 label=f"{robot}: {r.worst_outside_m * 1000:.1f} mm outside at {r.worst_outside_time:.2f} s")
    bottom.plot(trace[:, 0], trace[:, 3], color=color, lw=0.6,
                label=f"{robot} (at most {r.worst_velocity_use * 100:.0f} %)")


def _broken(points: np.ndarray) -> np.ndarray:
    """``points`` (n, 2) with a NaN row wherever two consecutive ones lie more than JUMP apart."""
    jumps = np.flatnonzero(np.hypot(*np.diff(points, axis=0).T) > JUMP) + 1
    return np.insert(points, jumps, np.nan, axis=0)


def plot_contacts(contacts: dict, path: Path) -> Path:
    """Draw each robot's contact report (robot -> :func:`contact_check.summary`): left, the puck's exit speed
    measured against the contact law's; right, the law's error against the mallet's speed at the contact."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4.5))
    top = 0.0
    for robot, report in contacts.items():
        each = report["each"]
        law = np.array([np.hypot(*c["exit_law"]) for c in each])
        measured = np.array([np.hypot(*c["exit_measured"]) for c in each])
        error = np.array([np.hypot(*np.subtract(c["exit_measured"], c["exit_law"])) for c in each])
        label = f"{robot} ({len(each)}, from {report['puck']})"
        left.scatter(law, measured, s=14, color=COLORS.get(robot), label=label)
        right.scatter([c["mallet_speed"] for c in each], error, s=14, color=COLORS.get(robot), label=label)
        top = max(top, float(np.max(law, initial=0.0)), float(np.max(measured, initial=0.0)))
    left.plot([0.0, top], [0.0, top], color="k", lw=0.8, ls="--", label="measured = law")
    left.set_xlabel("exit speed by the contact law [m/s]")
    left.set_ylabel("exit speed measured [m/s]")
    right.set_xlabel("mallet speed at the contact [m/s]")
    right.set_ylabel("|measured - law| exit velocity [m/s]")
    for ax in (left, right):
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    return save_figure(fig, path)
