"""What a game produced (ROS-free): sim time, score, hits from physics, faults by reason, tactics, and
each goal with the last mallet that touched the puck before it (own goals included).

``air-hockey game`` feeds it the referee's ``/game_status``, the simulation's ``/sim/contacts`` and each
robot's ``tactic`` topic, and prints :meth:`Scoreboard.result` at the end.
"""
from __future__ import annotations

import bisect
import re
from collections import Counter, deque
from typing import Sequence

from air_hockey_agent.core.game.referee import (EVENT_GOAL_BACK, EVENT_GOAL_FRONT, EVENT_NONE, EVENT_PUCK_OUT,
                                                EVENT_PUCK_STUCK, EVENT_RESET, EVENT_ROBOT_FAULT)

FAULT_EVENTS = {EVENT_PUCK_OUT: "puck_out", EVENT_PUCK_STUCK: "puck_stuck", EVENT_ROBOT_FAULT: "robot_fault"}
TACTIC_HISTORY = 64  # tactic entries kept per robot to name the tactic a contact began in (they arrive late)


def fault_key(event: int, reason: str) -> str:
    """A stable name for a referee event's reason (its numbers dropped), e.g.
    ``robot_fault: iiwa_front's mallet crossed the centre line``."""
    text = re.sub(r"\s*at \([^)]*\) m\b", "", reason)   # "at (x, y) m"
    text = re.sub(r"\s*\([^)]*\)", "", text)             # "(0.123 m)" details
    text = re.sub(r"\s+", " ", text).strip()
    return f"{FAULT_EVENTS[event]}: {text}"


class Scoreboard:
    """The game's tally. Times are sim-clock seconds; the game's own time (``played``) counts from
    :meth:`start` (the nodes come up and the robots go home on the same clock before that)."""

    def __init__(self, robots: Sequence[str]) -> None:
        self.robots = tuple(robots)
        self.sim_time = 0.0
        self.started_at: float | None = 0.0
        self.score = {r: 0 for r in self.robots}
        self.hits = {r: 0 for r in self.robots}
        self.faults: Counter = Counter()
        self.tactics = {r: Counter() for r in self.robots}
        self._last_tactic: dict[str, str] = {}
        self._history = {r: deque(maxlen=TACTIC_HISTORY) for r in self.robots}  # (time [s], tactic entered)
        self._touch: tuple[str, float, str | None] | None = None  # (robot, time [s], tactic) since the last event
        self._events: set[tuple[int, float]] = set()
        self.goal_log: list[dict] = []

    @property
    def goals(self) -> int:
        return sum(self.score.values())

    @property
    def robot_faults(self) -> int:
        return sum(n for k, n in self.faults.items() if k.startswith("robot_fault"))

    @property
    def played(self) -> float:
        """Seconds of sim time since the game started [s] (0 until the start has a time)."""
        return 0.0 if self.started_at is None else max(self.sim_time - self.started_at, 0.0)

    def start(self) -> None:
        """The referee started the game: at the latest sim time seen, or, when no clock has been heard yet
        (discovery on a loaded machine takes seconds), at the first one heard."""
        self.started_at = self.sim_time if self.sim_time > 0.0 else None

    def on_clock(self, t: float) -> None:
        if self.started_at is None:
            self.started_at = t
        self.sim_time = max(self.sim_time, t)

    def on_status(self, score_front: int, score_back: int, event: int, reason: str, event_time: float) -> None:
        """The referee's status (re-published: each event counts once). A goal is logged with the last
        touch; every event but a plain status ends the touch (the referee resets the puck or play)."""
        front, back = self.robots
        self.score[front], self.score[back] = int(score_front), int(score_back)
        if event == EVENT_NONE or (event, event_time) in self._events:
            return
        self._events.add((event, event_time))
        if event in (EVENT_GOAL_FRONT, EVENT_GOAL_BACK):
            self._log_goal(front if event == EVENT_GOAL_FRONT else back, event_time)
        elif event != EVENT_RESET:
            self.faults[fault_key(event, reason)] += 1
        self._touch = None

    def on_contact(self, robot: str, t: float | None = None) -> None:
        """A mallet-puck contact that began at ``t`` [s] sim time (default: the latest clock)."""
        if robot in self.hits:
            self.hits[robot] += 1
            when = self.sim_time if t is None else t
            self._touch = (robot, when, self._tactic_at(robot, when))

    def on_tactic(self, robot: str, name: str, t: float | None = None) -> None:
        """Counts each time a robot enters a tactic (decided at ``t`` [s] sim time; default: the latest clock)."""
        if robot in self.tactics and self._last_tactic.get(robot) != name:
            self._last_tactic[robot] = name
            self.tactics[robot][name] += 1
            self._history[robot].append((self.sim_time if t is None else t, name))

    def _tactic_at(self, robot: str, t: float) -> str | None:
        """The tactic ``robot`` was in at ``t`` [s]: the last one it entered at or before ``t``."""
        entries = self._history[robot]
        k = bisect.bisect_right([when for when, _ in entries], t)
        return entries[k - 1][1] if k else None

    def _log_goal(self, scorer: str, t: float) -> None:
        """A goal for ``scorer`` at ``t`` [s] sim time, with the last touch since the previous event."""
        conceding = self.robots[1] if scorer == self.robots[0] else self.robots[0]
        robot, when, tactic = self._touch if self._touch is not None else (None, None, None)
        self.goal_log.append({
            "time_s": round(t - (self.started_at or 0.0), 3), "scorer": scorer, "last_touch": robot,
            "tactic": tactic, "before_goal_s": None if when is None else round(t - when, 3),
            "own_goal": robot == conceding, "defender_tactic": self._tactic_at(conceding, t)})

    def result(self, recording: str | None) -> dict:
        return {"duration_s": round(self.played, 3), "score": dict(self.score), "hits": dict(self.hits),
                "faults": dict(self.faults), "tactics": {r: dict(c) for r, c in self.tactics.items()},
                "goals": [dict(g) for g in self.goal_log], "recording": recording}

    @classmethod
    def total(cls, robots: Sequence[str], results: Sequence[dict]) -> "Scoreboard":
        """The tally of several games (:meth:`result` dicts) as one board: durations, scores, hits,
        faults and tactic entries summed."""
        board = cls(robots)
        board.sim_time = sum(r["duration_s"] for r in results)
        for r in results:
            for robot in board.robots:
                board.score[robot] += r["score"][robot]
                board.hits[robot] += r["hits"][robot]
                board.tactics[robot].update(r["tactics"][robot])
            board.faults.update(r["faults"])
            game = {key: r[key] for key in ("seed", "versus_robot") if key in r}  # which game, when several
            board.goal_log += [{**g, **game} for g in r.get("goals", [])]
        return board

    def goal_sources(self) -> Counter:
        """Goals counted by where they came from: "<robot>'s <tactic>" for the scorer's own touch, "own goal
        by <robot> (<tactic>)", or "untouched, for <scorer>" (no mallet touched it since the last event)."""
        def source(g: dict) -> str:
            if g["last_touch"] is None:
                return f"untouched, for {g['scorer']}"
            if g["own_goal"]:
                return f"own goal by {g['last_touch']} ({g['tactic']})"
            return f"{g['last_touch']}'s {g['tactic']}"
        return Counter(source(g) for g in self.goal_log)

    def progress(self) -> str:
        front, back = self.robots
        return (f"sim {self.played:6.1f} s  score {front} {self.score[front]} : {self.score[back]} {back}  "
                f"hits {self.hits[front]} / {self.hits[back]}  faults {sum(self.faults.values())}")

    def table(self, recording: str | None) -> str:
        front, back = self.robots
        names = sorted(set(self.tactics[front]) | set(self.tactics[back]))
        rows = [("", front, back), ("score", self.score[front], self.score[back]),
                ("hits", self.hits[front], self.hits[back])]
        rows += [(f"tactic {n}", self.tactics[front][n], self.tactics[back][n]) for n in names]
        width = max(len(str(r[0])) for r in rows) + 2
        lines = [f"game over after {self.played:.1f} s of simulated time"]
        lines += [f"  {str(a):<{width}}{str(b):>12}{str(c):>12}" for a, b, c in rows]
        if self.goal_log:
            lines.append("  goals by the last touch: "
                         + ", ".join(f"{k} x{n}" for k, n in sorted(self.goal_sources().items())))
        lines.append("  faults: " + (", ".join(f"{k} x{n}" for k, n in sorted(self.faults.items())) or "none"))
        if recording:
            lines.append(f"  recording: {recording} (open it in Foxglove)")
        return "\n".join(lines)
