"""Ready (S: READY): nothing to hit or defend; the mallet waits at the ready point in front of the goal.

Beyond the thesis and S, a puck closer to the own goal line than ``ready_guard_depth`` is not left behind
the waiting mallet: slower than ``ready_guard_speed``, the mallet waits between it and the goal
(:func:`guard_point`); else, or when it is too deep for that, at the ready point moved away from the goal
until the puck's predicted path passes clear of it (:func:`clear_of`). In in-process self-play (seeds
31-46, 60 s) 4 of 8 goals had been such pucks, met from behind by the waiting mallet or crept into the
goal mouth past it (README "Tactics and the game").

With ``ready_blocks``, a puck going into the own goal by itself, which no other tactic takes, is met on
its path where the contact keeps it out (:func:`block_point`; the points tried lie on fixed lines across
the path, ``ready_block_step``, so that the chosen one does not slide with the prediction's samples), and
with ``ready_block_in_way``, when none is found in time, awaited in its way (:func:`in_the_way`); with
``ready_block_keep``, the block the arm is running is kept while it still holds (``kept`` of
:func:`block_point`); ``ready_block_choice`` says which passing position is tried first
(:func:`by_margin`). With ``ready_checks_way`` the waiting point is judged by its outcome: when the
mallet's way to it meets the predicted puck so that the contact sends the puck into the own goal, the
mallet waits at the nearest other point whose way does not (:func:`off_the_way`). With
``ready_switch_time`` a new waiting point is taken only once it has stayed that long, while the point the arm
is reaching is :func:`harmless` (a choice that flickered from one decision to the next re-planned the arm
every 10-20 ms, and it barely moved).
"""
from __future__ import annotations

import itertools

import numpy as np

from air_hockey_agent.core.game.tactics.base import (READY, Context, Proposal, Tactic, between, first_within,
                                                     reach_proposal, unit)


def guard_point(puck: np.ndarray, gap: float, ctx: Context) -> np.ndarray | None:
    """Where the mallet waits for a puck at ``puck`` (x, y [m], own frame) behind the ready line: on the line
    from the own goal's centre to the puck, ``gap`` [m] short of the puck. None when this point lies outside
    the arm's region (behind its back edge, 0.07 m deep, for a puck that deep): a mallet nearer the goal line
    than the puck can only push it goal-ward, and one pulled into the region beside such a puck sat in its
    way along the end rim and turned it into the goal (:class:`Ready` then keeps the mallet clear of it)."""
    puck = np.asarray(puck[:2], float)
    rel = puck - np.array([ctx.settings.x_at_depth(0.0), 0.0])
    distance = float(np.hypot(*rel))
    if distance <= 0.0:
        return None
    point = puck - gap * rel / distance
    return point if ctx.reach.region.contains(point) else None


def clear_of(point: np.ndarray, path: np.ndarray, gap: float, x_max: float) -> np.ndarray:
    """``point`` [m], moved away from the own goal (+x, at most to ``x_max``) until every position of the
    puck's predicted ``path`` (n, 2) [m] nearer the goal than it lies ``gap`` [m] or more from it: a mallet
    waiting in front of a puck nearer the goal can only push it in."""
    x = float(point[0])
    for _ in range(len(path)):
        dy = path[:, 1] - point[1]
        near = (path[:, 0] < x) & (np.abs(dy) < gap)
        need = float(np.max(path[near, 0] + np.sqrt(gap ** 2 - dy[near] ** 2), initial=-np.inf))
        if need <= x + 1e-9:
            break
        x = need
    return np.array([min(x, x_max), point[1]])


def way_meeting(target: np.ndarray, samples: tuple[np.ndarray, np.ndarray], ctx: Context,
                distances: tuple[float, ...]) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Where the mallet, reaching ``target`` [m] from where it is now (:meth:`ArmReach.reach_way`), first
    meets the puck predicted at ``samples`` (times [s] from now on, :meth:`Situation.samples_from`; states
    (n, 6)), meeting taken as coming within the first of ``distances`` [m] the puck comes within at all:
    the puck state, the unit normal (mallet to puck) and the mallet's velocity [m/s] then; None when it
    comes within none. (A contact distance first: judged where it comes within a larger one, a puck that
    does touch would get a normal it does not have; a larger one then counts near misses.)"""
    times, states = samples
    way, way_velocity = ctx.reach.reach_way(ctx.mallet, ctx.mallet_velocity, target, times - ctx.now)
    rel = states[:, :2] - way
    for distance in distances:
        found = first_within(rel, distance)
        if found is not None:
            k, s, r = found
            return between(states, k, s), unit(r), between(way_velocity, k, s)
    return None


def meeting_distances(st) -> tuple[float, float]:
    """The distances [m] :func:`way_meeting` tries: a contact, then a near miss within ``approach_clearance``."""
    return st.contact_distance, st.clear_distance


def enters_goal_alone(situation, ctx: Context) -> bool:
    """The puck's prediction crosses the own goal line inside the goal mouth."""
    crossing = situation.crossing(-ctx.shots.line)
    return crossing is not None and abs(crossing.y) < ctx.shots.mouth


def dodge_points(target: np.ndarray, ctx: Context) -> list[np.ndarray]:
    """Other waiting points than ``target`` [m], nearest first: the mallet held where it is and a grid
    around ``target`` in steps of a contact distance plus ``approach_clearance`` (a mallet that far off a
    puck's path is clear of it), ``ready_dodge_steps`` of them in y either way and away from the goal, one
    toward it, within the arm's region."""
    st = ctx.settings
    step, n = st.clear_distance, st.ready_dodge_steps
    points = [ctx.reach.clamp(target + step * np.array([i, j], float))
              for i in range(-1, n + 1) for j in range(-n, n + 1) if i or j]
    points.append(ctx.reach.clamp(ctx.mallet))
    points.sort(key=lambda q: float(np.hypot(*(q - target))))
    return points


def off_the_way(target: np.ndarray, situation, ctx: Context) -> np.ndarray | None:
    """A waiting point to use instead of ``target`` [m] when the mallet's way to it meets the puck so that
    the contact turns it into the own goal (a near miss, within ``approach_clearance``, counts): the
    nearest of :func:`dodge_points` whose way meets the puck without that, or misses it while the puck does
    not go in by itself; None when ``target`` is fine or no such point is found."""
    distances, samples = meeting_distances(ctx.settings), situation.samples_from(ctx.now, np.inf)
    meeting = way_meeting(target, samples, ctx, distances)
    if meeting is None or not ctx.shots.turns_in(*meeting):
        return None
    alone = None
    for point in dodge_points(target, ctx):
        meeting = way_meeting(point, samples, ctx, distances)
        if meeting is not None:
            if not ctx.shots.turns_in(*meeting):
                return point
            continue
        if alone is None:
            alone = enters_goal_alone(situation, ctx)
        if not alone:
            return point
    return None


def heading_in(situation, ctx: Context) -> bool:
    """The puck goes into the own goal by itself: its prediction crosses the own goal line inside the goal
    mouth, or, still moving toward the goal at the prediction's end (a slow puck takes longer than the
    horizon), its last sample carried on in a straight line would (:meth:`Situation.expected`'s
    extrapolation; the damping would only slow it)."""
    if enters_goal_alone(situation, ctx):
        return True
    last = situation.states[-1] if len(situation.states) else situation.puck
    line = -ctx.shots.line
    if last[2] >= 0.0 or last[0] <= line:
        return False
    return abs(last[1] + last[3] * (line - last[0]) / last[2]) < ctx.shots.mouth


def path_points(situation, ctx: Context) -> list[tuple[float, np.ndarray]]:
    """Times [s] and positions [m] of the puck's predicted path from now on, in the order the puck passes them:
    with ``ready_block_step`` > 0 where it crosses lines x = const that many metres apart, from the arm's
    region's far edge toward the goal (they move only as the prediction does); with 0 the prediction's own
    samples, which slide along the path from one decision to the next (a fast puck's first sample inside the
    region moved by 2-3 cm every 10 ms, more than ``resend_distance``: the block was sent again at every
    decision, each re-plan starting the arm's motion anew, and a mallet asked to move 13 cm in 0.3 s moved
    1 cm)."""
    step = ctx.settings.ready_block_step
    if step <= 0.0:
        times, states = situation.samples_from(ctx.now, np.inf)
        return [(float(t), state[:2]) for t, state in zip(times, states)]
    region = ctx.reach.region
    lines = np.arange(region.x_max, region.x_min - 1e-9, -step)
    crossings = ((x, situation.crossing(float(x))) for x in lines)
    return [(c.time, np.array([x, c.y])) for x, c in crossings if c is not None]


def time_to_spare(time: float, point: np.ndarray, ctx: Context) -> float:
    """How long [s] before the puck, there at ``time`` [s], the mallet would be at ``point`` [m]: the time left
    until then minus :meth:`ArmReach.reach_time` from where the mallet is (negative: after the puck)."""
    return time - ctx.now - ctx.reach.reach_time(ctx.mallet, point, ctx.mallet_velocity)


def by_margin(points: list[tuple[float, np.ndarray]], ctx: Context) -> list[tuple[float, np.ndarray]]:
    """``points`` (time [s], position [m]) ordered by :func:`time_to_spare`, the longest first."""
    return sorted(points, key=lambda point: time_to_spare(point[0], point[1], ctx), reverse=True)


def keeps_out(point: np.ndarray, samples: tuple[np.ndarray, np.ndarray], ctx: Context) -> bool:
    """A mallet waiting at ``point`` [m] (own frame) keeps out the puck predicted at ``samples`` (times [s],
    states (n, 6)): ``point`` lies in the arm's region, and the mallet's way to it (:func:`way_meeting`) meets
    the puck without turning it in (:meth:`ShotPredictor.turns_in`; met head-on on its path, it goes back out)."""
    if not ctx.reach.region.contains(point):
        return False
    meeting = way_meeting(point, samples, ctx, meeting_distances(ctx.settings))
    return meeting is not None and not ctx.shots.turns_in(*meeting)


def block_point(situation, ctx: Context, kept: np.ndarray | None = None) -> np.ndarray | None:
    """Where the mallet waits to keep out a puck that goes into the own goal by itself (:func:`heading_in`):
    ``kept`` [m] (a block under way) if given and it still keeps the puck out, else a position of the puck's
    path (:func:`path_points`, own frame [m]) that does (:func:`keeps_out`): with ``ready_block_choice``
    'first' the first the puck passes, with 'margin' the one the mallet reaches longest before the puck
    (:func:`by_margin`); None when the puck does not go in or no such position is found."""
    if not heading_in(situation, ctx):
        return None
    samples = situation.samples_from(ctx.now, np.inf)
    points = path_points(situation, ctx)
    if ctx.settings.ready_block_choice == "margin":
        points = by_margin(points, ctx)
    candidates = itertools.chain(() if kept is None else (kept,), (point for _, point in points))
    return next((point for point in candidates if keeps_out(point, samples, ctx)), None)


def in_the_way(situation, ctx: Context) -> np.ndarray | None:
    """Where the puck's predicted path crosses the ready point's line x = const [m] on its way into the own
    goal (:func:`enters_goal_alone`), inside the arm's region; None otherwise. Ready's answer, with
    ``ready_block_in_way``, when :func:`block_point` finds no block. The mallet waiting there
    rather than at the ready point may still meet a puck it cannot reach in time by the planner's reach
    (a 4.5 m/s bank shot crossed the line 12 cm beside the waiting mallet, reachable in about 0.2 s)."""
    if not enters_goal_alone(situation, ctx):
        return None
    x = ctx.settings.point(ctx.settings.ready_point)[0]
    crossing = situation.crossing(x)
    if crossing is None:
        return None
    point = np.array([x, crossing.y])
    return point if ctx.reach.region.contains(point) else None


def harmless(point: np.ndarray, situation, ctx: Context) -> bool:
    """The mallet's way to ``point`` [m] (own frame; :func:`way_meeting`) meets the puck without turning it into
    the own goal, or misses a puck that does not go in by itself (:func:`heading_in`)."""
    meeting = way_meeting(point, situation.samples_from(ctx.now, np.inf), ctx, meeting_distances(ctx.settings))
    if meeting is not None:
        return not ctx.shots.turns_in(*meeting)
    return not heading_in(situation, ctx)


def unseen(situation, ctx: Context) -> bool:
    """With ``ready_unseen_time`` > 0: no estimate (none, or one older than ``stale_estimate``), or one on the
    opponent's half whose last frame lies more than ``ready_unseen_time`` [s] back (a mocap dropout, up to
    0.9 s in the lab's recordings: the opponent's shot was not seen until the puck was 0.3 s from the goal;
    a puck last seen on the own half is left to the other rules: the mallet going deep could meet it on
    the way). A mallet waiting deeper covers more of the goal mouth against a shot it has not seen: a shot
    at 33 degrees crosses the ready point's line (0.16 m out) 0.10 m to the side of where it enters the
    goal, a line 0.08 m out 0.05 m to the side, and a centred mallet meets a puck whose centre passes
    within a contact distance (0.08 m) of its own."""
    wait = ctx.settings.ready_unseen_time
    return wait > 0.0 and (situation is None or (situation.puck[0] >= 0.0 and ctx.now - situation.t > wait))


class Ready(Tactic):
    tactic = READY

    def __init__(self) -> None:
        self._block: np.ndarray | None = None  # [m] the block point last proposed (own frame)
        self._new: tuple[float, np.ndarray] | None = None  # (since [s], point [m]) a new point not yet taken

    def propose(self, situation, ctx: Context) -> Proposal | None:
        proposal, block = self._choose(situation, ctx)
        kept = self._steadied(proposal, situation, ctx)
        if kept is not None:
            return kept  # the kept point stays the block it was (or none)
        self._block = block
        return proposal

    def _steadied(self, proposal: Proposal, situation, ctx: Context) -> Proposal | None:
        """With ``ready_switch_time``, the point the arm is reaching, kept instead of ``proposal`` that moves it
        by more than ``resend_distance``: while the new point has stayed (within ``resend_distance``) less than
        ``ready_switch_time`` [s] and the kept one is :func:`harmless`; None: ``proposal`` is taken."""
        st, running = ctx.settings, ctx.running
        if (st.ready_switch_time <= 0.0 or running is None or running.tactic != READY or situation is None
                or ctx.mallet is None or float(np.hypot(*(proposal.point - running.point))) <= st.resend_distance):
            self._new = None
            return None
        if self._new is None or float(np.hypot(*(self._new[1] - proposal.point))) > st.resend_distance:
            self._new = (ctx.now, proposal.point)
        if ctx.now - self._new[0] >= st.ready_switch_time or not harmless(running.point, situation, ctx):
            self._new = None
            return None
        x, y = running.point
        return reach_proposal(READY, running.point, ctx, f"keeping to ({x:.2f}, {y:.2f}): {proposal.reason}, "
                                                         f"not yet steady")

    def _choose(self, situation, ctx: Context) -> tuple[Proposal, np.ndarray | None]:
        """Ready's waiting point now, and the block it is (None: not a block)."""
        known = situation is not None and ctx.mallet is not None
        block = self._block_point(situation, ctx) if known and ctx.settings.ready_blocks else None
        if block is not None:
            return reach_proposal(READY, block, ctx, f"blocking the puck's way into the goal at "
                                                     f"({block[0]:.2f}, {block[1]:.2f})"), block
        st = ctx.settings
        way = in_the_way(situation, ctx) if known and st.ready_blocks and st.ready_block_in_way else None
        if way is not None:
            return reach_proposal(READY, way, ctx, f"in the way of the puck going into the goal, at "
                                                   f"({way[0]:.2f}, {way[1]:.2f}) (no block in time)"), None
        point, reason = self._waiting_point(situation, ctx)
        if st.ready_checks_way and known:
            dodge = off_the_way(ctx.reach.clamp(point), situation, ctx)
            if dodge is not None:
                point, reason = dodge, reason + "; off the way that would turn the puck into the own goal"
        return reach_proposal(READY, point, ctx, reason), None

    def _block_point(self, situation, ctx: Context) -> np.ndarray | None:
        """:func:`block_point`; with ``ready_block_keep``, the block the arm is running first, kept while it
        still keeps the puck out, rather than a new one. Chosen anew at every decision, the first position that
        passed jumped along a fast puck's path (from 0.2 to 0.6 m from the goal and back, and to the ready
        point when none passed for one decision): each re-plan started the arm's motion anew, the mallet
        moved 5 cm in 0.25 s and met the puck from the side, turning it into the goal (lab-table self-play,
        seed 159)."""
        st, kept, running = ctx.settings, self._block, ctx.running
        under_way = (kept is not None and running is not None and running.tactic == READY
                     and float(np.hypot(*(running.point - kept))) <= st.resend_distance)
        if not (st.ready_block_keep and under_way):
            kept = None
        return block_point(situation, ctx, kept)

    @staticmethod
    def _waiting_point(situation, ctx: Context) -> tuple[np.ndarray, str]:
        st = ctx.settings
        if unseen(situation, ctx):
            return st.point(st.ready_unseen_point), "the puck unseen: waiting deep in front of the goal"
        ready = st.point(st.ready_point)
        if situation is None or situation.puck[0] + st.table.length / 2 >= st.ready_guard_depth:
            return ready, "waiting at the ready point"
        puck, gap = situation.puck[:2], st.clear_distance
        guard = guard_point(puck, gap, ctx) if situation.speed <= st.ready_guard_speed else None
        if guard is not None:
            return guard, f"guarding the goal from the puck at ({puck[0]:.2f}, {puck[1]:.2f})"
        path = situation.samples_until(np.inf)[1][:, :2]
        clear = clear_of(ready, path, gap, ctx.reach.region.x_max)
        return clear, ("waiting at the ready point" if clear[0] == ready[0] else
                       f"waiting in front of the puck at ({puck[0]:.2f}, {puck[1]:.2f}), clear of it")
