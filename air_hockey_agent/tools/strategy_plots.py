"""PNG figures of a strategy test: success and partial success per strategy next to the thesis's
(fig. 5.7), and where the smash shots reached the opponent's goal line (fig. 5.8)."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from air_hockey_agent.core.game.strategy.report import THESIS
from air_hockey_agent.tools.files import save_figure


def write_plots(summary: dict, results: list[dict], out: Path, defended: bool = False, table: str = "") -> list[Path]:
    """The two PNGs in ``out``; ``defended``: the trials were played against the opponent's agent
    (``--defended``), ``table``: on that table file's simulated table (``--table``), which the titles say (the
    thesis's opponent held its home pose, on its own table)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    out.mkdir(parents=True, exist_ok=True)
    keys = list(summary)
    x = np.arange(len(keys))
    fig, ax = plt.subplots(figsize=(8, 4))
    ours = [summary[k]["success_rate"] for k in keys]
    partial = [summary[k].get("partial_rate", np.nan) for k in keys]
    thesis = [THESIS.get(k, {}).get("success_rate", np.nan) for k in keys]  # guard: ours, no thesis figure
    thesis_partial = [THESIS.get(k, {}).get("partial_rate", np.nan) for k in keys]
    ax.bar(x - 0.2, partial, 0.4, color="tab:blue", alpha=0.35, label="partial success (ours)")
    ax.bar(x - 0.2, ours, 0.4, color="tab:blue", label="success (ours)")
    ax.bar(x + 0.2, thesis_partial, 0.4, color="tab:gray", alpha=0.35, label="partial success (thesis)")
    ax.bar(x + 0.2, thesis, 0.4, color="tab:gray", label="success (thesis fig. 5.7)")
    ax.set_xticks(x, keys, rotation=20)
    ax.set_ylim(0, 1)
    ax.set_ylabel("rate")
    _title(ax, "ours against iiwa_back's own agent (--defended); the thesis's opponent held its home pose"
           if defended else "", table)
    # below the axes: inside, it covered the Prepare and Repel bars
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.22), ncol=2, frameon=False)
    fig.tight_layout()
    bars = save_figure(fig, out / "strategy_success.png", dpi=120)
    fig, ax = plt.subplots(figsize=(6, 4))
    smashes = {k: [100.0 * r["offset"] for r in results if r["strategy"] == k and r["offset"] is not None]
               for k in keys if k.startswith("smash")}
    # [cm] +-30 cm in 3 cm bins, wider (whole bins) where a shot missed by more: none is left out
    edge = 3.0 * math.ceil(max([10.0] + [abs(v) / 3.0 for offsets in smashes.values() for v in offsets]))
    for k, offsets in smashes.items():
        if offsets:
            ax.hist(offsets, bins=int(round(2 * edge / 3.0)), range=(-edge, edge), alpha=0.5, label=k)
    ax.axvspan(-9.3, 9.3, color="tab:green", alpha=0.1, label="goal mouth (puck centre)")
    ax.set_xlabel("y where the puck reaches the goal line [cm]")
    ax.set_ylabel("shots")
    _title(ax, "against iiwa_back's own agent (--defended): shots that reached the goal line" if defended else "",
           table)
    ax.legend()
    fig.tight_layout()
    spread = save_figure(fig, out / "smash_spread.png", dpi=120)
    return [bars, spread]


def _title(ax, setting: str, table: str) -> None:
    """The set-up beyond the thesis's, when there is one, as the axes' title: ``setting`` (or ''), and the
    table file."""
    lines = [text for text in (setting, table and f"on the simulated table of {table} (--table)") if text]
    if lines:
        ax.set_title("\n".join(lines), fontsize=9)
