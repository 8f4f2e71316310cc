"""Console scripts: `air-hockey --help`, node --help, the game launcher."""
import json
import os
import re
import shlex
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from air_hockey_agent.paths import config_file

BIN = Path(sys.executable).parent


def run(args, env=None, timeout=120):
    return subprocess.run(args, capture_output=True, text=True, timeout=timeout, env=env)


def test_air_hockey_help_lists_commands():
    result = run([str(BIN / "air-hockey"), "--help"])
    assert result.returncode == 0
    assert "game" in result.stdout


@pytest.mark.parametrize("args, message", [
    (["--duration", "-1"], "--duration must be a positive number"),
    (["--goals", "-2"], "--goals must be 0"),
    (["--real-time-factor", "-1"], "--real-time-factor must be 0 or more"),
    (["--record", "/nonexistent/dir/out.mcap"], "does not exist"),
    (["--in-process", "--markers", "--domain-id", "7"], "--markers, --domain-id need the node graph"),
    (["--in-process", "--log", "/tmp/game.log"], "--log needs the node graph"),
    (["--games", "3"], "--games needs --in-process"),
    (["--in-process", "--workers", "2"], "--workers needs --in-process and --games"),
])
def test_game_refuses_bad_arguments_in_one_line(args, message):
    result = run([str(BIN / "air-hockey"), "game", *args])
    assert result.returncode == 2
    assert message in result.stderr and len(result.stderr.strip().splitlines()) == 1


@pytest.mark.slow  # in-process: no ROS node
def test_in_process_games_add_up_in_one_json_object(tmp_path):
    """Two games on two worker processes, recorded: their sum, one bag per game that game-check reads, and
    the same games as played one after the other, unrecorded."""
    command = [str(BIN / "air-hockey"), "game", "--in-process", "--games", "2", "--seed", "5", "--duration", "2", "--json"]
    result = run([*command, "--workers", "2", "--record", str(tmp_path / "games.mcap")], timeout=300)
    serial = run(command, timeout=300)
    assert result.returncode == 0 and serial.returncode == 0, result.stderr[-2000:] + serial.stderr[-2000:]
    out, unrecorded = json.loads(result.stdout), json.loads(serial.stdout)
    bags = [tmp_path / "games" / f"seed_{seed}" for seed in (5, 6)]
    assert [g.pop("recording") for g in out["games"]] == [str(b) for b in bags]
    assert [g.pop("recording") for g in unrecorded["games"]] == [None, None]
    assert out == unrecorded
    checked = run([str(BIN / "air-hockey"), "game-check", *map(str, bags), "--json"], timeout=300)
    assert checked.returncode == 0 and set(json.loads(checked.stdout)) >= {str(b) for b in bags}, checked.stdout[-2000:]
    assert [g["seed"] for g in out["games"]] == [5, 6]
    assert out["total"]["duration_s"] == pytest.approx(sum(g["duration_s"] for g in out["games"]))
    assert out["total"]["duration_s"] >= 4.0
    for robot in ("iiwa_front", "iiwa_back"):
        assert out["total"]["hits"][robot] == sum(g["hits"][robot] for g in out["games"])
    assert "Traceback" not in result.stderr


@pytest.mark.slow  # in-process: no ROS node
def test_sigterm_stops_in_process_games_and_their_workers_at_once():
    """SIGTERM (kill, timeout) during games on worker processes: exit 143 within seconds, no worker left
    (a pool left to finish would have played every queued 60 s game first)."""
    proc = subprocess.Popen([str(BIN / "air-hockey"), "game", "--in-process", "--games", "4", "--workers", "2",
                             "--duration", "60"], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 60
    workers = []
    while time.monotonic() < deadline and len(workers) < 2:  # the two spawned workers (and the resource tracker)
        time.sleep(0.5)
        workers = [int(p) for p in run(["pgrep", "-f", "-P", str(proc.pid), "spawn_main"]).stdout.split()]
    assert len(workers) == 2, "the workers did not start"
    time.sleep(2.0)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=30)
    assert proc.returncode == 143, err[-2000:]
    assert "Traceback" not in err
    time.sleep(1.0)
    assert not [w for w in workers if os.path.exists(f"/proc/{w}")]


def _ctrl_c_once(command: list[str], in_stderr: bool, ready) -> tuple[int, str, str]:
    """Start an air-hockey tool, read its stderr (else its stdout, with stderr merged) until ``ready(line)``, send
    SIGINT, and wait: its exit code, stdout and stderr. Killed if still running, whatever the outcome."""
    proc = subprocess.Popen([str(BIN / "air-hockey"), *command], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE if in_stderr else subprocess.STDOUT, text=True)
    try:
        stream = proc.stderr if in_stderr else proc.stdout
        assert stream is not None
        for line in stream:
            if ready(line):
                break
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    return proc.returncode, out, err or ""


@pytest.mark.slow  # in-process: no ROS node
def test_ctrl_c_stops_a_run_of_games_on_one_worker():
    """Ctrl-C during the first of several games on one worker ends that game and the run (exit 130); before, the
    game ended and the next ones were played in full."""
    code, out, _ = _ctrl_c_once(["game", "--in-process", "--games", "3", "--workers", "1", "--duration", "60"],
                                False, lambda line: line.startswith("[game] sim"))  # the first game is being played
    assert code == 130, out[-2000:]
    assert "interrupted: ending the game" in out and "game over" not in out and "Traceback" not in out, out[-2000:]


@pytest.mark.slow  # in-process: no ROS node
def test_an_interrupted_strategy_test_reports_the_trials_it_finished(tmp_path):
    """Ctrl-C during a long strategy test: the workers stop, the table and --results hold the trials finished
    so far, and the exit is 130 (before, everything was lost)."""
    out = tmp_path / "trials.jsonl"
    code, table, err = _ctrl_c_once(
        ["strategy-test", "--in-process", "--workers", "2", "--trials", "100", "--results", str(out)], True,
        lambda line: "trials [" in line and not line.split("]")[1].strip().startswith("0/"))  # some trials done
    assert code == 130, err[-2000:]
    finished = int(err.split("interrupted: ")[1].split(" of 600")[0])
    assert 0 < finished < 600
    rows = [line.split() for line in table.splitlines()]
    counts = [int(row[1]) for row in rows if len(row) > 1 and row[0] in ("smash_straight", "smash_left",
                                                                        "smash_right", "cut", "prepare", "repel")
              and row[1].isdigit()]
    assert counts and sum(counts) == finished and "interrupted" in table.splitlines()[-1]
    assert len(out.read_text().splitlines()) == finished


@pytest.mark.integration
def test_short_game_both_robots_hit_and_nothing_is_left_running(ros_env, tmp_path):
    """The README's recorded game and its check (README "The game", run here with --json and a private
    domain): as fast as possible, 30 s of simulated time: both robots touch the puck (contacts reported
    by the simulation), the JSON result has the documented keys, the recording holds the visualizer's
    markers until 30 s after the start (the clock ran before it while the nodes came up), and every node
    process is gone afterwards."""
    game_line, check_line = readme_block("### The game", 2)
    assert game_line[:3] == ["game", "--duration", "30"] and check_line[:2] == ["game-check", "game"]
    bag = tmp_path / game_line[game_line.index("--record") + 1]
    game_line[game_line.index("--record") + 1] = str(bag)
    result = run([str(BIN / "air-hockey"), *game_line, "--json", "--domain-id", ros_env["ROS_DOMAIN_ID"]],
                 env=ros_env, timeout=400)
    assert result.returncode == 0, result.stderr[-2000:]
    lines = result.stdout.strip().splitlines()
    assert len(lines) == 1
    game = json.loads(lines[0])
    assert set(game) == {"duration_s", "score", "hits", "faults", "tactics", "goals", "recording"}
    for robot in game["score"]:  # each goal logged, with the tactic the last touch began in
        assert [g["scorer"] for g in game["goals"]].count(robot) == game["score"][robot], game
    assert all(g["tactic"] in game["tactics"][g["last_touch"]] for g in game["goals"] if g["last_touch"]), game
    assert game["duration_s"] >= 30.0
    assert game["hits"]["iiwa_front"] >= 1 and game["hits"]["iiwa_back"] >= 1, game
    assert not any(k.startswith("robot_fault") for k in game["faults"]), game
    assert Path(game["recording"]).is_dir() and any(Path(game["recording"]).glob("*.mcap"))
    assert "Traceback" not in result.stderr
    plots = tmp_path / check_line[check_line.index("--plot") + 1]
    checked = run([str(BIN / "air-hockey"), "game-check", game["recording"], "--json", "--plot", str(plots)])
    assert checked.returncode == 0, checked.stderr[-2000:]
    drawn = plots / f"{Path(game['recording']).name}_arms.png"
    assert drawn.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and f"wrote {drawn}" in checked.stderr
    arms = json.loads(checked.stdout)[game["recording"]]
    for robot in ("iiwa_front", "iiwa_back"):  # recorded joint states and plans of both arms, inside the region
        assert arms[robot]["joint_states"] > 1000 and arms[robot]["trajectories"] >= 1, arms
        assert arms[robot]["worst_outside_m"] < 0.005 and arms[robot]["trajectories_outside"] == 0, arms
        assert arms[robot]["contacts"]["puck"] == "/sim/puck_true_state", arms  # the contact law's report
    contacts = plots / f"{Path(game['recording']).name}_contacts.png"  # drawn where contacts were measured
    measured = any(arms[robot]["contacts"]["each"] for robot in ("iiwa_front", "iiwa_back"))
    assert contacts.is_file() == measured and (f"wrote {contacts}" in checked.stderr) == measured, checked.stderr
    spans, shown = _marker_stamps(game["recording"])
    from air_hockey_agent.bags.reader import iter_raw  # latched topics recorded from before the recorder joined
    latched = [topic for topic, _, _ in iter_raw(game["recording"], ["/iiwa_front/puck/physics", "/iiwa_back/puck/physics"])]
    assert sorted(set(latched)) == ["/iiwa_back/puck/physics", "/iiwa_front/puck/physics"], latched
    # 30 s from the referee's start: the clock runs before it while the nodes come up and the robots go
    # home (4.8-9.0 s of sim time in our runs), and counting from the clock's zero ended the game at 30.0 s
    # (the recording may begin a little after the start: its subscriptions are discovered on the way)
    assert spans[-1] >= 31.0 and spans[-1] - spans[0] >= 20.0, (spans[0], spans[-1])
    assert {"table", "puck", "prediction", "measurement", "score", "iiwa_front/mallet", "iiwa_back/mallet",
            "iiwa_front/hit", "iiwa_back/hit"} <= shown, shown
    leftovers = run(["pgrep", "-f", f"{BIN}/(table_sim|referee|tactics|puck_tracker|trajectory_generator|visualizer)"])
    assert leftovers.stdout.strip() == ""


def readme_block(heading: str, lines: int) -> list[list[str]]:
    """The arguments after ``.venv/bin/air-hockey`` of each line of the README's block under ``heading``
    that this file tests (``readme-test: tested by test/test_node_cli.py``), which has ``lines`` lines."""
    text = (Path(__file__).resolve().parents[1] / "README.md").read_text()
    section = text[text.index(heading):]
    block = re.search(r"tested by test/test_node_cli.py -->\n```bash\n(.*?)```", section, re.S).group(1)
    found = [shlex.split(line.split("  #")[0]) for line in block.splitlines() if line.strip()]
    assert all(line[0] == ".venv/bin/air-hockey" for line in found) and len(found) == lines
    return [line[1:] for line in found]


def _marker_stamps(bag: str) -> tuple[list[float], set[str]]:
    """Sim-time stamps of the recorded marker arrays and every namespace they drew."""
    from air_hockey_agent.bags.reader import iter_raw
    from air_hockey_agent.bags.types import typestore
    store, stamps, namespaces = typestore(), [], set()
    for _, _, raw in iter_raw(bag, ["/visualization/markers"]):
        array = store.deserialize_cdr(raw, "visualization_msgs/msg/MarkerArray")
        drawn = [m for m in array.markers if m.action == 0]
        namespaces |= {m.ns for m in drawn}
        stamps += [drawn[0].header.stamp.sec + drawn[0].header.stamp.nanosec * 1e-9] if drawn else []
    return sorted(stamps), namespaces


def _children(pid: int) -> list[int]:
    found = run(["pgrep", "-P", str(pid)])
    return [int(p) for p in found.stdout.split()]


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return Path(f"/proc/{pid}").is_dir() and "Z" not in Path(f"/proc/{pid}/stat").read_text().split()[2]


def _signalled_once_its_nodes_run(command: list[str], env: dict, count: int, sig: int,
                                  settle: float = 0.0) -> tuple[int, str, list[int], list[int]]:
    """Start an air-hockey tool, wait until it has ``count`` child processes (its nodes), send ``sig`` after
    ``settle`` s more and wait for the tool: its exit code, stderr, the nodes, and those still running 20 s
    after (killed: never leave a node behind, whatever the outcome)."""
    proc = subprocess.Popen([str(BIN / "air-hockey"), *command], env=env, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True)
    nodes: list[int] = []
    left: list[int] = []
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and len(nodes) < count and proc.poll() is None:
            time.sleep(0.2)
            nodes = _children(proc.pid)
        assert len(nodes) == count, f"{command[0]} started {len(nodes)} nodes"
        time.sleep(settle)
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline and any(_alive(pid) for pid in nodes):
            time.sleep(0.2)
        left = [pid for pid in nodes if _alive(pid)]
        for pid in left:
            os.killpg(pid, signal.SIGKILL)
    return proc.returncode, err, nodes, left


@pytest.mark.integration
def test_game_stopped_by_sigterm_while_starting_stops_every_node(ros_env):
    """`kill`, `timeout` or a CI runner stop a tool with SIGTERM: the game then stops its nodes as on Ctrl-C
    (they run in their own process groups, so before, all eight were left running) and exits 143."""
    code, err, nodes, left = _signalled_once_its_nodes_run(
        ["game", "--duration", "600", "--domain-id", ros_env["ROS_DOMAIN_ID"]], ros_env, 8, signal.SIGTERM)
    assert code in (0, 143), err[-2000:]  # 0: the game had begun, ended early and was reported
    assert "Traceback" not in err, err[-2000:]
    assert not left, f"{len(left)} of {len(nodes)} nodes still running after the game ended"


@pytest.mark.integration
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_strategy_test_stopped_by_a_signal_stops_every_node(ros_env, sig):
    """SIGTERM or Ctrl-C during a strategy test on nodes: exit 143 / 130 and every node stopped (its workers
    are threads: before, the tool ended and every node ran on, the simulation as fast as it could)."""
    code, err, nodes, left = _signalled_once_its_nodes_run(
        ["strategy-test", "--trials", "20", "--workers", "1", "--domain-id", ros_env["ROS_DOMAIN_ID"]], ros_env, 5,
        sig, settle=2.0)
    assert code == 128 + sig, err[-2000:]
    assert "Traceback" not in err, err[-2000:]
    assert not left, f"{len(left)} of {len(nodes)} nodes still running after the tool ended"


@pytest.mark.integration
def test_strategy_test_small_run_reports_real_hits(ros_env, tmp_path):
    """The README's small strategy test (README "Strategy test", run here with --json, --results and a
    private domain): one trial each of the three smashes, Repel and Guard, as fast as possible: the report
    has the documented structure, every smash or repel counted as a success was touched by the robot
    (contacts from the sim), the Guard trial (the force released) ended by its own rules, and the
    plots are drawn."""
    (line,) = readme_block("## Strategy test", 1)
    assert line[:6] == ["strategy-test", "--strategies", "smash", "repel", "guard", "--trials"] and "--plot" in line
    plots = tmp_path / line[line.index("--plot") + 1]
    line[line.index("--plot") + 1] = str(plots)
    lines_file = tmp_path / "trials.jsonl"
    result = run([str(BIN / "air-hockey"), *line, "--json", "--results", str(lines_file),
                  "--domain-id", ros_env["ROS_DOMAIN_ID"]], env=ros_env, timeout=600)
    assert result.returncode == 0, result.stderr[-2000:]
    for name in ("strategy_success.png", "smash_spread.png"):
        assert (plots / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", name
    report = json.loads(result.stdout.strip().splitlines()[-1])
    assert set(report) == {"smash_straight", "smash_left", "smash_right", "repel", "guard", "seconds"}
    assert {"success_rate", "offset_mean_m", "offset_std_m", "trials"} <= set(report["smash_left"])
    assert {"success_rate", "goal_rate", "mean_speed_mps", "trials"} <= set(report["repel"])
    assert {"success_rate", "touched_rate", "trials"} <= set(report["guard"])
    trials = [json.loads(line) for line in lines_file.read_text().splitlines()]
    assert len(trials) == 5 and not any(t["error"] for t in trials), trials
    assert all(len(t["state"]) == 6 for t in trials)  # the initial state, to play a trial again
    forced = [t for t in trials if t["strategy"] != "guard"]
    assert all(t["hit"] for t in forced if t["success"])
    assert all(t["tactic"].startswith(("smash: ", "repel: ")) for t in forced)  # the forced tactic and why
    assert sum(t["hit"] for t in forced) >= 2  # the robot played, not only the clock
    (guard,) = [t for t in trials if t["strategy"] == "guard"]
    assert guard["reason"] in ("left the goal's zone", "no goal in 4 s", "conceded"), guard
    leftovers = run(["pgrep", "-f", f"{BIN}/(table_sim|strategy_test|tactics|puck_tracker|trajectory_generator)"])
    assert leftovers.stdout.strip() == ""


@pytest.mark.integration
def test_strategy_test_with_a_defending_opponent(ros_env, tmp_path):
    """`strategy-test --defended` in the node graph: iiwa_back's own agent nodes run, held in Ready through its
    force_tactic until the tested robot's hit and then released; the report says so and gives how often the
    opponent touched the puck after the hit, and every process is gone afterwards."""
    lines_file = tmp_path / "trials.jsonl"
    result = run([str(BIN / "air-hockey"), "strategy-test", "--strategies", "smash", "--trials", "1", "--defended",
                  "--json", "--results", str(lines_file), "--domain-id", ros_env["ROS_DOMAIN_ID"]],
                 env=ros_env, timeout=600)
    assert result.returncode == 0, result.stderr[-2000:]
    assert "iiwa_back runs the agent's defaults and defends" in result.stderr
    report = json.loads(result.stdout.strip().splitlines()[-1])
    assert report["defended"] is True and {"defended_rate", "success_rate"} <= set(report["smash_left"])
    trials = [json.loads(line) for line in lines_file.read_text().splitlines()]
    outcomes = "; ".join(f"{t['strategy']}: hit {t['hit']}, {t['reason']} ({t['tactic']})" for t in trials)
    assert len(trials) == 3 and not any(t["error"] for t in trials) and all(t["hit"] for t in trials), outcomes
    assert sum(t["defended"] for t in trials) >= 2, outcomes  # the released opponent met the shots
    leftovers = run(["pgrep", "-f", f"{BIN}/(table_sim|strategy_test|tactics|puck_tracker|trajectory_generator)"])
    assert leftovers.stdout.strip() == ""


def test_strategy_test_on_a_table_file(ros_env, tmp_path):
    """`strategy-test --table config/lab_table.yaml` in the node graph: table_sim takes the file's table, the
    tracker and the tactics config/tracker.yaml's real-table physics (not the file's), the strategy_test node the file's
    timeout and table; the report names the file, and every process is gone afterwards."""
    log = tmp_path / "nodes.log"
    lab = str(config_file("lab_table.yaml"))
    result = run([str(BIN / "air-hockey"), "strategy-test", "--strategies", "cut", "--trials", "1", "--table", lab,
                  "--json", "--log", str(log), "--domain-id", ros_env["ROS_DOMAIN_ID"]], env=ros_env, timeout=600)
    assert result.returncode == 0, result.stderr[-2000:]
    assert json.loads(result.stdout.strip().splitlines()[-1])["table"] == lab
    text = log.read_text()
    sim = next(line for line in text.splitlines() if "table_sim" in line and "other than the defaults" in line)
    assert "surface_damping=0.085" in sim and "surface_tilt=0.002" in sim and "rim_restitution_slope=0.193" in sim
    assert "random_acceleration=0.01" in sim and "rim_tangential_scale=0.3" in sim
    tactics = next(line for line in text.splitlines() if "shots aimed with the tracker's puck physics" in line)
    assert "damping=0.125" in tactics
    trials = next(line for line in text.splitlines() if "[strategy_test]: parameters other than" in line)
    assert f"table_file='{lab}'" in trials and "timeout=25.0" in trials
    leftovers = run(["pgrep", "-f", f"{BIN}/(table_sim|strategy_test|tactics|puck_tracker|trajectory_generator)"])
    assert leftovers.stdout.strip() == ""
