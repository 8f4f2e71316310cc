"""Aggregate strategy-test trials into the thesis's figures (sec. 5.4, fig. 5.7) and the JSON report."""
from __future__ import annotations

import math
from typing import Iterable, Sequence

import numpy as np

# Thesis fig. 5.7 / sec. 5.4 (success, partial, and for Repel the goal rate and mean speed)
THESIS = {"smash_straight": {"success_rate": 0.822}, "smash_left": {"success_rate": 0.734},
          "smash_right": {"success_rate": 0.736}, "cut": {"success_rate": 0.343, "partial_rate": 0.767},
          "prepare": {"success_rate": 0.2615, "partial_rate": 0.4462},
          "repel": {"success_rate": 0.92, "goal_rate": 0.13, "mean_speed_mps": 1.57}}
# guard: ours, no thesis figure
KEYS = ("smash_straight", "smash_left", "smash_right", "cut", "prepare", "repel", "guard")


def _mean_std(values: Sequence[float]) -> tuple[float | None, float | None]:
    if not values:
        return None, None
    arr = np.asarray(values, float)
    return float(arr.mean()), float(arr.std())


def summarise(results: Iterable[dict], defended: bool = False) -> dict:
    """Per strategy: the rates of the issue's JSON report, plus failures by reason; with ``defended`` (the
    opponent played, ``strategy-test --defended``) also how often it touched the puck after the hit."""
    by: dict[str, list[dict]] = {}
    for r in results:
        by.setdefault(r["strategy"], []).append(r)
    out = {}
    for key in KEYS:
        trials = by.get(key, [])
        if not trials:
            continue
        n = len(trials)
        rate = lambda flag: sum(1 for t in trials if t[flag]) / n  # noqa: E731
        entry: dict = {"success_rate": rate("success"), "trials": n}
        if key.startswith("smash"):
            entry["offset_mean_m"], entry["offset_std_m"] = _mean_std([t["offset"] for t in trials if t["offset"] is not None])
        elif key in ("cut", "prepare"):
            entry["partial_rate"] = rate("partial")
        elif key == "guard":
            entry["touched_rate"] = rate("hit")
        else:
            entry["goal_rate"] = rate("goal")
            speeds = [t["defend_speed"] for t in trials if t["defend_speed"] is not None]
            entry["mean_speed_mps"], entry["speed_std_mps"] = _mean_std(speeds)
        if defended:
            entry["defended_rate"] = rate("defended")
        failures: dict[str, int] = {}
        for t in trials:
            if not t["success"]:
                failures[t["reason"]] = failures.get(t["reason"], 0) + 1
        entry["failures"] = failures
        out[key] = entry
    return out


def _pct(v) -> str:
    return "-" if v is None or (isinstance(v, float) and math.isnan(v)) else f"{100 * v:5.1f} %"


def table(summary: dict, seconds: float) -> str:
    lines = [f"{'strategy':<16}{'trials':>7}{'success':>10}{'thesis':>10}{'partial':>10}{'thesis':>10}  other"]
    for key, e in summary.items():
        ref = THESIS.get(key, {})
        other = ""
        if key.startswith("smash") and e.get("offset_mean_m") is not None:
            other = f"offset {e['offset_mean_m'] * 100:+.1f} +- {e['offset_std_m'] * 100:.1f} cm"
        if key == "guard":
            other = f"no goal conceded; the mallet touched the puck in {_pct(e['touched_rate']).strip()}"
        if key == "repel":
            speed = "-" if e["mean_speed_mps"] is None else f"{e['mean_speed_mps']:.2f} m/s"
            other = f"goals {_pct(e['goal_rate'])} (thesis 13 %), speed at the defend line {speed} (thesis 1.57)"
        if "defended_rate" in e:
            touched = f"the opponent touched the puck after the hit in {_pct(e['defended_rate']).strip()}"
            other = f"{other}; {touched}" if other else touched
        lines.append(f"{key:<16}{e['trials']:>7}{_pct(e['success_rate']):>10}{_pct(ref.get('success_rate')):>10}"
                     f"{_pct(e.get('partial_rate')):>10}{_pct(ref.get('partial_rate')):>10}  {other}")
    lines.append(f"{seconds:.0f} s of wall time")
    for key, e in summary.items():
        if e["failures"]:
            lines.append(f"  {key} failures: " + ", ".join(f"{r} x{n}" for r, n in sorted(e["failures"].items(), key=lambda kv: -kv[1])))
    return "\n".join(lines)
