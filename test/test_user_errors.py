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
    lines = result.stderr.strip().splitlines()
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


def test_a_whole_number_is_accepted_for_a_float_parameter_and_logged(ros_env, tmp_path):
    """`-p real_time_factor:=0` (the README's own command) and `restitution: 1` in a parameter file."""
    code, out = run_until([BIN / "table_sim", "--ros-args", "-p", "real_time_factor:=0"], "node ready", ros_env)
    assert code == 0 and "real_time_factor=0.0" in out and "Traceback" not in out, out[-2000:]
    params = write(tmp_path / "p.yaml", "/**/puck_tracker:\n  ros__parameters:\n    restitution: 1\n")
    code, out = run_until([BIN / "puck_tracker", "--ros-args", "--params-file", params], "node ready", ros_env)
    assert code == 0 and "restitution=1.0" in out and "Traceback" not in out, out[-2000:]
