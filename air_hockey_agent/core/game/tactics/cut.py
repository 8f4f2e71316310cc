"""Cut (thesis sec. 4.6; S: CUT): a puck approaching the own goal is met on its way and slowed so that it
stops inside the smash area (and can then be smashed).

S parked the mallet on the puck's path at the defend line, turned to deflect it toward the near long rim
(REFERENCE_FACTS 2.2). A parked mallet returns e = 0.8 of the puck's normal speed, and with the table's
damping (d = 0.5 1/s) a puck leaving at 1 m/s slides 2 m: in the first strategy tests 16 of 20 cut pucks
came to rest outside the smash area. Here the mallet may also give way: moving along -n at
``k e u / (1 + e)`` (u: the puck's closing speed along the contact normal n) leaves the puck
``(1 - k) e u`` of normal speed (k = 1 stops the normal motion: a catch). Every contact of
``cut_contact_steps`` times on the predicted path (from ``min_plan_time`` ahead to the defend line),
``cut_normal_steps`` normals within ``cut_normal_range`` of head-on and the ``cut_catch`` fractions k is
predicted with the puck model (:meth:`ShotPredictor.contact`: the contact as Routh's impact with the
mallet's friction, which takes tangential speed into spin); the one that stops deepest inside the
smash area, also with the normal off by the aim noise, is played. A contact that sends the puck into
the own goal or back into the mallet is never played, and one that would send it in were the puck to
meet the mallet ``cut_offset_noise`` off sideways (the prediction's and the arm's error at the contact;
:func:`offset_turns`) ranks below every contact without that risk: glancing contacts that were meant to
turn a fast puck just past the goal post met it a centimetre off in games and turned it in.
When the planner answers "too late" (the arm cannot be there by then), the next proposal meets the puck
at least ``lead_time_step`` later on its path than the refused one (``Context.lead_extra`` grows by the
step and by how much later than the earliest allowed contact the refused one lay: ``Proposal.slack``),
so the best contact the arm can still make is played. Before, the Cut was blocked for ``retry_delay``
and then asked for the same contact again, nearer in time: in ten games a third of its commands (95 of
301) were refused as too late; and while the lead grew from the earliest allowed contact alone, a
refused contact that lay later than that was asked again until the lead passed it.
"""
from __future__ import annotations

import math

import numpy as np

from air_hockey_agent.core.game.shots import Push
from air_hockey_agent.core.game.situation import Situation
from air_hockey_agent.core.game.tactics.base import CUT, Context, Proposal, Tactic
from air_hockey_agent.core.game.tactics.outcome import LazyRanked, Ranked, lazy_candidate, margin_steps
from air_hockey_agent.core.game.tactics.settings import TacticsSettings

CACHE_SIZE = 16
KEY_TIME = 0.02       # [s] predicted defend-line crossings closer than this in time ...
KEY_POSITION = 0.005  # [m] ... and in y share the ranked contacts


def _rotate(v: np.ndarray, angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([c * v[0] - s * v[1], s * v[0] + c * v[1]])


def offset_turns(relative: np.ndarray, n: np.ndarray, st: TacticsSettings) -> tuple[float, float]:
    """How far [rad] a contact normal ``n`` (unit, mallet to puck) turns either way when the puck, moving at
    ``relative`` [m/s] relative to the mallet, meets it ``cut_offset_noise`` [m] off to either side across
    its way, plus the aim noise: at angle a from head-on the normal turns to asin(sin a +- offset /
    contact distance), a head-on contact hardly, a glancing one by tens of degrees; past 90 deg the puck
    passes the mallet (the contact at 90 deg gives it no impulse)."""
    head_on = -relative / float(np.hypot(*relative))
    a = math.atan2(head_on[0] * n[1] - head_on[1] * n[0], float(head_on @ n))
    shift = st.cut_offset_noise / st.contact_distance
    lower, upper = (math.asin(min(max(math.sin(a) + s, -1.0), 1.0)) - a for s in (-shift, shift))
    return lower - st.aim_noise, upper + st.aim_noise


class Cut(Tactic):
    tactic = CUT

    def __init__(self) -> None:
        self._cache: dict[tuple, Ranked] = {}

    def propose(self, situation: Situation | None, ctx: Context) -> Proposal | None:
        st = ctx.settings
        if situation is None:
            return None
        c = situation.crossing(st.defend_x)
        if c is None or c.time - ctx.now < st.min_plan_time:
            return None
        key = (round(c.time / KEY_TIME), round(c.y / KEY_POSITION))
        if key not in self._cache:
            if len(self._cache) >= CACHE_SIZE:
                self._cache.clear()
            self._cache[key] = LazyRanked(self._ranked(situation, ctx, c.time))
        lead = st.min_plan_time + ctx.lead_extra  # [s] the earliest contact the Cut may ask for, from now
        best = self._cache[key].first(
            lambda t, push, run_on: t - ctx.now >= lead,
            lambda t, push, run_on: not ctx.shots.rebounds_into_mallet(push, run_on, st.recontact_watch))
        if best is None:
            return None
        t, push, _ = best
        slack = t - ctx.now - lead
        puck = situation.at(t)
        reason = (f"cut: puck crosses the defend line at y {c.y:+.2f} m in {c.time - ctx.now:.2f} s after "
                  f"{c.impacts_before} rim impact(s); met in {t - ctx.now:.2f} s, mallet "
                  f"{push.mallet_speed:.2f} m/s, to stop at ({push.rest[0]:.2f}, {push.rest[1]:.2f})")
        if push.mallet_speed == 0.0:  # parked on the path, arriving just before the puck
            return Proposal(CUT, push.hit_point, np.zeros(2), t - st.cut_arrive_early, reason, puck=puck[:2],
                            target=push.rest, later_ok=True, slack=slack)
        return Proposal(CUT, push.hit_point, push.mallet_velocity, t, reason, puck=puck[:2], target=push.rest,
                        later_ok=True, slack=slack)

    def _ranked(self, situation: Situation, ctx: Context, crossing_time: float) -> list[tuple]:
        """The contacts the arm can make, for :class:`LazyRanked`: each item is (contact time, contact,
        mallet follow-through [m]), ranked by how deep inside the smash area the puck stops in the worst of
        the aimed normal and the normal off by the aim noise either way; among equals the earlier
        contact, then the slower mallet."""
        st = ctx.settings
        candidates = []
        first = ctx.now + st.min_plan_time
        for t in np.linspace(first, crossing_time, st.cut_contact_steps):
            puck = situation.at(float(t))
            u_in = float(np.hypot(puck[2], puck[3]))
            if u_in <= 0.0 or puck[0] >= 0.0:
                continue
            head_on = -puck[2:4] / u_in  # the normal of a head-on contact (mallet to puck)
            for turn in np.linspace(-st.cut_normal_range, st.cut_normal_range, st.cut_normal_steps):
                candidates += self._contacts(puck, _rotate(head_on, float(turn)), float(t), ctx)
        return candidates

    def _contacts(self, puck: np.ndarray, n: np.ndarray, t: float, ctx: Context) -> list[tuple]:
        """The contacts with normal ``n`` at time ``t``, one per catch fraction the arm allows, as (key bound,
        exact key and item) for :class:`LazyRanked`."""
        st = ctx.settings
        closing = -float(puck[2:4] @ n)  # [m/s] the puck's speed toward the mallet along n
        if closing <= 0.0:
            return []
        hit = puck[:2] - n * st.contact_distance
        if not ctx.reach.region.contains(hit):
            return []
        top = ctx.reach.max_speed(hit, -n) * st.hit_speed_fraction
        out = []
        for k in st.cut_catch:
            speed = k * st.mallet_restitution * closing / (1.0 + st.mallet_restitution)
            if speed > min(top, ctx.speed_cap) or (0.0 < speed < st.prepare_speed[0]):
                continue

            def contact(turn: float, speed: float = speed) -> Push:  # the mallet gives way along its aimed
                aim = math.copysign(min(abs(turn), st.aim_noise), turn)  # normal (off by the aim noise at most)
                return ctx.shots.contact(puck, _rotate(n, turn), -speed * _rotate(n, aim), st.prepare_end_speed,
                                         st.prepare_horizon)
            follow = ctx.reach.follow_through_length(hit, -n, speed) if speed > 0.0 else 0.0
            candidate = lazy_candidate(st, contact, lambda push: push.enters_goal,
                                       lambda push: margin_steps(st, push),
                                       lambda score, speed=speed: (score, -t, -speed),
                                       lambda push, follow=follow: (t, push, follow),
                                       offset_turns(puck[2:4] + speed * n, n, st))
            if candidate is not None:
                out.append(candidate)
        return out
