"""Shot prediction (ROS-free): where a hit sends the puck, predicted with the project's puck model.

The earlier stack chose among a straight smash and two bank shots at random and aimed the banks with
the reflection law (REFERENCE_FACTS 2.2, 8.9-11), which ignores the rim's restitution, friction and the
spin a sliding impact gives (thesis eq. 3.2-3.4): fig. 5.8 of the thesis shows the resulting bias. Here
every candidate is aimed by solving "the predicted puck reaches the opponent's goal line at y = 0" for
the hit direction (secant iterations on the model's prediction, Routh impacts and spin included),
with the hit speed the arm allows along that direction, and the candidates are ranked by the
probability that the puck enters the goal when the direction is off by ``aim_noise``, scaled down by
``guarded_factor`` when the puck passes the opponent's defend line within a mallet's reach of its ready
point (the opponent runs the same agent, so its mallet waits there; a shot straight at the goal centre
ends on it).

Own frame: x toward the opponent; the opponent's goal line is x = +L/2.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from air_hockey_agent.core.game.tactics.settings import TacticsSettings
from air_hockey_agent.core.motion.task_motion import stop_fraction
from air_hockey_agent.core.puck.mallet_impact import puck_after_contact
from air_hockey_agent.core.puck.model import PuckModel, PuckParams
from air_hockey_agent.core.puck.prediction import predict_fast, prepare_prediction

VARIANTS = ("straight", "left_bank", "right_bank")  # left: off the y = +W/2 rim, right: off y = -W/2
SECANT_ITERATIONS = 4
FIRST_STEP = 0.02      # [rad] second secant point
MAX_STEP = 0.15        # [rad] largest secant step
HALVINGS = 2           # step halvings when a secant step leaves the shots that reach the goal line
LINE_INSET = 0.01      # [m] the goal line is sampled this far in front of the short rim (in free flight)
NO_Q = np.zeros(6)
RECONTACT_STEP = 0.02  # [s] sample spacing of the re-contact check (a meeting lasts >= 0.06 s below 2.7 m/s)


@dataclass(frozen=True)
class Shot:
    variant: str
    direction: np.ndarray      # unit hit direction (mallet velocity and centre line)
    hit_point: np.ndarray      # [m] mallet centre at the hit
    mallet_speed: float        # [m/s]
    puck_velocity: np.ndarray  # [m/s] right after the hit
    goal_y: float              # [m] predicted y at the opponent's goal line
    arrival: float             # [s] from the hit to the goal line
    success: float             # probability of entering the goal under the aim noise


@dataclass(frozen=True)
class Push:
    """A contact meant to leave the puck somewhere on the own half (Prepare, Cut)."""

    normal: np.ndarray          # unit contact normal, mallet centre to puck centre
    hit_point: np.ndarray       # [m] mallet centre at the contact
    mallet_velocity: np.ndarray  # [m/s] mallet velocity at the contact
    rest: np.ndarray            # [m] predicted position where the puck (nearly) stops
    crosses_centre: bool        # the prediction crosses the centre line on the way
    enters_goal: bool           # ... or the own goal line inside the goal mouth, or ends in the own goal
    after: np.ndarray           # puck state (6) right after the contact
    bounces: bool               # the prediction meets a rim

    @property
    def mallet_speed(self) -> float:
        return float(np.hypot(*self.mallet_velocity))


def _normal_cdf(z: float) -> float:
    return 0.5 * (1.0 + math.erf(z / math.sqrt(2.0)))


class ShotPredictor:
    """Aims and ranks shots at a puck for one robot (own frame)."""

    def __init__(self, model: PuckModel, settings: TacticsSettings, dt: float,
                 speed_at: Callable[[np.ndarray, np.ndarray], float]) -> None:
        self.model, self.s, self.dt, self.speed_at = model, settings, dt, speed_at
        self.physics_version = 0  # counts use_physics calls: shots aimed with older physics are stale
        table = model.table
        self.line = table.length / 2 - table.puck_radius - LINE_INSET
        self.mouth = table.goal_mouth
        self.scored_x = table.scored_x  # [m] the model keeps a puck that has scored beyond this |x|
        self.defend_line = table.length / 2 - settings.defend_line   # the opponent's, in our frame
        self.guard_y = -settings.ready_point[1]  # where the opponent's mallet waits (the same agent's ready point)
        prepare_prediction()  # not in the first decision

    def use_contact_law(self, settings: TacticsSettings) -> None:
        """Aim with these settings' mallet restitution and friction from now on (learned online,
        :mod:`~air_hockey_agent.core.game.contact_learning`): shots aimed before are stale."""
        self.s = settings
        self.physics_version += 1

    def use_physics(self, params: PuckParams) -> None:
        """Predict shots with these puck physics from now on (the robot's own frame), e.g. what the
        robot's tracker has learned online of the table."""
        self.model = self.model.with_params(params)
        self.physics_version += 1

    # --- one candidate ---------------------------------------------------------------------------
    def _evaluate(self, puck: np.ndarray, angle: float, speed: float | None) -> tuple | None:
        """(goal y, arrival, hit point, mallet speed, puck velocity) of a hit along ``angle``; None when
        the arm cannot hit there or the puck does not reach the goal line within the shot horizon."""
        d = np.array([math.cos(angle), math.sin(angle)])
        hit = puck[:2] - d * self.s.contact_distance
        top = self.speed_at(hit, d)
        if top <= 0.0:
            return None
        v = min(top * self.s.hit_speed_fraction, self.s.max_hit_speed, math.inf if speed is None else speed)
        state = self._after(puck, v * d, d)
        vp = state[2:4]
        crossings = predict_fast(self.model, state, None, self.s.shot_horizon, self.dt, NO_Q,
                                 lines=(self.line, self.defend_line)).crossings
        crossing, guard = crossings.get(self.line), crossings.get(self.defend_line)
        if crossing is None:
            return None
        return crossing.y, crossing.time, hit, v, vp, (crossing.y if guard is None else guard.y)

    def push(self, puck: np.ndarray, angle: float, mallet_speed: float, end_speed: float, horizon: float) -> Push:
        """A hit along ``angle`` [rad] at ``mallet_speed`` [m/s] on the puck (own-frame state, 6): :meth:`contact`."""
        d = np.array([math.cos(angle), math.sin(angle)])
        return self.contact(puck, d, mallet_speed * d, end_speed, horizon)

    def contact(self, puck: np.ndarray, normal: np.ndarray, mallet_velocity: np.ndarray, end_speed: float,
                horizon: float) -> Push:
        """Where a contact along the unit ``normal`` (mallet to puck) with the mallet moving at
        ``mallet_velocity`` [m/s] leaves the puck (own-frame state, 6, at the contact): predicted with the
        puck model (rim impacts included) until its speed would fall to ``end_speed`` under the damping
        alone, at most ``horizon`` [s]."""
        state = self._after(puck, mallet_velocity, normal)
        speed, damping = float(np.hypot(*state[2:4])), self.model.params.damping
        t = horizon if damping <= 0.0 or speed <= end_speed else min(horizon, math.log(speed / end_speed) / damping)
        own_line = -self.line
        pred = predict_fast(self.model, state, None, max(t, self.dt), self.dt, NO_Q, lines=(0.0, own_line))
        goal = pred.crossings.get(own_line)
        scored = (goal is not None and abs(goal.y) < self.mouth) or pred.state[0] < -self.scored_x
        return Push(np.asarray(normal, float), puck[:2] - normal * self.s.contact_distance,
                    np.asarray(mallet_velocity, float), pred.state[:2].copy(), 0.0 in pred.crossings,
                    scored, state, bool(pred.impacts))

    def turns_in(self, puck: np.ndarray, normal: np.ndarray, mallet_velocity: np.ndarray) -> bool:
        """A contact (as :meth:`contact`, followed as Prepare's pushes are: to ``prepare_end_speed``, at most
        ``prepare_horizon``) sends the puck into the own goal: what a kept command's and a waiting mallet's
        meetings with the puck are judged by."""
        return self.contact(puck, normal, mallet_velocity, self.s.prepare_end_speed, self.s.prepare_horizon).enters_goal

    def _after(self, puck: np.ndarray, mallet_velocity: np.ndarray, normal: np.ndarray) -> np.ndarray:
        """The puck's state right after a contact (:func:`puck_after_contact`), its angle set to 0 (the
        prediction does not need it)."""
        state = puck_after_contact(puck, mallet_velocity, normal, self.s.mallet_restitution, self.s.mallet_friction,
                                   self.model.table.puck_radius)
        state[4] = 0.0
        return state

    def rebounds_into_mallet(self, push: Push, follow_through: float, watch: float) -> bool:
        """The puck, rebounding from a rim, meets the mallet again within ``watch`` [s] of the contact while
        the mallet runs on ``follow_through`` [m] along its velocity and stays there (the planner's stop
        law; a mallet at rest stays at the contact point); judged once the puck has left the mallet by ``approach_clearance``,
        every ``RECONTACT_STEP`` s (the model lets the puck pass through the mallet, so a meeting lasts
        about 2 (r_puck + r_mallet) / speed), or once it has bounced off a rim (a puck 1 cm from the rim is
        back before it clears the mallet: pushed into the goal-line rim it was squeezed out sideways). A
        meeting is a gap below half ``approach_clearance`` that is closing: a puck against a long rim pushed
        along it bounces off the rim at once but moves away from the mallet (counted as a meeting, every
        push of such a puck was refused and it stayed until the possession limit). A push into a near rim
        was hit a second time, twice across the centre line."""
        if not push.bounces:
            return False
        speed = push.mallet_speed
        moving = speed > 0.0 and follow_through > 0.0
        stop_time = 2.0 * follow_through / speed if moving else 1.0
        d = push.mallet_velocity / speed if moving else np.zeros(2)
        every = max(1, int(round(RECONTACT_STEP / self.dt)))
        pred = predict_fast(self.model, push.after, None, watch, self.dt, NO_Q, sample_every=every)
        bounced = pred.impacts[0][0] if pred.impacts else math.inf  # first rim impact [s]
        left, contact, last = False, self.s.contact_distance, math.inf
        for t, s, _ in pred.samples:
            mallet = push.hit_point + d * follow_through * stop_fraction(min(t / stop_time, 1.0))
            gap = float(np.hypot(s[0] - mallet[0], s[1] - mallet[1])) - contact
            if left and gap < 0.5 * self.s.approach_clearance and gap < last:
                return True
            # a puck next to the rim is back before it has cleared the mallet
            left, last = left or gap > self.s.approach_clearance or t > bounced, gap
        return False

    def _first_shot(self, puck: np.ndarray, guess: float, speed: float | None) -> tuple[float, tuple | None]:
        """The angle nearest ``guess`` [rad] whose shot reaches the goal line (:meth:`_evaluate`), searched
        ``FIRST_STEP`` by step to either side, at most ``aim_search_steps`` steps each way; (guess, None)
        when none does. Beside the posts and near the arm's reach the reflection law's angle can miss the
        line (or have no hit) where a shot a step away scores: the secant would not have started."""
        for k in range(2 * self.s.aim_search_steps + 1):
            angle = guess + FIRST_STEP * ((k + 1) // 2) * (1.0 if k % 2 else -1.0)
            result = self._evaluate(puck, angle, speed)
            if result is not None:
                return angle, result
        return guess, None

    def aim(self, puck: np.ndarray, variant: str, speed: float | None = None) -> Shot | None:
        """The hit that sends ``puck`` (own-frame state, 6) into the goal centre by ``variant``: secant
        iterations on the direction, starting from the reflection-law guess (or the shot nearest it that
        reaches the line, :meth:`_first_shot`; its second point on the side where a shot reaches it)."""
        x, y = float(puck[0]), float(puck[1])
        ylim = self.model.table.y_limit
        mirror = {"straight": 0.0, "left_bank": 2.0 * ylim, "right_bank": -2.0 * ylim}[variant]
        a, r = self._first_shot(puck, math.atan2(mirror - y, self.line - x), speed)
        b = a + FIRST_STEP
        rb = None if r is None else self._evaluate(puck, b, speed)
        if rb is None and r is not None and self.s.aim_search_steps > 0:  # the other side
            b = a - FIRST_STEP
            rb = self._evaluate(puck, b, speed)
        slope = None
        for _ in range(SECANT_ITERATIONS):
            if r is None or rb is None or rb[0] == r[0]:
                break
            slope = (rb[0] - r[0]) / (b - a)
            step = max(-MAX_STEP, min(MAX_STEP, -rb[0] / slope))
            a, r = b, rb
            if abs(step) < 1e-4:
                break
            b = b + step
            rb = self._evaluate(puck, b, speed)
            for _ in range(HALVINGS):  # stepped off the shots that reach the line: come back halfway
                if rb is not None:
                    break
                b = 0.5 * (a + b)
                rb = self._evaluate(puck, b, speed)
        best = [(angle, res) for angle, res in ((a, r), (b, rb)) if res is not None]
        if slope is None or not best:
            return None
        angle, (goal_y, arrival, hit, v, vp, guard_y) = min(best, key=lambda item: abs(item[1][0]))
        spread = max(abs(slope) * self.s.aim_noise, 1e-9)
        edge = self.mouth - self.s.goal_aim_margin
        success = _normal_cdf((edge - goal_y) / spread) - _normal_cdf((-edge - goal_y) / spread)
        if abs(guard_y - self.guard_y) < self.s.contact_distance + self.s.guard_margin:
            success *= self.s.guarded_factor  # straight into the opponent's waiting mallet
        return Shot(variant, np.array([math.cos(angle), math.sin(angle)]), hit, v, vp, goal_y, arrival, success)

    def candidates(self, puck: np.ndarray, variants: tuple[str, ...] = VARIANTS, speed: float | None = None) -> list[Shot]:
        """The aimed shots of ``variants`` that may score."""
        return [s for s in (self.aim(puck, v, speed) for v in variants) if s is not None and s.success > 0.0]

    @staticmethod
    def pick(shots: list[Shot], tie: float = 0.05) -> Shot | None:
        """The most likely goal; within ``tie`` of it, the one that arrives first."""
        if not shots:
            return None
        top = max(s.success for s in shots)
        return min((s for s in shots if s.success >= top - tie), key=lambda s: s.arrival)

    def best(self, puck: np.ndarray, variants: tuple[str, ...] = VARIANTS, speed: float | None = None) -> Shot | None:
        return self.pick(self.candidates(puck, variants, speed))
