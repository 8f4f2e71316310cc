"""When a strategy-test trial ends and how it scored (thesis sec. 4.6 criteria), from the true puck
states and the mallet-puck contacts the simulation reports. Table frame; the tested robot defends
the goal at x = -L/2.

* Smash (straight, left, right): success = a goal; the offset is the puck's y where it reaches the
  opponent's goal line (its short rim when it misses).
* Cut: success = hit, then at rest in the smash area; partial = hit and no goal conceded. A puck the
  mallet stopped dead (at rest while their contact lasts, which the simulation reports only once it ends)
  was hit: before, such a caught Cut ended "at rest" without a hit (9 of 200 lab-table Cuts, seed 0).
* Prepare: success = at rest in the smash area; partial = at rest on the own half (success included);
  crossing the centre line is a failure.
* Repel: success = hit; also the puck's speed where it crosses the opponent's defend line, and goals.
* Guard (ours, nothing forced): success = no goal conceded until the puck leaves the goal's zone
  (``guard_exit_depth``) or ``guard_time`` has passed.

With a defending opponent (``strategy-test --defended``) the criteria stay these; a trial also says
whether the opponent touched the puck after the tested robot's hit (``defended``).
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

from air_hockey_agent.core.game.strategy.trials import Trial, TrialSettings

CROSS_MARGIN = 0.005  # [m] the goal line is reached this close to the short rim (the puck's centre)
START_TOLERANCE = 0.05  # [m] a trial starts with the first state this close to its initial position
#                         (states of the parked puck still in flight when the puck is set are ignored)


@dataclass
class TrialResult:
    strategy: str
    index: int
    success: bool = False
    partial: bool = False
    hit: bool = False
    goal: bool = False          # scored in the opponent's goal
    conceded: bool = False      # the puck entered the own goal
    offset: float | None = None         # [m] y at the opponent's goal line
    defend_speed: float | None = None   # [m/s] speed at the opponent's defend line after the hit
    rest: tuple | None = None           # [m] where the puck came to rest
    reason: str = ""
    duration: float = 0.0               # [s] simulated time of the trial
    defended: bool = False              # the opponent touched the puck after the hit (--defended)

    def as_dict(self) -> dict:
        return asdict(self)

    def record(self, error: bool, tactic: str, state: tuple | None = None) -> dict:
        """The trial's line of ``strategy-test --results``: these fields, whether it ended on an error
        (no outcome), the tested robot's tactic and its reason when it ended, and the trial's initial puck
        ``state`` (x, y, vx, vy, theta, omega [m, m/s, rad, rad/s], table frame; None: not known, a trial
        no worker finished)."""
        return {**self.as_dict(), "error": error, "tactic": tactic, "state": None if state is None else list(state)}


@dataclass
class TrialWatcher:
    """Feed it the true puck states and the tested robot's contacts of one trial; it says when the trial
    is over (:attr:`done`) and scores it (:meth:`result`)."""

    trial: Trial
    s: TrialSettings
    t0: float | None = None
    done: bool = False
    _result: TrialResult = field(init=False)
    _last_hit: float | None = None
    _crossed_centre: bool = False

    def __post_init__(self) -> None:
        self._result = TrialResult(self.trial.strategy, self.trial.index)

    def contact(self, t: float, duration: float = 0.0) -> None:
        """A contact that began at ``t`` [s] and lasted ``duration`` [s] (reported when it ended, so states
        from before its end may still arrive afterwards: those do not count as "at rest after the hit")."""
        if not self.done and self.t0 is not None and t >= self.t0:
            self._result.hit, self._last_hit = True, t + duration

    @property
    def hit(self) -> bool:
        """The tested robot has touched the puck since the trial began."""
        return self._result.hit

    def opponent_contact(self, t: float) -> None:
        """The opponent's mallet met the puck at ``t`` [s]: the tested robot's shot was defended if it had hit."""
        if not self.done and self._result.hit and t >= self._last_hit:
            self._result.defended = True

    def state(self, t: float, x: float, y: float, vx: float, vy: float, touching: bool = False) -> None:
        """The true puck state at ``t`` [s] (table frame); ``touching``: the tested robot's mallet is in a contact
        with the puck now (begun, not yet ended and reported)."""
        if self.done:
            return
        if self.t0 is None:
            x0, y0 = self.trial.state[:2]
            if math.hypot(x - x0, y - y0) > START_TOLERANCE:
                return
            self.t0 = t
        r, s, half = self._result, self.s, self.s.table.length / 2
        r.duration = t - self.t0
        if r.offset is None and x >= half - s.table.puck_radius - CROSS_MARGIN:
            r.offset = y
        if r.hit and r.defend_speed is None and x >= half - s.defend_line:
            r.defend_speed = math.hypot(vx, vy)
        if x > half:
            return self._end("goal", goal=True)
        if x < -half:
            return self._end("conceded", conceded=True)
        if self.trial.strategy == "guard":
            return self._guard_end(x, r.duration)
        if x > 0.0 and not self._crossed_centre:
            self._crossed_centre = True
            if self.trial.strategy in ("prepare", "cut") and r.hit:
                return self._end("crossed the centre line")
        after_hit = r.hit and t > self._last_hit
        speed = math.hypot(vx, vy)
        if speed < s.rest_speed and (after_hit or (not r.hit and self.trial.strategy in ("cut", "repel"))):
            if touching and not r.hit:  # caught: the contact that stopped the puck has not ended yet
                r.hit, self._last_hit = True, t
                return self._end("at rest against the mallet", rest=(x, y))
            return self._end("at rest", rest=(x, y))
        if after_hit and self.trial.strategy in ("cut", "prepare") and self._decided(x, y, speed):
            return self._end("decided: stops within its remaining travel", rest=(x, y))
        kind = self.trial.strategy
        if (kind.startswith("smash") or kind == "repel") and r.hit and t - self._last_hit > s.after_hit:
            return self._end(f"no goal {s.after_hit:g} s after the hit")
        if not r.hit and r.duration > s.hit_timeout:
            return self._end(f"timeout after {s.hit_timeout:g} s without a hit")
        if r.duration > s.timeout:
            return self._end(f"timeout after {s.timeout:g} s")

    def _guard_end(self, x: float, duration: float) -> None:
        """A guard trial ends without a goal once the puck is ``guard_exit_depth`` [m] from the own goal
        line (out of the goal's zone: the other tactics' business in a game) or after ``guard_time`` [s];
        a puck at rest does not end it (the mallet may still push it in)."""
        s = self.s
        if x > s.guard_exit_depth - s.table.length / 2:
            self._end("left the goal's zone")
        elif duration > s.guard_time:
            self._end(f"no goal in {s.guard_time:g} s")

    def _decided(self, x: float, y: float, speed: float) -> bool:
        """The puck cannot change the outcome any more: under the table's damping it slides at most
        speed / damping (friction only shortens that), and that disc touches no rim, not the centre line
        and not the smash area's edge, so where it stops is inside the area or outside it for certain
        (the last seconds of a slow slide otherwise took most of a Cut or Prepare trial)."""
        s, half = self.s, self.s.table.length / 2
        if s.damping <= 0.0:
            return False
        reach = speed / s.damping
        clear_of_rims = (abs(y) + reach < s.table.y_limit and x + reach < 0.0
                         and x - reach > -(half - s.table.puck_radius))
        return clear_of_rims and abs(s.area_margin(x, y)) > reach

    def _end(self, reason: str, goal: bool = False, conceded: bool = False, rest: tuple | None = None) -> None:
        r = self._result
        r.reason, r.goal, r.conceded, r.rest = reason, goal, conceded, rest
        self.done = True

    def result(self) -> TrialResult:
        return score(self.trial, self._result, self.s)


def score(trial: Trial, r: TrialResult, s: TrialSettings) -> TrialResult:
    """Apply the strategy's success criteria to an ended trial."""
    in_area = r.rest is not None and s.in_smash_area(*r.rest)
    own_half = r.rest is not None and r.rest[0] < 0.0
    kind = trial.strategy
    if kind.startswith("smash"):
        r.success = r.goal
    elif kind == "cut":
        r.success = r.hit and in_area and not r.conceded
        r.partial = r.hit and not r.conceded
    elif kind == "prepare":
        r.success = r.hit and in_area
        r.partial = r.hit and own_half
    elif kind == "repel":
        r.success = r.hit
    elif kind == "guard":
        r.success = not r.conceded
    return r
