"""Console scripts: `air-hockey --help`, node --help, honest not-implemented nodes, the game launcher."""
import json
import subprocess
import sys
from pathlib import Path

import pytest

BIN = Path(sys.executable).parent


def run(args, env=None, timeout=120):
    return subprocess.run(args, capture_output=True, text=True, timeout=timeout, env=env)


def test_air_hockey_help_lists_commands():
    result = run([str(BIN / "air-hockey"), "--help"])
    assert result.returncode == 0
    assert "game" in result.stdout


@pytest.mark.parametrize("node", ["strategy_test"])
def test_pending_node_says_not_implemented_and_exits_3(node, ros_env):
    result = run([str(BIN / node), "--ros-args", "-p", "use_sim_time:=true"], env=ros_env)
    assert result.returncode == 3
    assert "not implemented yet" in result.stdout + result.stderr


@pytest.mark.parametrize("args, message", [
    (["--duration", "-1"], "--duration must be a positive number"),
    (["--goals", "-2"], "--goals must be 0"),
    (["--real-time-factor", "-1"], "--real-time-factor must be 0 or more"),
    (["--record", "/nonexistent/dir/out.mcap"], "does not exist"),
])
def test_game_refuses_bad_arguments_in_one_line(args, message):
    result = run([str(BIN / "air-hockey"), "game", *args])
    assert result.returncode == 2
    assert message in result.stderr and len(result.stderr.strip().splitlines()) == 1


@pytest.mark.integration
def test_short_game_both_robots_hit_and_nothing_is_left_running(ros_env, tmp_path):
    """As fast as possible, 30 s of simulated time: both robots touch the puck (contacts reported by the
    simulation), the JSON result has the documented keys, and every node process is gone afterwards."""
    bag = tmp_path / "game.mcap"
    result = run([str(BIN / "air-hockey"), "game", "--duration", "30", "--seed", "2", "--json", "--record", str(bag),
                  "--domain-id", ros_env["ROS_DOMAIN_ID"]], env=ros_env, timeout=400)
    assert result.returncode == 0, result.stderr[-2000:]
    lines = result.stdout.strip().splitlines()
    assert len(lines) == 1
    game = json.loads(lines[0])
    assert set(game) == {"duration_s", "score", "hits", "faults", "tactics", "recording"}
    assert game["duration_s"] >= 30.0
    assert game["hits"]["iiwa_front"] >= 1 and game["hits"]["iiwa_back"] >= 1, game
    assert not any(k.startswith("robot_fault") for k in game["faults"]), game
    assert Path(game["recording"]).is_dir() and any(Path(game["recording"]).glob("*.mcap"))
    assert "Traceback" not in result.stderr
    leftovers = run(["pgrep", "-f", f"{BIN}/(table_sim|referee|tactics|puck_tracker|trajectory_generator)"])
    assert leftovers.stdout.strip() == ""
