"""The tactics state machine (thesis sec. 4.1, 4.6; the two-layer tactics of its reference [8]).

Every decision period the selector looks at the referee's status and the tracker's :class:`Situation`:

* game stopped: **Init** (no command); paused: **Home**; running: play.
* While an accepted hit is still valid (the prediction still puts the puck where the command was
  planned for) the selector keeps it, through the follow-through (``settle_time``); otherwise it
  re-decides at once. S locked every switch for 1.5 s (REFERENCE_FACTS 8.9); here a tactic changes as
  soon as the predicted situation does.
* Re-deciding tries the tactics whose entry conditions hold, in priority order, and plays the first
  that proposes a command: **Smash** (slow puck predicted in the smash area, or one moving away from the
  goal, chased), **Repel** (puck straight at the goal, no rim impact), **Cut** (any other approach with
  time to get there), **Prepare** (puck at rest outside the smash area), else **Ready**.
* The trajectory generator's answer steers the next try: "faster than the arm allows" caps the speed
  at the reported maximum, "beyond the joint limits" slows a self-timed hit down by ``limits_slowdown``
  (a tactic with nothing to play under its cap is blocked like a refused one),
  "too late" adds lead time to tactics that choose their own hit time (and makes a Cut meet the puck
  at least that much later on its path than the refused contact), and
  any other refusal (or "too late" for a puck that will not wait) blocks that tactic for
  ``retry_delay`` so the next one is tried. A hit is only committed to once the planner accepted it.
* Below that re-plan's tolerance, an accepted hit is moved with the puck (``hit_correction_distance``): the
  same command, shifted by how far the puck predicted at the hit time moved from where the command expects
  it, so the contact normal stays the planned one while the prediction grows more accurate, up to
  ``hit_correction_time`` before the hit (a refused shift leaves the command under way as it was); within
  ``min_plan_time`` of a Cut's or Repel's hit, where neither plans it anew, also a shift up to a contact
  distance.
* When a re-plan of a hit or cut under way finds nothing the planner accepts, the command under way is
  kept while the prediction still brings the puck to it (rather than falling back to Ready) and, with
  ``keep_checks_outcome``, while the contact it then makes does not send the puck into the own goal.
* A forced tactic (strategy test) is the only one tried until released.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Callable

import numpy as np

from air_hockey_agent.core.game.arm_reach import ArmReach
from air_hockey_agent.core.game.contact_learning import LearnedLaw, contact_learner
from air_hockey_agent.core.game.shots import VARIANTS, ShotPredictor
from air_hockey_agent.core.game.situation import Situation
from air_hockey_agent.core.game.tactics.base import (CUT, HOME, INIT, NAMES, PREPARE, READY, REPEL, SMASH, Context,
                                                     Proposal, Tactic, first_meeting, path_gap)
from air_hockey_agent.core.game.tactics.cut import Cut
from air_hockey_agent.core.game.tactics.home import Home
from air_hockey_agent.core.game.tactics.init import Init
from air_hockey_agent.core.game.tactics.prepare import Prepare
from air_hockey_agent.core.game.tactics.ready import Ready
from air_hockey_agent.core.game.tactics.repel import Repel
from air_hockey_agent.core.game.tactics.settings import TacticsSettings
from air_hockey_agent.core.game.tactics.smash import Smash
from air_hockey_agent.core.puck.model import flight_acceleration

STOPPED, PAUSED, RUNNING = 0, 1, 2           # air_hockey_msgs/GameStatus.STATUS_*
ACCEPTED, TOO_LATE, TOO_FAST, LIMITS = 0, 3, 5, 6  # air_hockey_msgs/TrajectoryStatus.OUTCOME_*


@dataclass
class Decision:
    tactic: int
    reason: str
    forced: bool
    command: Proposal | None  # send this now (None: keep what runs)
    changed: bool             # the tactic differs from the previous decision's

    @property
    def name(self) -> str:
        return NAMES[self.tactic]


@dataclass
class _Sent:
    proposal: Proposal
    stamp: float                 # [s] when it was sent; the planner's answer carries it back
    accepted: bool | None = None
    corrects: Proposal | None = None  # the accepted command this one moves with the puck (kept if refused)


def default_tactics() -> dict[int, Tactic]:
    return {t.tactic: t for t in (Init(), Home(), Ready(), Smash(), Cut(), Prepare(), Repel())}


class TacticsSelector:
    """One robot's tactics, in its own frame (ROS-free)."""

    def __init__(self, settings: TacticsSettings, reach: ArmReach, shots: ShotPredictor,
                 tactics: dict[int, Tactic] | None = None) -> None:
        self.s, self.reach, self.shots = settings, reach, shots
        self.tactics = tactics or default_tactics()
        self.current, self.reason, self.forced, self.variant = INIT, "game stopped", None, ""
        self.sent: _Sent | None = None
        self.executing: Proposal | None = None  # the last accepted command (the arm runs it until another one is)
        self.uncorrectable: Proposal | None = None  # an accepted command whose shift with the puck was refused
        self.contact_at = -math.inf  # [s] the time of the last contact the robot played (an accepted command's)
        self.fused_at: float | None = None  # [s] the last estimate that fused a frame (observe_puck; None: not told)
        self.blocked: dict[int, float] = {}
        self.lead_extra, self.speed_cap = 0.0, math.inf
        self.own_half_since: float | None = None  # [s] when the puck last came onto the own half
        self.learner = contact_learner(settings) if settings.contact_learning else None
        self.learned: LearnedLaw | None = None  # the mallet's law the shots are aimed with, once learned
        self.log: Callable[[str], None] | None = None
        self._log_at = 0  # the next log of the learned law when this many contacts were measured in all

    # --- the mallet's contact law, learned online -------------------------------------------------
    def observe_puck(self, t: float, state: np.ndarray) -> None:
        """A fused estimate of the tracker at ``t`` [s] (own frame, 6): for the mallet's law learned online, and
        when the puck was last seen (:meth:`_since_own_contact`)."""
        self.fused_at = t
        if self.learner is not None:
            self.learner.puck(t, float(state[0]), float(state[1]), float(state[4]))

    def observe_mallet(self, t: float, position: np.ndarray, velocity: np.ndarray) -> None:
        """The mallet at ``t`` [s] (own frame) from a joint state, for the mallet's law learned online."""
        if self.learner is not None:
            self.learner.mallet(t, position, velocity)

    def _learn(self, now: float) -> None:
        """Aim with the mallet's law as the robot's own contacts have it, when a new contact refitted it."""
        p = self.shots.model.params
        law = self.learner.update(now, flight_acceleration(p.damping, p.friction_surface, p.table_acceleration))
        if law is None:
            return
        self.learned = law
        self.s = replace(self.s, mallet_restitution=law.restitution, mallet_friction=law.friction)
        self.shots.use_contact_law(self.s)
        if self.log is not None and law.seen >= self._log_at:  # at the first fit, then each doubling
            self._log_at = 2 * law.seen
            self.log(f"mallet contact law learned from {law.contacts} contacts: restitution {law.restitution:.3f}, "
                     f"friction {law.friction:.3f} (median exit error {law.error_median:.3f} m/s)")

    # --- inputs ------------------------------------------------------------------------------------
    def force(self, tactic: int | None, variant: str = "") -> str:
        """Force ``tactic`` (a ``TACTIC_*`` id; for Smash optionally one ``variant`` of
        :data:`~air_hockey_agent.core.game.shots.VARIANTS`) until released with None."""
        if tactic is not None and tactic not in self.tactics:
            raise ValueError(f"unknown tactic {tactic} (known: {', '.join(f'{k} {v}' for k, v in NAMES.items())})")
        if variant and (tactic != SMASH or variant not in VARIANTS):
            raise ValueError(f"variant '{variant}' needs tactic smash and one of {', '.join(VARIANTS)}")
        self.forced, self.variant = tactic, variant
        self.sent, self.executing, self.blocked = None, None, {}
        self.lead_extra, self.speed_cap = 0.0, math.inf
        if tactic is None:
            return "released to the state machine"
        return f"tactic {NAMES[tactic]} forced" + (f" ({variant})" if variant else "")

    def on_status(self, stamp: float, outcome: int, max_speed: float, now: float) -> None:
        """The trajectory generator's answer to the command sent at ``stamp``."""
        sent = self.sent
        if sent is None or abs(stamp - sent.stamp) > 1e-6:
            return  # an answer to a command already replaced
        if outcome == ACCEPTED:
            sent.accepted, self.executing = True, sent.proposal
            return
        if sent.corrects is not None:  # a refused shift with the puck: the command under way stays as it is
            self.sent, self.uncorrectable = _Sent(sent.corrects, sent.stamp, True), sent.corrects
            return
        sent.accepted = False
        proposal = sent.proposal
        known = math.isfinite(max_speed) and max_speed > 0.0
        if outcome == TOO_FAST and known:
            self.speed_cap = max_speed * self.s.speed_cap_fraction
        elif outcome == LIMITS and proposal.is_hit and proposal.flexible_time:
            # the planner's estimate of the speed that keeps the broken joint limit (below the one asked),
            # else a fixed slowdown (a limit with no speed estimate reports the arm's fastest hit there)
            speed = float(np.linalg.norm(proposal.velocity))
            self.speed_cap = (max_speed * self.s.speed_cap_fraction if known and max_speed < speed
                              else self.s.limits_slowdown * speed)
        elif (outcome == TOO_LATE and (proposal.flexible_time or proposal.later_ok)
              and self.lead_extra < self.s.max_lead_extra):
            self.lead_extra = min(self.lead_extra + max(proposal.slack, 0.0) + self.s.lead_time_step,
                                  self.s.max_lead_extra)
        else:
            self.blocked[proposal.tactic] = now + self.s.retry_delay
        self.sent = None

    # --- decision ----------------------------------------------------------------------------------
    def step(self, now: float, status: int, situation: Situation | None, mallet: np.ndarray | None = None,
             mallet_velocity: np.ndarray | None = None) -> Decision:
        """The decision at ``now`` [s] for the referee's ``status``, the puck's ``situation`` and the mallet's
        position [m] and velocity [m/s] (own frame; None when unknown)."""
        situation = self._since_own_contact(now, situation)
        self._track_possession(now, status, situation)
        if self.learner is not None:
            self._learn(now)
        if status == STOPPED:
            self.sent, self.executing, self.blocked = None, None, {}
            return self._decide(INIT, "game stopped: holding", None)
        if status == PAUSED:
            wanted = [HOME]
        elif self._committed(now, situation):
            return Decision(self.current, self.reason, self.forced is not None, self._corrected(now, situation), False)
        elif self.forced is not None:
            wanted = [self.forced]
        else:
            wanted = self.candidates(situation)
        running = self.sent.proposal if self.sent is not None and self.sent.accepted else None
        # a forced tactic (strategy test) plays as asked: its trials move the puck, no referee counts
        possession = 0.0 if self.own_half_since is None or self.forced is not None else now - self.own_half_since
        ctx = Context(now, self.s, self.reach, self.shots, mallet, mallet_velocity, self.lead_extra, self.speed_cap,
                      self.variant, running, possession)
        for i, tactic in enumerate(wanted):
            if i and self.executing is not None and wanted[i - 1] == self.executing.tactic:
                kept = self._still_valid(now, situation)  # its own tactic, just tried, had nothing new to play
                if kept is not None:
                    return self._decide(kept.tactic,
                                        f"{NAMES[kept.tactic]} under way kept (its re-plan was refused)", None)
            if self.blocked.get(tactic, -math.inf) > now:
                continue
            proposal = self.tactics[tactic].propose(situation, ctx)
            if proposal is not None:
                return self._decide(tactic, proposal.reason, self._to_send(proposal, now))
            if tactic == self.current and not math.isinf(self.speed_cap):
                # nothing to play under the speed its refusal left: asked again uncapped once the tactic
                # changes, it would be refused again, and the tactic after it never get its turn
                self.blocked[tactic] = now + self.s.retry_delay
        if self.forced is not None and status == RUNNING:
            return self._decide(self.forced, f"{NAMES[self.forced]} forced: waiting until it applies", None)
        fallback = HOME if status == PAUSED else READY
        return self._decide(fallback, "nothing to do" if fallback == READY else "game paused", None)

    def candidates(self, situation: Situation | None) -> list[int]:
        """Tactics whose entry conditions hold, in priority order (READY last, always)."""
        if situation is None:
            return [READY]
        st, out = self.s, []
        if situation.speed <= st.smash_speed_limit(situation.leaving(st.approach_speed)):
            out.append(SMASH)
        if situation.approaching(st.approach_speed):
            out += [REPEL, CUT]
        if situation.speed <= st.static_speed:
            out.append(PREPARE)
        out.append(READY)
        return out

    # --- bookkeeping -------------------------------------------------------------------------------
    def _since_own_contact(self, now: float, situation: Situation | None) -> Situation | None:
        """``situation``, or with ``unseen_after_own_contact`` None (the puck unseen) while no frame has been fused
        since the last contact the robot played: the accepted command under way met the puck at its time, so an
        estimate from frames before it describes the puck before the contact, also when the tracker carried it
        on to a later frame it rejected. In mocap dropouts over the hit (up to 0.9 s in the lab's recordings)
        the tracker held the pre-hit puck, and the Smash re-planned after the follow-through sent the mallet
        back to where the puck had been while the shot crossed the table (thesis table, self-play seeds 513 and
        521). The last fused frame is :meth:`observe_puck`'s; not told, the estimate's own time."""
        sent = self.sent
        if sent is not None and sent.accepted and sent.proposal.puck is not None and sent.proposal.time <= now:
            self.contact_at = max(self.contact_at, sent.proposal.time)
        if situation is None or not self.s.unseen_after_own_contact:
            return situation
        seen = situation.t if self.fused_at is None else self.fused_at
        return None if seen < self.contact_at else situation

    def _track_possession(self, now: float, status: int, situation: Situation | None) -> None:
        """The referee's possession clock as the robot can keep it: it runs while the puck is on the own half
        (own-frame x < 0), also while no estimate comes (the referee's clock does not stop), and restarts
        when the puck crosses the centre line or play (re)starts."""
        if status != RUNNING or (situation is not None and situation.puck[0] >= 0.0):
            self.own_half_since = None
        elif situation is not None and self.own_half_since is None:
            self.own_half_since = now

    def _committed(self, now: float, situation: Situation | None) -> bool:
        """An accepted hit (or cut) is running, or its shift with the puck awaits the planner's answer, and the
        prediction still agrees with it."""
        sent = self.sent
        if sent is None or not (sent.accepted or sent.corrects is not None) or sent.proposal.tactic in (READY, HOME):
            return False
        p = sent.proposal
        if now > p.time + self.s.settle_time:
            return False
        if now > p.time or p.puck is None or situation is None:
            return True
        moved = float(np.hypot(*self._puck_moved(p, situation)))
        if not p.is_hit:
            return moved <= self.s.resend_distance
        if moved <= self.s.hit_replan_distance:
            return True
        return moved <= self.s.contact_distance and self._past_replanning(now, p)

    def _past_replanning(self, now: float, p: Proposal) -> bool:
        """Hit ``p``, timed by the puck (a Cut's or Repel's, not ``flexible_time``), is within ``min_plan_time``
        [s] of its time, where neither plans it anew (a Cut plans its contacts that far ahead at least, Repel
        ``repel_time``'s 0.4 s), and can still be moved with the puck (``hit_correction_*``; no shift of it
        refused). A lab Cut whose puck moved there more than ``hit_replan_distance`` met it up to centimetres off
        (a forced Cut, with nothing else to play, ran the old command on). A self-timed Smash or Prepare is
        planned again from now instead, aimed anew."""
        return not p.flexible_time and p.time - now < self.s.min_plan_time and self._correctable(now, p)

    def _correctable(self, now: float, p: Proposal) -> bool:
        """Command ``p`` may be moved with the puck now: a hit, with ``hit_correction_distance`` on, at least
        ``hit_correction_time`` [s] before its time, and no shift of it refused."""
        st = self.s
        return (st.hit_correction_distance > 0.0 and p.is_hit and p is not self.uncorrectable
                and p.time - now >= st.hit_correction_time)

    def _puck_moved(self, p: Proposal, situation: Situation) -> np.ndarray:
        """How far [m] (own frame x, y) the puck predicted now at command ``p``'s time lies from where ``p``
        expects it (a hit: where a puck at rest lies, :meth:`Situation.expected`)."""
        st = self.s
        if p.is_hit:
            return situation.expected(p.time, st.drift_speed, st.drift_significance)[:2] - p.puck
        return situation.at(p.time)[:2] - p.puck

    def _corrected(self, now: float, situation: Situation | None) -> Proposal | None:
        """The accepted hit under way moved with the puck, to send now: when the puck predicted at the hit time
        lies ``hit_correction_distance`` [m] or more from where the command expects it (and, by
        :meth:`_committed`, within ``hit_replan_distance``, or within a contact distance once it is too late to
        plan the hit anew: :meth:`_past_replanning`), the same command (time, velocity) shifted by that
        displacement, while ``hit_correction_time`` [s] or more is left before the hit; else None. A contact
        point off by d turns the contact normal by about d / contact distance (1 mm: 0.7 deg). A lab-table
        Cut's last plan was made a median 0.65 s before its contact, and the puck arrived a median 4.2 mm
        (p90 16 mm) from where it had been predicted (README "Strategy test")."""
        st, sent = self.s, self.sent
        p = sent.proposal
        if not sent.accepted or p.puck is None or situation is None or not self._correctable(now, p):
            return None
        shift = self._puck_moved(p, situation)
        if float(np.hypot(*shift)) < st.hit_correction_distance:
            return None
        moved = replace(p, point=p.point + shift, puck=p.puck + shift)
        self.sent = _Sent(moved, now, corrects=p)
        return moved

    def _still_valid(self, now: float, situation: Situation | None) -> Proposal | None:
        """The command the arm is running, kept when nothing new could be planned (the caller checks that its
        tactic was just tried: it still applies but had nothing to play): a hit or cut not yet at its time, whose
        puck the prediction still brings within ``contact_distance`` of where it was planned to be met (the
        mallet still meets it) before the command's follow-through ends. Falling back to Ready replaced
        it: a Cut re-planned as the prediction moved and refused as too late sent the arm away from the
        puck's path, and the next decision often asked for the Cut again. With ``keep_checks_outcome``, not
        while the contact the mallet then makes (:func:`first_meeting`) sends the puck into the own goal: a
        kept Cut meeting a fast puck a few centimetres off its plan turned it in (7 of 69 goals in self-play)."""
        p, st = self.executing, self.s
        if p is None or p.puck is None or situation is None or now >= p.time:
            return None
        end = p.time + st.settle_time
        path = situation.samples_until(end)[1][:, :2]
        if path_gap(path, p.puck) > st.contact_distance:
            return None
        meeting = first_meeting(p, situation, st.contact_distance, end) if st.keep_checks_outcome else None
        if meeting is not None and self.shots.turns_in(*meeting, p.velocity):
            return None
        return p

    def _to_send(self, proposal: Proposal, now: float) -> Proposal | None:
        """The proposal if it should be sent now; None when the last command already says the same
        (or is still waiting for its answer)."""
        sent = self.sent
        if sent is not None and sent.proposal.tactic == proposal.tactic:
            if sent.accepted is None and now - sent.stamp < self.s.retry_delay:
                return None
            if sent.accepted is not False and self._similar(sent.proposal, proposal):
                return None
        self.sent = _Sent(proposal, now)
        return proposal

    def _similar(self, a: Proposal, b: Proposal) -> bool:
        """``b`` says what ``a`` said: a hit's point within hit_replan_distance (the accuracy a shot needs),
        a reach's within resend_distance; velocities within resend_speed; times within resend_time unless
        the tactic chose its time."""
        st = self.s
        distance = st.hit_replan_distance if b.is_hit else st.resend_distance
        return (float(np.linalg.norm(a.point - b.point)) <= distance
                and float(np.linalg.norm(a.velocity - b.velocity)) <= st.resend_speed
                and (b.flexible_time or abs(a.time - b.time) <= st.resend_time))

    def _decide(self, tactic: int, reason: str, command: Proposal | None) -> Decision:
        changed = tactic != self.current
        if changed:
            self.lead_extra, self.speed_cap = 0.0, math.inf
        self.current, self.reason = tactic, reason
        return Decision(tactic, reason, self.forced is not None, command, changed)
