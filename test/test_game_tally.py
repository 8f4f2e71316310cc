"""Hits from physics (sim contact events) and the game's tally (ROS-free)."""
from __future__ import annotations

import numpy as np
import pytest

from air_hockey_agent.core.game.referee import EVENT_GOAL_BACK, EVENT_GOAL_FRONT, EVENT_PUCK_STUCK, EVENT_ROBOT_FAULT
from air_hockey_agent.core.game.scoreboard import Scoreboard, fault_key
from air_hockey_agent.sim.contacts import ContactLog


def test_contact_is_reported_once_when_it_ends_with_the_puck_velocity_then():
    log = ContactLog(merge_steps=3)
    puck = [0.1, 0.2, 0.0, 0.0]
    assert log.step(0.001, {"iiwa_front": True}, puck) == []
    assert log.step(0.002, {"iiwa_front": False}, [0.1, 0.2, 1.0, 0.0]) == []
    assert log.step(0.003, {"iiwa_front": True}, [0.1, 0.2, 1.5, 0.0]) == []   # a short gap: the same contact
    ended = []
    for k in range(3):
        ended += log.step(0.004 + 0.001 * k, {"iiwa_front": False}, [0.11, 0.2, 2.0, 0.5])
    assert len(ended) == 1
    c = ended[0]
    assert (c.robot, c.time, c.duration, c.x, c.y) == ("iiwa_front", 0.001, pytest.approx(0.002), 0.1, 0.2)
    assert c.speed == pytest.approx(np.hypot(2.0, 0.5))


def test_a_contact_is_open_from_its_first_step_until_it_ends():
    log = ContactLog(merge_steps=2)
    assert log.open_robots() == ()
    log.step(0.001, {"iiwa_front": True, "iiwa_back": False}, [0.1, 0.2, 0.0, 0.0])
    assert log.open_robots() == ("iiwa_front",)
    log.step(0.002, {"iiwa_front": False, "iiwa_back": False}, [0.1, 0.2, 0.0, 0.0])
    assert log.open_robots() == ("iiwa_front",)  # apart for fewer than merge_steps: the same contact
    assert len(log.step(0.003, {"iiwa_front": False, "iiwa_back": False}, [0.1, 0.2, 0.0, 0.0])) == 1
    assert log.open_robots() == ()


def test_the_true_states_touched_flags_are_the_messages():
    from air_hockey_msgs.msg import PuckState
    from air_hockey_agent.sim.contacts import TOUCHED_FLAGS
    assert TOUCHED_FLAGS == {"iiwa_front": PuckState.FLAG_TOUCHED_FRONT, "iiwa_back": PuckState.FLAG_TOUCHED_BACK}
    assert not set(TOUCHED_FLAGS.values()) & {PuckState.FLAG_PREDICTED, PuckState.FLAG_MEASUREMENT_USED,
                                              PuckState.FLAG_OUTLIER_REJECTED, PuckState.FLAG_REINITIALISED}


def test_world_reports_a_mallet_hitting_the_puck():
    """The pybullet table: a robot's mallet driven into the puck gives one contact event for that robot."""
    from air_hockey_agent.sim.params import load_sim_params
    from air_hockey_agent.sim.world import SimSettings, TableWorld
    from air_hockey_agent.motion_params import build_planner, load_motion_params
    from air_hockey_agent.tools.bench_planner import ready_state
    world = TableWorld(SimSettings.from_params(load_sim_params()))
    try:
        world.set_joint_positions("iiwa_front", ready_state(build_planner(load_motion_params(), "iiwa_front")).q)
        world.step(20)  # the mallet at the playing height (home is raised above the puck)
        mallet = world.mallet_position("iiwa_front")
        world.move_puck([mallet[0] + 0.085, mallet[1], -1.0, 0.0, 0.0, 0.0])  # 5 mm away, sliding into it
        world.take_contacts()
        in_contact = set()
        for _ in range(300):
            world.step()
            in_contact.update(world.in_contact())
        assert in_contact == {"iiwa_front"} and world.in_contact() == ()  # while it lasted, then ended
        contacts = world.take_contacts()
        assert [c.robot for c in contacts] == ["iiwa_front"]
        assert contacts[0].vx > 0.3  # bounced back off the (held) mallet
    finally:
        world.close()


def test_the_games_time_counts_from_its_start_even_before_the_clock_is_heard():
    """The game's duration counts from the referee's start. On a loaded machine the launcher's clock
    subscription may not have heard the clock yet when the start is answered: the game then starts at the
    first clock heard, not at the clock's zero (a 30 s game that had started at 7.9 s ended at 30 s)."""
    board = Scoreboard(("iiwa_front", "iiwa_back"))
    board.start()
    assert board.played == 0.0
    board.on_clock(7.9)
    board.on_clock(10.0)
    assert board.played == pytest.approx(2.1)


def test_scoreboard_counts_events_once_and_names_faults_without_numbers():
    board = Scoreboard(("iiwa_front", "iiwa_back"))
    board.on_clock(7.25)  # nodes up and robots home: the game starts here
    board.start()
    reason = "iiwa_front's mallet at (-1.065, 0.030) m is in the rim"
    board.on_status(0, 0, EVENT_ROBOT_FAULT, reason, 3.0)
    board.on_status(0, 0, EVENT_ROBOT_FAULT, reason, 3.0)  # re-published status: same event
    board.on_status(0, 1, EVENT_GOAL_BACK, "goal for iiwa_back", 9.0)
    board.on_status(0, 1, EVENT_PUCK_STUCK, "iiwa_back kept the puck on its side for over 15 s", 30.0)
    for robot, name in [("iiwa_front", "ready"), ("iiwa_front", "ready"), ("iiwa_front", "smash"),
                        ("iiwa_front", "ready"), ("iiwa_back", "cut")]:
        board.on_tactic(robot, name)
    board.on_contact("iiwa_back")
    board.on_clock(19.75)
    r = board.result(None)
    assert r["score"] == {"iiwa_front": 0, "iiwa_back": 1} and r["hits"] == {"iiwa_front": 0, "iiwa_back": 1}
    assert r["faults"] == {"robot_fault: iiwa_front's mallet is in the rim": 1,
                           "puck_stuck: iiwa_back kept the puck on its side for over 15 s": 1}
    assert r["tactics"]["iiwa_front"] == {"ready": 2, "smash": 1}
    assert board.robot_faults == 1 and r["duration_s"] == 12.5
    assert fault_key(EVENT_ROBOT_FAULT, "iiwa_back's mallet crossed the centre line (0.071 m)") == \
        "robot_fault: iiwa_back's mallet crossed the centre line"


def test_scoreboard_total_adds_up_games():
    robots = ("iiwa_front", "iiwa_back")
    one = {"duration_s": 60.0, "score": {"iiwa_front": 1, "iiwa_back": 0}, "hits": {"iiwa_front": 3, "iiwa_back": 2},
           "faults": {"puck_stuck: x": 1}, "tactics": {"iiwa_front": {"ready": 2}, "iiwa_back": {"cut": 1}},
           "recording": None}
    two = {"duration_s": 30.5, "score": {"iiwa_front": 0, "iiwa_back": 2}, "hits": {"iiwa_front": 1, "iiwa_back": 4},
           "faults": {"puck_stuck: x": 2, "puck_out: y": 1}, "tactics": {"iiwa_front": {"ready": 1, "smash": 1},
                                                                        "iiwa_back": {}}, "recording": None}
    total = Scoreboard.total(robots, [one, two]).result(None)
    assert total == {"duration_s": 90.5, "score": {"iiwa_front": 1, "iiwa_back": 2},
                     "hits": {"iiwa_front": 4, "iiwa_back": 6}, "faults": {"puck_stuck: x": 3, "puck_out: y": 1},
                     "tactics": {"iiwa_front": {"ready": 3, "smash": 1}, "iiwa_back": {"cut": 1}}, "goals": [],
                     "recording": None}
    assert one["faults"] == {"puck_stuck: x": 1}  # the inputs are not changed


def test_the_table_and_progress_line_show_the_tally_in_columns():
    """What `make game` prints: one column per robot, a row per tactic entered by either (0 for the other),
    faults with their counts, the recording when there is one."""
    board = Scoreboard(("iiwa_front", "iiwa_back"))
    board.on_clock(1.0)
    board.start()
    board.on_status(2, 1, EVENT_PUCK_STUCK, "puck at rest in the neutral zone for 2 s", 4.0)
    for robot, name in [("iiwa_front", "smash"), ("iiwa_back", "cut"), ("iiwa_back", "ready")]:
        board.on_tactic(robot, name)
    board.on_contact("iiwa_front")
    board.on_clock(61.0)
    assert board.progress() == "sim   60.0 s  score iiwa_front 2 : 1 iiwa_back  hits 1 / 0  faults 1"
    lines = board.table("game.mcap").splitlines()
    assert lines[0] == "game over after 60.0 s of simulated time"
    rows = {line.split()[0] + (" " + line.split()[1] if line.split()[0] == "tactic" else ""): line.split()[-2:]
            for line in lines[1:-2]}
    assert rows == {"iiwa_front": ["iiwa_front", "iiwa_back"], "score": ["2", "1"], "hits": ["1", "0"],
                    "tactic cut": ["0", "1"], "tactic ready": ["0", "1"], "tactic smash": ["1", "0"]}
    assert len({len(line) for line in lines[1:-2]}) == 1  # right-aligned columns
    assert lines[-2] == "  faults: puck_stuck: puck at rest in the neutral zone for 2 s x1"
    assert lines[-1] == "  recording: game.mcap (open it in Foxglove)"
    assert Scoreboard(("iiwa_front", "iiwa_back")).table(None).splitlines()[-1] == "  faults: none"


def test_each_goal_is_logged_with_the_last_touch_and_the_tactic_it_began_in():
    """A goal names the mallet that last touched the puck, in the tactic it was in when the contact began
    (tactic messages may arrive after the contact's), and whether it was an own goal; a referee event in
    between (the puck reset) leaves a later goal untouched."""
    robots = ("iiwa_front", "iiwa_back")
    board = Scoreboard(robots)
    board.on_clock(2.0)
    board.start()
    board.on_tactic("iiwa_back", "ready", 2.0)
    board.on_tactic("iiwa_back", "smash", 3.0)
    board.on_tactic("iiwa_front", "ready", 2.5)
    board.on_tactic("iiwa_back", "ready", 3.51)  # after the hit, heard before the contact's end
    board.on_contact("iiwa_back", 3.5)
    board.on_status(0, 1, EVENT_GOAL_BACK, "goal for iiwa_back", 4.25)
    board.on_status(0, 1, EVENT_GOAL_BACK, "goal for iiwa_back", 4.25)  # re-published
    board.on_tactic("iiwa_front", "cut", 7.0)
    board.on_contact("iiwa_front", 7.2)
    board.on_status(0, 2, EVENT_GOAL_BACK, "goal for iiwa_back", 8.0)   # the front robot's own goal
    board.on_contact("iiwa_back", 9.0)
    board.on_status(0, 2, EVENT_PUCK_STUCK, "puck at rest in the neutral zone for 2 s", 10.0)
    board.on_status(1, 2, EVENT_GOAL_FRONT, "goal for iiwa_front", 12.0)  # nobody touched it since the reset
    goals = board.result(None)["goals"]
    assert goals == [
        {"time_s": 2.25, "scorer": "iiwa_back", "last_touch": "iiwa_back", "tactic": "smash", "before_goal_s": 0.75,
         "own_goal": False, "defender_tactic": "ready"},
        {"time_s": 6.0, "scorer": "iiwa_back", "last_touch": "iiwa_front", "tactic": "cut", "before_goal_s": 0.8,
         "own_goal": True, "defender_tactic": "cut"},
        {"time_s": 10.0, "scorer": "iiwa_front", "last_touch": None, "tactic": None, "before_goal_s": None,
         "own_goal": False, "defender_tactic": "ready"}]
    assert board.table(None).splitlines()[-2] == ("  goals by the last touch: iiwa_back's smash x1, own goal by "
                                                  "iiwa_front (cut) x1, untouched, for iiwa_front x1")
    total = Scoreboard.total(robots, [{**board.result(None), "seed": 5}, {**board.result(None), "seed": 6}])
    assert [g["seed"] for g in total.result(None)["goals"]] == [5, 5, 5, 6, 6, 6]
    assert total.goal_sources()["own goal by iiwa_front (cut)"] == 2
    assert "seed" not in goals[0]  # the inputs are not changed
