"""The game in one process (sim/game_loop.py) and the ROS-free pieces the nodes now share with it:
the arm's command bookkeeping (core/motion/arm_commander.py) and the tracker's prediction for the
agents (core/estimation/agent_prediction.py)."""
import numpy as np
import pytest

from air_hockey_agent.core.estimation.agent_prediction import predict_for_agents
from air_hockey_agent.core.estimation.ekf import PuckEKF
from air_hockey_agent.core.game.situation import build_situation, situation_from_prediction
from air_hockey_agent.core.motion.arm_commander import ArmCommander
from air_hockey_agent.core.motion.planner import ACCEPTED, INVALID, Command
from air_hockey_agent.motion_params import build_planner, load_motion_params
from air_hockey_agent.sim.params import load_sim_params
from air_hockey_agent.tracker_params import load_tracker_params


@pytest.fixture(scope="module")
def commander():
    params = load_motion_params()
    return lambda: ArmCommander(build_planner(params, "iiwa_front"), 0.03, 0.2)


def test_arm_commander_starts_ahead_from_the_plan_or_the_measured_posture(commander):
    arm = commander()
    assert arm.plan(Command(np.array([-0.6, 0.0]), np.zeros(2), 1.0), 0.0).outcome == INVALID  # no joints yet
    q0 = np.array(load_sim_params()["home_joint_positions"], float)  # the simulated arms' home
    arm.measure(0.0, q0, np.zeros(7))
    start = arm.start_state(0.0)
    assert start.t == pytest.approx(0.03) and np.allclose(start.q, q0) and not np.any(start.dq)
    plan = arm.plan(Command(np.array([-0.7, 0.1]), np.zeros(2), 1.0), 0.0)
    assert plan.outcome == ACCEPTED, plan.message
    times, q, dq = arm.accept(plan, 0.0)
    assert times[0] == pytest.approx(0.03) and np.allclose(q[0], q0) and np.all(np.diff(times) > 0)
    # a later command starts from the running plan's state 30 ms on, not from the measured posture
    mid = arm.start_state(0.2)
    assert np.allclose(mid.q, arm.running.sample(0.23)[0]) and np.allclose(mid.dq, arm.running.sample(0.23)[1])
    assert np.any(mid.dq) and not np.allclose(mid.q, q0)
    # the arm is not where the plan says (a reset): the plan is dropped with the error, and the next
    # motion starts from the measured posture at rest
    assert arm.measure(0.2, arm.running.sample(0.2)[0], np.zeros(7)) is None and arm.running is not None
    error = arm.measure(0.25, q0 + 0.5, np.zeros(7))
    assert error > 0.2 and arm.running is None
    assert np.allclose(arm.start_state(0.25).q, q0 + 0.5)


def test_prediction_for_agents_matches_the_filter_and_the_message_the_node_built():
    params = load_tracker_params()
    ekf = PuckEKF.from_params(params)
    ekf.reset([0.2, -0.1, -1.5, 0.8, 0.0, 3.0], 10.0)
    out = predict_for_agents(ekf, 1.0, 0.02, 0.3)
    half = ekf.model.table.length / 2
    assert out.defend_lines == {"iiwa_front": pytest.approx(-half + 0.3), "iiwa_back": pytest.approx(half - 0.3)}
    assert out.sample_period == pytest.approx(2 / params["frequency"])  # whole model steps nearest 0.02 s
    direct = ekf.predict(1.0, [-half + 0.3, half - 0.3, -half, half], 2)
    assert np.allclose(out.prediction.state, direct.state) and len(out.prediction.impacts) == len(direct.impacts) >= 1
    assert -half + 0.3 in out.prediction.crossings  # the puck flies toward iiwa_front's line
    # the situation the tactics get equals the one the tactics node builds from the message's fields
    pred = out.prediction
    n = len(pred.samples)
    from_message = build_situation("iiwa_back", 10.0, ekf.x, 10.0 + out.sample_period * np.arange(1, n + 1),
                                   np.array([s for _, s, _ in pred.samples]),
                                   [(10.0 + t, x, y) for t, _, x, y, _ in pred.impacts])
    here = situation_from_prediction("iiwa_back", ekf.x, out)
    assert np.allclose(here.times, from_message.times) and np.allclose(here.states, from_message.states)
    assert np.allclose(here.puck, from_message.puck) and here.puck[0] == pytest.approx(-0.2)  # back's own frame


def _fingerprint(game) -> tuple:
    world = game.world
    joints = tuple(np.round(np.concatenate(world.joint_state(r)), 12).tobytes() for r in ("iiwa_front", "iiwa_back"))
    return np.round(world.puck_state(), 12).tobytes(), joints


@pytest.mark.slow  # in-process: no ROS node
def test_in_process_game_repeats_exactly_and_both_robots_play():
    """A seed repeats the game to the bit (puck and arm states at the end, the tally), another seed
    gives another game, and in 10 s both robots hit the puck and play a hit tactic."""
    from air_hockey_agent.sim.game_loop import InProcessGame
    results = []
    for seed in (3, 3, 4):
        game = InProcessGame(seed)
        try:
            duration = 10.0 if seed == 3 else 2.0
            results.append((game.run(duration), _fingerprint(game)))
        finally:
            game.close()
    (first, end1), (again, end2), (_, other) = results
    assert first == again and end1 == end2
    assert other[0] != end1[0]
    assert first["duration_s"] == pytest.approx(10.0, abs=0.01)
    assert first["hits"]["iiwa_front"] >= 1 and first["hits"]["iiwa_back"] >= 1, first
    assert not any(k.startswith("robot_fault") for k in first["faults"]), first
    for robot in ("iiwa_front", "iiwa_back"):
        assert {"smash", "cut"} & set(first["tactics"][robot]), first


def test_check_ends_the_game_where_it_raises():
    """The tool's interrupt check, called after every step, ends the game there as Ctrl-C does (a signal whose
    exception Python discarded is raised by it), and the result is the game up to that step."""
    from air_hockey_agent.sim.game_loop import play_game
    steps = []

    def check() -> None:
        steps.append(None)
        if len(steps) == 300:
            raise KeyboardInterrupt

    result = play_game(3, 10.0, check=check)
    assert len(steps) == 300
    assert 0.0 < result["duration_s"] < 10.0


@pytest.mark.slow  # in-process: no ROS node
def test_a_recorded_in_process_game_is_the_same_game_and_holds_the_node_graphs_topics(tmp_path):
    """Recording changes nothing in the game (the same tally and end state as unrecorded); the bag holds
    every topic the node graph's recording holds, game-check reads it (both arms, their trajectories),
    the tactic messages are the scoreboard's tactic entries, and the markers are the visualizer's scene."""
    from air_hockey_agent.bags.reader import bag_topics, iter_raw
    from air_hockey_agent.bags.types import typestore
    from air_hockey_agent.sim.game_loop import JOINT_NAMES, InProcessGame
    from air_hockey_agent.sim.game_record import GameRecorder
    from air_hockey_agent.sim.game_topics import MARKER_TOPICS, RECORDED_TOPICS
    from air_hockey_agent.tools.game_check import check_bag
    runs = []
    for record in (None, tmp_path / "game"):
        game = InProcessGame(8)
        try:
            if record is None:
                runs.append((game.run(3.0), _fingerprint(game)))
                continue
            with GameRecorder(record, JOINT_NAMES) as game.recorder:
                runs.append((game.run(3.0), _fingerprint(game)))
        finally:
            game.close()
    assert runs[0] == runs[1]
    result, bag = runs[1][0], tmp_path / "game"
    assert bag_topics(bag) == {**RECORDED_TOPICS, **MARKER_TOPICS}
    store, topics = typestore(), bag_topics(bag)
    messages: dict[str, list] = {}
    for topic, log_ns, raw in iter_raw(bag, dict.fromkeys(topics)):
        messages.setdefault(topic, []).append((log_ns, store.deserialize_cdr(raw, topics[topic])))
    for robot in ("iiwa_front", "iiwa_back"):
        assert len(messages[f"/{robot}/tactic"]) == sum(result["tactics"][robot].values())
        assert len(messages[f"/{robot}/hit_command"]) == len(messages[f"/{robot}/trajectory_status"])
    assert messages["/game_status"][-1][1].status == 2  # running
    from air_hockey_agent.core.puck.model import PuckParams
    for robot in ("iiwa_front", "iiwa_back"):  # the one tracker's physics, once (learning is off), from 0
        (_, physics), = messages[f"/{robot}/puck/physics"]
        assert (physics.stamp.sec, physics.stamp.nanosec, physics.impacts_learned) == (0, 0, 0)
        assert PuckParams.from_attributes(physics) == game.ekf.model.params
    end = messages["/iiwa_front/joint_states"][-1][1].header.stamp
    assert end.sec + end.nanosec * 1e-9 >= 3.0
    markers = messages["/visualization/markers"][-1][1].markers
    assert markers[0].action == 3 and {"table", "puck", "iiwa_front/mallet", "iiwa_back/mallet", "score"} <= {
        m.ns for m in markers}
    planners = {r: build_planner(load_motion_params(), r) for r in ("iiwa_front", "iiwa_back")}
    checked = check_bag(bag, planners)
    assert set(checked) == {"iiwa_front", "iiwa_back"}
    assert all(r["trajectories"] >= 1 and r["worst_outside_m"] == 0.0 for r in checked.values()), checked


@pytest.mark.slow  # in-process: no ROS node
def test_in_process_strategy_trials_repeat_exactly_and_score_real_hits():
    """The strategy test's chunk of trials on a fresh table twice: the same records, each with the trial's
    initial state; the smash and the repel are touched by the robot (contacts from the simulation) and
    scored; so is the guard trial's puck, which the agent (nothing forced) sends out of its goal's zone."""
    from air_hockey_agent.core.game.strategy.trials import make_trial
    from air_hockey_agent.sim.strategy_loop import chunk_seed, chunks, run_chunk
    from air_hockey_agent.strategy_params import trial_settings
    trials = [("smash_straight", 0), ("repel", 0), ("prepare", 1), ("guard", 1)]
    first, again = run_chunk(0, 0, trials), run_chunk(0, 0, trials)
    assert first == again
    assert [(r["strategy"], r["index"]) for r in first] == trials
    settings = trial_settings()
    assert [r["state"] for r in first] == [list(make_trial(s, i, 0, settings).state) for s, i in trials]
    assert first[0]["hit"] and first[1]["hit"] and not any(r["error"] for r in first), first
    assert first[0]["tactic"].startswith("smash: ") and first[2]["tactic"].startswith("prepare: ")
    assert first[3]["hit"] and first[3]["success"] and first[3]["reason"] == "left the goal's zone", first[3]
    # chunks are cut from the run's list alone (not by workers), each with its own table seed
    listed = [(s, i) for i in range(25) for s in ("cut", "repel")]
    assert [(c, len(share)) for c, share in chunks(listed)] == [(0, 20), (1, 20), (2, 10)]
    assert chunk_seed(0, 0) != chunk_seed(0, 1) and chunk_seed(0, 1) == chunk_seed(0, 1)


@pytest.mark.slow  # in-process: no ROS node, about 15 s
def test_the_trackers_hand_regime_leaves_the_agents_repel_its_goals():
    """The strategy test's first 40 Repel trials (seed 0, in process, as `strategy-test --in-process`
    plays them): at least 36 goals. Every 100-trial run measured 93-95 % goals before the tracker's hand
    regime and after a hit came to end it (README "Strategy test"); the regime as first landed, which
    followed a puck reset and launched within half a second with a hand's noise into its approach, scored
    30 of these 40 (the issue's target, 30 %, is far below either: this guards the tracker's effect on
    the agent)."""
    from air_hockey_agent.sim.strategy_loop import chunks, run_chunk
    records = [r for c, share in chunks([("repel", i) for i in range(40)]) for r in run_chunk(0, c, share)]
    assert all(r["hit"] and not r["error"] for r in records)
    assert sum(r["goal"] for r in records) >= 36, [r["index"] for r in records if not r["goal"]]


@pytest.mark.slow  # in-process: no ROS node, about 10 s
def test_a_defending_opponent_plays_only_after_the_hit():
    """strategy-test --in-process --defended: the same trials, the opponent's agent held in Ready until the
    tested robot's hit, then free. Without it the opponent holds its home pose and never touches the puck,
    and the shots mostly score; with it, its contacts after the hit mark the trial defended, and none scores
    (the agent's own defence: 0 of 300 smashes and 0 of 100 Repels scored in `strategy-test --in-process
    --defended`, README "Strategy test")."""
    from air_hockey_agent.sim.strategy_loop import run_chunk
    trials = [("smash_straight", 0), ("smash_left", 0), ("repel", 0)]
    alone = run_chunk(0, 0, trials)
    defended = run_chunk(0, 0, trials, defended=True)
    assert not any(r["defended"] for r in alone) and sum(r["goal"] for r in alone) >= 2, alone
    assert all(r["hit"] and not r["error"] for r in defended), defended
    assert all(r["defended"] and not r["goal"] for r in defended), defended
    assert [r["strategy"] for r in defended] == [s for s, _ in trials]


@pytest.mark.slow  # in-process: no ROS node
def test_in_process_tactics_aim_with_the_trackers_physics():
    """As puck/physics in the node graph: each robot's tactics predict their shots with the one tracker's
    physics, in the robot's own frame (the table acceleration turned for iiwa_back), from the start and
    again when the tracker has learned more of the table."""
    from types import SimpleNamespace

    from air_hockey_agent.sim.game_loop import InProcessGame
    game = InProcessGame(3)
    try:
        for player in game.players.values():
            assert player.selector.shots.model.params == game.ekf.model.params  # a level table
        learned = game.ekf.model.params.with_values(restitution=0.8, table_acceleration=(0.01, -0.02))
        game.ekf.model = game.ekf.model.with_params(learned)
        game.ekf.learning = SimpleNamespace(counts=(1, 0))  # one rim impact learned
        game._share_physics()
        assert game.players["iiwa_front"].selector.shots.model.params == learned
        assert game.players["iiwa_back"].selector.shots.model.params == learned.with_values(table_acceleration=(-0.01, 0.02))
    finally:
        game.close()


@pytest.mark.slow  # in-process: no ROS node
def test_a_goal_names_the_mallet_that_last_touched_the_puck_and_its_tactic_then():
    """The game's goal log against the simulation's own contacts and the agent's tactic at each step: the
    first goal of the first of a few seeds that score within 20 s (goals are rare in self-play; at a2ac083
    seed 36 scored after 5.3 s, the only one of seeds 0-17, 21 and 36 within 20 s but seed 0 at 19.8 s;
    seed 14 did at ff23a29; since hits move with the puck, 2b77fc6, of seeds 0-62 and 174 only 30 at 2.1 s,
    18 at 10.0 s, 47 at 14.8 s and 58 at 16.5 s; since the tracker knows the mallets, of seeds 0-59 16 at
    2.1 s, 54 at 3.8 s, 36 at 6.2 s, 55 at 6.8 s, 6, 28 and 58 later) is attributed to the last contact
    before it."""
    from air_hockey_agent.core.game.tactics.base import NAMES
    from air_hockey_agent.sim.game_loop import InProcessGame
    for seed in (16, 54, 36, 55):
        game = InProcessGame(seed)
        contacts, tactics, step = [], [], game.step

        def watched(step=step, contacts=contacts, tactics=tactics, game=game):
            out = step()
            contacts.extend((c.time, c.robot) for c in out.contacts)
            tactics.append((out.time, {r: NAMES[p.selector.current] for r, p in game.players.items()}))
            return out
        game.step = watched
        try:
            result = game.run(20.0, goals=1)
            started = game.board.started_at
        finally:
            game.close()
        if result["goals"]:
            break
    else:
        pytest.fail("no goal in any of the seeds' first 20 s: choose seeds that score (air-hockey game --in-process)")
    (goal,) = result["goals"]
    assert sum(result["score"].values()) == 1 and result["score"][goal["scorer"]] == 1
    touched_at, robot = max(contacts)
    in_tactic = [names[robot] for t, names in tactics if t < touched_at][-1]  # decided before the contact began
    assert (goal["last_touch"], goal["tactic"], goal["own_goal"]) == (robot, in_tactic, robot != goal["scorer"])
    assert goal["before_goal_s"] == pytest.approx(started + goal["time_s"] - touched_at, abs=1e-6)
