"""The package is laid out as colcon and `ros2 run` expect, in the venv and in a colcon-style install."""
import os
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import REPO

NODES = ["puck_tracker", "tactics", "trajectory_generator", "referee", "table_sim", "bag_player",
         "strategy_test", "prediction_optimizer", "visualizer"]


def _check_layout(prefix: Path) -> None:
    assert (prefix / "share" / "ament_index" / "resource_index" / "packages" / "air_hockey_agent").is_file()
    share = prefix / "share" / "air_hockey_agent"
    assert (share / "package.xml").is_file()
    assert (share / "config" / "tracker.yaml").is_file()
    assert {p.name for p in (share / "launch").iterdir()} == {"agent.launch.py", "game.launch.py"}
    for node in NODES:
        exe = prefix / "lib" / "air_hockey_agent" / node
        assert exe.is_file() and os.access(exe, os.X_OK), f"missing executable lib/air_hockey_agent/{node}"


def test_ament_index_finds_package_and_node_executables_in_venv():
    from ament_index_python.packages import get_package_prefix, get_package_share_directory

    prefix = Path(get_package_prefix("air_hockey_agent"))
    assert Path(get_package_share_directory("air_hockey_agent")) == prefix / "share" / "air_hockey_agent"
    _check_layout(prefix)


def test_ament_index_finds_interface_package():
    from ament_index_python.packages import get_package_share_directory

    share = Path(get_package_share_directory("air_hockey_msgs"))
    assert (share / "msg" / "PuckState.msg").is_file()
    assert (share / "srv" / "KalmanStep.srv").is_file()


def test_node_executable_from_lib_dir_runs(tmp_path):
    from ament_index_python.packages import get_package_prefix

    exe = Path(get_package_prefix("air_hockey_agent")) / "lib" / "air_hockey_agent" / "tactics"
    result = subprocess.run([str(exe), "--help"], capture_output=True, text=True, timeout=60)
    assert result.returncode == 0 and "tactics" in result.stdout


@pytest.mark.slow
def test_colcon_style_install_puts_executables_under_lib_package(tmp_path):
    """Run the setuptools commands colcon's ament_python build runs, into a fresh prefix."""
    prefix = tmp_path / "install"
    cmd = [sys.executable, "setup.py", "-q", "egg_info", "--egg-base", str(tmp_path),
           "build", "--build-base", str(tmp_path / "build"),
           "install", "--prefix", str(prefix), "--record", str(tmp_path / "record.txt"),
           "--single-version-externally-managed"]
    result = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr[-2000:]
    _check_layout(prefix)
    env = dict(os.environ, AMENT_PREFIX_PATH=str(prefix))
    found = subprocess.run([sys.executable, "-c", "from ament_index_python.packages import get_package_prefix;"
                            "print(get_package_prefix('air_hockey_agent'))"],
                           capture_output=True, text=True, env=env, timeout=60)
    assert found.stdout.strip() == str(prefix)


HEAVY = ("scipy.optimize", "numba", "pinocchio", "torch", "rclpy")


def heavy_imports(code: str) -> str:
    """The heavy libraries (:data:`HEAVY`) a fresh interpreter has imported after running ``code``."""
    probe = f"import sys\n{code}\nprint(' '.join(m for m in {HEAVY!r} if m in sys.modules))"
    result = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr[-1000:]
    return result.stdout.strip()


def test_the_parameter_checks_read_every_declaration_without_the_heavy_libraries():
    """Every tool and node checks its parameter files against every node's declarations (param_registry):
    reading them imported the tactics and motion stacks (numba, pinocchio) and the tool nodes' rclpy,
    0.5 s of each command's start."""
    assert heavy_imports("from air_hockey_agent.tracker_params import load_tracker_params\n"
                         "load_tracker_params()") == ""


def test_the_command_line_is_built_without_the_heavy_libraries():
    """Every `air-hockey` command builds the whole command line (each tool's parser) before it runs: that
    must not import scipy.optimize, numba, pinocchio, torch or rclpy, which only some tools need (they made
    a failing command take 1.2 s instead of 0.5 s). Each package's compiled modules are in place
    (setup_venv.sh byte-compiles it: with PYTHONDONTWRITEBYTECODE every process recompiled them)."""
    assert heavy_imports("from air_hockey_agent.tools.cli import build_parser\nbuild_parser()") == ""
    sources = sorted((REPO / "air_hockey_agent").rglob("*.py"))
    tag = sys.implementation.cache_tag
    compiled = [s for s in sources if (s.parent / "__pycache__" / f"{s.stem}.{tag}.pyc").exists()]
    assert len(compiled) == len(sources), sorted(set(map(str, sources)) - set(map(str, compiled)))[:5]
