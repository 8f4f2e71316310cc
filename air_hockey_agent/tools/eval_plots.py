"""Plots of ``air-hockey eval-prediction --plot DIR``: the report's figures drawn.

* ``eval_per_bag.png``: each bag's median prediction error per horizon, in session order (what the
  tracker learns online of the table carries from one bag to the next: the session's first bags show how
  fast it learns), with the reference filter's dashed when ``--reference`` ran;
* ``eval_horizons.png``: the median and 95th percentile of the error against the horizon, over all bags,
  for the tracker and the reference filter.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from air_hockey_agent.tools.files import save_figure

COLOURS = ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown")


def write_eval_plots(out: Path, summary: dict, rows: list[dict]) -> list[Path]:
    """The PNGs of a report ``summary`` and its bags' ``rows`` (``--per-bag``'s), written atomically into
    the directory ``out`` (which exists)."""
    import matplotlib
    matplotlib.use("Agg")
    return [_per_bag(out, rows), _horizons(out, summary)]


def _per_bag(out: Path, rows: list[dict]) -> Path:
    import matplotlib.pyplot as plt
    from matplotlib.ticker import MaxNLocator
    fig, ax = plt.subplots(figsize=(8, 4.5))
    index = np.arange(1, len(rows) + 1)
    keys = list(rows[0]["horizons"]) if rows else []
    for key, colour in zip(keys, COLOURS):
        ax.plot(index, [_mm(row["horizons"][key]["median_m"]) for row in rows], "o-", color=colour, ms=3,
                label=f"tracker, {key} s")
        if "reference_horizons" in rows[0]:
            ax.plot(index, [_mm(row["reference_horizons"][key]["median_m"]) for row in rows], "s--",
                    color=colour, ms=3, alpha=0.6, label=f"reference, {key} s")
    ax.set_yscale("log")
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_xlabel("bag, in session order")
    ax.set_ylabel("median prediction error [mm]")
    ax.grid(alpha=0.3, which="both")
    ax.set_title(f"Median error per bag, {len(rows)} bags as one session")
    ax.legend(fontsize=8, ncol=2)
    fig.tight_layout()
    return save_figure(fig, out / "eval_per_bag.png")


def _horizons(out: Path, summary: dict) -> Path:
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(7, 4.5))
    sets = [("tracker", summary["horizons"], "tab:blue")]
    if "reference" in summary:
        sets.append(("reference", summary["reference"]["horizons"], "tab:orange"))
    for name, horizons, colour in sets:
        h = [float(key) for key in horizons]
        ax.plot(h, [_mm(v["median_m"]) for v in horizons.values()], "o-", color=colour, label=f"{name}, median")
        ax.plot(h, [_mm(v["p95_m"]) for v in horizons.values()], "^:", color=colour, label=f"{name}, 95th percentile")
    ax.set_yscale("log")
    ax.set_xlabel("prediction horizon [s]")
    ax.set_ylabel("prediction error [mm]")
    ax.grid(alpha=0.3, which="both")
    ax.set_title(f"Error against horizon, {summary['bags']} bags, every valid pose compared")
    ax.legend(fontsize=8)
    fig.tight_layout()
    return save_figure(fig, out / "eval_horizons.png")


def _mm(value: float | None) -> float:
    return float("nan") if value is None else value * 1e3
