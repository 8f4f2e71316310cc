"""What a user types, run as the user runs it (issue #14): every bad input gets exit code 2 and one line
naming what is wrong and where; habits from ROS 2 (whole numbers for floats) work."""
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

BIN = Path(sys.executable).parent


def run(args, env=None, timeout=120, cwd=None):
    return subprocess.run([str(a) for a in args], capture_output=True, text=True, timeout=timeout, env=env, cwd=cwd)


def assert_one_line_error(result, *words):
    # pybullet prints its build banner when a node that simulates imports it
    lines = [line for line in result.stderr.strip().splitlines() if not line.startswith("pybullet build time")]
    assert result.returncode == 2, (result.returncode, result.stderr[-2000:])
    assert len(lines) == 1 and "Traceback" not in result.stderr, result.stderr[-2000:]
    for word in words:
        assert word in lines[0], lines[0]


def run_until(args, marker, env, timeout=60.0):
    """Start a node, wait for ``marker`` in its log, stop it with SIGINT; (return code, output)."""
    proc = subprocess.Popen([str(a) for a in args], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            env=env)
    out, deadline = [], time.monotonic() + timeout
    try:
        for line in proc.stdout:
            out.append(line)
            if marker in line or time.monotonic() > deadline:
                break
        proc.send_signal(signal.SIGINT)
        rest, _ = proc.communicate(timeout=30)
        out.append(rest)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    return proc.returncode, "".join(out)


# --- node parameters ---------------------------------------------------------------------------------
def write(path, text):
    path.write_text(text)
    return path


@pytest.mark.parametrize("make_args, words", [
    (lambda d: ["-p", "dampign:=0.3"], ["'dampign' is not a parameter of puck_tracker", "did you mean 'damping'"]),
    (lambda d: ["--params-file", write(d / "a.yaml", "/**/puck_traker:\n  ros__parameters:\n    damping: 0.3\n")],
     ["a.yaml", "'/**/puck_traker' names no node", "did you mean 'puck_tracker'"]),
    (lambda d: ["--params-file", write(d / "b.yaml", "/**/puck_tracker:\n  ros__parameters:\n    dampign: 0.3\n")],
     ["b.yaml", "'dampign' is not a parameter of node 'puck_tracker'", "did you mean 'damping'"]),
    (lambda d: ["--params-file", d / "missing.yaml"], ["missing.yaml", "cannot read"]),
    (lambda d: ["--params-file", write(d / "c.yaml", "a: [\n")], ["c.yaml", "not valid YAML"]),
    (lambda d: ["-p", "damping:=-1.0"], ["damping", "out of range"]),
])
def test_a_misspelled_or_bad_node_parameter_is_a_one_line_error(ros_env, tmp_path, make_args, words):
    result = run([BIN / "puck_tracker", "--ros-args", *make_args(tmp_path)], env=ros_env, timeout=60)
    assert_one_line_error(result, "[puck_tracker] error:", *words)


def test_parameters_that_contradict_each_other_are_a_one_line_error(ros_env):
    result = run([BIN / "tactics", "--ros-args", "-p", "drift_speed:=0.1"], env=ros_env, timeout=60)
    assert_one_line_error(result, "[tactics] error:", "'drift_speed' = 0.1 must not exceed 'static_speed'")


def test_a_whole_number_is_accepted_for_a_float_parameter_and_logged(ros_env, tmp_path):
    """`-p real_time_factor:=0` (the README's own command) and `damping: 1` in a parameter file."""
    code, out = run_until([BIN / "table_sim", "--ros-args", "-p", "real_time_factor:=0"], "node ready", ros_env)
    assert code == 0 and "real_time_factor=0.0" in out and "Traceback" not in out, out[-2000:]
    params = write(tmp_path / "p.yaml", "/**/puck_tracker:\n  ros__parameters:\n    damping: 1\n")
    code, out = run_until([BIN / "puck_tracker", "--ros-args", "--params-file", params], "node ready", ros_env)
    assert code == 0 and "damping=1.0" in out and "Traceback" not in out, out[-2000:]


# --- air-hockey tools ------------------------------------------------------------------------------
def rest_bag(path):
    """A 3 s mocap recording of a puck lying still (what `record` gives with table_sim alone)."""
    import numpy as np
    from air_hockey_agent.bags.writer import BagWriter
    from air_hockey_agent.core.estimation.synthetic import SyntheticFrame
    from air_hockey_agent.tools.synth_bag import POSE_TOPIC, TRUTH_TOPIC, _messages
    from air_hockey_agent.tracker_params import load_tracker_params
    frames = [SyntheticFrame(k / 120.0, np.array([0.3, -0.1, 0.2]), np.array([0.3, -0.1, 0.0, 0.0, 0.2, 0.0]))
              for k in range(360)]
    with BagWriter(path, {POSE_TOPIC: "geometry_msgs/msg/PoseStamped",
                          TRUTH_TOPIC: "air_hockey_msgs/msg/PuckState"}) as writer:
        for topic, stamp, msg in _messages(frames, 100.0, load_tracker_params()["mocap_table_pose"]):
            writer.write(topic, stamp, msg)
    return path


@pytest.mark.parametrize("make_args, words", [
    (lambda d: ["synth-bag", d / "out", "--shots", "0"], ["--shots", "integer >= 1", "'0'"]),
    (lambda d: ["synth-bag", d / "out", "--seed", "-1"], ["--seed", "0..2147483647", "'-1'"]),  # was numpy's traceback
    (lambda d: ["bench", "tactics", "--seed", "2147483648"], ["--seed", "0..2147483647"]),
    (lambda d: ["game", "--domain-id", "200"], ["--domain-id", "1..101", "'200'"]),
    (lambda d: ["play", d, "--domain-id", "0"], ["--domain-id", "1..101", "'0'"]),
    (lambda d: ["bench", "tracker", "--samples", "0"], ["--samples"]),
    (lambda d: ["bench", "sim", "--duration", "-1"], ["--duration", "> 0"]),
    (lambda d: ["sysid", d, "--batch", "0"], ["--batch"]),
    (lambda d: ["sysid", d, "--iterations", "0"], ["--iterations"]),
    (lambda d: ["sysid", d, "--split", "1.5"], ["--split", "< 1"]),
    (lambda d: ["sysid", d, "--iterations", "3"], ["--iterations", "only with --method hebo"]),
    (lambda d: ["sysid", d, "--loss", "loglik"], ["--loss", "only with --method hebo"]),
    (lambda d: ["noise-estimate", d, "--horizon", "-1"], ["--horizon", "> 0"]),
    (lambda d: ["record", d / "rec", "--duration", "-5"], ["--duration", ">= 0"]),
    (lambda d: ["strategy-test", "--workers", "0"], ["--workers"]),
    (lambda d: ["strategy-test", "--in-process", "--domain-id", "5"], ["--domain-id need the node graph"]),
    (lambda d: ["strategy-test", "--opponent-params", write(d / "o.yaml", "/**/tactics:\n  ros__parameters:\n"
                                                                 "    ready_guard_depth: 0.1\n")],
     ["--opponent-params needs --defended"]),
    (lambda d: ["strategy-test", "--defended", "--opponent-params", d / "none.yaml"],
     ["--opponent-params", "none.yaml", "no such file"]),
    (lambda d: ["game", "--in-process", "--table", d / "none.yaml"], ["--table", "none.yaml", "no such file"]),
    (lambda d: ["strategy-test", "--table", write(d / "t.yaml", "/**/puck_tracker:\n  ros__parameters:\n"
                                                                "    damping: 0.2\n")],
     ["--table", "t.yaml", "no '/**/table_sim' section"]),
    (lambda d: ["plot", d, "--out", write(d / "notabag.txt", "x")], ["--out", "is a file"]),
    # a parameter file the command reads nothing of (another node's) is an error, not silently without effect
    (lambda d: ["eval-prediction", d, "--params-file", write(d / "agent.yaml", "/**/tactics:\n  ros__parameters:\n"
                                                                               "    rate: 50.0\n")],
     ["agent.yaml", "--params-file sets no parameter of puck_tracker and sysid", "'/**/tactics'"]),
    (lambda d: ["synth-bag", d / "out", "--params-file", write(d / "sim.yaml", "/**/table_sim:\n  ros__parameters:\n"
                                                                                "    surface_damping: 0.2\n")],
     ["sim.yaml", "sets no parameter of puck_tracker and synth_bag"]),
    (lambda d: ["bench", "tracker", "--params-file", write(d / "ref.yaml", "/**/reference_filter:\n"
                                                                          "  ros__parameters:\n    damping: 0.2\n")],
     ["ref.yaml", "sets no parameter of puck_tracker,"]),
    (lambda d: ["plot", d, "--compare", write(d / "sim.yaml", "/**/table_sim:\n  ros__parameters:\n"
                                                              "    surface_damping: 0.2\n")],
     ["sim.yaml", "--compare sets no parameter of puck_tracker"]),
    (lambda d: ["game-check", d, "--plot", write(d / "taken.txt", "x") / "sub"], ["--plot", "cannot create"]),
    (lambda d: ["sysid", rest_bag(d / "bag"), "--out", write(d / "old.yaml", "x")], ["old.yaml", "exists already"]),
    (lambda d: ["noise-estimate", rest_bag(d / "bag")], ["found 0", "at rest throughout", "nothing moved it"]),
    (lambda d: ["shoot", "--speed", "-1", "--angle", "0"], ["--speed", ">= 0"]),
    (lambda d: ["service", "call", "/set_puck_state", "air_hockey_msgs/srv/SetPuckState", "{vx: 1.0, speed: 2}",
                "--timeout", "0.5"], ["speed: no such field in SetPuckState_Request"]),
    (lambda d: ["topic", "echo", "/no/such/topic", "--wait", "0.5"], ["/no/such/topic is not published"]),
    # an unknown option is reported by the tool it was given to (it named the top-level command)
    (lambda d: ["noise-estimate", d, "--bogus"], ["air-hockey noise-estimate: error", "--bogus",
                                                 "see air-hockey noise-estimate --help"]),
    (lambda d: ["bench", "tracker", "--bogus", "3"], ["air-hockey bench tracker: error", "--bogus 3"]),
    (lambda d: ["param", "get", "node", "name", "--bogus"], ["air-hockey param get: error", "--bogus"]),
    # a bag that is not there is one line, without a second "found 0 trajectories" line
    (lambda d: ["sysid", d / "missing"], ["missing: does not exist"]),
    (lambda d: ["noise-estimate", d / "missing"], ["missing: does not exist"]),
    (lambda d: ["plot", d], ["no bags (rosbag2 or ROS 1) in this directory"]),
])
def test_a_bad_tool_argument_is_a_one_line_error(ros_env, tmp_path, make_args, words):
    result = run([BIN / "air-hockey", *make_args(tmp_path)], env=ros_env, timeout=120)
    assert_one_line_error(result, *words)


@pytest.mark.parametrize("command", [["strategy-test", "--in-process", "--trials", "1"],
                                     ["game", "--in-process", "--duration", "1"]])
def test_a_value_out_of_bounds_in_an_edited_config_directory_is_one_line_naming_the_file(ros_env, tmp_path, command):
    """An edited config/ (AIR_HOCKEY_CONFIG_DIR's copy) with a value outside its bounds: the tools say which file,
    node and parameter in one line (it was a traceback that named no file)."""
    import shutil
    from air_hockey_agent.paths import config_dir
    copy = tmp_path / "config"
    shutil.copytree(config_dir(), copy)
    text = (copy / "agent.yaml").read_text()
    assert "    prepare_horizon: 8.0 " in text
    (copy / "agent.yaml").write_text(text.replace("    prepare_horizon: 8.0 ", "    prepare_horizon: 40.0 "))
    result = run([BIN / "air-hockey", *command], env={**ros_env, "AIR_HOCKEY_CONFIG_DIR": str(copy)}, timeout=120)
    assert_one_line_error(result, f"air-hockey {command[0]}: error: {copy / 'agent.yaml'}: /tactics: parameter "
                                  "'prepare_horizon' = 40.0 is outside [0.1, 30.0]")


def test_version_and_help_texts_are_plain():
    version = run([BIN / "air-hockey", "--version"])
    assert version.returncode == 0 and version.stdout.startswith("air-hockey ")
    for args in (["strategy-test", "--help"], ["bench", "tactics", "--help"], ["record", "--help"]):
        text = run([BIN / "air-hockey", *args]).stdout
        assert text and "``" not in text and ":class:" not in text and ":func:" not in text
    node_help = run([BIN / "tactics", "--help"]).stdout
    assert "tactics node" in node_help and "``" not in node_help


def test_synth_bag_and_eval_prediction_count_the_same_lost_frames(tmp_path):
    import json
    import re
    made = run([BIN / "air-hockey", "synth-bag", tmp_path / "bag", "--shots", "3", "--seed", "4"])
    assert made.returncode == 0, made.stderr
    lost = int(re.search(r"\((\d+) frames lost\)", made.stdout).group(1))
    evaluated = run([BIN / "air-hockey", "eval-prediction", tmp_path / "bag", "--json"])
    assert evaluated.returncode == 0, evaluated.stderr
    assert json.loads(evaluated.stdout)["lost_frames"] == lost > 0


def test_game_check_of_a_bag_without_joint_states_is_a_one_line_error(tmp_path):
    made = run([BIN / "air-hockey", "synth-bag", tmp_path / "puck_only", "--shots", "1", "--seed", "4"])
    assert made.returncode == 0, made.stderr
    assert_one_line_error(run([BIN / "air-hockey", "game-check", tmp_path / "puck_only"]),
                          "puck_only", "no /<robot>/joint_states", "air-hockey game --record")
    assert_one_line_error(run([BIN / "air-hockey", "game-check", tmp_path / "missing"]), "missing", "does not exist")


def test_prediction_optimizer_without_a_tracker_fails_in_one_line(ros_env, tmp_path):
    made = run([BIN / "air-hockey", "synth-bag", tmp_path / "bags" / "b", "--shots", "3", "--seed", "5"])
    assert made.returncode == 0, made.stderr
    result = run([BIN / "prediction_optimizer", "--ros-args", "-p", f"bags:={tmp_path / 'bags'}", "-p",
                  "topic:=/optitrack/puck", "-p", "tracker:=/nobody", "-p", "service_timeout:=1.0", "-p",
                  "iterations:=1", "-p", "batch:=1"], env=ros_env, timeout=120)
    lines = result.stderr.strip().splitlines()
    assert result.returncode == 1 and "Traceback" not in result.stderr, result.stderr[-2000:]
    assert lines[-1].startswith("[prediction_optimizer] error: optimisation stopped: service /nobody/")


def test_gui_without_a_display_is_a_one_line_error(ros_env):
    env = {k: v for k, v in ros_env.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    assert_one_line_error(run([BIN / "air-hockey", "game", "--gui", "--duration", "2"], env=env),
                          "--gui needs a display")
    result = run([BIN / "table_sim", "--ros-args", "-p", "gui:=true"], env=env, timeout=60)
    assert_one_line_error(result, "[table_sim] error: gui:=true needs a display")


@pytest.mark.parametrize("delay", [0.05, 0.4, 1.0])
def test_a_node_stopped_while_it_starts_leaves_no_traceback(ros_env, delay):
    """The launcher stops a node that is not ready yet with SIGTERM (it may still be importing, where
    SIGINT printed a KeyboardInterrupt traceback), a ready one with SIGINT."""
    from air_hockey_agent.tools.launch import Launcher, ProcessSpec
    with Launcher(ros_env, echo=None) as launcher:
        running = launcher.start(ProcessSpec("tactics", [str(BIN / "tactics"), "--ros-args", "-r", "__ns:=/iiwa_front"]))
        time.sleep(delay)
        launcher.stop("tactics", grace=10.0)
    output = "\n".join(running.lines)
    assert "Traceback" not in output and "KeyboardInterrupt" not in output, output[-2000:]
