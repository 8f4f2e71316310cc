"""Referee rules (ROS-free): game status, score, goals, puck out or stuck, illegal robot states.

Table frame (README "Frames and units"): ``iiwa_front`` defends the goal at x = -L/2, ``iiwa_back``
the one at x = +L/2. The rules, after the ROS 1 referee (REFERENCE_FACTS 4) with its gaps filled:

* **Goal**: the puck centre beyond a goal line by ``goal_margin`` inside the goal mouth. The other
  robot scores; the game pauses and the puck is put back on the side of the robot that conceded.
* **Puck out**: the puck centre beyond the table's edge by ``out_margin`` anywhere else, or no puck
  pose for ``lost_timeout``. Pause; the puck goes back on a random side.
* A goal or a puck out counts once ``confirm_frames`` poses in a row show it, or the puck was last seen
  there ``vanish_time`` ago (gone into the goal): one glitched mocap frame is no event (a game's puck
  bounced off a long rim and the referee saw it 6 cm beyond).
* **Puck stuck**: the puck has stayed within ``stuck_radius`` for ``stuck_time`` in the neutral zone
  (|x| < ``neutral_zone_length``/2, where neither robot can reach), or on one robot's side for
  ``possession_limit`` (the time-limit rule the ROS 1 referee lacked) and outside the neutral zone (the
  challenge's tournament rule: no foul for a puck its holder cannot reach). Pause; in the neutral zone
  the puck goes to a random side, after a possession foul to the other robot.
* **Robot fault**: a mallet outside its robot's half (beyond the centre line by ``centre_line_margin``)
  or closer to a rim than the mallet radius less ``rim_margin`` (ROS 1 Gazebo referee's box). The game
  stops (a real robot needs a person); with ``restart_after_fault`` it pauses, resets the robots and
  the puck and resumes (unattended simulation).
* After a pause the game resumes by itself ``pause_duration`` later, once the puck is seen on the
  table; ``start``/``pause``/``stop``/``reset`` are the operator's commands (``stop`` clears the score).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping, NamedTuple, Sequence

import numpy as np

from air_hockey_agent.core.table import TableGeometry

STOPPED, PAUSED, RUNNING = 0, 1, 2  # air_hockey_msgs/GameStatus.STATUS_*
STATUS_NAMES = {STOPPED: "stopped", PAUSED: "paused", RUNNING: "running"}  # status as a word, for logs and labels
(EVENT_NONE, EVENT_GOAL_FRONT, EVENT_GOAL_BACK, EVENT_PUCK_OUT, EVENT_PUCK_STUCK, EVENT_ROBOT_FAULT,
 EVENT_RESET) = range(7)  # air_hockey_msgs/GameStatus.EVENT_*
FRONT, BACK = "iiwa_front", "iiwa_back"
SIDE = {FRONT: -1.0, BACK: 1.0}  # sign of x on each robot's half
OTHER = {FRONT: BACK, BACK: FRONT}
# start_game's answer while the simulation has not yet done the resets the referee asked for (the caller
# tries again; any other refusal is final)
NOT_YET = "cannot start yet"


@dataclass(frozen=True)
class RefereeSettings:
    """Rule thresholds (``config/referee.yaml``); lengths [m], times [s]."""

    table: TableGeometry
    mallet_radius: float
    goal_margin: float
    out_margin: float
    lost_timeout: float
    confirm_frames: int
    vanish_time: float
    stuck_radius: float
    stuck_time: float
    neutral_zone_length: float
    possession_limit: float
    centre_line_margin: float
    rim_margin: float
    pause_duration: float
    restart_after_fault: bool
    reset_x_range: tuple[float, float]  # distance of a reset puck from the centre line
    reset_y_margin: float               # reset puck this far from the long rims (beyond its radius)

    @classmethod
    def from_params(cls, params: Mapping) -> "RefereeSettings":
        names = [f for f in cls.__dataclass_fields__ if f not in ("table", "mallet_radius")]
        values = {n: params[n] for n in names}
        values["reset_x_range"] = tuple(values["reset_x_range"])
        return cls(TableGeometry.from_params(params), params["mallet.radius"], **values)


class Decision(NamedTuple):
    """What the referee decided on one update: the event, why, and what has to happen now."""

    event: int
    reason: str
    reset_puck: tuple[float, float] | None = None  # put the puck here, at rest [m, table frame]
    reset_robots: bool = False


@dataclass
class GameState:
    status: int = STOPPED
    score: dict = field(default_factory=lambda: {FRONT: 0, BACK: 0})
    last_event: int = EVENT_NONE
    last_event_time: float = 0.0
    reason: str = ""


class Referee:
    """The rules applied to puck and mallet positions over time; ``update`` is called periodically."""

    def __init__(self, settings: RefereeSettings, rng: np.random.Generator) -> None:
        self.settings, self.rng = settings, rng
        self.state = GameState()
        self._last_seen: float | None = None
        self._puck: tuple[float, float] | None = None
        self._anchor: tuple[float, float, float] | None = None  # (x, y, t) where the puck settled
        self._side_since: tuple[float, float] | None = None     # (side sign, since t)
        self._beyond: tuple[str, int] = ("", 0)  # ("goal", "out" or "": the latest pose's zone, poses in a row)
        self._resume_at: float | None = None

    # --- inputs -------------------------------------------------------------------------------
    def observe_puck(self, t: float, x: float, y: float) -> None:
        """A puck position [m, table frame] seen at time t [s]."""
        self._last_seen, self._puck = t, (x, y)
        s = self.settings
        if self._anchor is None or np.hypot(x - self._anchor[0], y - self._anchor[1]) > s.stuck_radius:
            self._anchor = (x, y, t)
        side = float(np.sign(x))
        if self._side_since is None or side != self._side_since[0]:
            self._side_since = (side, t)
        zone = self._zone(x, y)
        self._beyond = (zone, self._beyond[1] + 1 if zone == self._beyond[0] else 1)

    def _zone(self, x: float, y: float) -> str:
        """"goal" for a puck centre beyond a goal line inside the mouth, "out" beyond the table's edge
        elsewhere, "" on the table."""
        s, table = self.settings, self.settings.table
        if abs(x) > table.length / 2 + s.goal_margin and abs(y) < table.goal_width / 2:
            return "goal"
        if abs(x) > table.length / 2 + s.out_margin or abs(y) > table.width / 2 + s.out_margin:
            return "out"
        return ""

    # --- operator commands ----------------------------------------------------------------------
    def start(self, t: float) -> tuple[bool, str]:
        if self.state.status == RUNNING:
            return True, "already running"
        if not self._puck_on_table(t):
            return False, "cannot start: no puck on the table"
        self._set(RUNNING)
        return True, "game running"

    def pause(self, t: float) -> tuple[bool, str]:
        if self.state.status != RUNNING:
            return False, "cannot pause: the game is not running"
        self._set(PAUSED)
        self._resume_at = None  # an operator's pause lasts until start
        return True, "game paused"

    def stop(self, t: float) -> tuple[bool, str]:
        self._set(STOPPED)
        self.state.score = {FRONT: 0, BACK: 0}
        return True, "game stopped, score cleared"

    def reset(self, t: float) -> Decision:
        """Operator reset: robots home, puck on a random side, game stopped (score kept)."""
        self._set(STOPPED)
        return self._record(t, Decision(EVENT_RESET, "reset by the operator", self._reset_point(None), True))

    # --- rules --------------------------------------------------------------------------------
    def update(self, t: float, mallets: Mapping[str, Sequence[float]]) -> Decision | None:
        """Apply the rules at time t [s] with the mallets' (x, y) [m, table frame]; a Decision when
        something happened."""
        if self.state.status == PAUSED and self._resume_at is not None and t >= self._resume_at \
                and self._puck_on_table(t):
            self._set(RUNNING)
        if self.state.status != RUNNING:
            return None
        decision = self._robot_fault(mallets) or self._puck_rules(t)
        if decision is None:
            return None
        stop = decision.event == EVENT_ROBOT_FAULT and not self.settings.restart_after_fault
        self._set(STOPPED if stop else PAUSED)
        self._resume_at = None if stop else t + self.settings.pause_duration
        if stop:
            decision = decision._replace(reset_puck=None, reset_robots=False)
        return self._record(t, decision)

    def _puck_rules(self, t: float) -> Decision | None:
        s = self.settings
        if self._lost(t):
            return Decision(EVENT_PUCK_OUT, f"no puck pose for {s.lost_timeout:g} s", self._reset_point(None))
        x, y = self._puck
        zone, poses = self._beyond
        confirmed = poses >= s.confirm_frames or t - self._last_seen >= s.vanish_time
        if zone == "goal" and confirmed:
            conceding = FRONT if x < 0 else BACK
            scorer = OTHER[conceding]
            self.state.score[scorer] += 1
            event = EVENT_GOAL_FRONT if scorer == FRONT else EVENT_GOAL_BACK
            return Decision(event, f"goal for {scorer} (puck in {conceding}'s goal)", self._reset_point(conceding))
        if zone == "out" and confirmed:
            return Decision(EVENT_PUCK_OUT, f"puck off the table at ({x:.3f}, {y:.3f}) m", self._reset_point(None))
        if self._anchor is not None and t - self._anchor[2] >= s.stuck_time and abs(x) < s.neutral_zone_length / 2:
            return Decision(EVENT_PUCK_STUCK, f"puck at rest in the neutral zone for {s.stuck_time:g} s",
                            self._reset_point(None))
        if (self._side_since is not None and self._side_since[0] != 0.0 and t - self._side_since[1] > s.possession_limit
                and abs(x) >= s.neutral_zone_length / 2):
            holder = FRONT if self._side_since[0] < 0 else BACK
            return Decision(EVENT_PUCK_STUCK, f"{holder} kept the puck on its side for over {s.possession_limit:g} s",
                            self._reset_point(OTHER[holder]))
        return None

    def _robot_fault(self, mallets: Mapping[str, Sequence[float]]) -> Decision | None:
        s, table = self.settings, self.settings.table
        x_max = table.length / 2 - s.mallet_radius + s.rim_margin
        y_max = table.width / 2 - s.mallet_radius + s.rim_margin
        for robot, (x, y) in mallets.items():
            own = SIDE[robot] * x  # distance into the robot's own half
            if own < -s.centre_line_margin:
                return Decision(EVENT_ROBOT_FAULT, f"{robot}'s mallet crossed the centre line ({-own:.3f} m)",
                                self._reset_point(None), True)
            if abs(x) > x_max or abs(y) > y_max:
                return Decision(EVENT_ROBOT_FAULT, f"{robot}'s mallet at ({x:.3f}, {y:.3f}) m is in the rim",
                                self._reset_point(None), True)
        return None

    # --- helpers ------------------------------------------------------------------------------
    def _lost(self, t: float) -> bool:
        """True when no puck pose came within ``lost_timeout`` before t."""
        return self._last_seen is None or t - self._last_seen > self.settings.lost_timeout

    def _puck_on_table(self, t: float) -> bool:
        if self._lost(t):
            return False
        x, y = self._puck
        table = self.settings.table
        return abs(x) < table.length / 2 and abs(y) < table.width / 2

    def _reset_point(self, robot: str | None) -> tuple[float, float]:
        """A resting place on ``robot``'s half (a random half for None): thresholds in config."""
        s, table = self.settings, self.settings.table
        side = SIDE[robot] if robot else float(self.rng.choice((-1.0, 1.0)))
        y_max = table.width / 2 - table.puck_radius - s.reset_y_margin
        return side * float(self.rng.uniform(*s.reset_x_range)), float(self.rng.uniform(-y_max, y_max))

    def _set(self, status: int) -> None:
        if status == RUNNING:
            self._anchor = self._side_since = None  # the stuck and possession clocks restart with a rally
        self.state.status = status

    def _record(self, t: float, decision: Decision) -> Decision:
        self.state.last_event, self.state.last_event_time, self.state.reason = decision.event, t, decision.reason
        return decision
