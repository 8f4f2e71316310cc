"""Head to head (ROS-free): one robot plays an agent variant, the other the defaults, over several games
(``air-hockey game --in-process --versus FILE --games N``), and the tally says which agent scored more.

Each seed is played twice, the variant on the first robot, then on the second (:func:`versus_games`), so
neither a side's advantage nor a seed's (where the referee puts the first puck, the mocap noise) favours
either agent: two equal agents tie every pair exactly, and a pair's games part only where the variant
plays otherwise. The sign test takes every goal as a coin flip between the two agents: a two-sided exact
binomial test of the variant's share of the goals against one half, and the same difference in standard
deviations of that coin, (a - b) / sqrt(a + b). Goals in one game are not quite independent, so read a
p-value near the line with care; more games narrow it (128 games of 60 s gave 70-80 goals here).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

VARIANT, DEFAULTS = "versus", "defaults"


def variant_robot(robots: Sequence[str], game_index: int) -> str:
    """The robot that plays the variant in game ``game_index`` (0-based): the sides alternate."""
    return robots[game_index % len(robots)]


def versus_games(seed: int, games: int, robots: Sequence[str]) -> list[tuple[int, str]]:
    """(seed, the variant's robot) of each of ``games`` games from ``seed``: each seed twice, the variant on
    ``robots[0]``, then on ``robots[1]``."""
    return [(seed + k // len(robots), variant_robot(robots, k)) for k in range(games)]


@dataclass
class VersusTally:
    """Goals, hits and games won of the variant and of the defaults, summed over the games."""

    games: int
    goals: dict      # VARIANT / DEFAULTS -> goals scored
    hits: dict       # VARIANT / DEFAULTS -> mallet-puck contacts
    won: dict        # VARIANT / DEFAULTS / "drawn" -> games

    @classmethod
    def from_results(cls, results: Sequence[dict], variant_robots: Sequence[str]) -> "VersusTally":
        """The tally of game ``results`` (scoreboard results: per robot "score" and "hits"), the variant
        having played ``variant_robots[i]`` in game i."""
        goals, hits = {VARIANT: 0, DEFAULTS: 0}, {VARIANT: 0, DEFAULTS: 0}
        won = {VARIANT: 0, DEFAULTS: 0, "drawn": 0}
        for result, robot in zip(results, variant_robots, strict=True):
            other = next(r for r in result["score"] if r != robot)
            mine, theirs = result["score"][robot], result["score"][other]
            goals[VARIANT] += mine
            goals[DEFAULTS] += theirs
            hits[VARIANT] += result["hits"][robot]
            hits[DEFAULTS] += result["hits"][other]
            won[VARIANT if mine > theirs else DEFAULTS if theirs > mine else "drawn"] += 1
        return cls(len(results), goals, hits, won)

    @property
    def p_value(self) -> float | None:
        """Two-sided sign test of the goals (None without a goal)."""
        from scipy.stats import binomtest
        n = self.goals[VARIANT] + self.goals[DEFAULTS]
        return float(binomtest(self.goals[VARIANT], n, 0.5).pvalue) if n else None

    @property
    def standard_deviations(self) -> float | None:
        """(variant's goals - defaults' goals) / sqrt(all goals): the difference in the coin's standard
        deviations (None without a goal)."""
        n = self.goals[VARIANT] + self.goals[DEFAULTS]
        return (self.goals[VARIANT] - self.goals[DEFAULTS]) / math.sqrt(n) if n else None

    def result(self, params_file: str) -> dict:
        """JSON-ready: the variant's file, the games, goals, hits, games won, the sign test."""
        return {"params_file": params_file, "games": self.games, "goals": dict(self.goals), "hits": dict(self.hits),
                "won": dict(self.won), "p_value": self.p_value, "standard_deviations": self.standard_deviations}

    def line(self, params_file: str) -> str:
        """One line for people."""
        p, sd = self.p_value, self.standard_deviations
        test = "no goal, no test" if p is None else f"sign test on the goals p = {p:.3g} ({sd:+.1f} sd)"
        return (f"versus {params_file} against the defaults, {self.games} game{'s' if self.games != 1 else ''}: "
                f"goals {self.goals[VARIANT]} : {self.goals[DEFAULTS]}, hits {self.hits[VARIANT]} : "
                f"{self.hits[DEFAULTS]}, games won {self.won[VARIANT]} : {self.won[DEFAULTS]} "
                f"({self.won['drawn']} drawn); {test}")
