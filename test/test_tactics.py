"""Tactics layer (ROS-free): situations, shots, the fastest-hit table and the state machine (thesis 4.6)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from air_hockey_agent.agent_params import load_agent_params, puck_model_for_tactics
from air_hockey_agent.paths import config_file
from air_hockey_agent.tracker_params import SIM_TABLE_FILE
from air_hockey_agent.core.game.arm_reach import ArmReach
from air_hockey_agent.core.game.shots import ShotPredictor
from air_hockey_agent.core.puck.mallet_impact import puck_after_contact, puck_after_hit
from air_hockey_agent.core.game.situation import build_situation, own_frame_physics, to_own_frame
from air_hockey_agent.core.game.speed_map import SpeedMap
from air_hockey_agent.core.game.tactics.base import (CUT, HOME, INIT, PREPARE, READY, REPEL, SMASH, Proposal,
                                                     first_meeting, path_gap)
from air_hockey_agent.core.game.tactics.selector import (ACCEPTED, LIMITS, PAUSED, RUNNING, STOPPED, TOO_FAST, TOO_LATE,
                                                         TacticsSelector)
from air_hockey_agent.core.game.tactics.settings import TacticsSettings
from air_hockey_agent.core.motion.region import Region
from air_hockey_agent.core.puck.prediction import predict_fast, predict_stepwise

DT = 1.0 / 120.0
TOP_SPEED = 2.0  # [m/s] a flat fastest-hit table: the state machine's tests do not depend on the arm
BASE = (-1.504, 0.0)


@pytest.fixture(scope="module")
def settings():
    return TacticsSettings.from_params(load_agent_params())


@pytest.fixture(scope="module")
def model():
    """The simulated table's puck model, as `air-hockey game` gives the tactics (the thresholds and speed
    ranges of config/agent.yaml were chosen on it; the tracker's defaults are a real, slower-damped table's)."""
    return puck_model_for_tactics(str(config_file(SIM_TABLE_FILE)))


def flat_reach(settings) -> ArmReach:
    t = settings.table
    region = Region.for_table(t.length, t.width, settings.mallet_radius, 0.02, BASE, 1.30)
    xs, ys, angles = np.linspace(-1.0, 0.0, 5), np.linspace(-0.6, 0.6, 5), np.linspace(-math.pi, math.pi, 5)
    # run-up 0.06-0.30 m, at most 0.4 s; follow-through 0.06-0.30 m, at most 0.4 s, no braking bound (a test arm:
    # config/motion.yaml's floors are 0.04 and 0.02 m); shortest reach
    # 0.26 s: a planning delay of 0.03 s and a height transition of 0.23 s
    return ArmReach(region, 0.06, 0.30, 0.4, 0.06, 0.30, 0.4, 0.0, 5.0, 0.23, 1.25,
                    SpeedMap(xs, ys, angles, np.full((5, 5, 5), TOP_SPEED)), 0.03, DT)


@pytest.fixture
def selector(settings, model):
    reach = flat_reach(settings)
    return TacticsSelector(settings, reach, ShotPredictor(model, settings, DT, reach.max_speed))


def selector_with(model, settings, **changes) -> TacticsSelector:
    """A selector like the fixture's with ``changes`` to the settings (e.g. a switch off)."""
    from dataclasses import replace
    changed = replace(settings, **changes)
    reach = flat_reach(changed)
    return TacticsSelector(changed, reach, ShotPredictor(model, changed, DT, reach.max_speed))


def situation(model, state, t0=0.0, robot="iiwa_front", horizon=1.0):
    """What the tracker would publish for a table-frame ``state``: its own model's prediction."""
    pred = predict_fast(model, np.asarray(state, float), None, horizon, DT, np.zeros(6), sample_every=6)
    times = [t0 + t for t, _, _ in pred.samples]
    states = np.array([s for _, s, _ in pred.samples])
    return build_situation(robot, t0, state, times, states, [(t0 + t, x, y) for t, _, x, y, _ in pred.impacts])


# --- building blocks --------------------------------------------------------------------------------
def test_samples_from_start_at_the_state_then_and_keep_the_later_samples(model):
    sit = situation(model, [-0.5, 0.1, 1.0, -0.5, 0.0, 0.0], t0=2.0)
    for start in (1.5, 2.0):  # not after the estimate: the estimate and every sample
        for got, want in zip(sit.samples_from(start, np.inf), sit.samples_until(np.inf)):
            np.testing.assert_array_equal(got, want)
    start = 0.5 * (sit.times[3] + sit.times[4])  # between two samples
    times, states = sit.samples_from(start, sit.times[9])
    np.testing.assert_array_equal(times, np.concatenate([[start], sit.times[4:10]]))
    np.testing.assert_allclose(states[0], 0.5 * (sit.states[3] + sit.states[4]), atol=1e-12)
    np.testing.assert_array_equal(states[1:], sit.states[4:10])
    times, states = sit.samples_from(sit.times[-1] + 1.0, np.inf)  # beyond the horizon: the last sample
    assert times.tolist() == [sit.times[-1] + 1.0]
    np.testing.assert_array_equal(states[0], sit.states[-1])


def test_expected_carries_a_creeping_puck_on_beyond_the_horizon_and_holds_a_resting_one(model):
    start = np.array([-0.5, 0.1, 0.05, -0.02, 0.0, 0.0])
    sit = situation(model, start, horizon=0.5)
    truth = predict_stepwise(model, start, None, 0.8, DT, np.zeros(6)).state
    beyond = sit.expected(0.8, 0.01)
    assert np.linalg.norm(beyond[:2] - truth[:2]) < 1e-3  # 0.3 s past the last sample
    assert np.linalg.norm(sit.at(0.8)[:2] - truth[:2]) > 0.01  # held at the last sample
    np.testing.assert_allclose(sit.expected(0.8, 0.06)[:4], [*start[:2], 0.0, 0.0])


@pytest.mark.parametrize("part, message", [
    ("estimate", "the estimate must be 6 finite values"),
    ("sample", "not finite"), ("time", "not finite"), ("impact", "not finite"), ("stamp", "stamp nan"),
    ("order", "do not increase"), ("before", "do not increase"), ("count", "sample times for"),
])
def test_a_malformed_prediction_is_refused_before_any_tactic_sees_it(model, selector, part, message):
    """What the tactics node gets from puck/prediction (fuzzing: a NaN or inf there ended in a tactic's
    OverflowError, which stops the node): each malformed part is a ValueError naming it, which the node logs
    as "message ignored"; the well-formed prediction it was made from passes and is played."""
    state = [-0.4, 0.1, 0.0, 0.0, 0.0, 0.0]
    good = situation(model, state, t0=1.0)
    t, est, times, samples, impacts = 1.0, list(state), good.times.copy(), good.states.copy(), [(1.2, 0.5, 0.5)]
    if part == "estimate":
        est[2] = math.inf
    elif part == "sample":
        samples[3, 0] = math.nan
    elif part == "time":
        times[2] = math.nan
    elif part == "impact":
        impacts = [(1.2, math.nan, 0.5)]
    elif part == "stamp":
        t = math.nan
    elif part == "order":
        times = times[::-1].copy()
    elif part == "before":
        times = times - 1.0
    elif part == "count":
        samples = samples[:-1]
    with pytest.raises(ValueError, match=message):
        build_situation("iiwa_front", t, est, times, samples, impacts)
    sit = build_situation("iiwa_front", 1.0, state, good.times, good.states, [(1.2, 0.5, 0.5)])
    assert selector.step(1.0, RUNNING, sit, np.array([-0.9, 0.0]), None).name == "smash"


def test_lazy_ranking_orders_exactly_as_scoring_everything_and_scores_only_what_it_needs():
    """LazyRanked against a stable sort of every exact key (ties in candidate order, dropped candidates
    left out): the same items in the same order; the best item costs fewer exact scorings than there
    are candidates."""
    from air_hockey_agent.core.game.tactics.outcome import LazyRanked
    rng = np.random.default_rng(3)
    for trial in range(50):
        n = int(rng.integers(1, 40))
        exact_keys = [(int(rng.integers(-3, 4)), -float(rng.integers(0, 3))) for _ in range(n)]
        dropped = rng.random(n) < 0.2
        bounds = [(k[0] + int(rng.integers(0, 3)), k[1]) for k in exact_keys]
        calls = []

        def exact(i):
            calls.append(i)
            return None if dropped[i] else (exact_keys[i], (i,))
        lazy = LazyRanked([(bounds[i], lambda i=i: exact(i)) for i in range(n)])
        expected = sorted([i for i in range(n) if not dropped[i]], key=lambda i: exact_keys[i], reverse=True)
        assert lazy.item(0) == (None if not expected else (expected[0],))
        first_cost = len(calls)
        got, i = [], 0
        while (item := lazy.item(i)) is not None:
            got.append(item[0])
            i += 1
        assert got == expected, trial
        assert sorted(calls) == list(range(n))  # each scored once, all of them by the end
        assert first_cost <= n
    # tight bounds: the best of 30 candidates costs one scoring
    scored = []
    lazy = LazyRanked([((k,), lambda k=k: scored.append(k) or ((k,), (k,))) for k in range(30)])
    assert lazy.item(0) == (29,) and scored == [29]


def test_own_frame_of_the_back_robot_is_the_table_turned_by_pi():
    s = to_own_frame(np.array([0.5, -0.2, 1.0, 0.3, 0.1, 2.0]), "iiwa_back")
    np.testing.assert_allclose(s, [-0.5, 0.2, -1.0, -0.3, 0.1 - math.pi, 2.0])
    np.testing.assert_allclose(to_own_frame(np.array([0.5, -0.2, 1, 0.3, 0.1, 2]), "iiwa_front"), [0.5, -0.2, 1, 0.3, 0.1, 2])


def test_the_back_robot_predicts_a_tilted_table_in_its_own_frame(model):
    """own_frame_physics turns the table acceleration with the frame: the back robot's own-frame prediction
    is the table-frame prediction seen from its side (a tilt toward +y, i.e. toward its -y)."""
    tilted = model.with_params(model.params.with_values(table_acceleration=(0.05, 0.2), friction_surface=0.0))
    own = tilted.with_params(own_frame_physics(tilted.params, "iiwa_back"))
    assert own.params.table_acceleration == (-0.05, -0.2)
    assert own_frame_physics(tilted.params, "iiwa_front") is tilted.params
    state = np.array([0.3, -0.1, -0.8, 0.5, 0.2, 3.0])
    table = predict_fast(tilted, state, None, 1.0, DT, np.zeros(6)).state
    seen = predict_fast(own, to_own_frame(state, "iiwa_back"), None, 1.0, DT, np.zeros(6)).state
    np.testing.assert_allclose(seen, to_own_frame(table, "iiwa_back"), atol=1e-12)


def test_shots_use_the_physics_they_are_given(settings, model):
    """ShotPredictor.use_physics (the tactics node: the tracker's puck/physics) changes what the shots
    predict: softer rims send a bank shot elsewhere."""
    reach = flat_reach(settings)
    shots = ShotPredictor(model, settings, DT, reach.max_speed)
    puck = np.array([-0.5, 0.1, 0.0, 0.0, 0.0, 0.0])  # at rest in the own half (own-frame state)
    before = {s.variant: s for s in shots.candidates(puck)}
    shots.use_physics(model.params.with_values(restitution=0.5, restitution_min=0.5))
    assert shots.model.params.restitution == 0.5 and shots.model.table is model.table
    after = {s.variant: s for s in shots.candidates(puck)}
    banks = [v for v in ("left_bank", "right_bank") if v in before and v in after]
    assert banks and all(not np.allclose(before[v].direction, after[v].direction) for v in banks)
    assert np.allclose(before["straight"].direction, after["straight"].direction)  # no rim on its way


def test_smash_aims_again_when_the_shots_physics_change(settings, model):
    """Smash keeps its aimed shots per puck cell; new physics (the tracker learned more of the table) make
    them stale: the same resting puck is aimed with the new physics at once."""
    from air_hockey_agent.core.game.tactics.base import Context
    from air_hockey_agent.core.game.tactics.smash import Smash
    reach = flat_reach(settings)
    shots = ShotPredictor(model, settings, DT, reach.max_speed)
    sit, smash = situation(model, [-0.5, 0.1, 0.0, 0.0, 0.0, 0.0]), Smash()
    ctx = Context(0.0, settings, reach, shots, mallet=np.array([-0.8, 0.0]), variant="left_bank")
    before = smash.propose(sit, ctx)
    shots.use_physics(model.params.with_values(restitution=0.5, restitution_min=0.5))
    after = smash.propose(sit, ctx)
    fresh = shots.aim(sit.puck, "left_bank")
    assert before is not None and after is not None
    assert not np.allclose(before.velocity, after.velocity) and np.allclose(after.point, fresh.hit_point)


@pytest.mark.parametrize("variant, xy", [("straight", (-0.576, -0.417)), ("left_bank", (-0.691, -0.362))])
def test_aim_finds_a_shot_where_the_reflection_laws_angle_or_its_neighbour_misses_the_line(settings, model,
                                                                                           variant, xy):
    """Beside a rim the reflection law's angle (straight from (-0.576, -0.417): its hit point lies beyond the
    arm's region) or the secant's second point one step on (the left bank from (-0.691, -0.362)) has no
    shot that reaches the goal line; aim_search_steps finds the nearest that does and the secant centres
    it, as a fine scan over the angles does. Without the search: no shot."""
    from dataclasses import replace
    reach = flat_reach(settings)
    puck = np.array([*xy, 0.0, 0.0, 0.0, 0.0])
    searching = ShotPredictor(model, settings, DT, reach.max_speed)
    shot = searching.aim(puck, variant)
    assert shot is not None and abs(shot.goal_y) < 0.02 and shot.success > 0.2  # steep: 2 deg spreads it wide
    ylim = model.table.y_limit
    guess = math.atan2({"straight": 0.0, "left_bank": 2 * ylim}[variant] - xy[1], searching.line - xy[0])
    scanned = [r for a in guess + np.linspace(-0.16, 0.16, 161) if (r := searching._evaluate(puck, a, None))]
    assert abs(shot.goal_y) <= min(abs(r[0]) for r in scanned) + 0.001  # as centred as the scan's best
    assert ShotPredictor(model, replace(settings, aim_search_steps=0), DT, reach.max_speed).aim(puck, variant) is None


def test_line_crossing_matches_straight_flight(model):
    sit = situation(model, [0.3, 0.1, -2.0, -0.2, 0.0, 0.0])
    c = sit.crossing(-0.5)
    # closed form of the damped flight: x(t) = x0 + v0 (1 - exp(-d t)) / d (friction ~ 0)
    d = model.params.damping
    t = -math.log(1.0 - 0.8 * d / 2.0) / d
    assert c is not None and c.impacts_before == 0
    assert c.time == pytest.approx(t, abs=2e-3)
    assert c.y == pytest.approx(0.1 - 0.1 * 0.8, abs=2e-3)


def test_mallet_impact_reverses_the_relative_normal_velocity():
    n = np.array([1.0, 0.0])
    v = puck_after_hit(np.array([-1.0, 0.5]), np.array([1.0, 0.0]), n, 1.0)
    np.testing.assert_allclose(v, [3.0, 0.5])  # elastic: relative normal speed 2 -> -2, tangential kept
    np.testing.assert_allclose(puck_after_hit(np.array([1.0, 0.0]), np.zeros(2), n, 0.8), [1.0, 0.0])  # separating


def test_a_contact_with_mallet_friction_is_rouths_impact_against_a_moving_wall():
    """puck_after_contact: without friction the frictionless law with the spin kept; with friction, in the
    mallet's frame a sticking contact ends the slip of the puck's edge (Routh, beta = 0) and a sliding one
    takes mu times the normal impulse off the slip; the normal impulse is the same either way; the result
    does not depend on the frame (a mallet moving at u is a wall at rest for a puck moving at v - u)."""
    from air_hockey_agent.core.puck.mallet_impact import puck_after_contact
    r, e = 0.03165, 0.8
    n = np.array([math.cos(0.4), math.sin(0.4)])
    b = np.array([n[1], -n[0]])
    puck, u = np.array([0.1, 0.2, -1.5, 0.3, 0.7, 2.0]), np.array([0.4, -0.2])
    free = puck_after_contact(puck, u, n, e, 0.0, r)
    np.testing.assert_allclose(free[2:4], puck_after_hit(puck[2:4], u, n, e))
    assert free[5] == puck[5] and np.array_equal(free[:2], puck[:2])
    for mu in (0.05, 0.5):  # sliding, then sticking, for this contact
        after = puck_after_contact(puck, u, n, e, mu, r)
        rel0, rel1 = puck[2:4] - u, after[2:4] - u
        assert rel1 @ n == pytest.approx(-e * (rel0 @ n))  # the normal impulse is friction's bound's base
        slip0, slip1 = rel0 @ b + r * puck[5], rel1 @ b + r * after[5]
        p_n, p_b = (rel1 - rel0) @ n, (rel1 - rel0) @ b  # impulses per unit mass
        assert after[5] - puck[5] == pytest.approx(2.0 * p_b / r)  # a uniform disc: I = m r^2 / 2
        if mu == 0.05:
            assert abs(p_b) == pytest.approx(mu * p_n) and slip1 * slip0 > 0.0  # sliding: Coulomb's bound
        else:
            assert slip1 == pytest.approx(0.0, abs=1e-12) and abs(p_b) < mu * p_n  # sticking: the slip ends
        at_rest = puck_after_contact(np.concatenate([puck[:2], puck[2:4] - u, puck[4:]]), np.zeros(2), n, e, mu, r)
        np.testing.assert_allclose(at_rest[2:4] + u, after[2:4])
        assert at_rest[5] == pytest.approx(after[5])
    leaving = puck_after_contact(np.array([0, 0, 1.0, 0, 0, 3.0]), np.zeros(2), np.array([1.0, 0.0]), e, 0.3, r)
    assert np.array_equal(leaving, [0, 0, 1.0, 0, 0, 3.0])  # separating: no contact


def test_speed_map_interpolates_and_marks_unreachable_cells():
    xs, ys, angles = [0.0, 1.0], [0.0, 1.0], [-1.0, 1.0]
    table = np.array([[[1.0, 2.0], [3.0, 4.0]], [[5.0, 6.0], [7.0, 8.0]]])
    m = SpeedMap(xs, ys, angles, table)
    # trilinear: value = 1 + 4 x + 2 y + (a + 1) / 2
    assert m.max_speed((0.5, 0.25), (math.cos(0.0), math.sin(0.0))) == pytest.approx(1 + 2 + 0.5 + 0.5)
    table[1, 1, 1] = 0.0  # a direction the arm cannot hit in at a reachable grid point: 0 along it nearby
    assert SpeedMap(xs, ys, angles, table).max_speed((0.9, 0.9), (math.cos(0.9), math.sin(0.9))) == 0.0
    table[1, 1, :] = 0.0  # a grid point the arm cannot reach at all (outside its region) is left out
    edge = SpeedMap(xs, ys, angles, table)
    w = {(0, 0): 0.5 * 0.75, (0, 1): 0.5 * 0.25, (1, 0): 0.5 * 0.75}  # bilinear weights at (0.5, 0.25)
    expected = sum(wt * table[i, j].mean() for (i, j), wt in w.items()) / sum(w.values())  # at angle 0
    assert edge.max_speed((0.5, 0.25), (1.0, 0.0)) == pytest.approx(expected)
    table[:, :, :] = 0.0
    table[0, 0, :] = 1.0
    assert SpeedMap(xs, ys, angles, table).max_speed((1.0, 1.0), (1.0, 0.0)) == 0.0  # no reachable neighbour


def test_an_unreadable_speed_map_cache_is_rebuilt_and_replaced(tmp_path):
    """The fastest-hit table's cache file cut short, emptied, overwritten, of another grid or with a NaN:
    rebuilt with a log line (an empty or cut file raised EOFError / BadZipFile, which stopped the tactics
    node's start), and the file is a good table again."""
    import zipfile
    from air_hockey_agent.core.game import speed_map
    from air_hockey_agent.motion_params import build_planner, load_motion_params
    params = load_motion_params()
    planner, grid, logs = build_planner(params, "iiwa_front"), (3, 3, 2), []
    built = speed_map.load_or_build(planner, params, grid, tmp_path, logs.append)
    path, = tmp_path.glob("speed_map_*.npz")
    good = path.read_bytes()
    other = SpeedMap([0.0, 1.0], [0.0, 1.0], [-1.0, 1.0], np.ones((2, 2, 2)))
    bad_speed = SpeedMap(built.xs, built.ys, built.angles, np.where(built.speeds > 0, np.nan, 0.0))
    for damage in (lambda: path.write_bytes(good[: len(good) // 2]), lambda: path.write_bytes(b""),
                   lambda: path.write_bytes(b"x" * 100), lambda: other.save(path), lambda: bad_speed.save(path)):
        damage()
        logs.clear()
        again = speed_map.load_or_build(planner, params, grid, tmp_path, logs.append)
        assert np.array_equal(again.speeds, built.speeds) and "unreadable" in logs[0] and "building" in logs[1]
        assert np.array_equal(SpeedMap.load(path, grid).speeds, built.speeds)
    with zipfile.ZipFile(path) as archive:  # still numpy's format: the names the loader reads
        assert {"xs.npy", "ys.npy", "angles.npy", "speeds.npy"} <= set(archive.namelist())
    logs.clear()
    speed_map.load_or_build(planner, params, grid, tmp_path, logs.append)
    assert logs == []  # a good cache is read without a word


def test_speed_map_agrees_with_the_planners_search():
    from air_hockey_agent.core.motion.hit_config import best_hit_configuration
    from air_hockey_agent.core.motion.ik import solve_ik
    from air_hockey_agent.motion_params import build_planner, load_motion_params
    planner = build_planner(load_motion_params(), "iiwa_front")
    table = SpeedMap.build(planner, (6, 5, 13))  # 30 deg between directions
    s, rng = planner.s, np.random.default_rng(3)
    checked = 0
    for _ in range(20):
        p = np.array([rng.uniform(-0.75, -0.35), rng.uniform(-0.3, 0.3)])
        a = rng.uniform(-1.0, 1.0)
        d = np.array([math.cos(a), math.sin(a)])
        ik = solve_ik(planner.kin, planner.limits, np.array([*p, s.height]), s.reference, s.reference,
                      s.ik_iterations, s.ik_tolerance)
        looked_up = table.max_speed(p, d)
        if not ik.ok or looked_up == 0.0:
            continue
        exact = best_hit_configuration(planner.kin, planner.limits, ik.q, d, s.ik_tolerance, s.hit_posture_range).max_speed
        assert looked_up == pytest.approx(exact, rel=0.2)
        checked += 1
    assert checked >= 10


def _in_a_follow_through(settings):
    """The real planner and reach, the ready point, and the arm in a hit's follow-through still carrying the
    mallet away from the ready point: its state, the mallet's position and velocity, and the time the
    trajectory generator plans a command sent then from (its state a planning delay ahead)."""
    from air_hockey_agent.agent_params import build_selector, load_agent_params
    from air_hockey_agent.core.motion.planner import ACCEPTED, ArmState, Command
    from air_hockey_agent.motion_params import build_planner, load_motion_params
    from air_hockey_agent.tools.bench_planner import ready_state
    planner = build_planner(load_motion_params(), "iiwa_front")
    reach = build_selector(load_agent_params(), "iiwa_front")[0].reach
    ready = settings.point(settings.ready_point)
    hit = planner.plan(Command(np.array([-0.6, 0.1]), np.array([1.3, 0.0]), 1.0), ready_state(planner, ready))
    assert hit.outcome == ACCEPTED, hit.message
    k = int(np.searchsorted(hit.times, hit.hit_time)) + 2  # in the follow-through, still moving away
    start = ArmState(float(hit.times[k]), hit.q[k], hit.dq[k])
    p, v = planner.kin.planar_motion(start.q, start.dq)
    assert v[0] > 0.5
    return planner, reach, ready, start, p, v, start.t - reach.planning_delay


def test_a_reach_timed_with_the_mallets_velocity_is_one_the_planner_accepts(settings):
    """Right after a hit the follow-through still carries the mallet away: the reach back to the ready
    point, timed from the mallet's position and velocity, is accepted by the motion planner itself; timed
    as from rest (the estimate before) the planner answers too late."""
    from air_hockey_agent.core.motion.planner import ACCEPTED, Command, TOO_LATE
    planner, reach, ready, start, p, v, now = _in_a_follow_through(settings)
    timed = planner.plan(Command(ready, np.zeros(2), now + reach.reach_time(p, ready, v)), start)
    assert timed.outcome == ACCEPTED, timed.message
    from_rest = planner.plan(Command(ready, np.zeros(2), now + reach.reach_time(p, ready)), start)
    assert from_rest.outcome == TOO_LATE, from_rest.message


# --- shots -----------------------------------------------------------------------------------------
@pytest.mark.parametrize("variant", ["straight", "left_bank", "right_bank"])
def test_aimed_shot_enters_the_goal_by_the_stepwise_model(variant, settings, model):
    shots = ShotPredictor(model, settings, DT, lambda p, d: TOP_SPEED)
    puck = np.array([-0.5, 0.1, 0.0, 0.0, 0.0, 0.0])
    shot = shots.aim(puck, variant)
    assert shot is not None and abs(shot.goal_y) < 0.01
    # independent check: the step-by-step reference predictor from the post-hit state
    state = np.array([puck[0], puck[1], *shot.puck_velocity, 0.0, 0.0])
    pred = predict_stepwise(model, state, np.eye(6), shot.arrival + 0.1, DT, np.zeros((6, 6)), lines=(shots.line,))
    assert abs(pred.crossings[shots.line].y) < 0.01
    walls = {w for t, w, x, y, s in pred.impacts if t < shot.arrival}
    assert walls == {"straight": set(), "left_bank": {2}, "right_bank": {0}}[variant]


def test_bank_shot_corrects_the_reflection_law(settings, model):
    """The reflection law (S) ignores restitution and rim friction; aimed with the model the goal is hit."""
    shots = ShotPredictor(model, settings, DT, lambda p, d: TOP_SPEED)
    puck = np.array([-0.6, -0.2, 0.0, 0.0, 0.0, 0.0])
    y_lim = model.table.y_limit
    mirror = math.atan2(2 * y_lim + 0.2, shots.line + 0.6)
    naive = shots._evaluate(puck, mirror, None)
    aimed = shots.aim(puck, "left_bank")
    assert abs(naive[0]) > 0.02   # the reflection law misses the centre by centimetres...
    assert abs(aimed.goal_y) < 0.005  # ...the model-aimed shot does not


def test_shot_in_the_pybullet_table_enters_the_goal(settings, model):
    """Against another implementation of the physics: the simulated table (pybullet, its own rim contacts),
    aimed with that table's parameters (config/tracker_sim_table.yaml, as `air-hockey game` does)."""
    from dataclasses import replace

    from air_hockey_agent.sim.params import load_sim_params
    from air_hockey_agent.sim.world import SimSettings, TableWorld, simulate_shot
    sim = SimSettings.from_params(load_sim_params())
    world = TableWorld(replace(sim, robot_bases={}))
    try:
        shots = ShotPredictor(model, settings, DT, lambda p, d: TOP_SPEED)
        for variant in ("straight", "left_bank", "right_bank"):
            puck = np.array([-0.45, 0.15, 0.0, 0.0, 0.0, 0.0])
            shot = shots.aim(puck, variant)
            _, states = simulate_shot(world, [puck[0], puck[1], *shot.puck_velocity, 0.0, 0.0], shot.arrival + 0.3)
            crossed = states[states[:, 0] > model.table.length / 2 - 0.01]
            assert len(crossed), variant
            assert abs(crossed[0, 1]) < model.table.goal_mouth, variant
    finally:
        world.close()


# --- the state machine (thesis 4.6 situations) ---------------------------------------------------------
def test_static_puck_in_the_smash_area_is_smashed_at_the_goal(selector, model, settings):
    d = selector.step(0.0, RUNNING, situation(model, [-0.5, 0.1, 0, 0, 0, 0]))
    assert d.tactic == SMASH and d.command is not None
    c = d.command
    assert np.linalg.norm(c.velocity) > 0.5 and c.time >= settings.smash_lead_time
    direction = c.velocity / np.linalg.norm(c.velocity)
    np.testing.assert_allclose(c.point + direction * settings.contact_distance, [-0.5, 0.1], atol=1e-6)


@pytest.mark.parametrize("on", [True, False])
def test_an_estimate_from_before_the_robots_own_hit_counts_as_unseen(model, settings, on):
    """A Smash accepted and played at its time, then no new estimate (a mocap dropout over the hit): after the
    follow-through the estimate from before the hit (the puck at rest where it was) no longer counts (Ready
    waits as for an unseen puck) instead of a Smash planned again at where the puck had lain (as without
    ``unseen_after_own_contact``); an estimate after the hit counts again."""
    selector = selector_with(model, settings, unseen_after_own_contact=on)
    before = situation(model, [-0.5, 0.1, 0, 0, 0, 0])
    d = selector.step(0.0, RUNNING, before)
    assert d.tactic == SMASH and d.command is not None
    selector.on_status(0.0, ACCEPTED, 3.0, 0.01)
    hit = d.command.time
    assert selector.step(hit - 0.05, RUNNING, before).tactic == SMASH  # before its time: the hit under way
    after = hit + settings.settle_time + 0.01
    d = selector.step(after, RUNNING, before)
    if not on:
        assert d.tactic == SMASH  # at the puck as it was (here the command under way again: nothing sent)
        return
    assert d.tactic == READY and d.reason == "waiting at the ready point", d.reason
    d = selector.step(after + 0.01, RUNNING, situation(model, [-0.5, 0.1, 0, 0, 0, 0], t0=hit + 0.01))
    assert d.tactic == SMASH and d.command is not None  # seen after the hit (missed): smashed again


def test_an_estimate_carried_past_the_robots_own_hit_on_rejected_frames_counts_as_unseen(selector, model,
                                                                                           settings):
    """As above, with the tracker's fused frames told (observe_puck): frames after the hit that the gate
    rejected carry the pre-hit estimate on to their stamps, so the estimate's time is no proof of a sighting;
    the last fused frame is. A frame fused after the hit counts again."""
    start = [-0.5, 0.1, 0, 0, 0, 0]
    selector.observe_puck(0.0, np.array(start, float))
    d = selector.step(0.0, RUNNING, situation(model, start))
    selector.on_status(0.0, ACCEPTED, 3.0, 0.01)
    hit = d.command.time
    after = hit + settings.settle_time + 0.01
    carried = situation(model, start, t0=after - 0.005)  # a rejected frame's stamp, after the hit
    d = selector.step(after, RUNNING, carried)
    assert d.tactic == READY and d.reason == "waiting at the ready point", d.reason
    selector.observe_puck(after + 0.005, np.array(start, float))
    d = selector.step(after + 0.01, RUNNING, situation(model, start, t0=after + 0.005))
    assert d.tactic == SMASH and d.command is not None


@pytest.mark.parametrize("puck", [(-0.25, 0.0), (-0.24, -0.2)])
def test_a_static_puck_beyond_the_smash_area_is_smashed_from_where_it_lies(selector, model, settings, puck):
    """Between the smash area's far edge and the centre line the arm can only push the puck forward, so it
    is shot at the goal from there (a Prepare pushed it toward the line, out of reach); by the stepwise
    model the shot enters the opponent's goal. Moving, it is not smashed there."""
    assert not settings.in_smash_area(*puck) and settings.beyond_smash_area(puck[0])
    d = selector.step(0.0, RUNNING, situation(model, [*puck, 0, 0, 0, 0]))
    assert d.tactic == SMASH and d.command is not None, d.reason
    v = d.command.velocity
    n = v / np.linalg.norm(v)
    np.testing.assert_allclose(d.command.point + n * settings.contact_distance, puck, atol=1e-6)
    vp = puck_after_hit(np.zeros(2), v, n, settings.mallet_restitution)
    line = settings.table.length / 2 - settings.table.puck_radius
    pred = predict_stepwise(model, np.array([*puck, *vp, 0.0, 0.0]), np.eye(6), 3.0, DT, np.zeros((6, 6)),
                            lines=(line,))
    assert line in pred.crossings and abs(pred.crossings[line].y) < settings.table.goal_mouth
    moving = selector.step(1.0, RUNNING, situation(model, [*puck, 0.2, 0.0, 0, 0], t0=1.0))
    assert moving.tactic != SMASH


@pytest.mark.parametrize("puck", [(-0.76, 0.25), (-0.5, -0.45), (-0.82, 0.0)])
def test_a_static_puck_outside_the_smash_area_is_pushed_to_stop_inside_it(selector, model, settings, puck):
    """In front of the goal, against a long rim, and behind the region's back edge: the pushed puck,
    predicted by the stepwise model (not the closed-form predictor Prepare searched with), stays on the
    own half and stops inside the smash area."""
    from air_hockey_agent.core.puck.mallet_impact import puck_after_hit
    d = selector.step(0.0, RUNNING, situation(model, [*puck, 0, 0, 0, 0]))
    assert d.tactic == PREPARE and d.command is not None, d.reason
    v = d.command.velocity
    assert settings.prepare_speed[0] - 1e-9 <= np.linalg.norm(v) <= settings.prepare_speed[1] + 1e-9
    n = v / np.linalg.norm(v)
    np.testing.assert_allclose(d.command.point + n * settings.contact_distance, puck, atol=1e-9)
    vp = puck_after_hit(np.zeros(2), v, n, settings.mallet_restitution)
    pred = predict_stepwise(model, np.array([*puck, *vp, 0.0, 0.0]), np.eye(6), 10.0, DT, np.zeros((6, 6)),
                            lines=(0.0,))
    assert 0.0 not in pred.crossings and np.hypot(*pred.state[2:4]) < 0.02
    assert settings.in_smash_area(*pred.state[:2])


def test_a_puck_no_push_keeps_on_the_own_half_is_cleared_past_the_neutral_zone(selector, model, settings):
    """0.19 m from the centre line the test arm reaches the puck only from behind (its reach ends 1.30 m
    from the base, and a hit needs 6 cm of follow-through): every push runs forward. Rather than leave it for the referee's possession limit, Prepare
    pushes it across the line; by the stepwise model (not the closed form Prepare searched with) it stops
    at least clear_depth past the line, and not in the opponent's goal."""
    puck = (-0.19, 0.1)
    selector.force(PREPARE)
    d = selector.step(0.0, RUNNING, situation(model, [*puck, 0, 0, 0, 0]))
    assert d.tactic == PREPARE and d.command is not None and "clear" in d.reason, d.reason
    v = d.command.velocity
    n = v / np.linalg.norm(v)
    vp = puck_after_hit(np.zeros(2), v, n, settings.mallet_restitution)
    pred = predict_stepwise(model, np.array([*puck, *vp, 0.0, 0.0]), np.eye(6), 10.0, DT, np.zeros((6, 6)))
    assert pred.state[0] >= settings.clear_depth and np.hypot(*pred.state[2:4]) < 0.02, pred.state
    assert abs(pred.state[0]) < settings.table.length / 2  # stopped on the table, not in a goal


def test_a_puck_at_rest_by_a_long_rim_beside_the_goal_is_banked_by_a_push_that_stops_soon(model, settings):
    """A puck at rest 13 cm from the own goal line, 6 cm from a long rim: Prepare banks it off the rim. With
    the follow-through as long as fits (``follow_through_time`` unbounded: a 0.2 m/s push ran on 0.3 m for
    3 s) every push into the rim bounced back into the running-on mallet, and nothing was played
    (lab-table self-play seed 309: the puck stayed until the referee's possession limit)."""
    from dataclasses import replace
    x0, ready = -settings.table.length / 2, settings.point(settings.ready_point)
    puck = situation(model, [x0 + 0.13, -(settings.table.y_limit - 0.06), 0, 0, 0, 0])
    reach = flat_reach(settings)
    for time, deceleration, plays in ((reach.follow_through_time, reach.follow_through_deceleration, True),
                                      (100.0, 0.0, False)):
        arm = replace(reach, follow_through_time=time, follow_through_deceleration=deceleration)
        selector = TacticsSelector(settings, arm, ShotPredictor(model, settings, DT, arm.max_speed))
        d = selector.step(0.0, RUNNING, puck, ready, np.zeros(2))
        assert (d.tactic == PREPARE and d.command is not None) == plays, (time, d.reason)


def test_a_puck_against_a_long_rim_is_pushed_only_with_the_short_stop(model, settings):
    """A puck at rest against a long rim beside the smash area: with the default stop (at least the floor,
    running on into the rim or into the puck's way back off it) nothing is played; with the optional short
    stop (``follow_through_deceleration`` 5 m/s^2, floor 5 mm) Prepare pushes it (README "Tactics and the
    game": lab-table self-play seed 400 left such a puck to the referee's possession limit)."""
    from dataclasses import replace
    ready, reach = settings.point(settings.ready_point), flat_reach(settings)
    for side in (1.0, -1.0):
        puck = situation(model, [-0.5, side * settings.table.y_limit, 0, 0, 0, 0])
        short = replace(reach, follow_through=0.005, follow_through_deceleration=5.0)
        for arm, plays in ((reach, False), (short, True)):
            selector = TacticsSelector(settings, arm, ShotPredictor(model, settings, DT, arm.max_speed))
            d = selector.step(0.0, RUNNING, puck, ready, np.zeros(2))
            assert (d.tactic == PREPARE and d.command is not None) == plays, (side, arm.follow_through, d.reason)


def test_a_puck_on_the_own_half_for_clear_after_is_cleared_and_the_clock_restarts_when_it_crosses(
        selector, model, settings):
    """The possession clock the robot keeps: a puck Prepare pushes toward the smash area at first is cleared
    across the centre line once it has been on the own half for clear_after (in a game a corner puck was
    pushed a little at a time until the referee's possession limit gave it away); the clock restarts when
    the puck crosses the line and when play restarts."""
    puck = [-0.6, 0.45, 0, 0, 0, 0]
    d = selector.step(0.0, RUNNING, situation(model, puck))
    assert d.tactic == PREPARE and "clear" not in d.reason, d.reason
    late = settings.clear_after + 0.01
    selector.sent = None  # the push was never played (the puck is where it was)
    d = selector.step(late, RUNNING, situation(model, puck, t0=late))
    assert d.tactic == PREPARE and "prepare (clear)" in d.reason and f"for {late:.1f} s on the own half" in d.reason
    v = d.command.velocity
    vp = puck_after_hit(np.zeros(2), v, v / np.linalg.norm(v), settings.mallet_restitution)
    pred = predict_stepwise(model, np.array([*puck[:2], *vp, 0.0, 0.0]), np.eye(6), 10.0, DT, np.zeros((6, 6)),
                            lines=(0.0,))
    assert pred.crossings and pred.state[0] >= settings.clear_depth, pred.state
    selector.sent = None
    assert selector.step(late + 0.2, RUNNING, None).tactic == READY  # no estimate for a moment: the clock runs on
    selector.sent = None
    d = selector.step(late + 0.3, RUNNING, situation(model, puck, t0=late + 0.3))
    assert "prepare (clear)" in d.reason and f"for {late + 0.3:.1f} s on the own half" in d.reason, d.reason
    for crossing, status in (([0.1, 0.0, 0, 0, 0, 0], RUNNING), (puck, PAUSED)):
        selector.sent = None
        selector.step(late + 0.5, status, situation(model, crossing, t0=late + 0.5))  # the clock restarts
        selector.sent = None
        d = selector.step(late + 1.0, RUNNING, situation(model, puck, t0=late + 1.0))
        assert d.tactic == PREPARE and "clear" not in d.reason, d.reason
    selector.force(PREPARE)  # the strategy test's forced Prepare plays its push whenever it is asked
    selector.step(late + 1.0, RUNNING, situation(model, puck, t0=late + 1.0))
    d = selector.step(2 * late + 1.0, RUNNING, situation(model, puck, t0=2 * late + 1.0))
    assert d.tactic == PREPARE and "clear" not in d.reason, d.reason


def test_a_tactic_with_nothing_to_play_under_its_speed_cap_waits_like_a_refused_one(selector, model, settings):
    """A smash refused with a speed the puck cannot reach the goal at has nothing to propose under that
    cap; the tactic after it is played, and the smash is not asked again uncapped (the cap goes when the
    tactic changes) until retry_delay has passed: it was, every decision, refused again, and a Prepare
    sent in between was replaced before its answer came (a game's possession foul)."""
    sit = situation(model, [-0.5, 0.1, 0, 0, 0, 0])
    assert selector.step(0.0, RUNNING, sit).tactic == SMASH
    selector.on_status(0.0, TOO_FAST, 0.05, 0.01)
    assert selector.step(0.02, RUNNING, sit).tactic != SMASH
    assert selector.step(0.04, RUNNING, sit).tactic != SMASH
    assert selector.step(0.04 + settings.retry_delay, RUNNING, sit).tactic == SMASH


def test_a_push_whose_puck_rebounds_into_the_stopping_mallet_is_flagged(selector):
    """A puck 4 cm from the -y rim pushed into it bounces back into the mallet, which runs on 0.3 m
    after the hit; pushed away from the rim it does not."""
    puck = np.array([-0.5, -0.45, 0.0, 0.0, 0.0, 0.0])
    into = selector.shots.push(puck, -math.pi / 2 + 0.2, 0.3, 0.005, 8.0)
    away = selector.shots.push(puck, math.pi / 2, 0.3, 0.005, 8.0)
    assert selector.shots.rebounds_into_mallet(into, 0.30, 1.5)
    assert not selector.shots.rebounds_into_mallet(away, 0.30, 1.5)


def test_a_push_into_a_rim_the_puck_nearly_touches_is_flagged_too(selector, settings):
    """A puck 1.2 cm from the goal-line rim pushed into it slowly is back before it has cleared the mallet
    (in pybullet it was squeezed between mallet and rim and out sideways at 0.5 m/s); the same push from
    0.3 m off the rim is not flagged."""
    rim = -settings.table.length / 2 + settings.table.puck_radius
    for gap, flagged in ((0.012, True), (0.3, False)):
        puck = np.array([rim + gap, -0.3, 0.0, 0.0, 0.0, 0.0])
        push = selector.shots.push(puck, math.pi - 0.26, 0.14, 0.005, 8.0)
        assert push.bounces and selector.shots.rebounds_into_mallet(push, 0.02, 1.5) == flagged, gap


def test_a_puck_against_a_long_rim_pushed_along_it_is_not_flagged_for_leaving_the_mallet(selector, settings):
    """A puck at rest against a long rim, pushed at 0.4 m/s 30 deg off the rim (the mallet runs on 8 cm):
    the rim impact comes at once, before the puck has cleared the mallet, but the puck moves away from it
    along the rim, and the push is not flagged (every such push was: a puck against a long rim got no push
    and stayed until the referee's possession limit, lab-table self-play seeds 400 and 410); pushed
    straight into the rim it comes back into the mallet and is."""
    puck = np.array([-0.7, settings.table.y_limit, 0.0, 0.0, 0.0, 0.0])
    for angle, flagged in ((math.radians(30.0), False), (math.pi / 2, True)):
        push = selector.shots.push(puck, angle, 0.4, 0.005, 8.0)
        assert push.bounces and selector.shots.rebounds_into_mallet(push, 0.08, 1.5) == flagged, angle


def test_puck_straight_at_the_goal_is_repelled_toward_the_opponent(selector, model):
    d = selector.step(0.0, RUNNING, situation(model, [0.6, 0.05, -1.8, -0.05, 0, 0]))
    assert d.tactic == REPEL and d.command is not None and d.command.velocity[0] > 0.5


@pytest.mark.parametrize("start", [(0.2, -0.1, -1.5, -1.6), (0.3, 0.2, -1.8, 1.2), (0.0, 0.3, -1.2, -0.2)])
def test_an_approaching_puck_is_cut_to_stop_in_the_smash_area(selector, model, settings, start):
    """Banked or straight: the Cut meets the puck before the defend line, and the puck it leaves, predicted
    by the stepwise model from the commanded contact (normal from the mallet to the predicted puck; Routh's
    impact with the mallet's friction, spin included), stops inside the smash area without conceding."""
    from air_hockey_agent.core.puck.mallet_impact import puck_after_contact
    sit = situation(model, [*start, 0, 0])
    c = sit.crossing(settings.defend_x)
    assert c is not None
    selector.force(CUT)  # (the third would be repelled: it comes straight at the goal)
    d = selector.step(0.0, RUNNING, sit)
    selector.force(None)
    assert d.tactic == CUT and d.command is not None, d.reason
    cmd = d.command
    t = cmd.time + (settings.cut_arrive_early if not cmd.is_hit else 0.0)
    assert t <= c.time + 1e-9
    puck = sit.at(t)
    n = (puck[:2] - cmd.point) / np.linalg.norm(puck[:2] - cmd.point)
    assert np.linalg.norm(puck[:2] - cmd.point) == pytest.approx(settings.contact_distance, abs=1e-6)
    after = puck_after_contact(puck, cmd.velocity, n, settings.mallet_restitution, settings.mallet_friction,
                               settings.table.puck_radius)
    pred = predict_stepwise(model, after, np.eye(6), 10.0, DT, np.zeros((6, 6)),
                            lines=(-settings.table.length / 2,))
    assert np.hypot(*pred.state[2:4]) < 0.02 and settings.in_smash_area(*pred.state[:2])


def test_no_defence_is_planned_with_too_little_time(selector, model, settings):
    sit = situation(model, [-0.55, 0.0, -2.0, 0.3, 0, 0])  # crosses the defend line in ~0.12 s
    d = selector.step(0.0, RUNNING, sit)
    assert d.tactic not in (CUT, REPEL)


def test_puck_leaving_on_the_opponents_half_means_ready(selector, model, settings):
    d = selector.step(0.0, RUNNING, situation(model, [0.4, 0.0, 1.0, 0.2, 0, 0]))
    assert d.tactic == READY
    np.testing.assert_allclose(d.command.point, settings.point(settings.ready_point))


def _gap(settings) -> float:
    return settings.contact_distance + settings.approach_clearance


def test_ready_guards_a_slow_puck_behind_the_ready_line_from_the_goal_side(selector, model, settings):
    goal = np.array([-settings.table.length / 2, 0.0])
    puck = np.array([goal[0] + 0.12, -0.30])  # deeper than the ready point, beside the goal, sliding along y
    d = selector.step(0.0, RUNNING, situation(model, [*puck, 0.0, 0.3, 0, 0]))
    assert d.tactic == READY and d.reason.startswith("guarding")
    p = d.command.point
    assert abs(np.linalg.norm(p - puck) - _gap(settings)) < 1e-9  # a contact distance and a clearance short
    cross = (puck - goal)[0] * (p - goal)[1] - (puck - goal)[1] * (p - goal)[0]
    assert abs(cross) < 1e-9 and np.linalg.norm(p - goal) < np.linalg.norm(puck - goal)  # between goal and puck
    assert selector.reach.region.contains(p)


def test_ready_does_not_guard_a_puck_too_deep_fast_or_far(selector, model, settings):
    ready = settings.point(settings.ready_point)
    x0 = -settings.table.length / 2
    for state, waits_there in (([x0 + 0.05, 0.30, 0.0, 0.3, 0, 0], True),  # its guard point: behind the region
                               ([x0 + 0.12, -0.30, 0.0, settings.ready_guard_speed + 0.2, 0, 0], False),  # fast
                               ([x0 + settings.ready_guard_depth + 0.02, -0.42, 0.3, 0.0, 0, 0], True)):  # far
        fresh = TacticsSelector(settings, selector.reach, selector.shots)
        d = fresh.step(0.0, RUNNING, situation(model, state))
        assert d.tactic == READY and not d.reason.startswith("guarding"), state
        if waits_there:
            assert d.reason == "waiting at the ready point", state
            np.testing.assert_allclose(d.command.point, ready)


def _clear_of_path(point, sit, gap) -> bool:
    path = np.vstack([sit.puck[:2], sit.states[:, :2]])
    deeper = path[path[:, 0] < point[0]]
    return not len(deeper) or np.min(np.hypot(*(deeper - point).T)) >= gap - 1e-9


def test_ready_waits_clear_of_a_puck_between_the_ready_point_and_the_goal(selector, model, settings):
    x0 = -settings.table.length / 2
    puck = np.array([x0 + 0.11, 0.01])  # in front of the goal, a few centimetres from the ready point
    sit = situation(model, [*puck, 0.0, 0.1, 0, 0])
    d = selector.step(0.0, RUNNING, sit)
    assert d.tactic == READY and "clear of it" in d.reason
    p = d.command.point
    assert p[1] == settings.ready_point[1] and p[0] > puck[0]  # moved away from the goal, not beside the puck
    assert _clear_of_path(p, sit, _gap(settings))
    assert np.linalg.norm(p - puck) < _gap(settings) + 0.01  # and no farther than that needs


def test_ready_steps_out_of_the_way_of_a_puck_sliding_behind_the_ready_point(selector, model, settings):
    """A puck sliding along y behind the ready point would meet the waiting mallet from behind (the
    own goal of seed 37 at 43.2 s in self-play); the mallet waits where the predicted path passes it."""
    x0 = -settings.table.length / 2
    sit = situation(model, [x0 + 0.11, -0.35, 0.0, 1.0, 0, 0])  # too fast to guard, passes under the ready point
    d = selector.step(0.0, RUNNING, sit)
    assert d.tactic == READY and "clear of it" in d.reason
    assert _clear_of_path(d.command.point, sit, _gap(settings))
    assert not _clear_of_path(settings.point(settings.ready_point), sit, settings.contact_distance)


def test_reach_way_is_the_planners_reach(settings):
    """The way a Ready's outcome check expects the mallet to take (``ArmReach.reach_way``) is the one the
    motion planner plans: from a follow-through still carrying the mallet away, the planned reach's mallet
    positions (forward kinematics of its joint knots) lie within 1 cm of it throughout."""
    from air_hockey_agent.core.motion.planner import ACCEPTED, Command
    planner, reach, ready, start, p, v, now = _in_a_follow_through(settings)
    plan = planner.plan(Command(ready, np.zeros(2), now + reach.reach_time(p, ready, v)), start)
    assert plan.outcome == ACCEPTED, plan.message
    planned = np.array([planner.kin.planar_motion(q, dq)[0] for q, dq in zip(plan.q, plan.dq)])
    way, _ = reach.reach_way(p - v * reach.planning_delay, v, ready, plan.times - now)
    assert np.max(np.hypot(*(planned - way).T)) < 0.01
    np.testing.assert_allclose(way[-1], ready, atol=1e-9)
    moved = float(np.max(np.hypot(*(planned - p).T)))
    assert moved > 0.1  # a real reach, not a mallet standing still


def _turned_in(point, sit, selector, mallet, velocity, now=0.0):
    """Does the mallet's way from ``mallet`` to ``point`` meet the puck so that it goes into the own goal,
    by the step-by-step reference predictor from the contact (not the shot model's fast one)?"""
    from air_hockey_agent.core.puck.mallet_impact import puck_after_contact
    from air_hockey_agent.core.game.tactics.ready import way_meeting
    st, ctx = selector.s, _ctx(selector, mallet, now, velocity)
    meeting = way_meeting(np.asarray(point, float), sit.samples_from(now, np.inf), ctx, (st.contact_distance,))
    if meeting is None:
        return False
    after = puck_after_contact(meeting[0], meeting[2], meeting[1], st.mallet_restitution, st.mallet_friction,
                               st.table.puck_radius)
    line = -st.table.length / 2 + st.table.puck_radius
    model = selector.shots.model
    pred = predict_stepwise(model, after, np.eye(6), 2.0, DT, np.zeros((6, 6)), lines=(line,))
    crossing = pred.crossings.get(line)
    return crossing is not None and abs(crossing.y) < st.table.goal_mouth


def test_ready_moves_off_a_way_that_would_turn_the_puck_into_the_own_goal(selector, model, settings):
    """A fast puck sliding along y just in front of the goal line (deeper than the ready point's depth less a
    contact distance) meets the mallet waiting at the ready point on its side and goes in (the largest cause
    of own goals in self-play); the mallet waits elsewhere, where it does not."""
    x0 = -settings.table.length / 2
    ready = settings.point(settings.ready_point)
    sit = situation(model, [x0 + 0.13, -0.45, -0.1, 1.8, 0, 0])
    assert _turned_in(ready, sit, selector, ready, np.zeros(2))  # the reference model agrees: it would go in
    d = selector.step(0.0, RUNNING, sit, ready, np.zeros(2))
    assert d.tactic == READY and "off the way" in d.reason, d.reason
    assert np.linalg.norm(d.command.point - ready) > 0.05
    assert not _turned_in(d.command.point, sit, selector, ready, np.zeros(2))
    assert selector.reach.region.contains(d.command.point)


def test_ready_blocks_on_the_pucks_path_from_now_on_with_an_old_estimate(model, settings):
    """An estimate 0.115 s old (mocap latency and a lost frame or two), a 1.6 m/s puck going into the goal: the
    block lies on the puck's path from now on, where the mallet's way from now meets it and the contact, by
    the step-by-step reference predictor, keeps it out. (Judged with the samples before now, which met a
    mallet extrapolated back along its present velocity, the block was the estimate's position, 0.19 m behind
    the puck.)"""
    from air_hockey_agent.core.game.tactics.ready import meeting_distances, way_meeting
    selector = selector_with(model, settings)
    selector.blocked = {tactic: math.inf for tactic in (SMASH, REPEL, CUT, PREPARE)}  # only Ready left
    now, mallet, velocity = 0.115, np.array([-0.776, -0.008]), np.array([0.42, -0.44])
    sit = situation(model, _into_the_goal(settings, 0.628, 0.094, 1.64))
    d = selector.step(now, RUNNING, sit, mallet, velocity)
    assert d.tactic == READY and d.reason.startswith("blocking"), d.reason
    p = d.command.point
    assert path_gap(sit.samples_from(now, np.inf)[1][:, :2], p) < 1e-9, p  # on the path from now on
    ctx = _ctx(selector, mallet, now, velocity)
    assert way_meeting(p, sit.samples_from(now, np.inf), ctx, meeting_distances(settings)) is not None
    assert not _turned_in(p, sit, selector, mallet, velocity, now)


def test_ready_stays_on_a_way_whose_meeting_sends_the_puck_away(model, settings):
    """A slow puck coming at the waiting mallet from the front is met there and sent back: no dodge (and,
    without ``ready_blocks``, which would go to meet it on its path, no block)."""
    selector = selector_with(model, settings, ready_blocks=False)
    ready = settings.point(settings.ready_point)
    sit = situation(model, [ready[0] + 0.3, 0.0, -0.4, 0.0, 0, 0])
    selector.blocked = {tactic: math.inf for tactic in (SMASH, REPEL, CUT, PREPARE)}  # only Ready left
    assert first_meeting(Proposal(READY, ready, np.zeros(2), 0.0, ""), sit, settings.contact_distance, 1.0)
    d = selector.step(0.0, RUNNING, sit, ready, np.zeros(2))
    assert d.tactic == READY and d.reason == "waiting at the ready point", d.reason
    np.testing.assert_allclose(d.command.point, ready)


def _into_the_goal(settings, depth, y, speed):
    """A table-frame puck ``depth`` [m] from the own goal line at ``y`` [m], heading at ``speed`` [m/s] for
    the goal's centre."""
    x0 = -settings.table.length / 2
    d = np.array([-depth, -y]) / math.hypot(depth, y)
    return [x0 + depth, y, *(speed * d), 0, 0]


def test_ready_blocks_a_puck_going_into_the_goal_on_its_path(selector, model, settings):
    """A slow puck behind the defend line heading into the goal, which no other tactic takes: the mallet
    waits on its predicted path, inside its region, where its way meets the puck and the contact, by the
    step-by-step reference predictor, keeps it out."""
    ready = settings.point(settings.ready_point)
    sit = situation(model, _into_the_goal(settings, 0.17, 0.25, 0.3))
    selector.blocked = {tactic: math.inf for tactic in (SMASH, REPEL, CUT, PREPARE)}  # only Ready left
    d = selector.step(0.0, RUNNING, sit, ready, np.zeros(2))
    assert d.tactic == READY and d.reason.startswith("blocking"), d.reason
    p = d.command.point
    assert path_gap(np.vstack([sit.puck[:2], sit.states[:, :2]]), p) < 1e-9  # on the predicted path
    assert selector.reach.region.contains(p)
    assert _met(p, sit, selector, ready, np.zeros(2)) and not _turned_in(p, sit, selector, ready, np.zeros(2))
    waiting = settings.point(settings.ready_point)
    assert _met(waiting, sit, selector, ready, np.zeros(2)) is False  # at the ready point it would pass by


def test_ready_does_not_block_a_puck_that_stays_out(selector, model, settings):
    ready = settings.point(settings.ready_point)
    x0 = -settings.table.length / 2
    for state in ([x0 + 0.17, 0.3, -0.05, 0.3, 0, 0],  # sliding toward the side rim
                  _into_the_goal(settings, 0.6, 0.0, 0.0)):  # at rest
        fresh = TacticsSelector(settings, selector.reach, selector.shots)
        fresh.blocked = {tactic: math.inf for tactic in (SMASH, REPEL, CUT, PREPARE)}
        d = fresh.step(0.0, RUNNING, situation(model, state), ready, np.zeros(2))
        assert d.tactic == READY and not d.reason.startswith("blocking"), (state, d.reason)


def _met(point, sit, selector, mallet, velocity, now=0.0) -> bool:
    from air_hockey_agent.core.game.tactics.ready import way_meeting
    st, ctx = selector.s, _ctx(selector, mallet, now, velocity)
    return way_meeting(np.asarray(point, float), sit.samples_from(now, np.inf), ctx, (st.contact_distance,)) is not None


def test_ready_checks_way_off_keeps_the_waiting_point(model, settings):
    fresh = selector_with(model, settings, ready_checks_way=False)
    x0 = -settings.table.length / 2
    ready = settings.point(settings.ready_point)
    d = fresh.step(0.0, RUNNING, situation(model, [x0 + 0.13, -0.45, -0.1, 1.8, 0, 0]), ready, np.zeros(2))
    assert d.tactic == READY and "off the way" not in d.reason


def _ctx(selector, mallet, now=0.0, velocity=(0.0, 0.0)):
    """The tactics' context of ``selector`` at ``now`` [s] with the mallet at ``mallet`` [m] moving at
    ``velocity`` [m/s] (own frame)."""
    from air_hockey_agent.core.game.tactics.base import Context
    return Context(now, selector.s, selector.reach, selector.shots, np.asarray(mallet, float),
                   np.asarray(velocity, float))


def test_the_block_points_stay_put_while_the_predictions_samples_slide(model, settings):
    """Ten milliseconds later on the same path, the points a block is chosen from lie where they lay (on
    fixed lines x = const, ``ready_block_step`` 0.05 m, within a millimetre), so an unchanged block is not
    re-sent; the prediction's own samples (``ready_block_step`` 0, the default) moved by more than
    ``resend_distance`` at a fast puck's speed."""
    from air_hockey_agent.core.game.tactics.ready import path_points
    start = _into_the_goal(settings, 0.7, -0.35, 3.0)
    first = situation(model, start)
    later = situation(model, first.at(0.01), t0=0.01)
    for step, moved in ((0.05, False), (0.0, True)):
        selector = selector_with(model, settings, ready_block_step=step)
        ready = settings.point(settings.ready_point)
        a, b = ([p for _, p in path_points(sit, _ctx(selector, ready, sit.t))] for sit in (first, later))
        a, b = ([p for p in points if selector.reach.region.contains(p)] for points in (a, b))
        gap = float(np.linalg.norm(a[0] - b[0]))
        assert (gap > settings.resend_distance) == moved and (moved or gap < 1e-3), (step, gap)
        if not moved:
            assert np.allclose(np.diff([p[0] for p in a]), -step)
            assert path_gap(np.vstack([first.puck[:2], first.states[:, :2]]), a[1]) < 1e-9  # on the path


def test_ready_keeps_the_block_it_runs_while_it_holds(model, settings):
    """With ``ready_block_keep``, 10 ms later on the same path of a 3 m/s puck into the goal, the block the
    arm was sent (and accepted) is kept: nothing is sent again. Without it the block is chosen anew from
    the prediction's samples, which moved by more than ``resend_distance``: sent again. A kept block
    that no longer holds (the puck now passes beside the goal) is dropped. (``ready_switch_time`` 0: the
    block's own rule alone.)"""
    from air_hockey_agent.core.game.tactics.ready import block_point
    first = situation(model, _into_the_goal(settings, 0.7, -0.35, 3.0))
    later = situation(model, first.at(0.01), t0=0.01)
    wide = situation(model, [*first.at(0.02)[:2], -3.0, 0.0, 0, 0], t0=0.02)  # toward the own end rim, wide
    ready = settings.point(settings.ready_point)
    for keep in (True, False):
        selector = selector_with(model, settings, ready_block_keep=keep, ready_switch_time=0.0)
        selector.blocked = {tactic: math.inf for tactic in (SMASH, REPEL, CUT, PREPARE)}  # only Ready left
        d = selector.step(0.0, RUNNING, first, ready, np.zeros(2))
        assert d.reason.startswith("blocking") and d.command is not None, d.reason
        selector.on_status(0.0, ACCEPTED, 3.0, 0.01)
        again = selector.step(0.01, RUNNING, later, ready, np.zeros(2))
        assert again.reason.startswith("blocking"), again.reason
        if keep:
            assert again.command is None and again.reason == d.reason
            kept = d.command.point  # held while it still keeps the puck out, dropped once it does not
            held = block_point(later, _ctx(selector, ready, 0.01), kept)
            assert held is not None and np.array_equal(held, kept)
            gone = block_point(wide, _ctx(selector, ready, 0.02), kept)
            assert gone is None or not np.array_equal(gone, kept)
            dropped = selector.step(0.02, RUNNING, wide, ready, np.zeros(2))
            assert not dropped.reason.startswith("blocking"), dropped.reason
        else:
            assert np.linalg.norm(again.command.point - d.command.point) > settings.resend_distance


def _ready_only(model, settings, **changes) -> TacticsSelector:
    selector = selector_with(model, settings, **changes)
    selector.blocked = {tactic: math.inf for tactic in (SMASH, REPEL, CUT, PREPARE)}  # only Ready left
    return selector


def test_ready_takes_a_new_waiting_point_once_it_has_stayed_ready_switch_time(model, settings):
    """The arm reaching the ready point (accepted) when a slow puck comes to lie behind the ready line beside
    the goal: Ready's new point, the guard, is sent only once it has been chosen for ``ready_switch_time``;
    until then the point under way is kept (its way misses a puck that does not go in) and nothing is sent.
    With 0 the guard is sent at once."""
    ready, x0, step = settings.point(settings.ready_point), -settings.table.length / 2, 1.0 / 64.0
    assert settings.ready_switch_time > 0.0  # on by default
    for hold in (settings.ready_switch_time, 0.0):
        selector = _ready_only(model, settings, ready_switch_time=hold)
        d = selector.step(0.0, RUNNING, situation(model, [0.4, 0.0, 1.0, 0.2, 0, 0]), ready, np.zeros(2))
        assert d.reason == "waiting at the ready point" and d.command is not None
        selector.on_status(0.0, ACCEPTED, 3.0, 0.01)
        for k in range(1, 10):
            t = k * step
            d = selector.step(t, RUNNING, situation(model, [x0 + 0.12, -0.30, 0.0, 0.05, 0, 0], t0=t), ready,
                              np.zeros(2))
            if d.command is not None:
                break
            assert d.reason.startswith("keeping to") and "guarding" in d.reason and "not yet steady" in d.reason
        assert d.reason.startswith("guarding") and d.command is not None
        assert t == step + math.ceil(hold / step) * step, (hold, t)


def test_ready_leaves_at_once_a_point_whose_way_lets_the_puck_in(model, settings):
    """The arm reaching a guard point beside the goal (accepted) when a 3 m/s puck heads into the goal's
    centre from the other side: the point under way misses it (not :func:`harmless`), so Ready's own choice
    (the ready point on the puck's path: from the guard no block is reached in time) is sent at the first
    decision."""
    from air_hockey_agent.core.game.tactics.ready import harmless
    x0 = -settings.table.length / 2
    selector = _ready_only(model, settings)
    d = selector.step(0.0, RUNNING, situation(model, [x0 + 0.12, -0.30, 0.0, 0.05, 0, 0]),
                      settings.point(settings.ready_point), np.zeros(2))
    assert d.reason.startswith("guarding") and d.command is not None
    selector.on_status(0.0, ACCEPTED, 3.0, 0.01)
    guard = d.command.point
    shot = situation(model, _into_the_goal(settings, 0.7, 0.35, 3.0), t0=0.01)
    assert not harmless(guard, shot, _ctx(selector, guard, 0.01))
    d = selector.step(0.01, RUNNING, shot, guard, np.zeros(2))
    assert d.reason == "waiting at the ready point" and d.command is not None, d.reason


def test_ready_block_choice_margin_takes_the_block_reached_longest_before_the_puck(model, settings):
    """A 3 m/s puck into the goal, the mallet at rest at the ready point: with ``ready_block_choice``
    'first' the block is the first passing position of the puck's path (the farthest from the goal, the
    tightest to reach); with 'margin' a position the mallet reaches longest before the puck among those
    that keep it out, with more time to spare than the first one (here the first is where the puck lies:
    the mallet's way toward it meets the puck coming), and nearer the mallet."""
    from air_hockey_agent.core.game.tactics.ready import (block_point, by_margin, keeps_out, path_points,
                                                          time_to_spare)
    sit = situation(model, _into_the_goal(settings, 0.7, -0.35, 3.0))
    ready = settings.point(settings.ready_point)
    chosen = {}
    for choice in ("first", "margin"):
        ctx = _ctx(selector_with(model, settings, ready_block_choice=choice), ready, sit.t)
        chosen[choice] = block_point(sit, ctx)
        assert chosen[choice] is not None, choice
    points = path_points(sit, ctx)
    samples = sit.samples_until(np.inf)
    passing = [(t, p) for t, p in points if keeps_out(p, samples, ctx)]
    assert np.allclose(chosen["first"], passing[0][1]) and len(passing) > 1

    def margin(point):
        return time_to_spare(next(t for t, p in points if np.allclose(p, point)), point, ctx)
    assert np.allclose(chosen["margin"], by_margin(passing, ctx)[0][1])
    assert margin(chosen["margin"]) > margin(chosen["first"])
    assert np.hypot(*(chosen["margin"] - ready)) < np.hypot(*(chosen["first"] - ready))


def test_ready_waits_deep_while_the_puck_is_unseen(model, settings):
    """With ``ready_unseen_time`` 0.1 s, an estimate whose last frame is 0.2 s old (a mocap dropout; the puck
    last seen at rest on the opponent's half) or none at all: Ready waits at ``ready_unseen_point``, inside
    the arm's region; with a fresh estimate, or with the option off (0), or for a puck last seen on the own
    half beside the ready point (the guard's rules), at the ready point."""
    sit = situation(model, [0.4, 0.1, 0.0, 0.0, 0.0, 0.0])
    own = situation(model, [-0.5, 0.3, 0.0, 0.0, 0.0, 0.0])
    ready, deep = settings.point(settings.ready_point), settings.point((0.08, 0.0))
    cases = ((0.1, sit, 0.2, deep), (0.1, None, 0.2, deep), (0.1, sit, 0.05, ready), (0.0, sit, 0.2, ready),
             (0.1, own, 0.2, ready))
    for wait, seen, now, where in cases:
        fresh = selector_with(model, settings, ready_unseen_time=wait, ready_unseen_point=(0.08, 0.0))
        fresh.blocked = {tactic: math.inf for tactic in (SMASH, REPEL, CUT, PREPARE)}  # only Ready left
        d = fresh.step(now, RUNNING, seen, ready + np.array([0.0, 0.2]), np.zeros(2))
        assert d.tactic == READY and d.command is not None, (wait, now, d.reason)
        assert np.allclose(d.command.point, where), (wait, now, d.command.point, d.reason)
        assert fresh.reach.region.contains(d.command.point)
        assert d.reason.startswith("the puck unseen") == (where is deep)


def test_ready_waits_in_the_way_of_a_puck_it_cannot_block_in_time(model, settings):
    """A 4 m/s puck into the goal that the mallet at the ready point cannot meet in time by the planner's
    reach: Ready moves it onto the puck's path where that crosses the ready point's line (not left at the
    ready point, as with ``ready_block_in_way`` off)."""
    ready = settings.point(settings.ready_point)
    sit = situation(model, _into_the_goal(settings, 0.35, -0.3, 4.0))
    for in_way in (True, False):
        fresh = selector_with(model, settings, ready_block_in_way=in_way)
        fresh.blocked = {tactic: math.inf for tactic in (SMASH, REPEL, CUT, PREPARE)}  # only Ready left
        d = fresh.step(0.0, RUNNING, sit, ready, np.zeros(2))
        assert d.tactic == READY and not d.reason.startswith("blocking"), d.reason
        if not in_way:
            assert d.reason == "waiting at the ready point", d.reason
            continue
        assert d.reason.startswith("in the way of the puck"), d.reason
        p = d.command.point
        assert p[0] == pytest.approx(ready[0]) and abs(p[1] - ready[1]) > 0.03
        assert path_gap(np.vstack([sit.puck[:2], sit.states[:, :2]]), p) < 1e-9


def test_ready_blocks_off_keeps_the_waiting_point(model, settings):
    fresh = selector_with(model, settings, ready_blocks=False)
    fresh.blocked = {tactic: math.inf for tactic in (SMASH, REPEL, CUT, PREPARE)}
    ready = settings.point(settings.ready_point)
    d = fresh.step(0.0, RUNNING, situation(model, _into_the_goal(settings, 0.17, 0.25, 0.3)), ready, np.zeros(2))
    assert d.tactic == READY and not d.reason.startswith("blocking"), d.reason


def test_the_back_robot_plays_in_its_own_frame(selector, model):
    d = selector.step(0.0, RUNNING, situation(model, [0.5, -0.1, 0, 0, 0, 0], robot="iiwa_back"))
    assert d.tactic == SMASH  # (0.5, -0.1) in the table is (-0.5, 0.1) on the back robot's own half


def test_referee_commands_are_obeyed(selector, model, settings):
    sit = situation(model, [-0.5, 0.1, 0, 0, 0, 0])
    d = selector.step(0.0, STOPPED, sit)
    assert d.tactic == INIT and d.command is None
    d = selector.step(0.01, PAUSED, sit)
    assert d.tactic == HOME and d.command is not None
    np.testing.assert_allclose(d.command.point, settings.point(settings.home_point))
    assert selector.step(0.02, RUNNING, sit).tactic == SMASH


def test_forced_tactic_stays_until_released(selector, model):
    sit = situation(model, [-0.5, 0.1, 0, 0, 0, 0])
    selector.force(CUT)
    for k in range(5):
        d = selector.step(0.01 * k, RUNNING, sit)
        assert d.tactic == CUT and d.forced and d.command is None  # waits for a puck to cut
    selector.force(None)
    assert selector.step(0.1, RUNNING, sit).tactic == SMASH
    with pytest.raises(ValueError):
        selector.force(42)


def test_accepted_hit_is_kept_until_the_prediction_moves(selector, model):
    sit = situation(model, [-0.5, 0.1, 0, 0, 0, 0])
    first = selector.step(0.0, RUNNING, sit)
    selector.on_status(0.0, 0, 3.0, 0.01)
    again = selector.step(0.02, RUNNING, sit)
    assert again.tactic == SMASH and again.command is None  # committed: nothing re-sent
    moved = situation(model, [-0.4, -0.2, 0, 0, 0, 0], t0=0.03)
    new = selector.step(0.03, RUNNING, moved)
    assert new.tactic == SMASH and new.command is not None  # no lock: re-planned at once
    assert not np.allclose(new.command.point, first.command.point)


def test_a_smash_re_aimed_at_a_drifting_puck_keeps_its_hit_time(selector, model, settings):
    """A slow puck's prediction drifts: the accepted smash is re-aimed (more than hit_replan_distance off)
    at the same hit time while min_plan_time is left, instead of being pushed smash_lead_time ahead at
    every re-plan (in a game: 17 re-plans over 7 s before the hit); closer to the hit, from now again."""
    first = selector.step(0.0, RUNNING, situation(model, [-0.55, -0.2, 0.15, 0.1, 0, 0])).command
    assert first is not None and first.tactic == SMASH and first.time == pytest.approx(settings.smash_lead_time)
    selector.on_status(0.0, 0, 3.0, 0.01)
    drifted = situation(model, [-0.52, -0.19, 0.12, 0.11, 0, 0], t0=0.2)
    again = selector.step(0.2, RUNNING, drifted).command
    assert again is not None and again.tactic == SMASH and again.time == first.time
    assert not np.allclose(again.point, first.point)
    selector.on_status(0.2, 0, 3.0, 0.21)
    late = first.time - settings.min_plan_time + 0.05
    moved = situation(model, [-0.45, -0.15, 0.1, 0.1, 0, 0], t0=late)
    last = selector.step(late, RUNNING, moved).command
    assert last is not None and last.time == pytest.approx(late + settings.smash_lead_time)


def test_a_smash_at_a_creeping_puck_aims_where_it_will_be_and_stays_with_it(selector, model, settings):
    """A puck creeping at 0.05 m/s (below static_speed, above drift_speed) is taken where the model puts it at
    the hit time, and while it creeps along that path the accepted smash is not re-sent (taken where it lay,
    a game's smash was re-aimed every 0.1 s at a puck creeping at 0.02-0.14 m/s until the possession limit
    ran out); a puck slower than drift_speed is hit where it lies."""
    start = np.array([-0.5, 0.1, 0.04, 0.03, 0.0, 0.0])
    assert settings.drift_speed < 0.05 < settings.static_speed
    first = selector.step(0.0, RUNNING, situation(model, start)).command
    assert first is not None and first.tactic == SMASH
    truth = predict_stepwise(model, start, None, first.time, DT, np.zeros(6)).state
    assert np.linalg.norm(first.puck - truth[:2]) < 1e-3 < np.linalg.norm(first.puck - start[:2]) - 0.02
    selector.on_status(0.0, 0, 3.0, 0.01)
    for t in (0.2, 0.4, 0.6):
        later = predict_stepwise(model, start, None, t, DT, np.zeros(6)).state
        decision = selector.step(t, RUNNING, situation(model, later, t0=t))
        assert decision.tactic == SMASH and decision.command is None, t
    resting = TacticsSelector(selector.s, selector.reach, selector.shots)
    still = resting.step(0.0, RUNNING, situation(model, [-0.5, 0.1, 0.005, 0.0, 0, 0])).command
    assert np.allclose(still.puck, [-0.5, 0.1])


def _with_velocity_std(sit, std_x, std_y, corr=0.0):
    from dataclasses import replace
    return replace(sit, velocity_covariance=np.array([[std_x ** 2, corr * std_x * std_y],
                                                      [corr * std_x * std_y, std_y ** 2]]))


def test_a_speed_within_its_own_noise_is_rest(model, settings):
    """Situation.resting: at most drift_speed, or at most drift_significance standard deviations of the
    velocity along its direction (the tracker's covariance: about 0.02 m/s in its hand regime)."""
    sit = situation(model, [-0.5, 0.1, 0.03, 0.0, 0.0, 0.0])
    assert sit.speed_std == 0.0 and not sit.resting(settings.drift_speed, settings.drift_significance)
    noisy = _with_velocity_std(sit, 0.02, 0.001)
    assert noisy.speed_std == pytest.approx(0.02) and noisy.resting(0.01, 3.0) and not noisy.resting(0.01, 1.0)
    across = _with_velocity_std(sit, 0.001, 0.02)  # uncertain across the motion only: the speed is known
    assert across.speed_std == pytest.approx(0.001) and not across.resting(0.01, 3.0)
    at_rest = _with_velocity_std(situation(model, [-0.5, 0.1, 0.0, 0.0, 0.0, 0.0]), 0.001, 0.02)
    assert at_rest.speed_std == pytest.approx(0.02) and at_rest.resting(0.0, 0.0)
    held = noisy.expected(0.8, 0.01, 3.0)
    assert np.allclose(held[:4], [-0.5, 0.1, 0.0, 0.0]) and noisy.expected(0.8, 0.01, 1.0)[0] > -0.49


def test_the_situation_takes_the_estimates_velocity_covariance_and_refuses_a_malformed_one(model):
    state = np.array([-0.5, 0.1, 0.03, 0.0, 0.0, 0.0])
    pred = predict_fast(model, state, None, 0.5, DT, np.zeros(6), sample_every=6)
    times, states = [t for t, _, _ in pred.samples], np.array([s for _, s, _ in pred.samples])
    cov = np.diag([1e-8, 1e-8, 4e-4, 9e-4, 1e-4, 1.0])
    cov[2, 3] = cov[3, 2] = 1e-4
    for robot in ("iiwa_front", "iiwa_back"):  # a rotation by pi leaves the velocity block as it is
        sit = build_situation(robot, 0.0, state, times, states, covariance=cov.ravel().tolist())
        assert np.allclose(sit.velocity_covariance, [[4e-4, 1e-4], [1e-4, 9e-4]])
    assert np.all(build_situation("iiwa_front", 0.0, state, times, states).velocity_covariance == 0.0)
    for bad in (np.zeros(35), np.full(36, math.nan)):
        with pytest.raises(ValueError, match="covariance must be 36 finite values"):
            build_situation("iiwa_front", 0.0, state, times, states, covariance=bad)


def test_a_smash_at_a_puck_whose_speed_is_noise_aims_where_it_lies(selector, model, settings):
    """A puck estimated at 0.03 m/s with a velocity std of 0.02 m/s (the tracker's hand regime: just set
    down) is hit where it lies; with the std of a settled estimate (1 mm/s) where it will be. In the
    strategy test such estimates re-aimed a straight Smash every 10 ms and missed the centre by up to 6 cm."""
    start = [-0.5, 0.1, 0.02, 0.02, 0.0, 0.0]
    sit = situation(model, start)
    noisy = TacticsSelector(selector.s, selector.reach, selector.shots).step(
        0.0, RUNNING, _with_velocity_std(sit, 0.02, 0.02)).command
    settled = TacticsSelector(selector.s, selector.reach, selector.shots).step(
        0.0, RUNNING, _with_velocity_std(sit, 0.001, 0.001)).command
    assert noisy.tactic == SMASH == settled.tactic
    assert np.allclose(noisy.puck, start[:2]) and np.linalg.norm(settled.puck - start[:2]) > 0.01


def test_a_slow_puck_leaving_the_smash_area_toward_the_line_is_smashed_beyond_it(model, settings):
    """A puck at 0.2 m/s leaving the smash area toward the centre line is smashed where it will be, beyond the
    area's far edge and still moving (faster than static_speed); held to a puck at rest there (the rule
    before beyond_smash_speed), the robot waits while it creeps on into the neutral zone."""
    start = [settings.x_at_depth(0.6), 0.05, 0.2, 0.02, 0.0, 0.0]
    decisions = {}
    for beyond in (settings.static_speed, settings.smash_puck_speed):
        sel = selector_with(model, settings, beyond_smash_speed=beyond, smash_chase_speed=0.0)
        sit = situation(model, start, horizon=1.5)
        decisions[beyond] = (sel.step(0.0, RUNNING, sit), sit)
    assert decisions[settings.static_speed][0].tactic == READY
    smash, sit = decisions[settings.smash_puck_speed]
    assert smash.tactic == SMASH and smash.command is not None
    at_hit = sit.expected(smash.command.time, settings.drift_speed)
    assert settings.beyond_smash_area(smash.command.puck[0])
    assert math.hypot(at_hit[2], at_hit[3]) > settings.static_speed


def test_a_puck_leaving_faster_than_smash_puck_speed_is_chased_and_the_shot_scores(model, settings):
    """A puck sliding away from the own goal at 0.9 m/s, still too fast for smash_puck_speed at the hit time,
    is smashed with smash_chase_speed (where the prediction puts it then, moving); the contact the command
    makes (the mallet's velocity on the moving puck) sends it into the opponent's goal by the step-by-step
    reference predictor. With the chase off (0) the robot waits while it leaves; a puck coming at the goal
    as fast, or leaving from behind the mallet (it would cross the mallet's way), is not chased."""
    start = [settings.x_at_depth(0.3), -0.1, 0.85, 0.25, 0.0, 0.0]
    sit = situation(model, start, horizon=1.5)
    ready = settings.point(settings.ready_point)
    chased = selector_with(model, settings).step(0.0, RUNNING, sit, ready, np.zeros(2))
    assert chased.tactic == SMASH and chased.command is not None, chased.reason
    c = chased.command
    at_hit = sit.expected(c.time, settings.drift_speed)
    assert math.hypot(at_hit[2], at_hit[3]) > settings.smash_puck_speed
    assert np.allclose(c.puck, at_hit[:2])
    normal = (at_hit[:2] - c.point) / np.linalg.norm(at_hit[:2] - c.point)
    after = puck_after_contact(at_hit, c.velocity, normal, settings.mallet_restitution, settings.mallet_friction,
                               model.table.puck_radius)
    line = settings.table.length / 2 - model.table.puck_radius
    path = predict_stepwise(model, after, None, settings.shot_horizon, DT, np.zeros(6), sample_every=1)
    crossing = next(s for _, s, _ in path.samples if s[0] >= line - 0.01)
    assert abs(crossing[1]) < model.table.goal_mouth
    off = selector_with(model, settings, smash_chase_speed=0.0).step(0.0, RUNNING, sit, ready, np.zeros(2))
    assert off.tactic == READY
    for state in ([settings.x_at_depth(0.6), -0.1, -0.85, 0.25, 0.0, 0.0],   # coming
                  [settings.x_at_depth(0.08), 0.2, 0.85, -0.25, 0.0, 0.0]):  # leaving from behind the mallet
        decision = selector_with(model, settings).step(0.0, RUNNING, situation(model, state, horizon=1.5), ready,
                                                       np.zeros(2))
        assert decision.tactic != SMASH, state


def test_a_smash_whose_way_to_the_strike_meets_a_puck_leaving_from_behind_the_mallet_is_not_played(model, settings):
    """A puck at 0.3 m/s leaving from behind the waiting mallet along the table's axis: judged against the puck
    at the hit time only, a straight smash is played, and the mallet's way to its run-up start (the planner's
    reach) meets the puck on its path (the step-by-step reference predictor) before the strike; with
    smash_checks_way no such smash is played. A puck ahead of the mallet is still smashed with the check."""
    ready = settings.point(settings.ready_point)
    start = [settings.x_at_depth(0.05), 0.0, 0.3, 0.0, 0.0, 0.0]
    sit = situation(model, start, horizon=1.5)
    unchecked = selector_with(model, settings, smash_checks_way=False)
    blind = unchecked.step(0.0, RUNNING, sit, ready, np.zeros(2))
    assert blind.tactic == SMASH, blind.reason
    c = blind.command
    speed = float(np.linalg.norm(c.velocity))
    run_up = unchecked.reach.run_up_start(c.point, c.velocity / speed, speed)
    strike_start = c.time - 2.0 * float(np.linalg.norm(c.point - run_up)) / speed
    path = predict_stepwise(model, np.asarray(start, float), None, strike_start, DT, np.zeros(6), sample_every=1)
    times = np.array([t for t, _, _ in path.samples])
    puck = np.array([s[:2] for _, s, _ in path.samples])
    way, _ = unchecked.reach.reach_way(ready, np.zeros(2), run_up, times)
    assert np.min(np.hypot(*(puck - way).T)) < settings.contact_distance
    checked = selector_with(model, settings).step(0.0, RUNNING, sit, ready, np.zeros(2))
    assert checked.tactic != SMASH, checked.reason
    ahead = situation(model, [settings.x_at_depth(0.4), 0.0, 0.3, 0.0, 0.0, 0.0], horizon=1.5)
    assert selector_with(model, settings).step(0.0, RUNNING, ahead, ready, np.zeros(2)).tactic == SMASH


def test_a_prepare_re_aimed_at_a_creeping_puck_keeps_its_hit_time(selector, model, settings):
    """The same for Prepare: a creeping puck's push is re-aimed when it strays from where it was expected (a
    game re-planned one 14 times in a row at 0.03 m/s) at the same time."""
    first = selector.step(0.0, RUNNING, situation(model, [-0.85, 0.3, 0.0, 0.0, 0, 0])).command
    assert first is not None and first.tactic == PREPARE and first.time == pytest.approx(settings.smash_lead_time)
    selector.on_status(0.0, 0, 3.0, 0.01)
    crept = situation(model, [-0.84, 0.3, 0.03, 0.0, 0, 0], t0=0.3)
    again = selector.step(0.3, RUNNING, crept).command
    assert again is not None and again.tactic == PREPARE and again.time == first.time


def test_switches_as_soon_as_the_situation_changes(selector, model):
    sit = situation(model, [-0.5, 0.1, 0, 0, 0, 0])
    selector.step(0.0, RUNNING, sit)
    selector.on_status(0.0, 0, 3.0, 0.01)
    attacked = situation(model, [0.6, 0.05, -1.8, -0.05, 0, 0], t0=0.05)  # (a new puck state, e.g. after a reset)
    assert selector.step(0.05, RUNNING, attacked).tactic == REPEL


def test_planner_answers_steer_the_next_command(selector, model):
    sit = situation(model, [-0.5, 0.1, 0, 0, 0, 0])
    first = selector.step(0.0, RUNNING, sit).command
    selector.on_status(0.0, TOO_FAST, 1.0, 0.01)
    capped = selector.step(0.02, RUNNING, sit).command
    assert capped is not None and np.linalg.norm(capped.velocity) <= 0.95 * 1.0 + 1e-9
    selector.on_status(0.02, TOO_LATE, math.nan, 0.03)
    later = selector.step(0.04, RUNNING, sit).command
    assert later.time - 0.04 > first.time - 0.0 + 0.1
    selector.on_status(0.04, 4, math.nan, 0.05)  # unreachable: smash blocked for retry_delay
    assert selector.step(0.06, RUNNING, sit).tactic != SMASH


def test_a_cut_refused_as_too_late_meets_the_puck_later_on_its_path(selector, model, settings):
    """"Too late" for a Cut (its time is the puck's, not its own) asks for a contact at least
    lead_time_step later instead of blocking the Cut and asking for the same contact again (a puck near
    enough that the best contact is one of the first: none of the later ones is better)."""
    sit = situation(model, [0.2, 0.0, -1.2, 0.6, 0, 0], horizon=2.0)
    selector.force(CUT)
    first = selector.step(0.0, RUNNING, sit)
    assert first.tactic == CUT and first.command is not None, first.reason
    selector.on_status(0.0, TOO_LATE, math.nan, 0.01)
    later = selector.step(0.02, RUNNING, sit)
    assert later.tactic == CUT and later.command is not None, later.reason
    early = settings.cut_arrive_early
    def contact(c):
        return c.time + (0.0 if c.is_hit else early)
    assert contact(first.command) < settings.min_plan_time + settings.lead_time_step  # the premise
    assert contact(later.command) - 0.02 >= settings.min_plan_time + settings.lead_time_step - 1e-9
    assert contact(later.command) > contact(first.command)
    selector.on_status(0.02, 4, math.nan, 0.03)  # unreachable: the Cut is blocked for retry_delay
    assert selector.step(0.04, RUNNING, sit).command is None


def test_a_cut_refused_as_too_late_is_not_asked_for_the_same_contact_again(selector, model, settings):
    """A refused contact that lay later than the earliest allowed one: the next contact lies at least
    lead_time_step after the refused one (the lead grew from the earliest allowed contact alone, so the same
    contact was asked again until the lead passed it)."""
    sit = situation(model, [0.2, 0.0, -1.2, 0.3, 0, 0], horizon=2.0)
    selector.force(CUT)
    first = selector.step(0.0, RUNNING, sit).command
    assert first is not None and first.is_hit and first.slack > settings.lead_time_step  # the premise
    selector.on_status(0.0, TOO_LATE, math.nan, 0.01)
    later = selector.step(0.02, RUNNING, sit).command
    assert later is not None and later.tactic == CUT
    assert later.time >= first.time + settings.lead_time_step + 0.02 - 1e-9


def test_a_running_cut_is_kept_when_its_re_plan_is_refused(selector, model, settings):
    """A Cut under way whose re-plan (the prediction moved by more than a re-plan's tolerance) was refused as
    too late is kept while the predicted puck still passes within contact_distance of the planned contact;
    falling back to Ready sent the arm away from the puck's path (in games too). A prediction that moved
    the puck farther than that falls back to Ready."""
    state = [0.3, 0.2, -1.5, 0.9, 0, 0]
    first = selector.step(0.0, RUNNING, situation(model, state, horizon=1.5))
    assert first.tactic == CUT and first.command is not None, first.reason
    selector.on_status(0.0, 0, math.nan, 0.0)  # accepted
    moved = situation(model, [0.3, 0.2 + 0.02, -1.5, 0.9, 0, 0], t0=0.02, horizon=1.5)
    replan = selector.step(0.02, RUNNING, moved)
    assert replan.tactic == CUT and replan.command is not None  # not committed: it moved 2 cm
    selector.on_status(0.02, TOO_LATE, math.nan, 0.02)
    kept = selector.step(0.04, RUNNING, moved)
    assert kept.tactic == CUT and kept.command is None and "kept" in kept.reason, kept.reason
    far = situation(model, [0.3, 0.2 + 0.25, -1.5, 0.9, 0, 0], t0=0.06, horizon=1.5)
    selector.blocked[CUT] = math.inf  # nothing new for the Cut: only the kept command or Ready remain
    assert selector.step(0.06, RUNNING, far).tactic == READY


CROSSING = [0.3, 0.2, -1.5, 0.9, 0, 0]  # a puck crossing the table toward the front robot's goal


def _accepted_cut(selector, model):
    """A Cut on the CROSSING puck (a moving contact), accepted at t = 0."""
    selector.force(CUT)
    first = selector.step(0.0, RUNNING, situation(model, CROSSING, horizon=1.5)).command
    assert first is not None and first.is_hit
    selector.on_status(0.0, ACCEPTED, math.nan, 0.0)
    return first


def _nudged(model, dy, t0):
    """The CROSSING puck seen at ``t0`` [s] where its prediction puts it, ``dy`` [m] to the side."""
    state = situation(model, CROSSING, horizon=1.5).at(t0) + np.array([0.0, dy, 0, 0, 0, 0])
    return situation(model, state, t0=t0, horizon=1.5)


def test_an_accepted_hit_is_moved_with_the_puck_keeping_its_contact_normal(selector, model, settings):
    """Below hit_replan_distance, the puck predicted at the hit time moved hit_correction_distance or more:
    the same command (time, velocity), shifted by exactly that displacement, is sent, so the contact normal
    stays the planned one; the shifted command becomes the one under way; a smaller move sends nothing."""
    first = _accepted_cut(selector, model)
    nudged = _nudged(model, 0.003, 0.02)
    shift = nudged.expected(first.time, settings.drift_speed, settings.drift_significance)[:2] - first.puck
    assert settings.hit_correction_distance <= np.hypot(*shift) <= settings.hit_replan_distance  # the premise
    d = selector.step(0.02, RUNNING, nudged)
    moved = d.command
    assert d.tactic == CUT and moved is not None and moved.time == first.time
    np.testing.assert_allclose(moved.velocity, first.velocity)
    np.testing.assert_allclose(moved.point - first.point, shift, atol=1e-12)
    np.testing.assert_allclose(moved.puck - moved.point, first.puck - first.point, atol=1e-12)  # the normal
    selector.on_status(0.02, ACCEPTED, math.nan, 0.02)
    assert selector.executing is moved
    assert selector.step(0.04, RUNNING, _nudged(model, 0.003, 0.04)).command is None
    assert selector.step(0.06, RUNNING, _nudged(model, 0.0035, 0.06)).command is None  # 0.5 mm more


def test_a_refused_shift_with_the_puck_leaves_the_hit_under_way_as_it_was(selector, model, settings):
    """The planner refuses the shifted command (here "too late"): the command under way stays the accepted
    one and committed (no re-plan, no later contact asked for), and it is not shifted again."""
    first = _accepted_cut(selector, model)
    assert selector.step(0.02, RUNNING, _nudged(model, 0.003, 0.02)).command is not None
    selector.on_status(0.02, TOO_LATE, math.nan, 0.02)
    assert selector.executing is first and selector.lead_extra == 0.0
    for k, dy in enumerate((0.003, 0.004), start=2):
        d = selector.step(0.02 * k, RUNNING, _nudged(model, dy, 0.02 * k))
        assert d.tactic == CUT and d.command is None, d.reason
    assert selector.sent.proposal is first and selector.sent.accepted


@pytest.mark.parametrize("dy, corrects, moves", [(0.02, True, True), (0.02, False, False), (0.12, True, False)])
def test_too_late_to_plan_anew_a_cut_moves_with_the_puck_up_to_a_contact_distance(model, settings, dy, corrects,
                                                                                   moves):
    """Within min_plan_time of a Cut's contact no Cut is planned anew: a puck moved there by more than
    hit_replan_distance but at most a contact distance is followed by the command under way (shifted as
    below the re-plan's tolerance), with hit_correction_distance on; farther, or with it off, no shift."""
    selector = selector_with(model, settings, hit_correction_distance=settings.hit_correction_distance if corrects
                             else 0.0)
    first = _accepted_cut(selector, model)
    t0 = first.time - (settings.min_plan_time + settings.hit_correction_time) / 2
    nudged = _nudged(model, dy, t0)
    shift = nudged.expected(first.time, settings.drift_speed, settings.drift_significance)[:2] - first.puck
    assert settings.hit_replan_distance < np.hypot(*shift)  # the premise
    assert (np.hypot(*shift) <= settings.contact_distance) == (dy < settings.contact_distance)
    d = selector.step(t0, RUNNING, nudged)
    shifted = (d.command is not None and d.command.time == first.time
               and np.allclose(d.command.velocity, first.velocity)
               and np.allclose(d.command.point - first.point, shift, atol=1e-12))
    assert shifted == moves, d.reason


def test_a_hit_moves_with_the_puck_only_when_asked_and_not_close_to_its_time(model, settings):
    selector = selector_with(model, settings, hit_correction_distance=0.0)
    _accepted_cut(selector, model)
    assert selector.step(0.02, RUNNING, _nudged(model, 0.003, 0.02)).command is None
    for correction_time, moves in ((settings.hit_correction_time, False), (0.0, True)):
        selector = selector_with(model, settings, hit_correction_time=correction_time)
        first = _accepted_cut(selector, model)
        late = first.time - settings.hit_correction_time + 0.01
        d = selector.step(late, RUNNING, _nudged(model, 0.003, late))
        assert d.tactic == CUT and (d.command is not None) == moves, d.reason


PARKED = np.array([-0.82, -0.09])  # [m] own frame: a Cut's mallet parked beside the goal mouth (a game's)


def _parked_cut(sit) -> Proposal:
    """A parked Cut at PARKED planned for the puck where ``sit``'s path passes nearest to it."""
    path = np.vstack([sit.puck[None, :2], sit.states[:, :2]])
    nearest = path[int(np.argmin(np.hypot(*(path - PARKED).T)))]
    return Proposal(CUT, PARKED, np.zeros(2), 0.3, "cut", puck=nearest)


@pytest.mark.parametrize("state, meets", [([-0.331, 0.422, -2.32, -2.06, 0, 0], True),
                                          ([-0.30, -0.09, -2.0, 0.0, 0, 0], True),
                                          ([-0.30, 0.20, -2.0, 0.0, 0, 0], False)])
def test_first_meeting_is_where_the_puck_first_touches_the_mallet(model, settings, state, meets):
    """The puck state where it first comes within a contact distance of the parked mallet, between the
    prediction's samples (50 ms, 10 cm apart here), with the normal from the mallet to it; None for a path
    passing by."""
    sit = situation(model, state, horizon=0.6)
    meeting = first_meeting(_parked_cut(sit), sit, settings.contact_distance, 0.6)
    assert (meeting is not None) == meets
    if meets:
        puck, normal = meeting
        assert np.hypot(*(puck[:2] - PARKED)) == pytest.approx(settings.contact_distance, abs=2e-3)
        np.testing.assert_allclose(normal, (puck[:2] - PARKED) / np.hypot(*(puck[:2] - PARKED)), atol=1e-9)
        assert float(puck[2:4] @ normal) < 0.0  # closing in


def test_a_kept_cut_whose_contact_now_turns_the_puck_into_the_own_goal_is_dropped(model, settings):
    """A game's own goal: a fast puck after a rim impact, predicted to pass the parked mallet's side, meets
    it glancing and goes into the goal (the Cut under way had been kept, its re-plan refused). With
    keep_checks_outcome the command is no longer kept (the selector re-decides); a puck met head-on is."""
    glancing = situation(model, [-0.331, 0.422, -2.32, -2.06, 0, 0], horizon=0.6)
    head_on = situation(model, [-0.30, -0.09, -2.0, 0.0, 0, 0], horizon=0.6)
    for checks, kept_glancing in ((True, False), (False, True)):
        selector = selector_with(model, settings, keep_checks_outcome=checks)
        for sit, kept in ((glancing, kept_glancing), (head_on, True)):
            selector.executing = _parked_cut(sit)
            assert (selector._still_valid(0.0, sit) is not None) == kept, (checks, sit.puck)


def test_smash_is_not_played_when_the_approach_would_knock_the_puck(selector, model, settings):
    from air_hockey_agent.core.game.tactics.base import Context
    from air_hockey_agent.core.game.tactics.smash import Smash
    sit = situation(model, [-0.5, -0.25, 0, 0, 0, 0])
    smash, reach = Smash(), selector.reach
    shot = selector.shots.aim(sit.puck, "left_bank")
    start = reach.run_up_start(shot.hit_point, shot.direction, shot.mallet_speed)
    beyond = sit.puck[:2] + (sit.puck[:2] - start)  # the mallet on the far side: its way runs through the puck
    blocked = Context(0.0, settings, reach, selector.shots, mallet=beyond, variant="left_bank")
    assert smash.propose(sit, blocked) is None
    behind = Context(0.0, settings, reach, selector.shots, mallet=start, variant="left_bank")
    assert smash.propose(sit, behind) is not None
    free = Context(0.0, settings, reach, selector.shots, mallet=beyond)
    chosen = smash.propose(sit, free)
    assert chosen is not None and "left_bank" not in chosen.reason  # another variant with a clear way


def test_a_hit_refused_for_joint_limits_is_asked_again_at_the_speed_the_planner_names(selector, model, settings):
    sit = situation(model, [-0.5, 0.1, 0, 0, 0, 0])
    first = selector.step(0.0, RUNNING, sit).command
    selector.on_status(0.0, LIMITS, 1.2, 0.01)  # "the strike needs ... % of its acceleration limit", 1.2 m/s keeps it
    named = selector.step(0.02, RUNNING, sit).command
    assert np.linalg.norm(named.velocity) == pytest.approx(settings.speed_cap_fraction * 1.2, abs=1e-6)
    selector.on_status(0.02, LIMITS, 3.5, 0.03)  # no limit-keeping speed: the arm's fastest hit, above the one asked
    slower = selector.step(0.04, RUNNING, sit).command
    assert np.linalg.norm(slower.velocity) == pytest.approx(settings.limits_slowdown * np.linalg.norm(named.velocity),
                                                            abs=1e-6)
    assert np.linalg.norm(first.velocity) > np.linalg.norm(named.velocity)


def test_a_speed_cap_never_asks_for_more_than_the_fastest_allowed_hit(selector, settings):
    puck = np.array([-0.5, 0.1, 0, 0, 0, 0])
    capped = selector.shots.aim(puck, "straight", speed=10.0)
    assert capped is not None and capped.mallet_speed <= settings.max_hit_speed + 1e-9


def test_the_puck_physics_file_is_read_and_a_bad_one_is_a_one_line_error(tmp_path):
    """puck_params_file: the tactics' shots use that file's physics; a missing or malformed one names the
    parameter and the file."""
    from air_hockey_agent.params import ParameterFileError
    from air_hockey_agent.sim.params import load_sim_params
    from air_hockey_agent.tracker_params import load_tracker_params
    assert puck_model_for_tactics(str(config_file(SIM_TABLE_FILE))).params.damping == load_sim_params()["surface_damping"]
    assert puck_model_for_tactics("").params.damping == load_tracker_params()["damping"]
    bad = tmp_path / "bad.yaml"
    bad.write_text("/**/puck_tracker:\n  ros__parameters:\n    damping: [\n")
    for path in (tmp_path / "missing.yaml", bad):
        with pytest.raises(ParameterFileError, match=rf"^parameter 'puck_params_file': .*{path.name}") as info:
            puck_model_for_tactics(str(path))
        assert "\n" not in str(info.value)


def test_path_gap_is_the_distance_to_the_nearest_segment():
    """Closed forms: a perpendicular foot inside a segment, a nearest end point, a single point, a
    zero-length segment; random polylines against a dense sampling of their segments."""
    path = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]])
    assert path_gap(path, np.array([0.5, 0.3])) == pytest.approx(0.3)
    assert path_gap(path, np.array([1.4, 0.5])) == pytest.approx(0.4)
    assert path_gap(path, np.array([-0.3, -0.4])) == pytest.approx(0.5)  # before the first end: 3-4-5
    assert path_gap(path[:1], np.array([0.3, 0.4])) == pytest.approx(0.5)
    assert path_gap(np.array([[0.2, 0.2], [0.2, 0.2]]), np.array([0.2, 0.5])) == pytest.approx(0.3)
    rng = np.random.default_rng(7)
    for _ in range(20):
        poly, point = rng.normal(size=(5, 2)), rng.normal(size=2)
        s = np.linspace(0.0, 1.0, 2001)[:, None]
        dense = np.vstack([a + s * (b - a) for a, b in zip(poly[:-1], poly[1:])])
        assert path_gap(poly, point) == pytest.approx(np.min(np.hypot(*(dense - point).T)), abs=1e-3)


def _first_contact_normal(relative_position: np.ndarray, relative_velocity: np.ndarray, distance: float):
    """Where a puck at ``relative_position`` (to the mallet) moving at ``relative_velocity`` first touches a
    mallet ``distance`` away (ray against circle): the unit normal, or None when it passes by."""
    w = relative_velocity / np.linalg.norm(relative_velocity)
    b = relative_position @ w
    disc = b * b - (relative_position @ relative_position - distance ** 2)
    if disc < 0.0:
        return None
    return (relative_position + (-b - math.sqrt(disc)) * w) / distance


@pytest.mark.parametrize("angle_deg", [0.0, 25.0, -50.0, 70.0])
def test_a_cut_contact_turns_as_the_puck_meets_the_mallet_off_sideways(settings, angle_deg):
    """offset_turns against geometry: the puck's way shifted cut_offset_noise sideways meets the mallet at the
    normal the turns give (less the aim noise); a glancing contact turns most, and one the offset lets
    pass turns to 90 deg from head-on (no impulse)."""
    from air_hockey_agent.core.game.tactics.cut import _rotate, offset_turns
    relative = np.array([-2.0, 0.7])
    head_on = -relative / np.linalg.norm(relative)
    n = _rotate(head_on, math.radians(angle_deg))
    lower, upper = offset_turns(relative, n, settings)
    lat = np.array([-relative[1], relative[0]]) / np.linalg.norm(relative)
    turns = []
    for side in (-1.0, 1.0):
        start = n * settings.contact_distance - 0.5 * relative + side * settings.cut_offset_noise * lat
        normal = _first_contact_normal(start, relative, settings.contact_distance)
        if normal is None:
            turns.append(math.copysign(math.pi / 2, angle_deg) - math.radians(angle_deg))  # passes by
        else:
            turns.append(math.atan2(n[0] * normal[1] - n[1] * normal[0], n @ normal))
    assert sorted(turns) == pytest.approx([lower + settings.aim_noise, upper - settings.aim_noise], abs=1e-9)
    spread = upper - lower - 2 * settings.aim_noise
    head_on_spread = 2 * math.asin(settings.cut_offset_noise / settings.contact_distance)
    assert spread == pytest.approx(head_on_spread, abs=1e-9) if angle_deg == 0.0 else spread > head_on_spread


def test_a_contact_a_sideways_offset_may_turn_into_the_goal_ranks_below_a_safe_one(settings):
    """lazy_candidate: a candidate whose contact turned by a risk is rejected ranks below every safe one, even
    one with a smaller margin; among safe ones the larger margin first; an aimed contact rejected is dropped."""
    from air_hockey_agent.core.game.tactics.outcome import LazyRanked, lazy_candidate
    def candidate(name, margin, goal_turn):  # the contact turned by goal_turn enters the goal
        return lazy_candidate(settings, lambda turn: (turn, margin - abs(turn)), lambda push: push[0] == goal_turn,
                              lambda push: push[1], lambda score: (score,), lambda push: (name, push),
                              risks=(-0.3, 0.3))
    ranked = LazyRanked([candidate("risky", 5.0, 0.3), candidate("safe", 1.0, None)])
    assert [ranked.item(i)[0] for i in range(2)] == ["safe", "risky"]
    ranked = LazyRanked([candidate("wide", 5.0, None), candidate("safe", 1.0, None)])
    assert [ranked.item(i)[0] for i in range(2)] == ["wide", "safe"]
    assert candidate("aimed_in", 5.0, 0.0) is None  # the aimed contact itself enters the goal: never played


def test_a_contact_whose_prediction_ends_in_the_goal_enters_it(selector, model, settings):
    """A puck crossing the sampled goal line just outside the mouth but still turning in scores in the model
    (it ends beyond scored_x): such a contact enters the goal."""
    from air_hockey_agent.core.game.shots import NO_Q
    table = model.table
    puck = np.array([-0.80, -0.236, -1.0, 1.0, 0.0, 0.0])
    line = selector.shots.line
    pred = predict_fast(model, puck, None, 1.5, DT, NO_Q, lines=(-line,))
    assert abs(pred.crossings[-line].y) > table.goal_mouth and pred.state[0] < -table.scored_x  # the case
    push = selector.shots.contact(puck, np.array([-0.7071, 0.7071]), np.zeros(2), settings.prepare_end_speed,
                                  settings.prepare_horizon)  # the mallet behind the puck: no impulse
    assert np.allclose(push.after[:4], puck[:4]) and push.enters_goal
