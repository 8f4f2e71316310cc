"""Head to head (`air-hockey game --versus FILE`): the tally and its sign test, which parameters a variant
may set, the variant reaching one robot's agent (in process and in the node graph's arguments), the CLI."""
import json
import math
import subprocess
import sys
from pathlib import Path

import pytest

from air_hockey_agent.core.game.versus import DEFAULTS, VARIANT, VersusTally, variant_robot, versus_games
from air_hockey_agent.params import ParameterFileError
from air_hockey_agent.sim.params import ROBOTS

BIN = Path(sys.executable).parent


def result(front: int, back: int, hits=(10, 20)) -> dict:
    return {"score": {"iiwa_front": front, "iiwa_back": back}, "hits": {"iiwa_front": hits[0], "iiwa_back": hits[1]}}


def write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def test_the_variant_alternates_sides_and_its_goals_are_counted_on_its_side():
    robots = [variant_robot(ROBOTS, k) for k in range(4)]
    assert robots == ["iiwa_front", "iiwa_back", "iiwa_front", "iiwa_back"]
    assert versus_games(31, 4, ROBOTS) == [(31, "iiwa_front"), (31, "iiwa_back"), (32, "iiwa_front"), (32, "iiwa_back")]
    # game 0: the variant (front) wins 2:1; game 1: the variant (back) loses 0:3 to the front; game 2 drawn
    tally = VersusTally.from_results([result(2, 1, (5, 6)), result(3, 0, (7, 8)), result(1, 1, (1, 2))], robots[:3])
    assert tally.goals == {VARIANT: 2 + 0 + 1, DEFAULTS: 1 + 3 + 1}
    assert tally.hits == {VARIANT: 5 + 8 + 1, DEFAULTS: 6 + 7 + 2}
    assert tally.won == {VARIANT: 1, DEFAULTS: 1, "drawn": 1}
    with pytest.raises(ValueError):  # a game without its side
        VersusTally.from_results([result(1, 0)], [])


def test_the_sign_test_is_the_exact_binomial_one():
    """7 : 1 goals: two-sided p = 2 (C(8,7) + C(8,8)) / 2^8 = 18 / 256; (7 - 1) / sqrt(8) standard deviations;
    no goal: no test."""
    tally = VersusTally(1, {VARIANT: 7, DEFAULTS: 1}, {VARIANT: 0, DEFAULTS: 0}, {})
    assert tally.p_value == pytest.approx(18 / 256)
    assert tally.standard_deviations == pytest.approx(6 / math.sqrt(8))
    even = VersusTally(1, {VARIANT: 5, DEFAULTS: 5}, {VARIANT: 0, DEFAULTS: 0}, {})
    assert even.p_value == pytest.approx(1.0) and even.standard_deviations == 0.0
    none = VersusTally(1, {VARIANT: 0, DEFAULTS: 0}, {VARIANT: 0, DEFAULTS: 0}, {VARIANT: 0, DEFAULTS: 0, "drawn": 1})
    assert none.p_value is None and "no goal, no test" in none.line("f.yaml")
    assert set(none.result("f.yaml")) == {"params_file", "games", "goals", "hits", "won", "p_value",
                                          "standard_deviations"}


def test_a_variant_sets_tactics_trajectory_generator_and_tracker_parameters_only(tmp_path):
    from air_hockey_agent.agent_params import load_agent_variant, load_agent_params
    from air_hockey_agent.motion_params import load_motion_params
    good = write(tmp_path / "good.yaml", "/**:\n  ros__parameters:\n    hit_speed_fraction: 0.8\n"
                                         "/**/trajectory_generator:\n  ros__parameters:\n    planning_delay: 0.02\n")
    agent, motion = load_agent_variant(good)
    assert agent["hit_speed_fraction"] == 0.8 and motion["planning_delay"] == 0.02
    defaults_agent, defaults_motion = load_agent_params(), load_motion_params()
    assert {k for k in agent if agent[k] != defaults_agent[k]} == {"hit_speed_fraction"}
    assert {k for k in motion if motion[k] != defaults_motion[k]} == {"planning_delay"}
    for text, words in [
        ("/**/table_sim:\n  ros__parameters:\n    mocap_rate: 100.0\n", ["section '/**/table_sim'", "sets only"]),
        ("/**:\n  ros__parameters:\n    mocap_rate: 100.0\n", ["'mocap_rate' is not a parameter of tactics or"]),
        ("/**:\n  ros__parameters:\n    ready_gard_depth: 0.0\n", ["did you mean 'ready_guard_depth'"]),
        ("/**/tactics:\n  ros__parameters:\n    ready_gard_depth: 0.0\n", ["'ready_gard_depth'"]),
        ("/iiwa_front/tactics:\n  ros__parameters:\n    ready_guard_depth: 0.0\n", ["for any namespace"]),
    ]:
        bad = write(tmp_path / "bad.yaml", text)
        with pytest.raises(ParameterFileError) as err:
            load_agent_variant(bad)
        assert str(bad) in str(err.value) and all(w in str(err.value) for w in words), err.value


def test_the_node_graph_gives_the_file_to_one_robots_agent_nodes():
    from air_hockey_agent.node_graph import game_nodes
    plain = game_nodes(False, 0.0, 4)
    nodes = game_nodes(False, 0.0, 4, versus=("iiwa_back", "/v.yaml"))
    with_file = {n.label for n in nodes if "/v.yaml" in n.params_files}
    assert with_file == {"iiwa_back/tactics", "iiwa_back/trajectory_generator", "iiwa_back/puck_tracker"}
    for node, before in zip(nodes, plain):  # the file comes after the node's own files; nothing else changes
        assert node.params_files[:len(before.params_files)] == before.params_files
        assert node.parameters == before.parameters
        assert (node.params_files[-1:] == ("/v.yaml",)) == (node.label in with_file)


@pytest.mark.slow  # in-process: no ROS node
def test_in_process_the_variant_reaches_one_robot_only_and_defaults_change_nothing(tmp_path):
    """The variant robot's selector, planner and tick read the file; the other robot's the defaults; a file
    that repeats a default plays the default game exactly."""
    from air_hockey_agent.sim.game_loop import InProcessGame
    variant = write(tmp_path / "v.yaml", "/**/tactics:\n  ros__parameters:\n    ready_guard_depth: 0.0\n"
                                         "/**/trajectory_generator:\n  ros__parameters:\n    planning_delay: 0.02\n")
    game = InProcessGame(3, versus=("iiwa_back", str(variant)))
    try:
        back, front = game.players["iiwa_back"], game.players["iiwa_front"]
        assert back.selector.s.ready_guard_depth == 0.0 and front.selector.s.ready_guard_depth > 0.0
        assert back.arm.planning_delay == 0.02 and front.arm.planning_delay != 0.02
        assert back.agent["puck_params_file"] == front.agent["puck_params_file"]  # the sim table's physics
    finally:
        game.close()
    assert len(game.trackers) == 1  # no puck_tracker parameter: one tracker for both, as before
    tracked = write(tmp_path / "t.yaml", "/**/puck_tracker:\n  ros__parameters:\n    mallet_contact:\n"
                                         "      enabled: false\n")
    game = InProcessGame(3, versus=("iiwa_back", str(tracked)))
    try:  # the variant's tracker is that robot's alone, as each robot's puck_tracker node in the node graph
        (shared, own) = game.trackers
        assert shared.robots == ("iiwa_front",) and own.robots == ("iiwa_back",) and shared.ekf is game.ekf
        assert own.ekf.mallets is None and shared.ekf.mallets is not None
        game.run(4.0)
        assert own.ekf.stats.frames == shared.ekf.stats.frames > 400  # both see every frame
        assert own.ekf.stats.mallet_contacts == 0 < shared.ekf.stats.mallet_contacts
        assert game.players["iiwa_back"].situation.t == own.ekf.stamp
    finally:
        game.close()
    same = write(tmp_path / "same.yaml", "/**/tactics:\n  ros__parameters:\n    ready_guard_depth: 0.24\n")
    results = []
    for versus in (None, ("iiwa_front", str(same))):
        game = InProcessGame(3, versus=versus)
        try:
            results.append(game.run(4.0))
        finally:
            game.close()
    assert results[0] == results[1]


@pytest.mark.slow  # in-process: no ROS node
def test_versus_plays_each_seed_on_both_sides_and_equal_agents_tie_exactly(tmp_path):
    """Each seed twice, the variant once per side; a variant equal to the defaults (a file repeating a
    default) ties every pair exactly, goals and hits; the tally is the results'; the text has the line."""
    same = write(tmp_path / "same.yaml", "/**/tactics:\n  ros__parameters:\n    ready_guard_depth: 0.24\n")
    command = [str(BIN / "air-hockey"), "game", "--in-process", "--games", "4", "--workers", "2", "--seed", "31",
               "--duration", "10", "--versus", str(same)]
    out = subprocess.run([*command, "--json"], capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    data = json.loads(out.stdout)
    assert [(g["seed"], g["versus_robot"]) for g in data["games"]] == versus_games(31, 4, ROBOTS)
    versus = data["total"]["versus"]
    sides = [robot for _, robot in versus_games(31, 4, ROBOTS)]
    assert versus == VersusTally.from_results(data["games"], sides).result(str(same))
    assert versus["goals"][VARIANT] == versus["goals"][DEFAULTS] and versus["hits"][VARIANT] == versus["hits"][DEFAULTS]
    assert sum(versus["hits"].values()) == sum(data["total"]["hits"].values()) > 0
    assert data["games"][0]["score"] == data["games"][1]["score"]  # the same game twice
    text = subprocess.run([*command[:4], "2", *command[5:]], capture_output=True, text=True, timeout=600)
    assert text.returncode == 0 and f"versus {same} against the defaults, 2 games: goals" in text.stdout
    odd = subprocess.run([*command[:4], "3", *command[5:]], capture_output=True, text=True, timeout=60)
    assert odd.returncode == 2 and "an even number" in odd.stderr and len(odd.stderr.strip().splitlines()) == 1


@pytest.mark.parametrize("text, words", [
    (None, ["--versus", "no such file"]),
    ("/**/referee:\n  ros__parameters:\n    rate: 50.0\n", ["--versus", "section '/**/referee'"]),
    ("/**/tactics:\n  ros__parameters:\n    ready_guard_depth: 7.0\n", ["--versus", "ready_guard_depth", "outside"]),
])
def test_a_bad_variant_file_is_a_one_line_error(tmp_path, text, words):
    path = tmp_path / "v.yaml"
    if text is not None:
        path.write_text(text)
    out = subprocess.run([str(BIN / "air-hockey"), "game", "--in-process", "--duration", "1", "--versus", str(path)],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 2 and len(out.stderr.strip().splitlines()) == 1, out.stderr
    assert str(path) in out.stderr and all(w in out.stderr for w in words), out.stderr


def test_the_strategy_tests_workers_give_the_file_to_the_agents_nodes():
    from air_hockey_agent.tools.strategy_test import worker_processes
    specs = {spec.label: spec.command for spec in worker_processes([("guard", 0)], 3, "/v.yaml")}
    with_file = {label for label, command in specs.items() if "/v.yaml" in command}
    assert with_file == {"tactics", "trajectory_generator", "puck_tracker"}
    assert not any("/v.yaml" in c for c in (s.command for s in worker_processes([("guard", 0)], 3))), \
        "no variant: no file"


@pytest.mark.slow  # in-process: no ROS node
def test_a_strategy_test_variant_meets_the_same_pucks(tmp_path, monkeypatch):
    """`strategy-test --params-file`: a file that repeats a default plays the trials exactly as the defaults
    do; the JSON names the file."""
    from air_hockey_agent.sim.strategy_loop import run_chunk
    same = write(tmp_path / "same.yaml", "/**/tactics:\n  ros__parameters:\n    ready_guard_depth: 0.24\n")
    off = write(tmp_path / "off.yaml", "/**/tactics:\n  ros__parameters:\n    ready_guard_depth: 0.0\n")
    trials = [("guard", 0), ("guard", 1)]
    assert run_chunk(1, 0, trials) == run_chunk(1, 0, trials, str(same))
    from air_hockey_agent.sim import game_loop
    made = []

    class Spy(game_loop.InProcessGame):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            made.append(self.players["iiwa_front"].selector.s.ready_guard_depth)
    monkeypatch.setattr(game_loop, "InProcessGame", Spy)
    run_chunk(1, 0, trials[:1], str(off))
    assert made == [0.0]
    out = subprocess.run([str(BIN / "air-hockey"), "strategy-test", "--in-process", "--strategies", "guard", "--trials",
                          "1", "--params-file", str(off), "--json"], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    report = json.loads(out.stdout)
    assert report["params_file"] == str(off) and report["guard"]["trials"] == 1


@pytest.mark.slow  # in-process: no ROS node
def test_a_defending_opponent_reads_its_own_variant(tmp_path, monkeypatch):
    """`strategy-test --defended --opponent-params FILE`: the opponent's agent reads FILE and the tested robot's
    does not (and --params-file the other way round); the JSON names the file."""
    from air_hockey_agent.sim import game_loop
    from air_hockey_agent.sim.strategy_loop import run_chunk
    mine = write(tmp_path / "mine.yaml", "/**/tactics:\n  ros__parameters:\n    ready_guard_depth: 0.1\n")
    theirs = write(tmp_path / "theirs.yaml", "/**/tactics:\n  ros__parameters:\n    ready_guard_depth: 0.0\n")
    made = []

    class Spy(game_loop.InProcessGame):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            made.append({r: p.selector.s.ready_guard_depth for r, p in self.players.items()})
    monkeypatch.setattr(game_loop, "InProcessGame", Spy)
    run_chunk(0, 0, [("smash_straight", 0)], str(mine), True, str(theirs))
    run_chunk(0, 0, [("smash_straight", 0)], "", True, str(theirs))
    default = made[1]["iiwa_front"]
    assert made == [{"iiwa_front": 0.1, "iiwa_back": 0.0}, {"iiwa_front": default, "iiwa_back": 0.0}]
    assert default not in (0.0, 0.1)
    out = subprocess.run([str(BIN / "air-hockey"), "strategy-test", "--in-process", "--strategies", "repel", "--trials",
                          "1", "--defended", "--opponent-params", str(theirs), "--json"],
                         capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    report = json.loads(out.stdout)
    assert report["opponent_params"] == str(theirs) and report["defended"] and report["repel"]["trials"] == 1
    assert f"iiwa_back runs the agent's defaults and {theirs} and defends" in out.stderr
