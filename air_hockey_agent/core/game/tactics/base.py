"""The common contract of the tactics (ROS-free): a tactic looks at the :class:`Situation` and either
proposes one mallet command or says it does not apply now.

Tactic ids are ``air_hockey_msgs/HitCommand.TACTIC_*``. A :class:`Proposal` is a command of the motion
layer (hit: point, velocity and time; reach-and-stop: zero velocity) in the robot's own frame, with the
puck position it was planned for, so the selector can tell when the prediction has moved away from it.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from air_hockey_agent.core.game.arm_reach import ArmReach
from air_hockey_agent.core.game.shots import ShotPredictor
from air_hockey_agent.core.game.situation import Situation
from air_hockey_agent.core.game.tactics.settings import TacticsSettings

INIT, HOME, READY, SMASH, CUT, PREPARE, REPEL = range(7)  # air_hockey_msgs/HitCommand.TACTIC_*
NAMES = {INIT: "init", HOME: "home", READY: "ready", SMASH: "smash", CUT: "cut", PREPARE: "prepare", REPEL: "repel"}
TACTIC_IDS = {name: tactic for tactic, name in NAMES.items()}


@dataclass(frozen=True)
class Proposal:
    """One command for the trajectory generator (own frame)."""

    tactic: int
    point: np.ndarray                 # [m] mallet centre at ``time``
    velocity: np.ndarray              # [m/s] mallet velocity there (zeros: reach and stop)
    time: float                       # [s] absolute
    reason: str
    puck: np.ndarray | None = None    # [m] predicted puck position at ``time`` the command was planned for
    target: np.ndarray = field(default_factory=lambda: np.zeros(2))  # [m] where the puck should go
    flexible_time: bool = False       # the tactic chose the time itself (it may slide while nothing else changes)
    later_ok: bool = False            # after "too late" the tactic can pick a later moment (Context.lead_extra)
    slack: float = 0.0                # [s] how much later ``time`` lies than the earliest moment the tactic
                                      #     allowed (its lead plus Context.lead_extra); "too late" adds it

    @property
    def is_hit(self) -> bool:
        return bool(np.any(self.velocity != 0.0))


@dataclass
class Context:
    """What a tactic may use besides the situation."""

    now: float
    settings: TacticsSettings
    reach: ArmReach
    shots: ShotPredictor
    mallet: np.ndarray | None = None  # [m] current mallet position (own frame), if known
    mallet_velocity: np.ndarray | None = None  # [m/s] and its velocity (own frame), if known
    lead_extra: float = 0.0           # [s] added to flexible hit times (and to a Cut's earliest contact) after
                                      #     the planner said "too late"
    speed_cap: float = float("inf")   # [m/s] after the planner said "faster than the arm allows"
    variant: str = ""                 # a forced Smash variant (strategy test); empty: the tactic chooses
    running: Proposal | None = None   # the accepted command the arm is executing (None: none, or not known yet)
    possession: float = 0.0           # [s] how long the puck has been on the own half (0: it is not)


class Tactic:
    """Base class: ``tactic`` id, ``name``, and :meth:`propose`."""

    tactic: int = INIT

    @property
    def name(self) -> str:
        return NAMES[self.tactic]

    def propose(self, situation: Situation | None, ctx: Context) -> Proposal | None:  # pragma: no cover
        raise NotImplementedError


def path_gap(path: np.ndarray, point: np.ndarray) -> float:
    """Smallest distance [m] from ``point`` (2,) to the polyline through ``path`` (n, 2) positions."""
    if len(path) == 1:
        return float(np.linalg.norm(path[0] - point))
    a, ab = path[:-1], np.diff(path, axis=0)
    length2 = np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-18)
    s = np.clip(np.einsum("ij,ij->i", point - a, ab) / length2, 0.0, 1.0)
    return float(np.min(np.hypot(*(a + s[:, None] * ab - point).T)))


def first_within(rel: np.ndarray, distance: float) -> tuple[int, float, np.ndarray] | None:
    """Where the relative positions ``rel`` (n, 2) [m] of a puck to a mallet, sampled in time and taken as
    linear between samples, first come within ``distance`` [m]: (k, s, the relative position there) for the
    point a fraction ``s`` of the way from sample k - 1 to sample k ((0, 0, rel[0]) when the first sample is
    within already); None when never."""
    inside = np.flatnonzero(np.hypot(*rel.T) <= distance)
    if not len(inside):
        return None
    k = int(inside[0])
    if k == 0:
        return 0, 0.0, rel[0]
    # the circle's first crossing on the segment before sample k: |a + s b| = distance
    a, b = rel[k - 1], rel[k] - rel[k - 1]
    bb, ab = float(b @ b), float(a @ b)
    s = (-ab - np.sqrt(max(ab * ab - bb * (float(a @ a) - distance ** 2), 0.0))) / bb
    s = min(max(s, 0.0), 1.0)
    return k, s, a + s * b


def between(values: np.ndarray, k: int, s: float) -> np.ndarray:
    """``values`` (sampled rows) a fraction ``s`` of the way from row k - 1 to row k (row 0 for k = 0)."""
    return values[0] if k == 0 else (1.0 - s) * values[k - 1] + s * values[k]


def unit(v: np.ndarray) -> np.ndarray:
    return v / max(float(np.hypot(*v)), 1e-12)


def first_meeting(p: Proposal, situation: Situation, contact_distance: float,
                  until: float) -> tuple[np.ndarray, np.ndarray] | None:
    """Where the puck, on ``situation``'s prediction up to ``until`` [s], first comes within
    ``contact_distance`` [m] of the mallet of command ``p`` (own frame), taken as moving through
    ``p.point`` at ``p.velocity`` (at rest there for a parked cut): the puck state (6) then and the unit
    contact normal (mallet to puck); None when it does not within the prediction."""
    times, states = situation.samples_until(until)
    rel = states[:, :2] - (p.point + np.outer(times - p.time, p.velocity))
    found = first_within(rel, contact_distance)
    if found is None:
        return None
    k, s, r = found
    return between(states, k, s), unit(r)


def approach_clear(puck: np.ndarray, hit_point: np.ndarray, velocity: np.ndarray, ctx: Context) -> bool:
    """The mallet's straight way from where it is to the strike's start (behind ``hit_point`` along the
    hit ``velocity`` [m/s]) keeps ``approach_clearance`` beyond contact off the puck at ``puck`` [m] (else it would
    knock the puck away, or into the own goal, before the strike: seen in the first strategy tests)."""
    if ctx.mallet is None:
        return True
    speed = float(np.linalg.norm(velocity))
    way = np.array([ctx.mallet, ctx.reach.run_up_start(hit_point, velocity / speed, speed)], float)
    return path_gap(way, puck[:2]) >= ctx.settings.clear_distance


def strike_way_clear(situation: Situation, hit_point: np.ndarray, velocity: np.ndarray, t_hit: float,
                     ctx: Context) -> bool:
    """The mallet's way to the strike of a hit at ``hit_point`` [m] with ``velocity`` [m/s] at ``t_hit`` [s]
    keeps a clear distance (a contact distance plus ``approach_clearance``) off the puck as predicted from now
    until the strike begins: the planner's staged approach, its shortest reach from where the mallet is to the
    run-up's start (:meth:`ArmReach.reach_way`), where it waits for the strike (a run-up from rest, taking
    twice its length over the hit speed). :func:`approach_clear` judges the straight way against the puck at
    the hit time only: a puck leaving from behind the mallet crossed its way and was hit early, into the own
    goal."""
    if ctx.mallet is None:
        return True
    speed = float(np.linalg.norm(velocity))
    start = ctx.reach.run_up_start(hit_point, velocity / speed, speed)
    times, states = situation.samples_from(ctx.now, t_hit - 2.0 * float(np.linalg.norm(hit_point - start)) / speed)
    way, _ = ctx.reach.reach_way(ctx.mallet, ctx.mallet_velocity, start, times - ctx.now)
    return first_within(states[:, :2] - way, ctx.settings.clear_distance) is None


def self_timed_hit_time(tactic: int, ctx: Context) -> float:
    """When a hit whose time the tactic chooses itself (Smash, Prepare) is played [s]: a hit of ``tactic``
    already under way keeps its time while at least ``min_plan_time`` is left (re-aimed at a slow puck whose
    estimate drifted, it would otherwise be pushed ``smash_lead_time`` ahead at every re-plan and never
    arrive: in a game a puck drifting at 0.1-0.2 m/s was re-planned 17 times over 7 s before it was hit);
    else ``smash_lead_time`` (plus any "too late" extra) from now."""
    st, running = ctx.settings, ctx.running
    if running is not None and running.tactic == tactic and running.time - ctx.now >= st.min_plan_time:
        return running.time
    return ctx.now + st.smash_lead_time + ctx.lead_extra


def reach_proposal(tactic: int, point: np.ndarray, ctx: Context, reason: str) -> Proposal:
    """Reach ``point`` and stop, with the time the arm needs (plus any "too late" extra)."""
    p = ctx.reach.clamp(point)
    t = ctx.now + ctx.reach.reach_time(ctx.mallet, p, ctx.mallet_velocity) + ctx.lead_extra
    return Proposal(tactic, p, np.zeros(2), t, reason, flexible_time=True)
