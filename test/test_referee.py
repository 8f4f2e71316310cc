"""Referee rules (core.game.referee): goals, puck out/lost/stuck, possession, robot faults, resume."""
import numpy as np
import pytest

from air_hockey_agent.core.game.referee import (BACK, EVENT_GOAL_BACK, EVENT_GOAL_FRONT, EVENT_PUCK_OUT,
                                           EVENT_PUCK_STUCK, EVENT_RESET, EVENT_ROBOT_FAULT, FRONT, PAUSED,
                                           RUNNING, STOPPED, Referee, RefereeSettings)
from air_hockey_agent.params import load_node_params
from air_hockey_agent.referee_params import PARAM_FILES, REFEREE_PARAMS

HOME = {FRONT: (-0.84, 0.0), BACK: (0.84, 0.0)}  # mallets at home, near their goals


@pytest.fixture
def settings():
    return RefereeSettings.from_params(load_node_params(PARAM_FILES, "/referee", REFEREE_PARAMS))


@pytest.fixture
def referee(settings):
    ref = Referee(settings, np.random.default_rng(0))
    ref.observe_puck(0.0, 0.3, 0.1)
    assert ref.start(0.0) == (True, "game running")
    return ref


def run(ref, t0, t1, path, mallets=HOME, rate=100.0):
    """Observe the puck along path(t) and update from t0 to t1; the first decision and its time."""
    for t in np.arange(t0, t1, 1.0 / rate):
        ref.observe_puck(t, *path(t))
        decision = ref.update(t, mallets)
        if decision is not None:
            return t, decision
    return None, None


def test_start_needs_a_puck_on_the_table(settings):
    ref = Referee(settings, np.random.default_rng(0))
    ok, message = ref.start(0.0)
    assert not ok and "no puck" in message
    ref.observe_puck(0.0, 0.0, 0.0)
    assert ref.start(0.5)[0] and ref.state.status == RUNNING


@pytest.mark.parametrize("direction, scorer, event", [(-1, BACK, EVENT_GOAL_BACK), (1, FRONT, EVENT_GOAL_FRONT)])
def test_a_puck_in_a_goal_scores_for_the_other_robot_and_comes_back_on_the_conceding_side(
        referee, settings, direction, scorer, event):
    t, decision = run(referee, 0.0, 2.0, lambda t: (direction * (0.5 + 1.0 * t), 0.05))
    assert decision.event == event and referee.state.score[scorer] == 1
    assert referee.state.score[FRONT if scorer == BACK else BACK] == 0
    crossed = (settings.table.length / 2 + settings.goal_margin - 0.5) / 1.0
    assert t == pytest.approx(crossed + (settings.confirm_frames - 1) / 100.0, abs=0.011)  # poses at 100 Hz
    assert np.sign(decision.reset_puck[0]) == direction  # the conceding robot's half, where the puck went in
    assert referee.state.status == PAUSED


def test_a_puck_over_the_rim_beside_the_goal_is_out_not_a_goal(referee):
    _, decision = run(referee, 0.0, 2.0, lambda t: (0.5 + t, 0.3))
    assert decision.event == EVENT_PUCK_OUT and referee.state.score == {FRONT: 0, BACK: 0}


@pytest.mark.parametrize("glitch", [(0.4, 0.584), (-0.99, 0.02)])
def test_one_glitched_pose_beyond_a_rim_or_goal_line_is_no_event(referee, settings, glitch):
    """A game's puck bounced off a long rim and one mocap pose put it 6 cm beyond (a marker glitch): that was
    "puck off the table". Now a goal or a puck out needs confirm_frames poses in a row; a puck seen
    beyond the line and then no more is gone there after vanish_time."""
    path = lambda t: glitch if abs(t - 0.5) < 1e-9 else (0.4, 0.45)
    assert run(referee, 0.0, 1.0, path) == (None, None)
    assert referee.state.status == RUNNING and referee.state.score == {FRONT: 0, BACK: 0}
    t, decision = run(referee, 1.0, 2.0, lambda t: glitch)
    assert decision is not None and t == pytest.approx(1.0 + (settings.confirm_frames - 1) / 100.0)
    referee.observe_puck(3.0, 0.4, 0.45)
    assert referee.start(3.0)[0]
    referee.observe_puck(3.01, *glitch)  # seen there once, then not at all
    assert referee.update(3.01 + settings.vanish_time / 2, HOME) is None
    assert referee.update(3.01 + settings.vanish_time, HOME) is not None


def test_a_lost_puck_pauses_after_the_timeout(referee, settings):
    referee.observe_puck(0.0, 0.2, 0.0)
    assert referee.update(settings.lost_timeout - 0.01, HOME) is None
    decision = referee.update(settings.lost_timeout + 0.01, HOME)
    assert decision.event == EVENT_PUCK_OUT and "no puck pose" in decision.reason


def test_a_puck_resting_in_the_neutral_zone_is_stuck_but_a_slow_one_is_not(referee, settings):
    t, decision = run(referee, 0.0, 5.0, lambda t: (0.02, 0.1 + 1e-4 * np.sin(30 * t)))
    assert decision.event == EVENT_PUCK_STUCK and t == pytest.approx(settings.stuck_time, abs=0.02)
    ref2 = Referee(settings, np.random.default_rng(0))
    ref2.observe_puck(0.0, -0.07, 0.0)
    ref2.start(0.0)
    _, none = run(ref2, 0.0, 1.4, lambda t: (-0.07 + 0.1 * t, 0.0))  # 0.1 m/s through the zone
    assert none is None


def test_holding_the_puck_on_one_side_too_long_is_a_foul_and_the_puck_goes_to_the_other_robot(referee, settings):
    t, decision = run(referee, 0.0, 30.0, lambda t: (0.5 + 0.2 * np.sin(t), 0.0))
    assert decision.event == EVENT_PUCK_STUCK and "iiwa_back kept the puck" in decision.reason
    assert t == pytest.approx(settings.possession_limit, abs=0.02) and decision.reset_puck[0] < 0


def test_no_possession_foul_while_the_puck_is_in_the_neutral_zone(referee, settings):
    half = settings.neutral_zone_length / 2
    # drifting (never at rest) inside the zone on iiwa_back's side past the limit: no foul
    t, decision = run(referee, 0.0, settings.possession_limit + 5.0,
                      lambda t: (0.5 * half + 0.2 * half * np.sin(t), 0.1 * np.sin(0.5 * t)))
    assert decision is None
    # the clock kept running: the foul comes as soon as the puck leaves the zone
    t0 = settings.possession_limit + 5.0
    t, decision = run(referee, t0, t0 + 2.0, lambda t: (0.6 * half + (t - t0), 0.0))
    assert decision.event == EVENT_PUCK_STUCK and "iiwa_back kept the puck" in decision.reason
    assert t == pytest.approx(t0 + 0.4 * half, abs=0.02)


@pytest.mark.parametrize("mallet, what", [((0.1, 0.0), "centre line"), ((-0.5, 0.5), "in the rim")])
def test_a_mallet_where_it_must_not_be_stops_the_game(referee, mallet, what):
    _, decision = run(referee, 0.0, 0.1, lambda t: (0.3, 0.0), mallets={FRONT: mallet, BACK: HOME[BACK]})
    assert decision.event == EVENT_ROBOT_FAULT and what in decision.reason and "iiwa_front" in decision.reason
    assert referee.state.status == STOPPED and not decision.reset_robots


def test_with_restart_after_fault_a_fault_resets_everything_and_play_resumes(settings):
    ref = Referee(settings.__class__(**{**settings.__dict__, "restart_after_fault": True}), np.random.default_rng(1))
    ref.observe_puck(0.0, 0.3, 0.0)
    ref.start(0.0)
    decision = ref.update(0.01, {FRONT: (0.2, 0.0), BACK: HOME[BACK]})
    assert decision.event == EVENT_ROBOT_FAULT and decision.reset_robots and decision.reset_puck is not None
    assert ref.state.status == PAUSED
    ref.observe_puck(settings.pause_duration, *decision.reset_puck)
    assert ref.update(settings.pause_duration - 0.1, HOME) is None and ref.state.status == PAUSED
    ref.update(settings.pause_duration + 0.02, HOME)
    assert ref.state.status == RUNNING


def test_after_a_goal_play_resumes_only_once_the_puck_is_back_on_the_table(referee, settings):
    t, decision = run(referee, 0.0, 2.0, lambda t: (0.5 + t, 0.0))
    later = t + settings.pause_duration + 0.1
    referee.observe_puck(later, 1.2, 0.0)  # still in the goal
    referee.update(later, HOME)
    assert referee.state.status == PAUSED
    referee.observe_puck(later + 0.1, *decision.reset_puck)
    referee.update(later + 0.1, HOME)
    assert referee.state.status == RUNNING and referee.state.score[FRONT] == 1


def test_operator_commands(referee):
    assert referee.pause(1.0)[0] and referee.state.status == PAUSED
    assert referee.update(100.0, HOME) is None and referee.state.status == PAUSED  # an operator pause holds
    referee.observe_puck(100.0, 0.3, 0.0)
    assert referee.start(100.0)[0]
    referee.state.score[FRONT] = 3
    reset = referee.reset(101.0)
    assert reset.event == EVENT_RESET and reset.reset_robots and referee.state.status == STOPPED
    assert referee.state.score[FRONT] == 3  # a reset keeps the score ...
    assert referee.stop(102.0)[0] and referee.state.score == {FRONT: 0, BACK: 0}  # ... stop clears it


def test_reset_points_lie_inside_the_configured_band(settings):
    ref = Referee(settings, np.random.default_rng(3))
    points = np.array([ref._reset_point(None) for _ in range(500)])
    y_max = settings.table.width / 2 - settings.table.puck_radius - settings.reset_y_margin
    assert np.all(np.abs(points[:, 0]) >= settings.reset_x_range[0])
    assert np.all(np.abs(points[:, 0]) <= settings.reset_x_range[1]) and np.all(np.abs(points[:, 1]) <= y_max)
    assert 0.4 < np.mean(points[:, 0] > 0) < 0.6  # both halves
