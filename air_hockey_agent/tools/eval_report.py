"""The text report of ``air-hockey eval-prediction`` (:mod:`.eval_prediction`): its JSON summary as tables
in millimetres (thesis table 5.3's layout)."""
from __future__ import annotations

from air_hockey_agent.core.estimation.table_learning import describe_learning


def _hand_line(summary: dict) -> str:
    """How often the filter's hand regime held (a hand or mallet moving the puck: tracker.yaml's hand.*)."""
    hand, frames = summary["hand"], summary["frames"]
    share = f" ({hand['frames'] / frames * 100:.1f} % of the frames)" if frames else ""
    return f"hand regime (a hand or mallet moving the puck): {hand['regimes']} times, {hand['frames']} frames{share}"


def format_table(summary: dict) -> str:
    """Human-readable report (thesis table 5.3 layout: error per horizon in millimetres)."""
    nis, rejected, reinit = summary["nis"], summary["rejected_fraction"], summary["reinit_per_s"]
    lines = [f"bags: {summary['bags']}, frames: {summary['frames']}, lost frames: {summary['lost_frames']}, "
             f"outliers rejected: {summary['outliers_rejected']}, poses off the table: {summary['off_table_poses']}",
             "filter: rejected " + ("-" if rejected is None else f"{rejected * 100:.1f} %") + " of the poses on the table, "
             + ("-" if reinit is None else f"{reinit:.2f}") + " re-initialisations per second, NIS median "
             + ("-" if nis["median"] is None else f"{nis['median']:.2f}") + " mean "
             + ("-" if nis["mean"] is None else f"{nis['mean']:.2f}") + " (consistent: 2.37, 3)",
             _hand_line(summary),
             "NIS median by regime: " + ", ".join(
                 f"{r} " + ("-" if v["median"] is None else f"{v['median']:.2f}") + f" (n {v['n']})"
                 for r, v in summary["nis_by_regime"].items()),
             f"{'horizon [s]':>11} {'mean [mm]':>10} {'median [mm]':>12} {'p95 [mm]':>9} {'n':>8}"]
    for key, s in summary["horizons"].items():
        if s["n"]:
            lines.append(f"{key:>11} {s['mean_m'] * 1e3:>10.2f} {s['median_m'] * 1e3:>12.2f} "
                         f"{s['p95_m'] * 1e3:>9.2f} {s['n']:>8}")
        else:
            lines.append(f"{key:>11} {'-':>10} {'-':>12} {'-':>9} {0:>8}")
    return "\n".join(lines + [_learning_line(summary)] + _path_table(summary["by_path"])
                     + _thesis_table(summary["thesis_style"]) + _reference_table(summary.get("reference"))
                     + _per_bag_table(summary.get("per_bag")))


def _per_bag_table(rows: list | None) -> list[str]:
    """Each bag's median errors [mm], rejected fraction, re-initialisations per second and NIS median, in
    session order (what was learned online carries from one bag to the next)."""
    if rows is None:
        return []
    keys = list(rows[0]["horizons"]) if rows else []
    title = "median [mm] at " + " / ".join(keys) + " s"
    lines = ["per bag, in session order (the table learned online carries from one bag to the next)",
             f"{'frames':>8} {title:>30} {'rejected':>9} {'re-init/s':>9} {'NIS':>6}"
             + ("  reference median [mm]" if rows and "reference_horizons" in rows[0] else "") + "  bag"]
    for row in rows:
        medians = " / ".join(_mm(h["median_m"]) for h in row["horizons"].values())
        rejected = "-" if row["rejected_fraction"] is None else f"{row['rejected_fraction'] * 100:.1f} %"
        reinit = "-" if row["reinit_per_s"] is None else f"{row['reinit_per_s']:.2f}"
        nis = "-" if row["nis_median"] is None else f"{row['nis_median']:.2f}"
        theirs = row.get("reference_horizons")
        extra = "" if theirs is None else "  " + " / ".join(_mm(h["median_m"]) for h in theirs.values()).rjust(21)
        lines.append(f"{row['frames']:>8} {medians:>30} {rejected:>9} {reinit:>9} {nis:>6}{extra}  {row['bag']}")
    return lines


def _mm(value: float | None) -> str:
    return "-" if value is None else f"{value * 1e3:.1f}"


def _reference_table(reference: dict | None) -> list[str]:
    """The reference filter's errors [mm] per horizon and the tracker's median as a ratio to its."""
    if reference is None:
        return []
    nis, reinit = reference["nis"], reference["reinit_per_s"]
    lines = [f"reference filter, {reference['filter']}: "
             + ("-" if reinit is None else f"{reinit:.2f}") + " re-initialisations per second, NIS median "
             + ("-" if nis["median"] is None else f"{nis['median']:.2f}") + " mean "
             + ("-" if nis["mean"] is None else f"{nis['mean']:.2f}"),
             f"{'horizon [s]':>11} {'mean [mm]':>10} {'median [mm]':>12} {'p95 [mm]':>9} {'n':>8} "
             f"{'tracker / reference median':>27}"]
    for key, s in reference["horizons"].items():
        ratio = reference["median_ratio"][key]
        cells = ([f"{s[f] * 1e3:.2f}" for f in ("mean_m", "median_m", "p95_m")] if s["n"] else ["-"] * 3)
        lines.append(f"{key:>11} {cells[0]:>10} {cells[1]:>12} {cells[2]:>9} {s['n']:>8} "
                     + ("-" if ratio is None else f"{ratio:.3f}").rjust(27))
    return lines


def _learning_line(summary: dict) -> str:
    """What the tracker learned online of the table over the bags (in their order, as one session)."""
    if all(summary[key] is None for key in ("rim_law", "table_acceleration", "marker_noise", "process_noise")):
        return ("learned online: nothing (rim_adaptation, acceleration_adaptation, noise_adaptation and "
                "process_noise_adaptation are off)")
    return "learned online over the bags: " + describe_learning(summary)


def _thesis_table(thesis: dict) -> list[str]:
    """Loss, min and median over trajectories [mm] per horizon (thesis tables 5.2-5.4, sysid's columns)."""
    lines = [f"thesis-style, over {thesis['trajectories']} cut trajectories "
             "(as sysid reports it: the configured physics, nothing learned)",
             f"{'horizon [s]':>11} {'loss [mm]':>10} {'traj. min [mm]':>15} {'traj. median [mm]':>18} {'n':>8}"]
    for key, r in thesis.items():
        if key == "trajectories":
            continue
        cells = [("-" if r[f] is None else f"{r[f] * 1e3:.2f}") for f in ("loss_m", "min_m", "median_m")]
        lines.append(f"{key:>11} {cells[0]:>10} {cells[1]:>15} {cells[2]:>18} {r['n']:>8}")
    return lines


PATH_TITLES = {"rest": "from rest", "no_impact": "no rim impact", "one_impact": "one rim impact",
               "impacts": "two or more", "goal": "into a goal"}


def _path_table(by_path: dict) -> list[str]:
    """Median and mean error [mm] (and n) per horizon by the predicted path: where the error comes from (the
    mean times n is a path's share of the all-comparison mean)."""
    lines = ["median / mean error [mm] (n) by the predicted path",
             f"{'horizon [s]':>11} " + "".join(f"{title:>22}" for title in PATH_TITLES.values())]
    for key, paths in by_path.items():
        cells = [("-" if v["median_m"] is None else f"{v['median_m'] * 1e3:.1f} / {v['mean_m'] * 1e3:.1f}")
                 + f" ({v['n']})" for v in paths.values()]
        lines.append(f"{key:>11} " + "".join(f"{c:>22}" for c in cells))
    return lines


