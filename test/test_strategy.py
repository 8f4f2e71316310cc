"""Strategy test (ROS-free parts): initial states of thesis sec. 4.6 and the success criteria on
hand-made outcome traces, with their boundary cases."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from air_hockey_agent.core.game.strategy.report import summarise
from air_hockey_agent.core.game.strategy.scoring import TrialResult, TrialWatcher
from air_hockey_agent.core.game.strategy.trials import STRATEGIES, TrialSettings, make_trial
from air_hockey_agent.strategy_params import load_strategy_params

HALF = 1.956 / 2


@pytest.fixture(scope="module")
def s():
    return TrialSettings.from_params(load_strategy_params())


def test_initial_states_follow_the_thesis_set_up(s):
    for i in range(50):
        smash = make_trial("smash_left", i, 7, s).state
        assert s.in_smash_area(smash[0], smash[1]) and smash[2:4] == (0.0, 0.0)
        prep = make_trial("prepare", i, 7, s).state
        assert prep[0] < 0 and not s.in_smash_area(prep[0], prep[1])
        for kind in ("cut", "repel"):
            x, y, vx, vy = make_trial(kind, i, 7, s).state[:4]
            assert x == pytest.approx(HALF - s.defend_line) and abs(y) <= s.start_y
            assert math.hypot(vx, vy) == pytest.approx(s.shot_speed) and vx < 0
        x, y, vx, vy = make_trial("repel", i, 7, s).state[:4]
        assert y + vy * (-HALF - x) / vx == pytest.approx(0.0, abs=1e-9)  # aimed at the goal centre


def test_trials_depend_only_on_seed_strategy_and_index(s):
    assert make_trial("cut", 3, 1, s) == make_trial("cut", 3, 1, s)
    assert make_trial("cut", 3, 1, s) != make_trial("cut", 4, 1, s) != make_trial("cut", 3, 2, s)
    with pytest.raises(ValueError):
        make_trial("dribble", 0, 0, s)
    assert len(STRATEGIES) == 7


def test_guard_trials_start_behind_the_ready_line_in_any_direction(s):
    """Guard (ours): a puck between the ready line and the own goal, slower than guard_speed, heading any way."""
    states = [make_trial("guard", i, 3, s).state for i in range(300)]
    depth = np.array([st[0] + HALF for st in states])
    speed = np.array([math.hypot(st[2], st[3]) for st in states])
    assert depth.min() >= s.guard_depth[0] and depth.max() <= s.guard_depth[1]
    assert max(abs(st[1]) for st in states) <= s.table.y_limit - s.guard_rim_margin
    assert speed.max() <= s.guard_speed and speed.min() < 0.1 * s.guard_speed
    toward_goal = sum(st[2] < 0 for st in states)
    assert 100 < toward_goal < 200  # any direction: about half toward the goal
    assert make_trial("guard", 5, 3, s).tactic == "" and make_trial("guard", 5, 3, s).variant == ""  # nothing forced


def test_no_trial_starts_on_the_mallet_waiting_at_the_ready_point(s):
    """With the waiting mallet known (the configured settings: the agent's ready point), a draw within start_gap of
    contact with it is drawn again; every other trial keeps its state. Without it (NaN) nothing is redrawn:
    seed 0's Prepare trials 20, 25, 52 and 56 then start on the mallet."""
    from air_hockey_agent.strategy_params import trial_settings
    known = trial_settings()
    x0, y0 = known.waiting
    assert x0 == pytest.approx(-HALF + 0.16) and y0 == 0.0
    assert known.contact_distance == pytest.approx(0.03165 + 0.04815)  # config/table.yaml puck and mallet radii

    def gap(st):
        return math.hypot(st[0] - x0, st[1] - y0) - known.contact_distance
    for kind in ("smash_straight", "smash_right", "prepare", "guard"):
        for i in range(100):
            plain, kept = make_trial(kind, i, 0, s).state, make_trial(kind, i, 0, known).state
            assert gap(kept) >= known.start_gap
            assert kept == plain or gap(plain) < known.start_gap
    on_mallet = [i for i in range(100) if gap(make_trial("prepare", i, 0, s).state) < known.start_gap]
    assert on_mallet == [20, 25, 52, 56]


def play(trial, s, states, hits=()):
    """Feed a trace that starts at the trial's initial position (the watcher waits for it)."""
    w = TrialWatcher(trial, s)
    x0, y0 = trial.state[:2]
    w.state(states[0][0], x0, y0, *trial.state[2:4])
    for t in hits:
        w.contact(t)
    for t, st in states:
        w.state(t, *st)
        if w.done:
            break
    return w


def test_states_before_the_puck_is_set_are_ignored(s):
    trial = make_trial("repel", 0, 0, s)
    w = TrialWatcher(trial, s)
    w.state(0.0, 0.6, 0.0, 0.0, 0.0)  # the parked puck, at rest: not this trial's
    w.contact(0.0)
    assert not w.done and w.t0 is None and not w.result().hit


def straight(t0, t1, x0, y0, vx, vy, dt=0.01):
    return [(t, (x0 + vx * (t - t0), y0 + vy * (t - t0), vx, vy)) for t in np.arange(t0, t1, dt)]


def test_smash_scores_only_with_a_goal_and_reports_the_offset(s):
    trial = make_trial("smash_straight", 0, 0, s)
    w = play(trial, s, straight(0.0, 2.0, -0.5, 0.0, 3.0, 0.03), hits=[0.0])
    r = w.result()
    assert w.done and r.goal and r.success and r.offset == pytest.approx(0.03 * (HALF - 0.03165 - 0.005 + 0.5) / 3, abs=2e-3)
    miss = play(trial, s, straight(0.0, 5.0, -0.5, 0.0, 0.1, 0.0) , hits=[0.0]).result()
    assert not miss.success and "after the hit" in miss.reason


def test_cut_success_needs_rest_in_the_smash_area(s):
    trial = make_trial("cut", 0, 0, s)
    inside = play(trial, s, [(0.0, trial.state[:4]), (0.01, (-0.5, 0.0, 0.0, 0.0))], hits=[0.0]).result()
    assert inside.success and inside.partial
    x_edge = -HALF + s.smash_depth[1]
    just_out = play(trial, s, [(0.0, trial.state[:4]), (0.01, (x_edge + 0.001, 0.0, 0.0, 0.0))], hits=[0.0]).result()
    assert not just_out.success and just_out.partial
    conceded = play(trial, s, straight(0.0, 1.0, -0.8, 0.0, -1.0, 0.0), hits=[0.0]).result()
    assert conceded.conceded and not conceded.partial
    not_hit = play(trial, s, [(0.0, (-0.5, 0.0, 0.0, 0.0))]).result()
    assert not not_hit.success and not not_hit.partial


def test_a_cut_that_stops_the_puck_dead_against_the_mallet_is_a_hit(s):
    """The simulation reports a contact when it ends; a Cut whose mallet stopped the puck dead (at rest while
    their contact lasts) was scored "at rest" without a hit. At rest while touching is a hit, and only for the
    touching robot's rest: a puck at rest on its own, untouched, is still no hit."""
    trial = make_trial("cut", 0, 0, s)
    start = (0.0, trial.state[:4])
    caught = TrialWatcher(trial, s)
    for t, st in (start, (0.01, (-0.5, 0.0, 0.0, 0.0))):
        caught.state(t, *st, touching=t > 0.0)
    r = caught.result()
    assert caught.done and r.hit and r.success and r.reason == "at rest against the mallet"
    alone = play(trial, s, [start, (0.01, (-0.5, 0.0, 0.0, 0.0))]).result()
    assert not alone.hit and not alone.success and alone.reason == "at rest"
    pushed = TrialWatcher(make_trial("prepare", 0, 0, s), s)  # a push begins on a puck at rest: no end there
    x0, y0 = pushed.trial.state[:2]
    pushed.state(0.0, x0, y0, 0.0, 0.0)
    pushed.state(0.01, x0, y0, 0.0, 0.0, touching=True)
    assert not pushed.done and not pushed.hit


def test_prepare_partial_on_the_own_half_and_failure_across_the_centre(s):
    trial = make_trial("prepare", 0, 0, s)
    assert play(trial, s, [(0.0, trial.state[:4]), (0.01, (-0.1, 0.4, 0.0, 0.0))], hits=[0.0]).result().partial
    across = play(trial, s, straight(0.0, 1.0, -0.05, 0.0, 0.5, 0.0), hits=[0.0]).result()
    assert not across.partial and "centre" in across.reason
    waiting = play(trial, s, [(t, (-0.8, 0.3, 0.0, 0.0)) for t in np.arange(0, 12, 0.1)])
    assert waiting.done and "without a hit" in waiting.result().reason  # a static puck nobody hits ...
    assert s.hit_timeout < waiting.result().duration <= s.hit_timeout + 0.1 + 1e-9  # ... ends at hit_timeout


def test_repel_success_is_the_hit_and_speed_is_taken_at_the_defend_line(s):
    trial = make_trial("repel", 0, 0, s)
    r = play(trial, s, straight(0.5, 2.0, -0.7, 0.0, 2.0, 0.0), hits=[0.5]).result()
    assert r.success and r.goal and r.defend_speed == pytest.approx(2.0)
    summary = summarise([r.as_dict(), play(trial, s, [(0.0, (-0.5, 0.0, 0.0, 0.0))]).result().as_dict()])
    assert summary["repel"]["success_rate"] == 0.5 and summary["repel"]["goal_rate"] == 0.5
    assert summary["repel"]["mean_speed_mps"] == pytest.approx(2.0)


def test_states_from_before_a_reported_contact_ended_are_not_a_rest_after_the_hit(s):
    """table_sim reports a contact when it ends; the puck's states from before then may arrive later
    (the strategy test once scored hit smashes "at rest" at their initial position this way)."""
    trial = make_trial("smash_straight", 0, 0, s)
    x0, y0 = trial.state[:2]
    w = TrialWatcher(trial, s)
    w.state(0.0, x0, y0, 0.0, 0.0)
    w.contact(0.90, 0.004)                # the hit, reported at 0.905 s
    w.state(0.899, x0, y0, 0.0, 0.0)      # a state from before it, delivered late
    w.state(0.902, x0, y0, 0.4, 0.0)      # during the contact
    assert not w.done
    for t, st in straight(0.91, 2.0, x0, y0, 3.0, 0.0):
        w.state(t, *st)
        if w.done:
            break
    assert w.done and w.result().goal


def test_a_shot_is_defended_when_the_opponent_touches_the_puck_after_the_hit(s):
    """strategy-test --defended: an opponent's contact counts only after the tested robot's hit has ended
    (before it, or in a trial without a hit, the shot was not defended); the summary reports the rate only
    for a defended run, and its table says it."""
    from air_hockey_agent.core.game.strategy.report import table
    trial = make_trial("smash_straight", 0, 0, s)
    x0, y0 = trial.state[:2]
    early = TrialWatcher(trial, s)
    early.state(0.0, x0, y0, 0.0, 0.0)
    early.opponent_contact(0.5)            # before any hit
    early.contact(0.9, 0.004)
    early.opponent_contact(0.902)          # during the hit: not after it
    assert early.hit and not early._result.defended
    early.opponent_contact(1.4)
    assert early._result.defended
    for t, st in straight(1.41, 2.0, x0, y0, -1.0, 0.0):  # sent back: no goal, the trial ends on its own
        early.state(t, *st)
        if early.done:
            break
    stopped = early.result()
    assert stopped.defended and not stopped.success and stopped.as_dict()["defended"]
    scored = play(trial, s, straight(0.91, 2.0, x0, y0, 3.0, 0.0), hits=[0.9]).result()
    assert scored.success and not scored.defended
    records = [stopped.as_dict(), scored.as_dict()]
    assert "defended_rate" not in summarise(records)["smash_straight"]
    summary = summarise(records, defended=True)
    assert summary["smash_straight"]["defended_rate"] == 0.5
    assert "the opponent touched the puck after the hit in 50.0 %" in table(summary, 1.0).splitlines()[1]


def test_guard_succeeds_unless_the_puck_enters_the_own_goal(s):
    """A guard trial ends at a goal conceded (failure), when the puck has left the goal's zone, or after guard_time
    (both successes); a puck at rest does not end it (the mallet may still push it in)."""
    trial = make_trial("guard", 0, 0, s)
    x0, y0 = trial.state[:2]
    conceded = play(trial, s, straight(0.0, 1.0, x0, y0, -0.5, 0.0), hits=[0.05]).result()
    assert conceded.conceded and not conceded.success and conceded.reason == "conceded" and conceded.hit
    out = play(trial, s, straight(0.0, 2.0, x0, y0, 0.6, 0.0)).result()
    assert out.success and out.reason == "left the goal's zone"
    assert out.duration == pytest.approx((s.guard_exit_depth - HALF - x0) / 0.6, abs=0.011)
    resting = play(trial, s, [(t, (x0, y0, 0.0, 0.0)) for t in np.arange(0.0, 10.0, 0.01)])
    r = resting.result()
    assert resting.done and r.success and r.reason == f"no goal in {s.guard_time:g} s"
    assert s.guard_time < r.duration <= s.guard_time + 0.011


def test_a_slow_slide_is_decided_once_its_remaining_travel_cannot_change_the_outcome():
    """With the table's damping d a puck at v slides at most v / d: a Cut or Prepare trial ends when that
    disc is clear of the smash area's edge, the rims and the centre line, and not before."""
    s = TrialSettings.from_params(load_strategy_params(), damping=0.5)
    trial = make_trial("prepare", 0, 0, s)
    x0, y0 = trial.state[:2]
    inside_x = -HALF + 0.45  # the area's middle: 0.23 m from its depth edges, y 0
    for speed, decided in ((0.1, True), (0.12, False)):  # reach 0.2 m < margin 0.23 m; 0.24 m > 0.23 m
        w = TrialWatcher(trial, s)
        w.state(0.0, x0, y0, 0.0, 0.0)
        w.contact(0.0, 0.01)
        w.state(0.5, inside_x, 0.0, speed, 0.0)
        assert w.done is decided, (speed, w.result().reason)
        if decided:
            assert w.result().success and "decided" in w.result().reason
    far = TrialWatcher(trial, s)  # outside the area, clear of it: decided as partial
    far.state(0.0, x0, y0, 0.0, 0.0)
    far.contact(0.0, 0.01)
    far.state(0.5, -HALF + 0.80, 0.0, 0.055, 0.0)  # 0.12 m beyond the area, reach 0.11 m
    assert far.done and not far.result().success and far.result().partial
    undecided = TrialWatcher(trial, TrialSettings.from_params(load_strategy_params()))  # no damping known
    undecided.state(0.0, x0, y0, 0.0, 0.0)
    undecided.contact(0.0, 0.01)
    undecided.state(0.5, inside_x, 0.0, 0.06, 0.0)
    assert not undecided.done


def test_a_trial_record_is_the_result_with_error_tactic_and_initial_state():
    """The --results line of a trial (the node's and a failed worker's): every result field as it is,
    then whether it ended on an error, the tested robot's tactic with its reason, and the trial's initial
    puck state (as JSON gives it: a list; None for a trial no worker finished)."""
    result = TrialResult("smash_left", 3, hit=True, reason="timeout after 5 s without a hit", duration=5.0)
    state = (-0.6, 0.1, 0.0, 0.0, 0.0, 0.0)
    record = result.record(error=False, tactic="smash: smash forced: waiting until it applies", state=state)
    assert record == {**result.as_dict(), "error": False, "tactic": "smash: smash forced: waiting until it applies",
                      "state": list(state)}
    assert json.loads(json.dumps(record))["state"] == list(state)
    failed = TrialResult("cut", 7, reason="not finished twice (worker failed)").record(error=True, tactic="")
    assert failed["error"] and failed["tactic"] == "" and not failed["success"] and failed["rest"] is None
    assert failed["state"] is None


def test_the_summary_and_its_table_per_strategy():
    """What strategy-test prints: rates per strategy next to the thesis's, the smash offsets, Repel's goals and
    speed ('-' with no speed measured), failures by reason, most frequent first."""
    from air_hockey_agent.core.game.strategy.report import table

    def trial(strategy, success, partial=False, goal=False, offset=None, speed=None, reason="scored"):
        return {"strategy": strategy, "success": success, "partial": partial, "goal": goal, "offset": offset,
                "defend_speed": speed, "reason": reason}
    trials = [trial("smash_straight", True, offset=0.01), trial("smash_straight", True, offset=-0.03),
              trial("smash_straight", False, reason="no goal"),
              trial("cut", True, partial=True), trial("cut", False, partial=True, reason="at rest"),
              trial("cut", False, reason="conceded"), trial("cut", False, reason="at rest"),
              trial("repel", True, goal=True, speed=None),
              trial("guard", True), trial("guard", False, reason="conceded")]
    trials[-1]["hit"], trials[-2]["hit"] = True, False
    summary = summarise(trials)
    assert list(summary) == ["smash_straight", "cut", "repel", "guard"]  # KEYS' order, only those played
    smash, cut, repel = summary["smash_straight"], summary["cut"], summary["repel"]
    assert smash["success_rate"] == pytest.approx(2 / 3) and smash["offset_mean_m"] == pytest.approx(-0.01)
    assert smash["offset_std_m"] == pytest.approx(0.02) and cut["partial_rate"] == 0.5
    assert cut["failures"] == {"at rest": 2, "conceded": 1} and repel["mean_speed_mps"] is None
    lines = table(summary, 12.4).splitlines()
    assert lines[1].split()[:5] == ["smash_straight", "3", "66.7", "%", "82.2"]
    assert "offset -1.0 +- 2.0 cm" in lines[1]
    assert lines[2].split()[:9] == ["cut", "4", "25.0", "%", "34.3", "%", "50.0", "%", "76.7"]
    assert "goals 100.0 % (thesis 13 %), speed at the defend line - (thesis 1.57)" in lines[3]
    assert summary["guard"]["touched_rate"] == 0.5 and "partial_rate" not in summary["guard"]
    assert lines[4].split()[:6] == ["guard", "2", "50.0", "%", "-", "-"]  # ours: no thesis figure
    assert lines[4].endswith("no goal conceded; the mallet touched the puck in 50.0 %")
    assert lines[5] == "12 s of wall time"
    assert lines[6] == "  smash_straight failures: no goal x1"
    assert lines[7] == "  cut failures: at rest x2, conceded x1"
    assert lines[8] == "  guard failures: conceded x1"


def test_strategy_test_runs_the_thesiss_four_unless_guard_is_asked_for():
    """Guard is ours: the default run is the thesis's 600 trials (issue #12's time); Guard only on request."""
    from air_hockey_agent.tools.cli import build_parser
    parser = build_parser()
    assert sorted(parser.parse_args(["strategy-test"]).strategies) == ["cut", "prepare", "repel", "smash"]
    assert parser.parse_args(["strategy-test", "--strategies", "guard"]).strategies == ["guard"]
    assert not parser.parse_args(["strategy-test"]).defended  # the thesis's set-up: the opponent holds home
    assert parser.parse_args(["strategy-test", "--defended"]).defended
